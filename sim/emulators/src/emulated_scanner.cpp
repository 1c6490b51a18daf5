// EmulatedScanner: the GRBL and ILD1420 emulators as one simulated scanner (see
// emulated_scanner.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/emulated_scanner.hpp"

#include <stdlib.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "scanmesh/common/error.hpp"

namespace scanmesh::sim {

namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

std::filesystem::path make_port_dir() {
  std::string tmpl = (std::filesystem::temp_directory_path() / "scanmesh-emu-XXXXXX").string();
  if (!::mkdtemp(tmpl.data()))
    throw Error("emulated scanner: cannot create a folder for the ports under " +
                std::filesystem::temp_directory_path().string());
  return tmpl;
}

}  // namespace

EmulatedScanner::EmulatedScanner(recon::Mesh part, const ScanSettings& settings,
                                 EmulatedScannerOptions options)
    : options_(std::move(options)), rng_(settings.seed) {
  if (settings.sensor != "point")
    throw ConfigError("emulated scanner: sensor '" + settings.sensor +
                      "' has no protocol emulator (the emulated scanner is an ILD1420 point "
                      "sensor on a GRBL stage); use the in-process simulation for it");
  if (!(options_.sensor_blocks_per_tick >= 1 && options_.sensor_blocks_per_tick <= 100))
    throw ConfigError("emulated scanner: sensor_blocks_per_tick must be in 1 .. 100");
  if (!(options_.measuring_range_mm > 0))
    throw ConfigError("emulated scanner: measuring_range_mm must be > 0");
  SimConfig cfg = settings.to_config();
  cfg.sensor.range_mm = options_.measuring_range_mm;
  noise_mm_ = settings.noise_mm;
  dropout_ = settings.dropout;
  scene_ = std::make_unique<Scene>(std::move(part));
  simulator_ = std::make_unique<Simulator>(*scene_, cfg);
  tracer_ = std::make_unique<RayTracer>(*scene_, simulator_->optics().config());
  const Trajectory& traj = simulator_->plan().trajectory;
  for (const Move& m : traj.moves()) rotary_ = rotary_ || m.from.a_rad != 0 || m.to.a_rad != 0;

  if (options_.port_dir.empty()) {
    owned_dir_ = make_port_dir();
    options_.port_dir = owned_dir_;
  }
  GrblEmulatorOptions go;
  go.motion.limits = cfg.path.limits;
  go.motion.start = traj.moves().empty() ? StagePose{} : traj.moves().front().from;
  go.motion.home = go.motion.start;
  go.rotary_a = rotary_;
  stage_ = std::make_unique<GrblEmulator>((options_.port_dir / "grbl0").string(), go);
  Ild1420EmulatorOptions io;
  io.measuring_range_mm = options_.measuring_range_mm;
  io.blocks_per_tick = options_.sensor_blocks_per_tick;
  io.name = "ILD1420-" + std::to_string(static_cast<int>(options_.measuring_range_mm));
  io.layout = "dclh";  // distance, counter, timestamp low and high words
  io.timed_values = [this](drivers::Timestamp t) { return measure(t); };
  sensor_ = std::make_unique<MicroEpsilonIld1420Emulator>(
      (options_.port_dir / "ild0").string(), [] { return drivers::SensorSample{}; }, io);
}

EmulatedScanner::~EmulatedScanner() {
  stop();
  sensor_.reset();
  stage_.reset();
  if (!owned_dir_.empty()) {
    std::error_code ec;
    std::filesystem::remove_all(owned_dir_, ec);
  }
}

void EmulatedScanner::start() {
  stage_->start();
  sensor_->start();
}

void EmulatedScanner::stop() noexcept {
  if (sensor_) sensor_->stop();
  if (stage_) stage_->stop();
}

drivers::SensorSample EmulatedScanner::measure(drivers::Timestamp t) {
  const StagePose pose = stage_->motion().pose(t);
  const RayHit hit = tracer_->trace_at(simulator_->optics(), simulator_->calibration(), pose, 0);
  drivers::SensorSample s;
  s.t_host = t;
  s.value_mm = std::numeric_limits<double>::quiet_NaN();
  const double standoff = simulator_->optics().config().standoff_mm;
  const bool dropped = dropout_ > 0 && std::uniform_real_distribution<double>()(rng_) < dropout_;
  if (hit.cause == SampleCause::kOk && !dropped) {
    double v = hit.t - standoff;
    if (noise_mm_ > 0) v += std::normal_distribution<double>(0, noise_mm_)(rng_);
    if (v < 0 || v > options_.measuring_range_mm) {
      s.status = drivers::SensorStatus::kOverRange;
      s.value_mm = v < 0 ? -std::numeric_limits<double>::infinity()
                         : std::numeric_limits<double>::infinity();
    } else {
      s.status = drivers::SensorStatus::kOk;
      s.value_mm = v;
    }
  } else if (hit.cause == SampleCause::kOutOfRange) {
    s.status = drivers::SensorStatus::kOverRange;
    s.value_mm = hit.t < standoff ? -std::numeric_limits<double>::infinity()
                                  : std::numeric_limits<double>::infinity();
  } else {
    s.status = drivers::SensorStatus::kNoTarget;
  }
  return s;
}

acq::ScannerModel EmulatedScanner::model() const {
  acq::ScannerModel m;
  acq::SensorConfig optics = simulator_->optics().config();
  optics.rate_hz = sensor_rate_hz();
  m.sensors.push_back({options_.sensor_name, optics, simulator_->calibration()});
  m.stage = options_.stage_name;
  // Host receive times for both devices. The samples do carry their measurement instants (the
  // ILD1420's timestamp words, journalled), but GRBL's status reports carry none: the driver
  // stamps them on receipt, with the host's typical delay in them. A device clock mapped by its
  // lower envelope (the least delayed sample) would put the sensor on the true timeline and the
  // stage a typical delay behind it: a bias of delay x speed (measured: 0.17 mm median at
  // 100 mm/s on a loaded host, acquisition/NOTEBOOK.md). Stamped on receipt, both carry that
  // delay and it cancels; what stays is its jitter. The blocks of a 1 ms tick are on average
  // half a tick older than their read.
  m.accumulator.use_device_clock = false;
  m.accumulator.sensor_latency = std::chrono::microseconds(500);
  // The stage stands at the end of the scan: the last samples take its final pose.
  m.accumulator.max_hold = std::chrono::milliseconds(50);
  return m;
}

acq::ScanProgram EmulatedScanner::program() const {
  acq::ScanProgram p;
  p.uses_table = rotary_;
  for (const Move& m : simulator_->plan().trajectory.moves()) {
    const double dx = m.to.x_mm - m.from.x_mm, dy = m.to.y_mm - m.from.y_mm,
                 dz = m.to.z_mm - m.from.z_mm;
    const double linear_mm = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double table_deg = std::abs(m.to.a_rad - m.from.a_rad) * kDegPerRad;
    // The plan's peak speed along the move (its profile runs over s in [0, 1]), in the
    // controller's feed units: the larger of the linear and the table rate.
    const double v = m.profile.peak_velocity() * std::max(linear_mm, table_deg);
    if (!(v > 0)) continue;
    p.moves.push_back({m.to, v * 60.0, m.sensing});
  }
  return p;
}

}  // namespace scanmesh::sim
