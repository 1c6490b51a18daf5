// Modbus stage register maps: validation, register encoding/decoding, read planning and the two
// built-in drive families (see modbus_stage/codec.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/modbus_stage/codec.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "scanmesh/common/error.hpp"

namespace scanmesh::drivers::modbus_stage {

std::optional<RegisterType> register_type_from_string(std::string_view word) {
  if (word == "u16") return RegisterType::kU16;
  if (word == "i16") return RegisterType::kI16;
  if (word == "u32") return RegisterType::kU32;
  if (word == "i32") return RegisterType::kI32;
  return std::nullopt;
}

std::int64_t decode_value(RegisterType type, WordOrder order, std::span<const std::uint16_t> r) {
  switch (type) {
    case RegisterType::kU16:
      return r[0];
    case RegisterType::kI16:
      return static_cast<std::int16_t>(r[0]);
    case RegisterType::kU32:
    case RegisterType::kI32: {
      const std::uint32_t hi = order == WordOrder::kHighFirst ? r[0] : r[1];
      const std::uint32_t lo = order == WordOrder::kHighFirst ? r[1] : r[0];
      const std::uint32_t v = (hi << 16) | lo;
      return type == RegisterType::kU32 ? static_cast<std::int64_t>(v)
                                        : static_cast<std::int64_t>(static_cast<std::int32_t>(v));
    }
  }
  return 0;
}

void encode_value(RegisterType type, WordOrder order, std::int64_t value,
                  std::span<std::uint16_t> regs) {
  const auto v = static_cast<std::uint32_t>(value);
  if (register_count(type) == 1) {
    regs[0] = static_cast<std::uint16_t>(v);
    return;
  }
  const auto hi = static_cast<std::uint16_t>(v >> 16);
  const auto lo = static_cast<std::uint16_t>(v & 0xFFFF);
  regs[0] = order == WordOrder::kHighFirst ? hi : lo;
  regs[1] = order == WordOrder::kHighFirst ? lo : hi;
}

std::int32_t units_to_counts(const AxisMap& a, double units) {
  const double c = std::round(units * a.counts_per_unit);
  if (!std::isfinite(c) || c < std::numeric_limits<std::int32_t>::min() ||
      c > std::numeric_limits<std::int32_t>::max())
    throw ConfigError("axis " + std::string(to_string(a.axis)) + ": position " +
                      std::to_string(units) + " " + a.unit_name() + " is outside the drive's range");
  return static_cast<std::int32_t>(c);
}

std::vector<std::uint16_t> encode_write(const StageRegisterMap& map, const RegisterWrite& w,
                                        std::int32_t target_counts, double speed_units_s,
                                        double accel_units_s2) {
  std::vector<std::uint16_t> out;
  auto clamp16 = [](double v) {
    if (!std::isfinite(v)) return std::uint16_t{65535};
    return static_cast<std::uint16_t>(std::clamp(std::round(v), 1.0, 65535.0));
  };
  for (const WriteValue& v : w.values) {
    switch (v.kind) {
      case WriteValue::Kind::kConstant:
        out.push_back(v.constant);
        break;
      case WriteValue::Kind::kTarget: {
        const RegisterType t = map.position.type == RegisterType::kU32 ? RegisterType::kU32
                                                                       : RegisterType::kI32;
        std::uint16_t regs[2];
        encode_value(t, map.word_order, target_counts, regs);
        out.push_back(regs[0]);
        out.push_back(regs[1]);
        break;
      }
      case WriteValue::Kind::kSpeed:
        out.push_back(clamp16(speed_units_s * map.speed_scale));
        break;
      case WriteValue::Kind::kAccel:
        out.push_back(clamp16(accel_units_s2 * map.accel_scale));
        break;
      case WriteValue::Kind::kAccelTime:
        out.push_back(clamp16(map.accel_scale / accel_units_s2));
        break;
    }
  }
  return out;
}

const AxisMap* StageRegisterMap::find(StageAxis axis) const {
  for (const auto& a : axes)
    if (a.axis == axis) return &a;
  return nullptr;
}

void StageRegisterMap::validate() const {
  std::vector<std::string> problems;
  auto fits = [](const RegisterRef& r) { return r.address + register_count(r.type) <= 65536; };
  if (!fits(position)) problems.push_back("position: address + size exceeds 65535");
  if (register_count(status.type) != 1) problems.push_back("status: must be u16 or i16");
  for (int b : {bits.moving, bits.homing, bits.homed, bits.fault, bits.probe_latched,
                bits.in_position})
    if (b < -1 || b > 15) problems.push_back("status bits must be 0..15");
  if (bits.moving < 0 && bits.in_position < 0)
    problems.push_back("status: needs a moving or an in_position bit");
  if (move.empty()) problems.push_back("move: no register writes");
  bool has_target = false;
  for (const auto& w : move)
    for (const auto& v : w.values) has_target = has_target || v.kind == WriteValue::Kind::kTarget;
  if (!move.empty() && !has_target) problems.push_back("move: no \"target\" value");
  for (const auto* list : {&init, &move, &home, &stop, &reset, &probe_arm})
    for (const auto& w : *list) {
      std::size_t n = 0;
      for (const auto& v : w.values) n += v.kind == WriteValue::Kind::kTarget ? 2 : 1;
      if (n == 0 || n > 123) problems.push_back("a write must have 1..123 registers");
      if (w.address + n > 65536) problems.push_back("a write exceeds address 65535");
    }
  if (!probe_arm.empty() && (!probe_position || bits.probe_latched < 0))
    problems.push_back("probe: arming needs probe_position and a probe_latched bit");
  if (!(speed_scale > 0) || !std::isfinite(speed_scale)) problems.push_back("speed_scale must be > 0");
  if (!(accel_scale > 0) || !std::isfinite(accel_scale)) problems.push_back("accel_scale must be > 0");
  if (!(max_speed_units_s >= 0)) problems.push_back("max_speed must be >= 0");
  if (!(default_accel_units_s2 > 0) || !std::isfinite(default_accel_units_s2))
    problems.push_back("accel must be > 0");
  if (axes.empty()) problems.push_back("no axes");
  std::set<int> units;
  std::set<StageAxis> names;
  for (std::size_t i = 0; i < axes.size(); ++i) {
    const AxisMap& a = axes[i];
    const std::string where =
        "axis " + std::to_string(i + 1) + " (" + std::string(to_string(a.axis)) + ")";
    if (a.unit < 1 || a.unit > 247) problems.push_back(where + ": unit must be 1..247");
    if (!units.insert(a.unit).second) problems.push_back(where + ": unit " + std::to_string(a.unit) + " used twice");
    if (!names.insert(a.axis).second) problems.push_back(where + ": axis named twice");
    if (!std::isfinite(a.counts_per_unit) || a.counts_per_unit == 0)
      problems.push_back(where + ": counts_per_unit must be finite and non-zero");
    if (!std::isfinite(a.min) || !std::isfinite(a.max) || a.min > a.max)
      problems.push_back(where + ": travel min must be <= max");
  }
  if (!problems.empty()) {
    std::string msg = "profile " + profile + ": ";
    for (std::size_t i = 0; i < problems.size(); ++i) msg += (i ? "; " : "") + problems[i];
    throw ConfigError(msg);
  }
}

std::vector<ReadBlock> plan_reads(const StageRegisterMap& map, int max_gap) {
  std::vector<RegisterRef> refs{map.position, map.status};
  if (map.alarm) refs.push_back(*map.alarm);
  std::sort(refs.begin(), refs.end(),
            [](const RegisterRef& a, const RegisterRef& b) { return a.address < b.address; });
  std::vector<ReadBlock> blocks;
  for (const RegisterRef& r : refs) {
    const int end = r.address + register_count(r.type);
    if (!blocks.empty()) {
      ReadBlock& last = blocks.back();
      const int last_end = last.address + last.count;
      if (r.address <= last_end + max_gap && end - last.address <= 125) {
        last.count = static_cast<std::uint16_t>(std::max(last_end, end) - last.address);
        continue;
      }
    }
    blocks.push_back({r.address, static_cast<std::uint16_t>(end - r.address)});
  }
  return blocks;
}

namespace {

/// The registers of `ref` inside the concatenated image of `plan`.
std::span<const std::uint16_t> locate(const RegisterRef& ref, std::span<const ReadBlock> plan,
                                      std::span<const std::uint16_t> image) {
  std::size_t offset = 0;
  for (const ReadBlock& b : plan) {
    if (ref.address >= b.address && ref.address + register_count(ref.type) <= b.address + b.count) {
      const std::size_t at = offset + (ref.address - b.address);
      if (at + register_count(ref.type) <= image.size())
        return image.subspan(at, register_count(ref.type));
      return {};
    }
    offset += b.count;
  }
  return {};
}

bool bit(std::uint16_t word, int b) { return b >= 0 && ((word >> b) & 1U) != 0; }

}  // namespace

AxisReading decode_axis(const StageRegisterMap& map, const AxisMap& axis,
                        std::span<const ReadBlock> plan, std::span<const std::uint16_t> image) {
  AxisReading r;
  const auto pos = locate(map.position, plan, image);
  const auto st = locate(map.status, plan, image);
  if (pos.empty() || st.empty()) return r;
  r.position = counts_to_units(axis, decode_value(map.position.type, map.word_order, pos));
  const std::uint16_t w = st[0];
  const StatusBits& b = map.bits;
  r.moving = b.moving >= 0 ? bit(w, b.moving) : !bit(w, b.in_position);
  r.homing = bit(w, b.homing);
  r.homed = bit(w, b.homed);
  r.fault = bit(w, b.fault);
  r.probe_latched = bit(w, b.probe_latched);
  if (map.alarm) {
    const auto al = locate(*map.alarm, plan, image);
    if (!al.empty())
      r.alarm_code = static_cast<int>(decode_value(map.alarm->type, map.word_order, al));
    // A drive with an alarm register but no fault bit: a non-zero code is the fault.
    if (b.fault < 0) r.fault = r.alarm_code != 0;
  }
  return r;
}

std::string alarm_text(const StageRegisterMap& map, int code) {
  const auto it = map.alarm_names.find(code);
  if (it != map.alarm_names.end()) return it->second;
  return "alarm " + std::to_string(code);
}

namespace {

WriteValue c(std::uint16_t v) { return {WriteValue::Kind::kConstant, v}; }
WriteValue target() { return {WriteValue::Kind::kTarget, 0}; }

}  // namespace

StageRegisterMap leadshine_pr_map() {
  StageRegisterMap m;
  m.profile = "leadshine-pr";
  m.vendor = "Leadshine";
  m.model = "CS2RS / iEM-RS (PR motion block)";
  m.word_order = WordOrder::kHighFirst;
  m.position = {0x602A, RegisterType::kI32};
  m.status = {0x1003, RegisterType::kU16};
  m.bits = {.moving = 2, .homing = 3, .homed = 4, .fault = 0, .probe_latched = 5};
  m.alarm = RegisterRef{0x2203, RegisterType::kU16};
  m.alarm_names = {{0x0E0, "Er0E0 over-current"},
                   {0x0C0, "Er0C0 over-voltage"},
                   {0x0D0, "Er0D0 under-voltage"},
                   {0x180, "Er180 position following error too large"},
                   {0x1A0, "Er1A0 over-speed"},
                   {0x150, "Er150 encoder disconnected"}};
  m.probe_position = RegisterRef{0x2212, RegisterType::kI32};
  // PR0 block: mode, position high, position low, velocity (rpm), acceleration and deceleration
  // (ms per 1000 rpm), dwell, trigger 0x0010 = start PR0 now.
  m.move = {{0x6200,
             {c(0x0001), target(), {WriteValue::Kind::kSpeed, 0}, {WriteValue::Kind::kAccelTime, 0},
              {WriteValue::Kind::kAccelTime, 0}, c(0), c(0x0010)}}};
  m.home = {{0x6002, {c(0x0020)}}};
  m.stop = {{0x6002, {c(0x0040)}}};
  m.reset = {{0x0033, {c(0x1111)}}};
  m.probe_arm = {{0x2210, {c(0x0001)}}};
  // 5 mm lead: 1 mm/s = 12 rpm; 1000 rpm = 83.33 mm/s, reached in 83333 / a ms.
  m.speed_scale = 12;
  m.accel_scale = 83333.3;
  m.max_speed_units_s = 250;
  m.default_accel_units_s2 = 1000;
  m.axes = {{StageAxis::kX, 1, 2000, 0, 400},
            {StageAxis::kY, 2, 2000, 0, 300},
            {StageAxis::kZ, 3, 2000, -100, 100}};
  return m;
}

StageRegisterMap delta_asda_map() {
  StageRegisterMap m;
  m.profile = "delta-asda";
  m.vendor = "Delta";
  m.model = "ASDA-A2/B2 (PR mode)";
  m.word_order = WordOrder::kLowFirst;
  m.position = {0x0012, RegisterType::kI32};  // P0-09 monitor 1, showing the feedback position
  m.status = {0x005C, RegisterType::kU16};    // P0-46 servo output status (DO bits)
  m.bits = {.homed = 8, .fault = 6, .probe_latched = 10, .in_position = 4};
  m.alarm = RegisterRef{0x0002, RegisterType::kU16};  // P0-01 current alarm code
  m.alarm_names = {{1, "AL001 overcurrent"},
                   {2, "AL002 overvoltage"},
                   {3, "AL003 undervoltage"},
                   {6, "AL006 overload"},
                   {7, "AL007 overspeed"},
                   {9, "AL009 position control error too large"},
                   {11, "AL011 encoder error"},
                   {13, "AL013 emergency stop"},
                   {14, "AL014 reverse inhibit limit"},
                   {15, "AL015 forward inhibit limit"}};
  m.probe_position = RegisterRef{0x05E0, RegisterType::kI32};
  m.init = {{0x0022, {c(0), c(0)}}};  // P0-17 = 0: monitor 1 shows the feedback position (PUU)
  m.move = {{0x0606, {target()}},       // P6-03: PR#1 target
            {0x0578, {{WriteValue::Kind::kSpeed, 0}, c(0)}},  // P5-60: PR speed, 0.1 rpm
            {0x050E, {c(1), c(0)}}};    // P5-07 = 1: run PR#1
  m.home = {{0x050E, {c(0), c(0)}}};    // P5-07 = 0: homing
  m.stop = {{0x050E, {c(1000), c(0)}}}; // P5-07 = 1000: stop the PR
  m.reset = {{0x040E, {c(0x0002), c(0)}}};
  m.probe_arm = {{0x054E, {c(0x0001), c(0)}}};
  // Turntable 1:1, 100000 PUU per revolution; 1 deg/s = 1/6 rpm = 1.667 x 0.1 rpm.
  m.speed_scale = 10.0 / 6.0;
  m.accel_scale = 1;
  m.max_speed_units_s = 360;
  m.default_accel_units_s2 = 720;
  m.axes = {{StageAxis::kA, 1, 100000.0 / 360.0, 0, 0}};
  return m;
}

}  // namespace scanmesh::drivers::modbus_stage
