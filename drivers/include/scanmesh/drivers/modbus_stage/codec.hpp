// Modbus servo / stepper drives as stage axes: the register map as data (position, status word
// bits, alarm register and its code names, probe latch, and the register writes that start a
// move, homing, a stop, an alarm reset, the probe arming), its validation, and the pure
// decoding and encoding of registers. One drive (Modbus unit) per axis.
// SPDX-License-Identifier: MIT
//
// Models (profiles in config/devices/): Leadshine CS2RS / iEM-RS style drives with the PR motion
//   block (0x6200.., 32-bit values high word first, trigger word), and Delta ASDA-A2/B2 style
//   drives (parameters Pg-nn at 0x0100*g + 2*nn, 32-bit values low word first, PR paths started
//   through P5-07). Documents: CS2RS User Manual §4.2-4.3, App. A, p. 43; ASDA-B2 manual ch. 7-8,
//   ASDA-A2 ch. 9 (PROTOCOLS.md §3.3). Addresses are 0-based PDU addresses.
// Transport: RegisterBus (libmodbus RTU or TCP), one unit per axis (RegisterBus::select_unit).
// Quirks:
//   - Word order is per drive family (Leadshine high word first, Delta low word first): a profile
//     setting, applied to every 32-bit register of the map.
//   - Separate drives cannot interpolate: a multi-axis move gives each axis its share of the feed
//     and of the acceleration (|d_i| / |d|), so that the axes start, cruise and stop together and
//     the tool travels a straight line (as far as the drives' start times agree).
//   - Status-word bits, the alarm register and the probe-latch registers of the shipped profiles
//     are [unverified]: the manuals' appendices were not at hand; check them against your drive.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/drivers/motion_stage.hpp"

namespace scanmesh::drivers::modbus_stage {

enum class RegisterType { kU16, kI16, kU32, kI32 };
/// Order of the two registers of a 32-bit value: kLowFirst = low word at the lower address.
enum class WordOrder { kLowFirst, kHighFirst };

constexpr int register_count(RegisterType t) {
  return (t == RegisterType::kU16 || t == RegisterType::kI16) ? 1 : 2;
}
std::optional<RegisterType> register_type_from_string(std::string_view word);  ///< "u16", "i32" ...

/// One value in a drive's holding registers (FC03).
struct RegisterRef {
  std::uint16_t address = 0;
  RegisterType type = RegisterType::kI32;
};

/// One register write of a command: the registers from `address` on, written with one FC16 (FC06
/// for a single register). Each value is a constant or a placeholder the command fills in.
struct WriteValue {
  enum class Kind {
    kConstant,  ///< `constant` as is
    kTarget,    ///< target position in counts (2 registers for a 32-bit type, word order applied)
    kSpeed,     ///< speed in units/s * speed_scale (1 register, rounded, clamped to 1..65535)
    kAccel,     ///< acceleration in units/s^2 * accel_scale (1 register, clamped to 1..65535)
    kAccelTime, ///< accel_scale / acceleration: a ramp time (Leadshine ms per 1000 rpm), 1..65535
  };
  Kind kind = Kind::kConstant;
  std::uint16_t constant = 0;
};
struct RegisterWrite {
  std::uint16_t address = 0;
  std::vector<WriteValue> values;
};

/// Bits of the status word (-1: the drive has no such bit).
struct StatusBits {
  int moving = -1;         ///< a motion is running
  int homing = -1;         ///< the homing cycle is running
  int homed = -1;          ///< the homing cycle completed since power-up
  int fault = -1;          ///< the drive is in alarm (code in the alarm register)
  int probe_latched = -1;  ///< the probe input latched a position since it was armed
  int in_position = -1;    ///< target reached (Delta TPOS): moving = not in position, when the
                           ///< drive has no moving bit
};

/// One axis of the stage: which drive, how counts map to units.
struct AxisMap {
  StageAxis axis = StageAxis::kX;
  int unit = 1;                     ///< Modbus unit of its drive, 1..247
  double counts_per_unit = 1000;    ///< counts per mm (linear) or per degree (A); finite, != 0
  double min = 0, max = 0;          ///< travel in the axis unit (min == max: unknown)
  std::string unit_name() const { return axis == StageAxis::kA ? "deg" : "mm"; }
};

/// A drive family's register map plus the stage's axes. Plain data, loaded from a TOML profile
/// (factory/stage_profile.cpp) or built in code (tests).
struct StageRegisterMap {
  std::string profile = "custom";
  std::string vendor, model;
  WordOrder word_order = WordOrder::kHighFirst;
  RegisterRef position;  ///< actual position, counts (i32 or u32 usually)
  RegisterRef status{0, RegisterType::kU16};
  StatusBits bits;
  std::optional<RegisterRef> alarm;        ///< alarm code register (0 = no alarm)
  std::map<int, std::string> alarm_names;  ///< code -> name ("over-current")
  std::optional<RegisterRef> probe_position;  ///< latched position, counts
  /// Writes at open() (e.g. select the monitored value), then the command writes.
  std::vector<RegisterWrite> init, move, home, stop, reset, probe_arm;
  double speed_scale = 1;  ///< register value per unit/s (rpm per mm/s ...); > 0
  double accel_scale = 1;  ///< register value per unit/s^2; > 0
  double max_speed_units_s = 0;  ///< 0 = no limit
  double default_accel_units_s2 = 1000;  ///< used for moves; > 0
  std::vector<AxisMap> axes;

  /// Checks everything and reports every problem at once: throws ConfigError ("profile
  /// leadshine-pr: axis 2 (y): unit 2 used twice; ...").
  void validate() const;
  const AxisMap* find(StageAxis axis) const;
};

/// Decodes a register value (regs.size() >= register_count(type)).
std::int64_t decode_value(RegisterType type, WordOrder order, std::span<const std::uint16_t> regs);
/// Encodes a 32-bit (or 16-bit) value into registers in the given order.
void encode_value(RegisterType type, WordOrder order, std::int64_t value,
                  std::span<std::uint16_t> regs);

/// Position in the axis unit from counts.
inline double counts_to_units(const AxisMap& a, std::int64_t counts) {
  return static_cast<double>(counts) / a.counts_per_unit;
}
/// Counts for a position (rounded); throws ConfigError when outside the int32 range.
std::int32_t units_to_counts(const AxisMap& a, double units);

/// The registers of one command write, placeholders filled in.
std::vector<std::uint16_t> encode_write(const StageRegisterMap& map, const RegisterWrite& w,
                                        std::int32_t target_counts, double speed_units_s,
                                        double accel_units_s2);

/// What one poll of an axis's drive says.
struct AxisReading {
  double position = 0;  ///< axis unit
  bool moving = false, homing = false, homed = false, fault = false, probe_latched = false;
  int alarm_code = 0;
};

/// The reads one axis poll needs (few requests; registers of the map merged when close).
struct ReadBlock {
  std::uint16_t address = 0;
  std::uint16_t count = 0;
};
/// Plans the reads of position, status and alarm (not the probe latch), merging refs up to
/// `max_gap` unused registers apart.
std::vector<ReadBlock> plan_reads(const StageRegisterMap& map, int max_gap = 8);
/// Decodes one axis from the registers of plan_reads() concatenated in order. Pure, no
/// allocation.
AxisReading decode_axis(const StageRegisterMap& map, const AxisMap& axis,
                        std::span<const ReadBlock> plan, std::span<const std::uint16_t> image);

/// "AL009 excessive deviation" style text of an alarm code: the profile's name, or "alarm N".
std::string alarm_text(const StageRegisterMap& map, int code);

/// A Leadshine-style and a Delta-style map (the shipped profiles' content), for tests and as
/// defaults.
StageRegisterMap leadshine_pr_map();
StageRegisterMap delta_asda_map();

}  // namespace scanmesh::drivers::modbus_stage
