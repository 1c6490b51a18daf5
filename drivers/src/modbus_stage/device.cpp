// Device class of Modbus drive stages (see modbus_stage/device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/modbus_stage/device.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <thread>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::modbus_stage {

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kDegPerRad = 180.0 / std::numbers::pi;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool linear(StageAxis a) { return a != StageAxis::kA; }

}  // namespace

Device::Device(StageOptions options, RegisterBusFactory transport, StageRegisterMap map)
    : StageBase(std::move(options)), factory_(std::move(transport)), map_(std::move(map)) {
  check_stage_options();
  if (!factory_) throw ConfigError(name() + ": no transport factory");
  map_.validate();
  plan_ = plan_reads(map_);
  for (const auto& b : plan_) image_size_ += b.count;
  image_.assign(image_size_ * map_.axes.size(), 0);
  readings_.assign(map_.axes.size(), AxisReading{});
}

Device::~Device() { close(); }

StageCapabilities Device::capabilities() const {
  StageCapabilities c;
  for (const auto& a : map_.axes) c.axes.push_back({a.axis, a.unit_name(), a.min, a.max});
  c.max_feed_mm_min = map_.max_speed_units_s * 60;
  c.report_rate_hz = 1e6 / static_cast<double>(options().poll_interval.count());
  c.homing = !map_.home.empty();
  c.probing = !map_.probe_arm.empty();
  c.jog = false;
  return c;
}

void Device::rethrow_named(const DeviceError& e, const AxisMap& axis,
                           const std::string& operation) const {
  throw DeviceError(e.kind(), e.device().empty() ? name() : e.device(),
                    std::string(to_string(axis.axis)) + " (unit " + std::to_string(axis.unit) +
                        "): " + operation + ": " + e.operation(),
                    e.detail());
}

// ---- worker: polling ----

void Device::poll_axes() {
  for (std::size_t i = 0; i < map_.axes.size(); ++i) {
    const AxisMap& axis = map_.axes[i];
    const std::span<std::uint16_t> image(image_.data() + i * image_size_, image_size_);
    try {
      bus_->select_unit(axis.unit);
      std::size_t offset = 0;
      for (const ReadBlock& b : plan_) {
        bus_->read_registers(RegisterKind::kHolding, b.address, image.subspan(offset, b.count));
        offset += b.count;
      }
    } catch (const DeviceError& e) {
      rethrow_named(e, axis, "poll");
    }
    readings_[i] = decode_axis(map_, axis, plan_, image);
  }
  const Timestamp t = monotonic_now();
  StagePose pose;
  bool moving = false, homing = false;
  const AxisMap* faulted = nullptr;
  int code = 0;
  for (std::size_t i = 0; i < map_.axes.size(); ++i) {
    const AxisReading& r = readings_[i];
    switch (map_.axes[i].axis) {
      case StageAxis::kX: pose.x_mm = r.position; break;
      case StageAxis::kY: pose.y_mm = r.position; break;
      case StageAxis::kZ: pose.z_mm = r.position; break;
      case StageAxis::kA: pose.a_rad = r.position / kDegPerRad; break;
    }
    moving = moving || r.moving;
    homing = homing || r.homing;
    if (r.fault && !faulted) {
      faulted = &map_.axes[i];
      code = r.alarm_code;
    }
  }
  if (homing_requested_ && !moving && !homing) homing_requested_ = false;
  StageStatus st = StageStatus::kIdle;
  if (faulted) {
    st = StageStatus::kAlarm;
    set_alarm(code, std::string(to_string(faulted->axis)) + ": " + alarm_text(map_, code));
  } else if (homing || homing_requested_) {
    st = StageStatus::kHoming;
  } else if (moving) {
    st = StageStatus::kMoving;
  }
  publish(pose, st, t);
}

Device::Step Device::acquire(std::string& timeout_detail) {
  run_jobs();
  const auto now = Clock::now();
  if (now < next_poll_) return Step::kPending;  // woken for a command before the poll was due
  // Fixed rate: the schedule advances by the interval; after a stall it restarts from now.
  next_poll_ += std::chrono::duration_cast<Clock::duration>(options().poll_interval);
  if (next_poll_ < now) next_poll_ = now + options().poll_interval;
  try {
    poll_axes();
  } catch (const DeviceError& e) {
    switch (e.kind()) {
      case DeviceErrorKind::kTimeout:
        timeout_detail = e.what();
        return Step::kTimeout;
      case DeviceErrorKind::kProtocol:
        counters().error_replies.fetch_add(1);  // a Modbus exception: the drive answered
        return Step::kAnswered;
      default:
        throw;
    }
  }
  return Step::kAnswered;
}

bool Device::pause(Worker& worker) {
  if (has_jobs()) return true;
  return worker.sleep_until_notified(next_poll_);
}

void Device::on_start() { next_poll_ = Clock::now(); }

void Device::on_reconnected() {
  next_poll_ = Clock::now();
  homing_requested_ = false;
  clear_alarm_state();
}

std::string Device::lost_after_timeouts(int count, const std::string& detail) const {
  return std::to_string(count) + " consecutive timeouts (" + detail + ")";
}

void Device::open_device() {
  bus_ = factory_();
  if (!bus_) throw DeviceError(DeviceErrorKind::kIo, name(), "open", "transport factory failed");
  for (const AxisMap& axis : map_.axes) {
    if (map_.init.empty()) continue;
    bus_->select_unit(axis.unit);
    write_list(map_.init, axis, 0, 1, 1, "init");
  }
  try {
    poll_axes();
  } catch (const DeviceError& e) {
    bus_.reset();
    throw DeviceError(e.kind(), e.device(), "first position: " + e.operation(), e.detail());
  }
  DeviceIdentity id;
  id.vendor = map_.vendor;
  id.model = map_.model + " (profile " + map_.profile + ")";
  set_identity(std::move(id));
}

bool Device::reconnect_once() {
  bus_ = factory_();
  if (!bus_) return false;
  for (const AxisMap& axis : map_.axes) {
    if (map_.init.empty()) continue;
    bus_->select_unit(axis.unit);
    write_list(map_.init, axis, 0, 1, 1, "init");
  }
  poll_axes();
  return true;
}

// ---- commands ----

void Device::write_list(const std::vector<RegisterWrite>& list, const AxisMap& axis,
                        std::int32_t target, double speed, double accel, const std::string& what) {
  try {
    bus_->select_unit(axis.unit);
    for (const RegisterWrite& w : list) {
      const std::vector<std::uint16_t> regs = encode_write(map_, w, target, speed, accel);
      bus_->write_registers(w.address, regs);
    }
  } catch (const DeviceError& e) {
    if (e.kind() == DeviceErrorKind::kProtocol) counters().error_replies.fetch_add(1);
    rethrow_named(e, axis, what);
  }
}

void Device::command_all(const std::vector<RegisterWrite>& list, const std::string& what) {
  if (list.empty())
    throw DeviceError(DeviceErrorKind::kProtocol, name(), what,
                      "profile " + map_.profile + " has no " + what + " registers");
  for (const AxisMap& axis : map_.axes) write_list(list, axis, 0, 1, 1, what);
}

std::vector<double> Device::targets_of(const StageTarget& t, bool relative) const {
  std::vector<double> out(map_.axes.size(), kNaN);
  auto set = [&](StageAxis axis, const std::optional<double>& v, double factor) {
    if (!v) return;
    const AxisMap* a = map_.find(axis);
    if (!a)
      throw ConfigError(name() + ": profile " + map_.profile + " has no " +
                        std::string(to_string(axis)) + " axis");
    if (!std::isfinite(*v)) throw ConfigError(name() + ": target is not finite");
    out[static_cast<std::size_t>(a - map_.axes.data())] = *v * factor;
  };
  set(StageAxis::kX, t.x_mm, 1);
  set(StageAxis::kY, t.y_mm, 1);
  set(StageAxis::kZ, t.z_mm, 1);
  set(StageAxis::kA, t.a_rad, kDegPerRad);
  if (relative) {
    const StageStatusReport now = status();
    for (std::size_t i = 0; i < out.size(); ++i) {
      if (std::isnan(out[i])) continue;
      double cur = 0;
      switch (map_.axes[i].axis) {
        case StageAxis::kX: cur = now.pose.x_mm; break;
        case StageAxis::kY: cur = now.pose.y_mm; break;
        case StageAxis::kZ: cur = now.pose.z_mm; break;
        case StageAxis::kA: cur = now.pose.a_rad * kDegPerRad; break;
      }
      out[i] += cur;
    }
  }
  return out;
}

std::vector<std::size_t> Device::start_moves(const std::vector<double>& targets,
                                             double feed_per_min) {
  // Quirk: separate drives cannot interpolate; each linear axis gets its share of the feed and of
  // the acceleration, so that all of them run one normalised profile and the tool moves straight.
  double length = 0;
  for (std::size_t i = 0; i < targets.size(); ++i) {
    if (std::isnan(targets[i]) || !linear(map_.axes[i].axis)) continue;
    const double d = targets[i] - readings_[i].position;
    length += d * d;
  }
  length = std::sqrt(length);
  std::vector<std::size_t> moved;
  for (std::size_t i = 0; i < targets.size(); ++i) {
    if (std::isnan(targets[i])) continue;
    const AxisMap& axis = map_.axes[i];
    const std::int32_t counts = units_to_counts(axis, targets[i]);
    const double d = std::abs(targets[i] - readings_[i].position);
    if (d * std::abs(axis.counts_per_unit) < 0.5) continue;  // already there
    const double share = linear(axis.axis) && length > 0 ? d / length : 1.0;
    double speed = feed_per_min / 60.0 * share;
    if (map_.max_speed_units_s > 0) speed = std::min(speed, map_.max_speed_units_s);
    write_list(map_.move, axis, counts, speed, map_.default_accel_units_s2 * share, "move");
    moved.push_back(i);
  }
  return moved;
}

void Device::move_to(const StageTarget& target, double feed_mm_min) {
  if (!(feed_mm_min > 0) || !std::isfinite(feed_mm_min))
    throw ConfigError(name() + ": move: the feed must be > 0");
  const std::vector<double> targets = targets_of(target, false);
  call<void>("move", options().timeout * 4, [this, targets, feed_mm_min](auto done) {
    try {
      start_moves(targets, feed_mm_min);
      done->set_value();
    } catch (...) {
      done->set_exception(std::current_exception());
    }
  });
}

void Device::move_by(const StageTarget& delta, double feed_mm_min) {
  if (!(feed_mm_min > 0) || !std::isfinite(feed_mm_min))
    throw ConfigError(name() + ": move: the feed must be > 0");
  StageTarget d = delta;
  call<void>("move", options().timeout * 4, [this, d, feed_mm_min](auto done) {
    try {
      // Relative to the latest positions the worker read (not to a stale caller's copy).
      start_moves(targets_of(d, true), feed_mm_min);
      done->set_value();
    } catch (...) {
      done->set_exception(std::current_exception());
    }
  });
}

void Device::jog(const StageTarget& delta, double feed_mm_min) { move_by(delta, feed_mm_min); }

void Device::home() {
  call<void>("home", options().timeout * 4, [this](auto done) {
    try {
      command_all(map_.home, "home");
      homing_requested_ = true;
      set_status(StageStatus::kHoming);
      done->set_value();
    } catch (...) {
      done->set_exception(std::current_exception());
    }
  });
}

void Device::halt() {
  call<void>("stop", options().timeout * 4, [this](auto done) {
    try {
      command_all(map_.stop, "stop");
      homing_requested_ = false;
      done->set_value();
    } catch (...) {
      done->set_exception(std::current_exception());
    }
  });
}

void Device::clear_alarm() {
  call<void>("alarm reset", options().timeout * 4, [this](auto done) {
    try {
      command_all(map_.reset, "alarm reset");
      clear_alarm_state();
      done->set_value();
    } catch (...) {
      done->set_exception(std::current_exception());
    }
  });
}

ProbeMoveResult Device::run_probe(const ProbeMove& m) {
  const double norm = std::sqrt(m.i * m.i + m.j * m.j + m.k * m.k);
  const double dir[3] = {m.i / norm, m.j / norm, m.k / norm};
  std::vector<double> targets(map_.axes.size(), kNaN);
  std::vector<std::size_t> probing;
  for (std::size_t i = 0; i < map_.axes.size(); ++i) {
    const StageAxis a = map_.axes[i].axis;
    if (a == StageAxis::kA) continue;
    const double c = dir[static_cast<int>(a)];
    if (std::abs(c) < 1e-12) continue;
    targets[i] = readings_[i].position + c * m.travel_mm;
    probing.push_back(i);
  }
  for (int k = 0; k < 3; ++k)
    if (std::abs(dir[k]) >= 1e-12 && !map_.find(static_cast<StageAxis>(k)))
      throw ConfigError(name() + ": probe: the direction needs a " +
                        std::string(to_string(static_cast<StageAxis>(k))) + " axis");
  for (std::size_t i : probing) write_list(map_.probe_arm, map_.axes[i], 0, 1, 1, "probe arm");
  poll_axes();
  ProbeMoveResult result;
  for (std::size_t i : probing) {
    if (readings_[i].probe_latched) {
      result.outcome = ProbeMoveResult::Outcome::kTriggeredAtStart;
      result.detail = std::string(to_string(map_.axes[i].axis)) +
                      ": the probe latch is set before the move (probe deflected)";
      return result;
    }
  }
  start_moves(targets, m.feed_mm_min);
  const auto deadline = Clock::now() + options().timeout * 4 +
                        std::chrono::milliseconds(static_cast<std::int64_t>(
                            m.travel_mm / m.feed_mm_min * 60000.0 * 3));
  for (;;) {
    // The probing move is polled at the report rate; the drives latch in hardware, so the rate
    // bounds only how soon the driver learns of the trigger, not its accuracy.
    std::this_thread::sleep_for(options().poll_interval);
    poll_axes();
    bool latched = false, moving = false;
    for (std::size_t i : probing) {
      latched = latched || readings_[i].probe_latched;
      moving = moving || readings_[i].moving;
    }
    if (latched) break;
    if (!moving) {
      result.outcome = ProbeMoveResult::Outcome::kNoContact;
      result.detail = "no contact within " + std::to_string(m.travel_mm) + " mm";
      return result;
    }
    if (Clock::now() > deadline) {
      command_all(map_.stop, "stop");
      throw DeviceError(DeviceErrorKind::kTimeout, name(), "probe",
                        "the probing move did not end in time");
    }
  }
  // The latched positions: every probing drive latches on the same probe signal.
  StageStatusReport now = status();
  ProbeTrigger g;
  g.t = monotonic_now();
  g.pose = now.pose;
  for (std::size_t i : probing) {
    const AxisMap& axis = map_.axes[i];
    std::uint16_t regs[2];
    const std::span<std::uint16_t> out(regs, register_count(map_.probe_position->type));
    try {
      bus_->select_unit(axis.unit);
      bus_->read_registers(RegisterKind::kHolding, map_.probe_position->address, out);
    } catch (const DeviceError& e) {
      rethrow_named(e, axis, "probe position");
    }
    const double v = counts_to_units(axis, decode_value(map_.probe_position->type, map_.word_order, out));
    switch (axis.axis) {
      case StageAxis::kX: g.pose.x_mm = v; break;
      case StageAxis::kY: g.pose.y_mm = v; break;
      case StageAxis::kZ: g.pose.z_mm = v; break;
      case StageAxis::kA: break;
    }
  }
  result.outcome = ProbeMoveResult::Outcome::kContact;
  result.trigger = g;
  publish_probe(result.trigger);
  return result;
}

ProbeMoveResult Device::probe_move(const ProbeMove& move) {
  const double norm = std::sqrt(move.i * move.i + move.j * move.j + move.k * move.k);
  if (!(norm > 1e-9) || !std::isfinite(norm))
    throw ConfigError(name() + ": probe: the direction must be a non-zero vector");
  if (!(move.travel_mm > 0) || !std::isfinite(move.travel_mm) || !(move.feed_mm_min > 0))
    throw ConfigError(name() + ": probe: travel and feed must be > 0");
  if (map_.probe_arm.empty())
    throw ConfigError(name() + ": profile " + map_.profile + " has no probe registers");
  const auto limit = options().timeout * 8 +
                     std::chrono::milliseconds(static_cast<std::int64_t>(
                         move.travel_mm / move.feed_mm_min * 60000.0 * 4));
  return call<ProbeMoveResult>("probe", limit, [this, move](auto promise) {
    try {
      promise->set_value(run_probe(move));
    } catch (...) {
      promise->set_exception(std::current_exception());
    }
  });
}

}  // namespace scanmesh::drivers::modbus_stage
