// JournalRecorder and ReplayBackend: the pipeline recording into, and replaying from, journals.
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/journal_backend.hpp"

#include <algorithm>
#include <thread>

#include "scanmesh/acquisition/scanner_json.hpp"
#include "scanmesh/common/error.hpp"

namespace scanmesh::acq {

namespace {

nlohmann::json parse_object(std::string_view text, const char* what) {
  nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (!j.is_object()) throw ConfigError(std::string(what) + " must be a JSON object");
  return j;
}

}  // namespace

JournalRecorder::JournalRecorder(const std::filesystem::path& path, const ScannerModel& model,
                                 JournalOptions options)
    : writer_(path, std::move(options)) {
  for (std::size_t i = 0; i < model.sensors.size(); ++i) {
    const auto& s = model.sensors[i];
    sensors_.push_back(writer_.add_sensor(s.name, {{"sensor_kind", std::string(to_string(s.config.kind))}}));
    if (s.config.kind == SensorKind::kProbe)
      probes_[static_cast<std::uint16_t>(i)] = writer_.add_probe(s.name);
  }
  stage_ = writer_.add_stage(model.stage.empty() ? "stage" : model.stage);
}

void JournalRecorder::saw(Timestamp t) {
  if (t > last_) last_ = t;
  last_wall_ = std::chrono::steady_clock::now();
}

Timestamp JournalRecorder::now() const {
  return last_ + std::chrono::duration_cast<std::chrono::nanoseconds>(
                     std::chrono::steady_clock::now() - last_wall_);
}

void JournalRecorder::write_parameters(std::string_view json) {
  nlohmann::json j = parse_object(json, "journal parameters");
  if (!j.contains("kind")) j["kind"] = "scan";
  writer_.write_parameters(last_, j);
}

void JournalRecorder::write_sensor(std::uint16_t device, std::span<const SensorSample> samples) {
  if (samples.empty()) return;
  writer_.write_sensor(sensors_.at(device), samples);
  saw(samples.back().t_host);
}

void JournalRecorder::write_stage(const StageSample& sample) {
  writer_.write_stage(stage_, sample);
  saw(sample.t);
}

void JournalRecorder::write_probe(std::uint16_t device, const ProbeTrigger& trigger) {
  auto it = probes_.find(device);
  if (it == probes_.end())
    it = probes_.emplace(device, writer_.add_probe("probe" + std::to_string(device))).first;
  writer_.write_probe(it->second, trigger);
  saw(trigger.t);
}

void JournalRecorder::write_event(std::string_view json) {
  writer_.write_event(now(), parse_object(json, "a journal event"));
}

void JournalRecorder::flush() { writer_.tick(now()); }

void JournalRecorder::close() { writer_.close(); }

// ---------------------------------------------------------------------------------------------

namespace {

/// Thrown from a visitor to stop reading (found what it wanted, or the replay was stopped).
struct StopReading {};

/// Finds the first "scan" parameters record.
class ParameterFinder final : public JournalVisitor {
 public:
  void on_parameters(const ChannelInfo&, Timestamp, std::string_view json) override {
    nlohmann::json j = nlohmann::json::parse(json, nullptr, false);
    if (j.is_object() && j.value("kind", "") == "scan") {
      found = std::move(j);
      throw StopReading{};
    }
  }
  void on_sensor(const ChannelInfo&, std::span<const SensorSample>) override {
    // Samples before the parameters: the journal was not written by the pipeline.
    throw StopReading{};
  }
  nlohmann::json found;
};

}  // namespace

class ReplayBackend::Visitor final : public JournalVisitor {
 public:
  Visitor(ReplayBackend& b, drivers::Worker& w, SampleInput& in) : b_(b), worker_(w), input_(in) {
    for (std::size_t i = 0; i < b.model_.sensors.size(); ++i)
      index_[b.model_.sensors[i].name] = static_cast<std::uint16_t>(i);
  }
  void on_sensor(const ChannelInfo& c, std::span<const SensorSample> s) override {
    if (s.empty()) return;
    gate(s.front().t_host);
    input_.on_sensor(device(c), s);
    count(s.size());
  }
  void on_stage(const ChannelInfo&, const StageSample& s) override {
    gate(s.t);
    input_.on_stage(s);
    count(1);
  }
  void on_probe(const ChannelInfo& c, const ProbeTrigger& g) override {
    gate(g.t);
    input_.on_probe(device(c), g);
    count(1);
  }

 private:
  std::uint16_t device(const ChannelInfo& c) const {
    const auto it = index_.find(c.device);
    if (it == index_.end())
      throw InputError("journal channel " + c.topic + ": device '" + c.device +
                       "' is not in the recorded scanner model");
    return it->second;
  }
  void count(std::size_t n) {
    std::lock_guard lock(b_.mutex_);
    b_.delivered_ += n;
  }
  /// Pauses, stops, and paces the replay.
  void gate(Timestamp t) {
    {
      std::unique_lock lock(b_.mutex_);
      b_.cv_.wait(lock, [this] { return !b_.paused_ || b_.stopping_; });
      if (b_.stopping_) throw StopReading{};
    }
    if (worker_.stop_requested()) throw StopReading{};
    if (b_.options_.speed <= 0) return;
    const auto wall = std::chrono::steady_clock::now();
    if (!first_) {
      first_ = t;
      start_ = wall;
      return;
    }
    const auto due = start_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                  (t - *first_) / b_.options_.speed);
    if (due > wall) worker_.sleep_for(due - wall);
  }

  ReplayBackend& b_;
  drivers::Worker& worker_;
  SampleInput& input_;
  std::map<std::string, std::uint16_t> index_;
  std::optional<Timestamp> first_;
  std::chrono::steady_clock::time_point start_;
};

ReplayBackend::ReplayBackend(std::vector<std::filesystem::path> segments, ReplayOptions options)
    : segments_(std::move(segments)), options_(options) {
  if (segments_.empty()) throw ConfigError("replay: no journal given");
  ParameterFinder finder;
  try {
    read_journal(segments_.front(), finder, {true});
  } catch (const StopReading&) {
  }
  const std::string what = segments_.front().string();
  if (finder.found.is_null())
    throw InputError(what + ": no scan parameters record (not a journal written by a scan)");
  parameters_ = finder.found;
  if (!parameters_.contains("scanner"))
    throw InputError(what + ": the scan parameters have no 'scanner'");
  model_ = scanner_model_from_json(parameters_["scanner"], what + ": scanner");
}

ReplayBackend::~ReplayBackend() { stop(); }

std::vector<DeviceStatus> ReplayBackend::devices() const {
  std::lock_guard lock(mutex_);
  DeviceStatus d{"replay", "sensor", "replay", segments_.front().string(), state_, "", {}};
  d.stats.samples = delivered_;
  return {d};
}

std::vector<JournalReport> ReplayBackend::reports() const {
  std::lock_guard lock(mutex_);
  return reports_;
}

void ReplayBackend::start(SampleInput& input) {
  stop();
  {
    std::lock_guard lock(mutex_);
    stopping_ = false;
    paused_ = false;
    state_ = drivers::DeviceState::kAcquiring;
  }
  worker_.start([this, &input](drivers::Worker& w) { run(w, input); },
                [&input](const std::exception& e) { input.on_failure(e.what()); });
}

void ReplayBackend::run(drivers::Worker& worker, SampleInput& input) {
  Visitor visitor(*this, worker, input);
  std::vector<JournalReport> reports;
  try {
    for (const auto& seg : segments_) reports.push_back(read_journal(seg, visitor, {options_.tolerate_damage}));
  } catch (const StopReading&) {
    return;  // stopped: no end
  }
  {
    std::lock_guard lock(mutex_);
    reports_ = std::move(reports);
    state_ = drivers::DeviceState::kOpen;
  }
  input.on_end();
}

void ReplayBackend::pause() {
  std::lock_guard lock(mutex_);
  paused_ = true;
}

void ReplayBackend::resume() {
  {
    std::lock_guard lock(mutex_);
    paused_ = false;
  }
  cv_.notify_all();
}

void ReplayBackend::stop() noexcept {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  worker_.stop();
  std::lock_guard lock(mutex_);
  if (state_ != drivers::DeviceState::kClosed) state_ = drivers::DeviceState::kOpen;
}

}  // namespace scanmesh::acq
