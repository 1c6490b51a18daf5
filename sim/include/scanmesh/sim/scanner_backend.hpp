// The simulated scanner as a scan backend: a simulated sensor on a simulated stage scanning a
// reference mesh, delivering its sample streams into the acquisition pipeline at the scan's own
// pace (or faster), with the devices' states and the faults a real scanner shows.
// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "scanmesh/acquisition/backend.hpp"
#include "scanmesh/drivers/device_support.hpp"
#include "scanmesh/recon/mesh.hpp"
#include "scanmesh/sim/simulator.hpp"

namespace scanmesh::sim {

struct SimulatedScannerOptions {
  std::string sensor_name = "sim-sensor";
  std::string stage_name = "sim-stage";
  /// Playback speed relative to the scan, > 0 (1: live; 10: ten times faster), or 0: as fast as
  /// the pipeline takes them. Default 1.
  double speed = 1;
  /// Fault: the sensor is lost this far into the scan (scan time) for `loss_duration`, then comes
  /// back; nothing it measured is lost (the motion holds while it is away, as the pipeline asks).
  std::optional<std::chrono::nanoseconds> sensor_loss_at;
  std::chrono::nanoseconds loss_duration{std::chrono::milliseconds(300)};
};

/// Runs `Simulator` over the scene on start() (on its own thread) and delivers the recorded
/// streams in time order: sensor device 0, the stage, probe triggers. Timestamps are the
/// simulation's own (a clock that starts at the plan's start time).
class SimulatedScanner final : public acq::ScanBackend {
 public:
  /// Validates the configuration (ConfigError).
  SimulatedScanner(recon::Mesh part, SimConfig config, SimulatedScannerOptions options = {});
  ~SimulatedScanner() override;

  std::string_view kind() const override { return "sim"; }
  acq::ScannerModel model() const override;
  std::vector<acq::DeviceStatus> devices() const override;
  void start(acq::SampleInput& input) override;
  void pause() override;
  void resume() override;
  void stop() noexcept override;

  const Simulator& simulator() const { return *simulator_; }

 private:
  void run(drivers::Worker& worker, acq::SampleInput& input);
  void set_sensor_state(drivers::DeviceState state, const std::string& reason,
                        acq::SampleInput* input);

  std::unique_ptr<Scene> scene_;
  std::unique_ptr<Simulator> simulator_;
  SimulatedScannerOptions options_;
  mutable std::mutex mutex_;  // guards the states and the pause bookkeeping
  drivers::DeviceState sensor_state_ = drivers::DeviceState::kClosed;
  drivers::DeviceState stage_state_ = drivers::DeviceState::kClosed;
  std::string sensor_reason_;
  std::uint64_t sensor_samples_ = 0, stage_samples_ = 0, gaps_ = 0;
  bool paused_ = false;
  std::chrono::steady_clock::time_point pause_began_;
  std::chrono::steady_clock::duration paused_total_{0};
  drivers::Worker worker_;
};

}  // namespace scanmesh::sim
