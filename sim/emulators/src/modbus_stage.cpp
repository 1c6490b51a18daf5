// Modbus drive stage emulator (see modbus_stage.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/modbus_stage.hpp"

#include <cmath>
#include <numbers>
#include <random>

#include "scanmesh/common/error.hpp"

namespace scanmesh::sim {

namespace ms = drivers::modbus_stage;
using drivers::StageAxis;

namespace {

constexpr double kRadPerDeg = std::numbers::pi / 180.0;

double component(const StagePose& p, StageAxis axis) {
  switch (axis) {
    case StageAxis::kX: return p.x_mm;
    case StageAxis::kY: return p.y_mm;
    case StageAxis::kZ: return p.z_mm;
    case StageAxis::kA: return p.a_rad / kRadPerDeg;  // the drive counts degrees
  }
  return 0;
}

}  // namespace

ModbusStageModel::ModbusStageModel(ModbusStageOptions options)
    : options_(std::move(options)), no_input_(1, 0), rng_(options_.motion.probe.seed) {
  options_.map.validate();
  for (const ms::AxisMap& m : options_.map.axes) {
    Axis a;
    a.map = m;
    a.holding.assign(65536, 0);
    StageMotionOptions o;
    o.limits = options_.motion.limits;
    o.homing_speed_mm_s = options_.motion.homing_speed_mm_s;
    o.start = {component(options_.motion.start, m.axis), 0, 0, 0};
    o.home = {component(options_.motion.home, m.axis), 0, 0, 0};
    a.motion = std::make_unique<StageMotion>(o);
    axes_.push_back(std::move(a));
  }
}

ModbusStageModel::Axis* ModbusStageModel::axis_of_unit(int unit) {
  for (auto& a : axes_)
    if (a.map.unit == unit) return &a;
  return nullptr;
}

ModbusTables ModbusStageModel::tables(int unit) {
  Axis* a = axis_of_unit(unit);
  if (!a) return {};
  return {std::span(no_input_), std::span(a->holding)};
}

StagePose ModbusStageModel::combined(Timestamp t) {
  StagePose p;
  for (auto& a : axes_) {
    const double v = a.motion->pose(t).x_mm;
    switch (a.map.axis) {
      case StageAxis::kX: p.x_mm = v; break;
      case StageAxis::kY: p.y_mm = v; break;
      case StageAxis::kZ: p.z_mm = v; break;
      case StageAxis::kA: p.a_rad = v * kRadPerDeg; break;
    }
  }
  return p;
}

bool ModbusStageModel::touching(const StagePose& p) const {
  const auto& probe = options_.motion.probe;
  if (!probe.scene || never_triggers_) return false;
  const Vec3 tip = part_from_sensor(probe.calibration, p) * Vec3(0, 0, 0);
  return probe.scene->bvh().closest_point(tip).distance <= probe.tip_radius_mm;
}

void ModbusStageModel::check_probe(Timestamp now) {
  const Timestamp from = last_check_.ns == 0 ? now : last_check_;
  last_check_ = now;
  bool armed = false, latched = false;
  for (const auto& a : axes_) {
    armed = armed || a.armed;
    latched = latched || a.latched;
  }
  if (!armed || latched || now <= from) return;
  // Sample the combined path finely enough that the tip cannot pass through the surface
  // unseen, then bisect the first touching interval to the contact instant.
  const double r = options_.motion.probe.tip_radius_mm;
  const double v_max = options_.motion.limits.linear_velocity_mm_s * std::sqrt(3.0);
  const auto step = std::chrono::nanoseconds(
      std::max<std::int64_t>(1000, static_cast<std::int64_t>(r / 4 / v_max * 1e9)));
  Timestamp lo = from;
  Timestamp hit{};
  for (Timestamp t = from + step;; t = t + step) {
    if (t > now) t = now;
    if (touching(combined(t))) {
      hit = t;
      break;
    }
    lo = t;
    if (t == now) return;
  }
  Timestamp hi = hit;
  while ((hi - lo).count() > 100) {
    const Timestamp mid{lo.ns + (hi.ns - lo.ns) / 2};
    if (touching(combined(mid)))
      hi = mid;
    else
      lo = mid;
  }
  // Every drive latches on the shared probe signal and stops there.
  const StagePose at = combined(hi);
  std::normal_distribution<double> noise(0.0, options_.motion.probe.noise_mm);
  for (auto& a : axes_) {
    a.motion->abort(hi);
    if (!a.armed) continue;
    double v = component(at, a.map.axis);
    if (options_.motion.probe.noise_mm > 0 && a.map.axis != StageAxis::kA) v += noise(rng_);
    a.latched = true;
    a.latched_counts = std::llround(v * a.map.counts_per_unit);
  }
}

void ModbusStageModel::refresh(Axis& a, Timestamp now) {
  const ms::StageRegisterMap& m = options_.map;
  if (a.homing && !a.motion->homing(now)) {
    a.homing = false;
    a.homed = true;
  }
  const bool moving = a.motion->moving(now);
  auto put = [&](const ms::RegisterRef& ref, std::int64_t value) {
    const auto u = static_cast<std::uint32_t>(value);
    if (ref.type == ms::RegisterType::kU16 || ref.type == ms::RegisterType::kI16) {
      a.holding[ref.address] = static_cast<std::uint16_t>(u);
      return;
    }
    const bool high_first = m.word_order == ms::WordOrder::kHighFirst;
    a.holding[ref.address] = static_cast<std::uint16_t>(high_first ? u >> 16 : u & 0xFFFF);
    a.holding[ref.address + 1] = static_cast<std::uint16_t>(high_first ? u & 0xFFFF : u >> 16);
  };
  put(m.position, std::llround(a.motion->pose(now).x_mm * a.map.counts_per_unit));
  std::uint16_t word = 0;
  auto set_bit = [&](int b, bool on) {
    if (b >= 0 && on) word = static_cast<std::uint16_t>(word | (1U << b));
  };
  set_bit(m.bits.moving, moving);
  set_bit(m.bits.homing, a.homing);
  set_bit(m.bits.homed, a.homed);
  set_bit(m.bits.fault, a.fault);
  set_bit(m.bits.probe_latched, a.latched);
  set_bit(m.bits.in_position, !moving);
  a.holding[m.status.address] = word;
  if (m.alarm) put(*m.alarm, a.alarm_code);
  if (m.probe_position) put(*m.probe_position, a.latched_counts);
}

void ModbusStageModel::before_reply(const ModbusRequest& r) {
  std::lock_guard lock(mutex_);
  const Timestamp now = drivers::monotonic_now();
  check_probe(now);
  if (Axis* a = axis_of_unit(r.unit)) refresh(*a, now);
}

bool ModbusStageModel::matches(const Axis& a, const ModbusRequest& r,
                               const std::vector<ms::RegisterWrite>& list) const {
  if (list.empty()) return false;
  const ms::RegisterWrite& w = list.back();
  std::uint32_t n = 0;
  for (const auto& v : w.values) n += v.kind == ms::WriteValue::Kind::kTarget ? 2 : 1;
  if (r.address > w.address || r.address + r.count < w.address + n) return false;
  std::uint32_t at = w.address;
  for (const auto& v : w.values) {
    if (v.kind == ms::WriteValue::Kind::kConstant && a.holding[at] != v.constant) return false;
    at += v.kind == ms::WriteValue::Kind::kTarget ? 2 : 1;
  }
  return true;
}

std::int64_t ModbusStageModel::read_value(const Axis& a, std::uint16_t address, bool wide,
                                          bool is_signed) const {
  if (!wide) return a.holding[address];
  const bool high_first = options_.map.word_order == ms::WordOrder::kHighFirst;
  const std::uint32_t first = a.holding[address], second = a.holding[address + 1];
  const std::uint32_t v = high_first ? (first << 16) | second : (second << 16) | first;
  return is_signed ? static_cast<std::int32_t>(v) : static_cast<std::int64_t>(v);
}

void ModbusStageModel::start_move(Axis& a, Timestamp now) {
  const ms::StageRegisterMap& m = options_.map;
  double target = a.motion->pose(now).x_mm, speed = m.max_speed_units_s, accel = 0;
  for (const auto& w : m.move) {
    std::uint32_t at = w.address;
    for (const auto& v : w.values) {
      switch (v.kind) {
        case ms::WriteValue::Kind::kTarget:
          target = static_cast<double>(read_value(a, static_cast<std::uint16_t>(at), true,
                                                  m.position.type != ms::RegisterType::kU32)) /
                   a.map.counts_per_unit;
          at += 2;
          continue;
        case ms::WriteValue::Kind::kSpeed:
          speed = a.holding[at] / m.speed_scale;
          break;
        case ms::WriteValue::Kind::kAccel:
          accel = a.holding[at] / m.accel_scale;
          break;
        case ms::WriteValue::Kind::kAccelTime:
          accel = a.holding[at] > 0 ? m.accel_scale / a.holding[at] : 0;
          break;
        case ms::WriteValue::Kind::kConstant:
          break;
      }
      ++at;
    }
  }
  if (!(speed > 0)) speed = options_.motion.limits.linear_velocity_mm_s;
  a.motion->queue_move({target, 0, 0, 0}, speed, Trajectory::kNoCap, now, accel);
  ++moves_started_;
}

void ModbusStageModel::after_write(const ModbusRequest& r) {
  std::lock_guard lock(mutex_);
  Axis* a = axis_of_unit(r.unit);
  if (!a) return;
  const Timestamp now = drivers::monotonic_now();
  check_probe(now);
  const ms::StageRegisterMap& m = options_.map;
  // Order matters where commands share a register (Delta P5-07: 1000 stop, 0 home, 1 move).
  if (matches(*a, r, m.stop)) {
    a->motion->abort(now);
    a->homing = false;
  } else if (matches(*a, r, m.reset)) {
    a->fault = false;
    a->alarm_code = 0;
  } else if (matches(*a, r, m.probe_arm)) {
    a->armed = true;
    a->latched = false;
    last_check_ = now;
    // A deflected probe latches at once.
    if (touching(combined(now))) {
      a->latched = true;
      a->latched_counts = std::llround(a->motion->pose(now).x_mm * a->map.counts_per_unit);
    }
  } else if (a->fault) {
    // A drive in alarm ignores motion commands.
  } else if (matches(*a, r, m.home)) {
    a->motion->start_homing(now);
    a->homing = true;
  } else if (matches(*a, r, m.move)) {
    start_move(*a, now);
  }
}

StagePose ModbusStageModel::pose(Timestamp now) {
  std::lock_guard lock(mutex_);
  check_probe(now);
  return combined(now);
}

void ModbusStageModel::raise_alarm(StageAxis axis, int code) {
  std::lock_guard lock(mutex_);
  for (auto& a : axes_) {
    if (a.map.axis != axis) continue;
    a.motion->abort(drivers::monotonic_now());
    a.fault = true;
    a.alarm_code = code;
  }
}

void ModbusStageModel::set_probe_never_triggers(bool on) {
  std::lock_guard lock(mutex_);
  never_triggers_ = on;
}

void ModbusStageModel::follow(std::function<StagePose(Timestamp)> path, Timestamp until) {
  std::lock_guard lock(mutex_);
  for (auto& a : axes_) {
    const StageAxis axis = a.map.axis;
    a.motion->follow([path, axis](Timestamp t) { return StagePose{component(path(t), axis), 0, 0, 0}; },
                     until);
  }
}

std::uint64_t ModbusStageModel::moves_started() const {
  std::lock_guard lock(mutex_);
  return moves_started_;
}

}  // namespace scanmesh::sim
