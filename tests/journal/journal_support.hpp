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

inline drv::StageSample stage_sample(std::uint64_t i, std::int64_t t0_ns = 1'000'000'000,
                                     std::int64_t period_ns = 1'000'000) {
  drv::StageSample s;
  s.seq = i;
  s.t.ns = t0_ns + static_cast<std::int64_t>(i) * period_ns;
  s.pose = {0.01 * static_cast<double>(i), -0.5 * static_cast<double>(i % 100), 3.25,
            1e-4 * static_cast<double>(i)};
  return s;
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

/// One record of a journal as the tests see it: a sample (sensor, stage or probe) or a JSON
/// record, on a device or topic.
struct Item {
  std::string topic;
  drv::SensorSample sensor{};
  drv::StageSample stage{};
  std::string json;
  std::int64_t t_ns = 0;

  friend bool operator==(const Item& a, const Item& b) {
    return a.topic == b.topic && same_sample(a.sensor, b.sensor) && a.stage.seq == b.stage.seq &&
           a.stage.t == b.stage.t && same_pose(a.stage.pose, b.stage.pose) && a.json == b.json &&
           a.t_ns == b.t_ns;
  }
};

inline Item sensor_item(const std::string& device, const drv::SensorSample& s) {
  Item it;
  it.topic = "/sensors/" + device;
  it.sensor = s;
  return it;
}
inline Item pose_item(const std::string& topic, std::uint64_t seq, drv::Timestamp t,
                      const drv::StagePose& p) {
  Item it;
  it.topic = topic;
  it.stage = {seq, t, p};
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
    items.push_back(pose_item(c.topic, s.seq, s.t, s.pose));
  }
  void on_probe(const acq::ChannelInfo& c, const drv::ProbeTrigger& p) override {
    items.push_back(pose_item(c.topic, p.seq, p.t, p.pose));
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
