// Stage-against-emulator harness for the stage driver tests: collects position reports, probe
// triggers and state changes, fast stage options, and the reference parts the probe touches.
// SPDX-License-Identifier: MIT
#pragma once

#include <catch2/catch.hpp>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "scanmesh/drivers/motion_stage.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/simulator.hpp"
#include "support/sensor_harness.hpp"

namespace scanmesh::test {

/// Records what a stage driver delivers through its callbacks (worker thread).
class StageCollector {
 public:
  drivers::StageCallbacks callbacks() {
    drivers::StageCallbacks c;
    c.on_sample = [this](const drivers::StageSample& s) {
      {
        std::lock_guard lock(mutex_);
        samples_.push_back(s);
      }
      cv_.notify_all();
    };
    c.on_probe = [this](const drivers::ProbeTrigger& g) {
      std::lock_guard lock(mutex_);
      probes_.push_back(g);
    };
    c.on_state = [this](drivers::DeviceState st, const std::string& reason) {
      std::lock_guard lock(mutex_);
      states_.emplace_back(st, reason);
    };
    return c;
  }
  std::size_t count() {
    std::lock_guard lock(mutex_);
    return samples_.size();
  }
  std::vector<drivers::StageSample> copy() {
    std::lock_guard lock(mutex_);
    return samples_;
  }
  std::vector<drivers::ProbeTrigger> probes() {
    std::lock_guard lock(mutex_);
    return probes_;
  }
  bool wait_for(std::size_t n, std::chrono::milliseconds limit = kWaitLimit) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, limit, [&] { return samples_.size() >= n; });
  }
  bool resumes(std::size_t more) { return wait_for(count() + more); }
  bool saw(drivers::DeviceState st, const std::string& needle = "") {
    std::lock_guard lock(mutex_);
    for (const auto& [s, reason] : states_)
      if (s == st && reason.find(needle) != std::string::npos) return true;
    return false;
  }
  std::string state_log() {
    std::lock_guard lock(mutex_);
    std::string out;
    for (const auto& [s, reason] : states_)
      out += std::string(drivers::to_string(s)) + ": " + reason + "\n";
    return out;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<drivers::StageSample> samples_;
  std::vector<drivers::ProbeTrigger> probes_;
  std::vector<std::pair<drivers::DeviceState, std::string>> states_;
};

/// Short timeouts, fast reports and backoff, so loss and recovery happen within a test.
inline drivers::StageOptions fast_stage_options(std::string name,
                                                std::chrono::milliseconds timeout = 150ms) {
  drivers::StageOptions o;
  o.name = std::move(name);
  o.poll_interval = 10ms;
  o.timeout = timeout;
  o.timeouts_until_lost = 3;
  o.backoff_initial = 20ms;
  o.backoff_max = 200ms;
  o.homing_timeout = 20s;
  return o;
}

/// A built-in part as the touch probe's scene (shared by emulator and test).
inline std::shared_ptr<const sim::Scene> part_scene(const std::string& part) {
  return std::make_shared<const sim::Scene>(sim::make_part(part));
}

inline double distance(const drivers::StagePose& a, const drivers::StagePose& b) {
  const double dx = a.x_mm - b.x_mm, dy = a.y_mm - b.y_mm, dz = a.z_mm - b.z_mm;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

}  // namespace scanmesh::test
