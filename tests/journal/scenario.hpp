// A scan in miniature written to a journal: a 100 kHz point sensor, a line profiler (64 points,
// device clock) at 1 kHz, a 1 kHz stage, probe triggers, events and parameters, interleaved as
// a pipeline would write them; returns the records in the order written.
// SPDX-License-Identifier: MIT
#pragma once

#include <functional>
#include <vector>

#include "journal/journal_support.hpp"

namespace scanmesh::test {

struct Scenario {
  int milliseconds = 2000;  ///< of sample time
  int point_per_ms = 100;   ///< point sensor samples per ms
  std::uint32_t profile_points = 64;
};

/// Writes the scenario through `w` (channels included) and returns what was written. `after`
/// runs after every millisecond of data (for tests that look at the file meanwhile).
inline std::vector<Item> write_scenario(acq::JournalWriter& w, const Scenario& sc = {},
                                        const std::function<void(int)>& after = {}) {
  std::vector<Item> items;
  const auto point = w.add_sensor("lkg0", {{"driver", "keyence-lkg"}});
  const auto line = w.add_sensor("line0", {{"driver", "sim-line"}});
  const auto stage = w.add_stage("xyz");
  const auto probe = w.add_probe("probe0");
  const std::int64_t t0 = 1'000'000'000;
  const nlohmann::json cfg{{"kind", "sensor_config"}, {"device", "lkg0"}, {"rate_hz", 100000}};
  w.write_parameters({t0}, cfg);
  items.push_back(json_item("/parameters", cfg, t0));
  const nlohmann::json started{{"event", "started"}, {"name", "bracket"}};
  w.write_event({t0}, started);
  items.push_back(json_item("/events", started, t0));
  std::vector<drivers::SensorSample> batch;
  for (int ms = 0; ms < sc.milliseconds; ++ms) {
    batch.clear();
    for (int k = 0; k < sc.point_per_ms; ++k)
      batch.push_back(sensor_sample(0, static_cast<std::uint64_t>(ms * sc.point_per_ms + k), 1,
                                    false, t0, 10'000));
    w.write_sensor(point, batch);
    for (const auto& s : batch) items.push_back(sensor_item("lkg0", s));
    batch.clear();
    for (std::uint32_t k = 0; k < sc.profile_points; ++k)
      batch.push_back(sensor_sample(1, static_cast<std::uint64_t>(ms) * sc.profile_points + k,
                                    sc.profile_points, true, t0, 1'000'000));
    w.write_sensor(line, batch);
    for (const auto& s : batch) items.push_back(sensor_item("line0", s));
    const auto st = stage_sample(static_cast<std::uint64_t>(ms), t0);
    w.write_stage(stage, st);
    items.push_back(pose_item("/stages/xyz", st.seq, st.t, st.pose));
    if (ms % 200 == 100) {
      const drivers::ProbeTrigger p{static_cast<std::uint64_t>(ms / 200), st.t, st.pose};
      w.write_probe(probe, p);
      items.push_back(pose_item("/probes/probe0", p.seq, p.t, p.pose));
    }
    if (after) after(ms);
  }
  const std::int64_t t_end = t0 + std::int64_t{sc.milliseconds} * 1'000'000;
  const nlohmann::json stopped{{"event", "stopped"}, {"reason", "done"}};
  w.write_event({t_end}, stopped);
  items.push_back(json_item("/events", stopped, t_end));
  return items;
}

/// Samples (sensor, stage, probe) among the items.
inline std::uint64_t sample_count(const std::vector<Item>& items) {
  std::uint64_t n = 0;
  for (const auto& it : items) n += it.json.empty() ? 1 : 0;
  return n;
}

}  // namespace scanmesh::test
