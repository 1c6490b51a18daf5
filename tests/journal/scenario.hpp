// A scan in miniature for the journal tests: a 100 kHz point sensor, a line profiler (64 points,
// device clock) at 1 kHz, a 1 kHz stage, probe triggers, events and parameters, interleaved as
// a pipeline would write them, millisecond by millisecond. Every step is a pure function of its
// number, so a test can rebuild what a killed writer wrote.
// SPDX-License-Identifier: MIT
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include "journal/journal_support.hpp"

namespace scanmesh::test {

struct Scenario {
  int milliseconds = 2000;  ///< of sample time
  int point_per_ms = 100;   ///< point sensor samples per ms
  std::uint32_t profile_points = 64;
};

inline constexpr std::int64_t kScenarioT0 = 1'000'000'000;

/// What the scan writes in one millisecond.
struct Step {
  std::vector<drivers::SensorSample> point;
  std::vector<drivers::SensorSample> line;
  drivers::StageSample stage;
  std::optional<drivers::ProbeTrigger> probe;
};

inline Step scenario_step(const Scenario& sc, int ms) {
  Step s;
  for (int k = 0; k < sc.point_per_ms; ++k)
    s.point.push_back(sensor_sample(0, static_cast<std::uint64_t>(ms * sc.point_per_ms + k), 1,
                                    false, kScenarioT0, 10'000));
  for (std::uint32_t k = 0; k < sc.profile_points; ++k)
    s.line.push_back(sensor_sample(1, static_cast<std::uint64_t>(ms) * sc.profile_points + k,
                                   sc.profile_points, true, kScenarioT0, 1'000'000));
  s.stage = stage_sample(static_cast<std::uint64_t>(ms), kScenarioT0);
  if (ms % 200 == 100) s.probe = probe_trigger(static_cast<std::uint64_t>(ms / 200), s.stage);
  return s;
}

/// The items of a step, in the order they are written.
inline void step_items(const Step& s, std::vector<Item>& items) {
  for (const auto& x : s.point) items.push_back(sensor_item("lkg0", x));
  for (const auto& x : s.line) items.push_back(sensor_item("line0", x));
  items.push_back(stage_item("/stages/xyz", s.stage));
  if (s.probe) items.push_back(probe_item("/probes/probe0", *s.probe));
}

inline const nlohmann::json& scenario_config() {
  static const nlohmann::json cfg{
      {"kind", "sensor_config"}, {"device", "lkg0"}, {"rate_hz", 100000}};
  return cfg;
}
inline const nlohmann::json& scenario_started() {
  static const nlohmann::json j{{"event", "started"}, {"name", "bracket"}};
  return j;
}

/// The items written before the first step.
inline std::vector<Item> scenario_head() {
  return {json_item("/parameters", scenario_config(), kScenarioT0),
          json_item("/events", scenario_started(), kScenarioT0)};
}

/// The scenario's channels on a writer.
struct ScenarioChannels {
  acq::SensorChannel point;
  acq::SensorChannel line;
  acq::StageChannel stage;
  acq::ProbeChannel probe;
};

inline ScenarioChannels begin_scenario(acq::JournalWriter& w) {
  ScenarioChannels c{w.add_sensor("lkg0", {{"driver", "keyence-lkg"}}),
                     w.add_sensor("line0", {{"driver", "sim-line"}}), w.add_stage("xyz"),
                     w.add_probe("probe0")};
  w.write_parameters({kScenarioT0}, scenario_config());
  w.write_event({kScenarioT0}, scenario_started());
  return c;
}

inline void write_step(acq::JournalWriter& w, const ScenarioChannels& c, const Step& s) {
  w.write_sensor(c.point, s.point);
  w.write_sensor(c.line, s.line);
  w.write_stage(c.stage, s.stage);
  if (s.probe) w.write_probe(c.probe, *s.probe);
}

/// Writes the scenario through `w` (channels included) and returns what was written. `after`
/// runs after every millisecond of data (for tests that look at the file meanwhile).
inline std::vector<Item> write_scenario(acq::JournalWriter& w, const Scenario& sc = {},
                                        const std::function<void(int)>& after = {}) {
  std::vector<Item> items = scenario_head();
  const ScenarioChannels c = begin_scenario(w);
  for (int ms = 0; ms < sc.milliseconds; ++ms) {
    const Step s = scenario_step(sc, ms);
    write_step(w, c, s);
    step_items(s, items);
    if (after) after(ms);
  }
  const std::int64_t t_end = kScenarioT0 + std::int64_t{sc.milliseconds} * 1'000'000;
  const nlohmann::json stopped{{"event", "stopped"}, {"reason", "done"}};
  w.write_event({t_end}, stopped);
  items.push_back(json_item("/events", stopped, t_end));
  return items;
}

/// Checks, as a journal is read, that its records are the beginning of the scenario, sample by
/// sample (nothing missing, nothing altered, in the order written), without keeping them.
class ScenarioChecker final : public acq::JournalVisitor {
 public:
  explicit ScenarioChecker(Scenario sc = {}) : sc_(sc) {}

  std::uint64_t samples = 0;
  std::string problem;  ///< the first difference (empty: none)

  void on_sensor(const acq::ChannelInfo& c, std::span<const drivers::SensorSample> s) override {
    for (const auto& x : s) {
      const bool point = phase_ == 0;
      if ((phase_ != 0 && phase_ != 1) || c.device != (point ? "lkg0" : "line0")) {
        return fail("a sample of " + c.device + " out of order");
      }
      const auto want =
          point ? sensor_sample(0, static_cast<std::uint64_t>(ms_ * sc_.point_per_ms + k_), 1,
                                false, kScenarioT0, 10'000)
                : sensor_sample(1, static_cast<std::uint64_t>(ms_) * sc_.profile_points + k_,
                                sc_.profile_points, true, kScenarioT0, 1'000'000);
      if (!same_sample(x, want))
        return fail("sample " + std::to_string(x.seq) + " of " + c.device + " differs");
      next();
    }
  }
  void on_stage(const acq::ChannelInfo&, const drivers::StageSample& s) override {
    if (phase_ != 2 || !same_stage(s, stage_sample(static_cast<std::uint64_t>(ms_), kScenarioT0)))
      return fail("stage sample " + std::to_string(s.seq) + " out of order or altered");
    next();
  }
  void on_probe(const acq::ChannelInfo&, const drivers::ProbeTrigger& p) override {
    const auto st = stage_sample(static_cast<std::uint64_t>(ms_), kScenarioT0);
    if (phase_ != 3 || !same_probe(p, probe_trigger(static_cast<std::uint64_t>(ms_ / 200), st)))
      return fail("probe trigger " + std::to_string(p.seq) + " out of order or altered");
    next();
  }
  void on_event(const acq::ChannelInfo&, drivers::Timestamp, std::string_view j) override {
    if (samples > 0 || json_ != 1 || nlohmann::json::parse(j) != scenario_started())
      return fail("an unexpected event " + std::string(j));
    ++json_;
  }
  void on_parameters(const acq::ChannelInfo&, drivers::Timestamp, std::string_view j) override {
    if (samples > 0 || json_ != 0 || nlohmann::json::parse(j) != scenario_config())
      return fail("unexpected parameters " + std::string(j));
    ++json_;
  }

 private:
  void fail(const std::string& what) {
    if (problem.empty()) problem = what + " (after " + std::to_string(samples) + " good samples)";
  }
  void next() {
    ++samples;
    ++k_;
    const int n = phase_ == 0   ? sc_.point_per_ms
                  : phase_ == 1 ? static_cast<int>(sc_.profile_points)
                                : 1;
    if (k_ < n) return;
    k_ = 0;
    ++phase_;
    if (phase_ == 3 && ms_ % 200 != 100) ++phase_;
    if (phase_ == 4) {
      phase_ = 0;
      ++ms_;
    }
  }

  Scenario sc_;
  int ms_ = 0;
  int phase_ = 0;  // 0 point sensor, 1 line profiler, 2 stage, 3 probe
  int k_ = 0;
  int json_ = 0;
};

/// Samples (sensor, stage, probe) among the items.
inline std::uint64_t sample_count(const std::vector<Item>& items) {
  std::uint64_t n = 0;
  for (const auto& it : items) n += it.json.empty() ? 1 : 0;
  return n;
}

}  // namespace scanmesh::test
