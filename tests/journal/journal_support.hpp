// Shared by the journal tests: deterministic sample streams and a visitor that records what a
// journal holds as a flat list of items.
// SPDX-License-Identifier: MIT
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "scanmesh/acquisition/journal.hpp"
#include "support/process.hpp"
#include "support/temp_dir.hpp"

namespace scanmesh::test {

namespace drv = scanmesh::drivers;

/// Sample `i` of a sensor stream: a deterministic function of (stream, i), so that any sample
/// read back can be checked by itself. Profiles of `points` points share a seq; every 37th
/// sample is no_target (NaN), every 101st an alarm with a device code.
inline drv::SensorSample sensor_sample(int stream, std::uint64_t i, std::uint32_t points = 1,
                                       bool device_time = false, std::int64_t t0_ns = 1'000'000'000,
                                       std::int64_t period_ns = 10'000) {
  drv::SensorSample s;
  s.seq = i / points;
  s.index = static_cast<std::uint32_t>(i % points);
  s.t_host.ns = t0_ns + static_cast<std::int64_t>(s.seq) * period_ns + stream * 7;
  if (device_time) s.t_device = drv::Timestamp{static_cast<std::int64_t>(s.seq) * 9'999 + 5};
  if (i % 101 == 100) {
    s.status = drv::SensorStatus::kAlarm;
    s.value_mm = std::numeric_limits<double>::quiet_NaN();
    s.device_code = 0x80000000u + static_cast<std::uint32_t>(i % 1000);
  } else if (i % 37 == 36) {
    s.status = drv::SensorStatus::kNoTarget;
    s.value_mm = std::numeric_limits<double>::quiet_NaN();
  } else {
    s.status = drv::SensorStatus::kOk;
    s.value_mm = 12.5 + std::sin(static_cast<double>(i) * 0.001 + stream) * 3.0 + 1e-9 * i;
  }
  return s;
}

/// Stage report `i`: odd ones carry a controller time, every tenth says the stage is idle.
inline drv::StageSample stage_sample(std::uint64_t i, std::int64_t t0_ns = 1'000'000'000,
                                     std::int64_t period_ns = 1'000'000) {
  drv::StageSample s;
  s.seq = i;
  s.t.ns = t0_ns + static_cast<std::int64_t>(i) * period_ns;
  s.pose = {0.01 * static_cast<double>(i), -0.5 * static_cast<double>(i % 100), 3.25,
            1e-4 * static_cast<double>(i)};
  if (i % 2 == 1) s.t_device = drv::Timestamp{static_cast<std::int64_t>(i) * 999'983};
  s.status = i % 10 == 0 ? drv::StageStatus::kIdle : drv::StageStatus::kMoving;
  return s;
}

/// Probe trigger `n` latched at stage report s: every other one with the controller's surface
/// point (a CMM).
inline drv::ProbeTrigger probe_trigger(std::uint64_t n, const drv::StageSample& s) {
  drv::ProbeTrigger p;
  p.seq = n;
  p.t = s.t;
  p.pose = s.pose;
  p.t_device = s.t_device;
  if (n % 2 == 0)
    p.surface = drv::SurfacePoint{s.pose.x_mm + 1.5, s.pose.y_mm, s.pose.z_mm - 2.0, 0.6, 0, 0.8};
  return p;
}

inline bool same_double(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

inline bool same_sample(const drv::SensorSample& a, const drv::SensorSample& b) {
  return a.seq == b.seq && a.t_host == b.t_host && a.t_device == b.t_device && a.index == b.index &&
         same_double(a.value_mm, b.value_mm) && a.status == b.status &&
         a.device_code == b.device_code;
}

inline bool same_pose(const drv::StagePose& a, const drv::StagePose& b) {
  return same_double(a.x_mm, b.x_mm) && same_double(a.y_mm, b.y_mm) &&
         same_double(a.z_mm, b.z_mm) && same_double(a.a_rad, b.a_rad);
}

inline bool same_stage(const drv::StageSample& a, const drv::StageSample& b) {
  return a.seq == b.seq && a.t == b.t && same_pose(a.pose, b.pose) && a.t_device == b.t_device &&
         a.status == b.status;
}

inline bool same_surface(const std::optional<drv::SurfacePoint>& a,
                         const std::optional<drv::SurfacePoint>& b) {
  if (a.has_value() != b.has_value()) return false;
  if (!a) return true;
  return same_double(a->x_mm, b->x_mm) && same_double(a->y_mm, b->y_mm) &&
         same_double(a->z_mm, b->z_mm) && same_double(a->i, b->i) && same_double(a->j, b->j) &&
         same_double(a->k, b->k);
}

inline bool same_probe(const drv::ProbeTrigger& a, const drv::ProbeTrigger& b) {
  return a.seq == b.seq && a.t == b.t && same_pose(a.pose, b.pose) && a.t_device == b.t_device &&
         same_surface(a.surface, b.surface);
}

/// One record of a journal as the tests see it: a sample (sensor, stage or probe) or a JSON
/// record, on a device or topic.
struct Item {
  std::string topic;
  drv::SensorSample sensor{};
  drv::StageSample stage{};
  drv::ProbeTrigger probe{};
  std::string json;
  std::int64_t t_ns = 0;

  friend bool operator==(const Item& a, const Item& b) {
    return a.topic == b.topic && same_sample(a.sensor, b.sensor) && same_stage(a.stage, b.stage) &&
           same_probe(a.probe, b.probe) && a.json == b.json && a.t_ns == b.t_ns;
  }
};

inline Item sensor_item(const std::string& device, const drv::SensorSample& s) {
  Item it;
  it.topic = "/sensors/" + device;
  it.sensor = s;
  return it;
}
inline Item stage_item(const std::string& topic, const drv::StageSample& s) {
  Item it;
  it.topic = topic;
  it.stage = s;
  return it;
}
inline Item probe_item(const std::string& topic, const drv::ProbeTrigger& p) {
  Item it;
  it.topic = topic;
  it.probe = p;
  return it;
}
inline Item json_item(const std::string& topic, const nlohmann::json& j, std::int64_t t) {
  Item it;
  it.topic = topic;
  it.json = j.dump();
  it.t_ns = t;
  return it;
}

/// Collects every record of a journal in the order the reader delivers them.
class Recorder final : public acq::JournalVisitor {
 public:
  std::vector<Item> items;
  std::vector<acq::ChannelInfo> channels;
  void on_channel(const acq::ChannelInfo& c) override { channels.push_back(c); }
  void on_sensor(const acq::ChannelInfo& c, std::span<const drv::SensorSample> s) override {
    for (const auto& x : s) items.push_back(sensor_item(c.device, x));
  }
  void on_stage(const acq::ChannelInfo& c, const drv::StageSample& s) override {
    items.push_back(stage_item(c.topic, s));
  }
  void on_probe(const acq::ChannelInfo& c, const drv::ProbeTrigger& p) override {
    items.push_back(probe_item(c.topic, p));
  }
  void on_event(const acq::ChannelInfo& c, drv::Timestamp t, std::string_view j) override {
    items.push_back(json_item(c.topic, nlohmann::json::parse(j), t.ns));
  }
  void on_parameters(const acq::ChannelInfo& c, drv::Timestamp t, std::string_view j) override {
    items.push_back(json_item(c.topic, nlohmann::json::parse(j), t.ns));
  }
};

/// The scan report's sum of samples per kind of channel.
inline std::uint64_t samples_of(const acq::JournalReport& r, acq::ChannelKind kind) {
  std::uint64_t n = 0;
  for (const auto& c : r.channels)
    if (c.channel.kind == kind) n += c.samples;
  return n;
}

}  // namespace scanmesh::test
