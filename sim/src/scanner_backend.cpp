// SimulatedScanner: the simulated scanner delivering into the acquisition pipeline.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/scanner_backend.hpp"

#include <cmath>

#include "scanmesh/common/error.hpp"
#include "scanmesh/sim/replay.hpp"
#include "scanmesh/sim/stream.hpp"

namespace scanmesh::sim {

namespace {

using Steady = std::chrono::steady_clock;

/// Forwards the replayed streams into the pipeline and remembers how far the scan is.
class Forward final : public SampleSink {
 public:
  explicit Forward(acq::SampleInput& input) : input_(input) {}
  void on_sensor(std::span<const SensorSample> samples) override {
    input_.on_sensor(0, samples);
    sensor += samples.size();
    if (!samples.empty()) last = samples.back().t_host;
  }
  void on_stage(const StageSample& sample) override {
    input_.on_stage(sample);
    ++stage;
    last = sample.t;
  }
  void on_probe(const ProbeTrigger& trigger) override {
    input_.on_probe(0, trigger);
    last = trigger.t;
  }
  std::uint64_t sensor = 0, stage = 0;
  Timestamp last;

 private:
  acq::SampleInput& input_;
};

/// Steady time with the paused intervals taken out.
class PausableClock final : public Clock {
 public:
  explicit PausableClock(std::function<Steady::duration()> paused) : paused_(std::move(paused)) {}
  Timestamp now() const override {
    const auto t = Steady::now().time_since_epoch() - paused_();
    return Timestamp{std::chrono::duration_cast<std::chrono::nanoseconds>(t).count()};
  }

 private:
  std::function<Steady::duration()> paused_;
};

}  // namespace

SimulatedScanner::SimulatedScanner(recon::Mesh part, SimConfig config,
                                   SimulatedScannerOptions options)
    : scene_(std::make_unique<Scene>(std::move(part))),
      simulator_(std::make_unique<Simulator>(*scene_, std::move(config))),
      options_(std::move(options)) {
  if (!(options_.speed >= 0) || !std::isfinite(options_.speed))
    throw ConfigError("sim: speed must be >= 0 (0: as fast as possible)");
}

SimulatedScanner::~SimulatedScanner() { stop(); }

acq::ScannerModel SimulatedScanner::model() const {
  acq::ScannerModel m;
  m.sensors.push_back({options_.sensor_name, simulator_->optics().config(),
                       simulator_->calibration()});
  m.stage = options_.stage_name;
  // The simulated machine's latencies are known exactly (a real one's are calibrated).
  m.accumulator.sensor_latency = simulator_->config().imperfections.sensor_latency;
  m.accumulator.stage_latency = simulator_->config().imperfections.stage_latency;
  return m;
}

std::vector<acq::DeviceStatus> SimulatedScanner::devices() const {
  std::lock_guard lock(mutex_);
  const char* kind = simulator_->optics().config().kind == SensorKind::kProbe ? "probe" : "sensor";
  acq::DeviceStatus sensor{options_.sensor_name, kind, "sim", "", sensor_state_, sensor_reason_, {}};
  sensor.stats.samples = sensor_samples_;
  sensor.stats.gaps = gaps_;
  acq::DeviceStatus stage{options_.stage_name, "stage", "sim", "", stage_state_, "", {}};
  stage.stats.samples = stage_samples_;
  return {sensor, stage};
}

void SimulatedScanner::set_sensor_state(drivers::DeviceState state, const std::string& reason,
                                        acq::SampleInput* input) {
  {
    std::lock_guard lock(mutex_);
    sensor_state_ = state;
    sensor_reason_ = reason;
  }
  if (input) input->on_device_state(options_.sensor_name, state, reason);
}

void SimulatedScanner::start(acq::SampleInput& input) {
  stop();
  {
    std::lock_guard lock(mutex_);
    sensor_state_ = drivers::DeviceState::kAcquiring;
    stage_state_ = drivers::DeviceState::kAcquiring;
    sensor_reason_.clear();
    paused_ = false;
    paused_total_ = {};
  }
  worker_.start([this, &input](drivers::Worker& w) { run(w, input); },
                [this, &input](const std::exception& e) {
                  set_sensor_state(drivers::DeviceState::kLost,
                                   options_.sensor_name + ": " + e.what(), nullptr);
                  input.on_failure(options_.sensor_name + ": " + e.what());
                });
}

void SimulatedScanner::pause() {
  std::lock_guard lock(mutex_);
  if (paused_) return;
  paused_ = true;
  pause_began_ = Steady::now();
}

void SimulatedScanner::resume() {
  std::lock_guard lock(mutex_);
  if (!paused_) return;
  paused_ = false;
  paused_total_ += Steady::now() - pause_began_;
}

void SimulatedScanner::stop() noexcept {
  worker_.stop();
  std::lock_guard lock(mutex_);
  if (sensor_state_ != drivers::DeviceState::kClosed) sensor_state_ = drivers::DeviceState::kOpen;
  if (stage_state_ != drivers::DeviceState::kClosed) stage_state_ = drivers::DeviceState::kOpen;
}

void SimulatedScanner::run(drivers::Worker& worker, acq::SampleInput& input) {
  // The whole scan is simulated first (fast: the ray casting runs on every core), then played.
  ScanRecorder recorder;
  simulator_->run(recorder);
  RecordedStream stream;
  stream.sensor = std::move(recorder.scan().sensor);
  stream.stage = std::move(recorder.scan().stage);
  stream.probe = std::move(recorder.scan().probe);
  stream.complete = true;
  {
    std::lock_guard lock(mutex_);
    gaps_ = recorder.scan().stats.missing;
  }
  const Timestamp first = !stream.stage.empty() ? stream.stage.front().t : Timestamp{};

  PausableClock steady([this] {
    std::lock_guard lock(mutex_);
    return paused_ ? paused_total_ + (Steady::now() - pause_began_) : paused_total_;
  });
  VirtualClock virtual_clock;
  const bool paced = options_.speed > 0;
  ReplayOptions ro;
  ro.speed = paced ? options_.speed : 1.0;
  Replayer replayer(stream, paced ? static_cast<const Clock&>(steady) : virtual_clock, ro);
  Forward forward(input);
  bool loss_done = !options_.sensor_loss_at.has_value();
  while (!replayer.done()) {
    if (worker.stop_requested()) return;
    bool paused;
    {
      std::lock_guard lock(mutex_);
      paused = paused_;
    }
    if (paused) {
      if (!worker.sleep_for(std::chrono::milliseconds(5))) return;
      continue;
    }
    if (!paced) {
      const auto due = replayer.next_due();
      if (due) virtual_clock.set(*due);
    }
    replayer.poll(forward);
    {
      std::lock_guard lock(mutex_);
      sensor_samples_ = forward.sensor;
      stage_samples_ = forward.stage;
    }
    if (!loss_done && forward.last - first >= *options_.sensor_loss_at) {
      // The sensor drops off the bus; it comes back after loss_duration (scan time).
      loss_done = true;
      set_sensor_state(drivers::DeviceState::kLost,
                       options_.sensor_name + ": lost: no data (simulated loss)", &input);
      const auto away = paced ? std::chrono::duration_cast<std::chrono::nanoseconds>(
                                    options_.loss_duration / options_.speed)
                              : options_.loss_duration;
      if (!worker.sleep_for(away)) return;
      set_sensor_state(drivers::DeviceState::kAcquiring, options_.sensor_name + ": back", &input);
      continue;
    }
    if (paced) {
      const auto due = replayer.next_due();
      if (due) {
        const auto wait = std::min(*due - steady.now(), std::chrono::nanoseconds(5'000'000));
        if (wait.count() > 0 && !worker.sleep_for(wait)) return;
      }
    }
  }
  input.on_end();
}

}  // namespace scanmesh::sim
