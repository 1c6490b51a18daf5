// DevicesBackend: a sensor and a stage driver running a scan program (see devices_backend.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/devices_backend.hpp"

#include <cmath>
#include <numbers>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::acq {

namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

/// Length of a move in the controller's feed units (mm, and degrees for the table).
double feed_length(const drivers::StagePose& a, const drivers::StagePose& b) {
  const double dx = b.x_mm - a.x_mm, dy = b.y_mm - a.y_mm, dz = b.z_mm - a.z_mm;
  const double da = (b.a_rad - a.a_rad) * kDegPerRad;
  return std::sqrt(dx * dx + dy * dy + dz * dz + da * da);
}

drivers::StageTarget target_of(const drivers::StagePose& p, bool table) {
  drivers::StageTarget t;
  t.x_mm = p.x_mm;
  t.y_mm = p.y_mm;
  t.z_mm = p.z_mm;
  if (table) t.a_rad = p.a_rad;
  return t;
}

}  // namespace

std::vector<std::string> ScanProgram::problems() const {
  std::vector<std::string> out;
  if (moves.empty()) out.push_back("scan program: no moves");
  for (std::size_t i = 0; i < moves.size(); ++i) {
    const ScanMove& m = moves[i];
    if (!(m.feed_mm_min > 0) || !std::isfinite(m.feed_mm_min))
      out.push_back("scan program: move " + std::to_string(i) + ": feed must be > 0 mm/min");
    const auto& p = m.to;
    if (!std::isfinite(p.x_mm) || !std::isfinite(p.y_mm) || !std::isfinite(p.z_mm) ||
        !std::isfinite(p.a_rad))
      out.push_back("scan program: move " + std::to_string(i) + ": target not finite");
    if (!uses_table && p.a_rad != 0)
      out.push_back("scan program: move " + std::to_string(i) +
                    " turns the table but uses_table is not set");
  }
  return out;
}

double ScanProgram::nominal_seconds() const {
  double s = 0;
  for (std::size_t i = 1; i < moves.size(); ++i)
    s += feed_length(moves[i - 1].to, moves[i].to) / moves[i].feed_mm_min * 60.0;
  return s;
}

DevicesBackend::DevicesBackend(std::unique_ptr<drivers::DisplacementSensor> sensor,
                               std::unique_ptr<drivers::MotionStage> stage, ScannerModel model,
                               ScanProgram program, DevicesBackendOptions options)
    : sensor_(std::move(sensor)),
      stage_(std::move(stage)),
      model_(std::move(model)),
      program_(std::move(program)),
      options_(std::move(options)) {
  std::vector<std::string> problems = program_.problems();
  if (!sensor_) problems.push_back("devices backend: no sensor");
  if (!stage_) problems.push_back("devices backend: no stage");
  if (model_.sensors.size() != 1) problems.push_back("devices backend: the model needs one sensor");
  if (!(options_.reposition_feed_mm_min > 0))
    problems.push_back("devices backend: reposition_feed_mm_min must be > 0");
  if (!problems.empty()) {
    std::string msg = "invalid devices backend:";
    for (const auto& p : problems) msg += "\n  " + p;
    throw ConfigError(msg);
  }
  if (model_.stage.empty()) model_.stage = stage_->name();
}

DevicesBackend::~DevicesBackend() { stop(); }

std::vector<DeviceStatus> DevicesBackend::devices() const {
  std::string sensor_reason, stage_reason;
  {
    std::lock_guard lock(mutex_);
    sensor_reason = sensor_reason_;
    stage_reason = stage_reason_;
  }
  DeviceStatus s{sensor_->name(),  "sensor",      options_.sensor_driver, options_.sensor_port,
                 sensor_->state(), sensor_reason, sensor_->stats()};
  DeviceStatus t{stage_->name(),  "stage",      options_.stage_driver, options_.stage_port,
                 stage_->state(), stage_reason, stage_->stats()};
  return {s, t};
}

void DevicesBackend::set_reason(bool sensor, const std::string& reason) {
  std::lock_guard lock(mutex_);
  (sensor ? sensor_reason_ : stage_reason_) = reason;
}

void DevicesBackend::start(SampleInput& input) {
  stop();
  {
    std::lock_guard lock(mutex_);
    pause_requested_ = false;
  }
  forwarding_ = false;
  motion_done_ = false;
  sensor_->open();  // throws DeviceError naming the device
  try {
    stage_->open();
    drivers::StageCallbacks sc;
    sc.on_sample = [&input](const drivers::StageSample& s) { input.on_stage(s); };
    sc.on_probe = [&input](const drivers::ProbeTrigger& t) { input.on_probe(0, t); };
    sc.on_state = [this, &input](drivers::DeviceState state, const std::string& reason) {
      set_reason(false, reason);
      input.on_device_state(stage_->name(), state, reason);
    };
    stage_->start(std::move(sc));
    drivers::SensorCallbacks cb;
    cb.on_sample = [this, &input](const drivers::SensorSample& s) {
      if (forwarding_.load(std::memory_order_acquire)) input.on_sensor(0, std::span(&s, 1));
    };
    cb.on_state = [this, &input](drivers::DeviceState state, const std::string& reason) {
      set_reason(true, reason);
      input.on_device_state(sensor_->name(), state, reason);
    };
    sensor_->start(std::move(cb));
  } catch (...) {
    stage_->close();
    sensor_->close();
    throw;
  }
  running_ = true;
  program_thread_ = std::jthread([this, &input](std::stop_token st) { run(st, input); });
}

void DevicesBackend::pause() {
  {
    std::lock_guard lock(mutex_);
    pause_requested_ = true;
  }
  forwarding_ = false;  // the samples a held motion would produce are held too
  cv_.notify_all();
}

void DevicesBackend::resume() {
  {
    std::lock_guard lock(mutex_);
    pause_requested_ = false;
  }
  cv_.notify_all();
}

bool DevicesBackend::paused() const {
  std::lock_guard lock(mutex_);
  return pause_requested_;
}

void DevicesBackend::stop() noexcept {
  if (program_thread_.joinable()) {
    program_thread_.request_stop();
    cv_.notify_all();
    program_thread_.join();
  }
  forwarding_ = false;
  if (!running_.exchange(false)) return;
  try {
    if (!motion_done_ && stage_->state() == drivers::DeviceState::kAcquiring) stage_->halt();
  } catch (...) {  // a lost stage cannot be halted; stop() never throws
  }
  sensor_->stop();
  stage_->stop();
  sensor_->close();
  stage_->close();
}

DevicesBackend::Wait DevicesBackend::run_move(std::stop_token& stop, const ScanMove& move) {
  const drivers::StagePose from = stage_->status().pose;
  try {
    stage_->move_to(target_of(move.to, program_.uses_table), move.feed_mm_min);
  } catch (const drivers::DeviceError& e) {
    // Lost or not answering: the pipeline pauses on the loss; run the move again afterwards.
    if (e.kind() == drivers::DeviceErrorKind::kDisconnected ||
        e.kind() == drivers::DeviceErrorKind::kTimeout)
      return Wait::kPaused;
    throw;
  }
  const double nominal_s = feed_length(from, move.to) / move.feed_mm_min * 60.0;
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(static_cast<std::int64_t>(nominal_s * 1000)) +
                        options_.move_slack;
  for (;;) {
    if (stop.stop_requested()) return Wait::kStopped;
    if (paused()) return Wait::kPaused;
    const drivers::StageStatusReport r = stage_->wait_idle(std::chrono::milliseconds(50));
    switch (r.status) {
      case drivers::StageStatus::kIdle:
        return Wait::kDone;
      case drivers::StageStatus::kAlarm:
        throw drivers::DeviceError(drivers::DeviceErrorKind::kProtocol, stage_->name(), "move",
                                   "alarm " + std::to_string(r.alarm_code) + ": " + r.alarm_text);
      case drivers::StageStatus::kLost:
        return Wait::kPaused;  // the pipeline pauses on the loss; the move is run again
      default:
        break;
    }
    if (std::chrono::steady_clock::now() > deadline)
      throw drivers::DeviceError(drivers::DeviceErrorKind::kTimeout, stage_->name(), "move",
                                 "the move did not end within its time plus " +
                                     std::to_string(options_.move_slack.count()) + " ms");
  }
}

bool DevicesBackend::hold(std::stop_token& stop) {
  // Halt the axes; a lost stage stands anyway (its driver reconnects on its own).
  try {
    if (stage_->state() != drivers::DeviceState::kLost) stage_->halt();
    halts_.fetch_add(1);
  } catch (const drivers::DeviceError&) {
  }
  std::unique_lock lock(mutex_);
  for (;;) {
    if (stop.stop_requested()) return false;
    if (!pause_requested_ && stage_->state() == drivers::DeviceState::kAcquiring) return true;
    cv_.wait_for(lock, std::chrono::milliseconds(20));
  }
}

void DevicesBackend::run(std::stop_token stop, SampleInput& input) {
  try {
    const auto& moves = program_.moves;
    drivers::StagePose line_start = stage_->status().pose;
    bool interrupted = false;
    std::size_t k = 0;
    while (k < moves.size()) {
      if (stop.stop_requested()) return;
      if (paused() || interrupted) {
        forwarding_ = false;
        if (!hold(stop)) return;
        // Back to where the interrupted move began: a scan line is measured again whole.
        if (interrupted) {
          const ScanMove back{line_start, options_.reposition_feed_mm_min, false};
          const Wait w = run_move(stop, back);
          if (w == Wait::kStopped) return;
          if (w == Wait::kPaused) continue;  // paused again on the way back
        }
        interrupted = false;
      }
      forwarding_ = true;
      const Wait w = run_move(stop, moves[k]);
      if (w == Wait::kStopped) return;
      if (w == Wait::kPaused) {
        interrupted = true;
        continue;
      }
      moves_done_.fetch_add(1);
      line_start = moves[k].to;
      ++k;
    }
    forwarding_ = false;
    motion_done_ = true;
    input.on_end();
  } catch (const std::exception& e) {
    forwarding_ = false;
    input.on_failure(e.what());
  }
}

std::unique_ptr<DevicesBackend> make_devices_backend(const drivers::SensorConfig& sensor,
                                                     const drivers::StageConfig& stage,
                                                     ScannerModel model, ScanProgram program,
                                                     DevicesBackendOptions options) {
  drivers::SensorConfig sc = sensor;
  drivers::StageConfig tc = stage;
  if (!model.sensors.empty() && !model.sensors[0].name.empty())
    sc.options.name = model.sensors[0].name;
  if (!model.stage.empty()) tc.options.name = model.stage;
  options.sensor_driver = sc.driver;
  options.sensor_port = !sc.port.empty() ? sc.port : sc.tcp;
  options.stage_driver = tc.driver;
  options.stage_port = !tc.port.empty() ? tc.port : tc.tcp;
  return std::make_unique<DevicesBackend>(drivers::make_displacement_sensor(sc),
                                          drivers::make_motion_stage(tc), std::move(model),
                                          std::move(program), std::move(options));
}

}  // namespace scanmesh::acq
