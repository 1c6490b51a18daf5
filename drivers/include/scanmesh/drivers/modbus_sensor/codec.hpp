// Generic Modbus register-mapped displacement sensor: the register map as data (fields with
// address, kind, type, word order, scale and offset), its validation, the request plan, and the
// pure decoding of register values into a measurement. The Baumer OM20/OM30 map is built in.
// SPDX-License-Identifier: MIT
//
// Models: any sensor that exposes its distance in Modbus registers. Built-in profile: Baumer
//   OM20 / OM30 (RS485 Modbus RTU), "OM20/OM30 RS485 with Modbus RTU, Operating Manual V1",
//   §3.5 and §7.3, pp. 13, 14, 23, 45 (PROTOCOLS.md §1.5).
// Transport: RegisterBus (libmodbus, RTU or TCP); addresses are 0-based PDU addresses.
// Quirks:
//   - Baumer: multi-register values are little-endian in word order (low word at the lower
//     address), unlike e.g. Leadshine drives (high word first): the word order is per field.
//   - Baumer: a multi-register value must be read in full (partial access is refused), so the
//     request plan never splits a field across two requests.
//   - Baumer: the measurement block (quality 200, outputs 201, distance 202-203, timestamp
//     209-212) is read with one FC04 request of 13 registers from 200.
//   - Identity strings: 2 ASCII characters per register, high byte first (the Modbus byte order
//     of a register); trailing NULs and spaces are trimmed. [unverified] The manual lists only
//     the register ranges; the byte order inside a register is the usual Modbus convention.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/drivers/register_bus.hpp"
#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::drivers::modbus_sensor {

enum class FieldType { kU16, kI16, kU32, kI32, kF32 };
/// Order of the two registers of a 32-bit value: kLowFirst = low word at the lower address.
enum class WordOrder { kLowFirst, kHighFirst };

std::string_view to_string(FieldType type);
std::optional<FieldType> field_type_from_string(std::string_view word);  // "u16", "f32", ...

/// Registers a value of this type occupies (1 or 2).
constexpr int register_count(FieldType type) {
  return (type == FieldType::kU16 || type == FieldType::kI16) ? 1 : 2;
}

/// One value in the device's registers. value = raw * scale + offset (raw: the integer or
/// float32 the registers hold; or the selected bit, 0/1, when bit >= 0).
struct RegisterField {
  /// Role of the field: "distance" (mm, required), "status" (non-zero = alarm), "quality"
  /// (>= RegisterMap::quality_critical = alarm), "alarm" (non-zero = alarm), "timestamp_s",
  /// "timestamp_us" (device clock, seconds and microseconds parts).
  std::string name;
  RegisterKind kind = RegisterKind::kInput;
  std::uint16_t address = 0;  ///< first register, 0-based PDU address
  FieldType type = FieldType::kU16;
  WordOrder word_order = WordOrder::kLowFirst;  ///< 32-bit types only
  double scale = 1;                             ///< finite, non-zero. Default 1
  double offset = 0;                            ///< finite. Default 0
  int bit = -1;  ///< -1 = whole value; 0..31 = this bit of an integer field
};

/// Where one identity string lives (2 ASCII characters per register, high byte first).
struct RegisterString {
  RegisterKind kind = RegisterKind::kInput;
  std::uint16_t address = 0;
  std::uint16_t count = 0;  ///< registers, 1..125
};

/// A sensor's register map. Plain data: built in code (baumer_om30_map()) or loaded from a
/// profile file (profile.hpp).
struct RegisterMap {
  std::string profile = "custom";  ///< name for messages ("baumer-om30")
  std::vector<RegisterField> fields;
  /// Identity strings read once by open(); absent = the device has none.
  std::optional<RegisterString> vendor, model, serial, firmware;
  /// Quality value at and above which the measurement is flagged kAlarm. Default 2 (Baumer
  /// "critical"); valid 0..65535.
  double quality_critical = 2;
  /// Requests may cover up to this many unused registers between two fields to save a round
  /// trip. Default 16; valid 0..100.
  int max_gap = 16;
  /// Capabilities (0 = unknown): fastest measurement rate, measuring range.
  double max_rate_hz = 0;
  double range_min_mm = 0;
  double range_max_mm = 0;

  /// Checks every field and reports every problem at once: throws ConfigError whose message
  /// lists all of them ("profile baumer-om30: field 2 (distance): scale must be finite and
  /// non-zero; ..."). Requires exactly one "distance" field.
  void validate() const;
  const RegisterField* find(std::string_view name) const;
};

/// The built-in Baumer OM20/OM30 map (PROTOCOLS.md §1.5): quality IR 200, outputs IR 201
/// (bit 1 alarm), distance float32 IR 202-203 low word first, timestamp s IR 209-210 and µs IR
/// 211-212 (u32, low word first), identity strings IR 0 (vendor), 32 (product), 95 (serial),
/// 110 (firmware).
RegisterMap baumer_om30_map();

/// One read request.
struct RegisterBlock {
  RegisterKind kind = RegisterKind::kInput;
  std::uint16_t address = 0;
  std::uint16_t count = 0;  ///< 1..125
};

/// Decodes one field from the registers starting at the field's own address (regs.size() must
/// be >= register_count(field.type); otherwise NaN).
double decode_field(const RegisterField& field, std::span<const std::uint16_t> regs);
/// Encodes a value into the registers of a field (the inverse, for emulators and tests).
void encode_field(const RegisterField& field, double value, std::span<std::uint16_t> regs);
/// Identity string: 2 characters per register, high byte first, trailing NUL/space trimmed;
/// non-printable characters become '?'.
std::string decode_string(std::span<const std::uint16_t> regs);

/// What one poll of the map yields (no transport, no clock).
struct Measurement {
  SensorStatus status = SensorStatus::kNoTarget;
  double value_mm = 0;                ///< NaN unless kOk
  std::uint32_t device_code = 0;      ///< alarm: the raw status/alarm/quality value that flagged it
  std::optional<Timestamp> t_device;  ///< from timestamp_s (+ timestamp_us) when mapped
};

/// The request plan of a map and the decoding of the registers it returns. Pure; no allocation
/// per decode. Status rules (first match wins):
///   1. distance NaN or infinite          -> kNoTarget (Baumer: no object / out of range)
///   2. "alarm" or "status" field non-zero -> kAlarm, device_code = that raw value
///   3. "quality" >= quality_critical      -> kAlarm, device_code = quality
///   4. otherwise                          -> kOk with the distance
class MapDecoder {
 public:
  /// Validates the map (throws ConfigError) and plans the fewest read requests covering all
  /// fields, never splitting a field, merging gaps up to map.max_gap registers.
  explicit MapDecoder(RegisterMap map);

  const RegisterMap& map() const { return map_; }
  const std::vector<RegisterBlock>& blocks() const { return blocks_; }
  /// Total registers of all blocks: the size of the image decode() takes.
  std::size_t image_size() const { return image_size_; }
  /// image = the registers of blocks() concatenated in order.
  Measurement decode(std::span<const std::uint16_t> image) const;

 private:
  struct Slot {
    int field = -1;          // index into map_.fields, -1 = not mapped
    std::size_t offset = 0;  // into the image
  };
  RegisterMap map_;
  std::vector<RegisterBlock> blocks_;
  std::size_t image_size_ = 0;
  Slot distance_, status_, quality_, alarm_, ts_s_, ts_us_;
};

}  // namespace scanmesh::drivers::modbus_sensor
