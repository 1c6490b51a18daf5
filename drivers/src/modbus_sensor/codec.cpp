// Register map validation, request planning and register decoding of the generic Modbus sensor.
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/modbus_sensor/codec.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <set>

#include "scanmesh/common/error.hpp"

namespace scanmesh::drivers::modbus_sensor {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::string_view kFieldNames[] = {"distance", "status",      "quality",
                                            "alarm",    "timestamp_s", "timestamp_us"};

bool is_integer(FieldType t) { return t != FieldType::kF32; }

std::uint32_t combine(const RegisterField& f, std::span<const std::uint16_t> regs) {
  const std::uint32_t a = regs[0];
  const std::uint32_t b = regs[1];
  return f.word_order == WordOrder::kLowFirst ? (b << 16) | a : (a << 16) | b;
}

}  // namespace

std::string_view to_string(FieldType type) {
  switch (type) {
    case FieldType::kU16:
      return "u16";
    case FieldType::kI16:
      return "i16";
    case FieldType::kU32:
      return "u32";
    case FieldType::kI32:
      return "i32";
    case FieldType::kF32:
      return "f32";
  }
  return "?";
}

std::optional<FieldType> field_type_from_string(std::string_view word) {
  for (auto t :
       {FieldType::kU16, FieldType::kI16, FieldType::kU32, FieldType::kI32, FieldType::kF32}) {
    if (to_string(t) == word) return t;
  }
  return std::nullopt;
}

const RegisterField* RegisterMap::find(std::string_view name) const {
  for (const auto& f : fields)
    if (f.name == name) return &f;
  return nullptr;
}

void RegisterMap::validate() const {
  std::vector<std::string> problems;
  std::set<std::string> seen;
  int distance_count = 0;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    const RegisterField& f = fields[i];
    const std::string where = "field " + std::to_string(i + 1) + " (" + f.name + ")";
    if (std::find(std::begin(kFieldNames), std::end(kFieldNames), f.name) ==
        std::end(kFieldNames)) {
      problems.push_back(where +
                         ": unknown name (distance, status, quality, alarm, timestamp_s, "
                         "timestamp_us)");
    }
    if (!seen.insert(f.name).second) problems.push_back(where + ": duplicate name");
    if (f.name == "distance") ++distance_count;
    if (static_cast<int>(f.address) + register_count(f.type) > 65536)
      problems.push_back(where + ": address + size exceeds 65535");
    if (!std::isfinite(f.scale) || f.scale == 0)
      problems.push_back(where + ": scale must be finite and non-zero");
    if (!std::isfinite(f.offset)) problems.push_back(where + ": offset must be finite");
    if (f.bit != -1) {
      if (!is_integer(f.type))
        problems.push_back(where + ": bit needs an integer type");
      else if (f.bit < 0 || f.bit >= 16 * register_count(f.type))
        problems.push_back(where + ": bit out of range for " + std::string(to_string(f.type)));
    }
    if (f.name == "distance" && f.bit != -1) problems.push_back(where + ": distance has no bit");
  }
  if (distance_count == 0) problems.push_back("no \"distance\" field");
  for (const auto* s : {&vendor, &model, &serial, &firmware}) {
    if (*s && ((*s)->count < 1 || (*s)->count > 125 ||
               static_cast<int>((*s)->address) + (*s)->count > 65536)) {
      problems.push_back("identity string at " + std::to_string((*s)->address) +
                         ": count must be 1..125 within the address space");
    }
  }
  if (!(quality_critical >= 0 && quality_critical <= 65535))
    problems.push_back("quality_critical must be 0..65535");
  if (max_gap < 0 || max_gap > 100) problems.push_back("max_gap must be 0..100");
  if (!(max_rate_hz >= 0) || !std::isfinite(max_rate_hz))
    problems.push_back("max_rate_hz must be >= 0");
  if (!std::isfinite(range_min_mm) || !std::isfinite(range_max_mm) || range_max_mm < range_min_mm)
    problems.push_back("range_min_mm/range_max_mm must be finite with min <= max");
  if (!problems.empty()) {
    std::string msg = "register map " + profile + ": ";
    for (std::size_t i = 0; i < problems.size(); ++i) msg += (i ? "; " : "") + problems[i];
    throw ConfigError(msg);
  }
}

RegisterMap baumer_om30_map() {
  RegisterMap m;
  m.profile = "baumer-om30";
  m.fields = {
      {"quality", RegisterKind::kInput, 200, FieldType::kU16, WordOrder::kLowFirst, 1, 0, -1},
      {"alarm", RegisterKind::kInput, 201, FieldType::kU16, WordOrder::kLowFirst, 1, 0, 1},
      {"distance", RegisterKind::kInput, 202, FieldType::kF32, WordOrder::kLowFirst, 1, 0, -1},
      {"timestamp_s", RegisterKind::kInput, 209, FieldType::kU32, WordOrder::kLowFirst, 1, 0, -1},
      {"timestamp_us", RegisterKind::kInput, 211, FieldType::kU32, WordOrder::kLowFirst, 1, 0, -1},
  };
  m.vendor = RegisterString{RegisterKind::kInput, 0, 16};
  m.model = RegisterString{RegisterKind::kInput, 32, 26};
  m.serial = RegisterString{RegisterKind::kInput, 95, 10};
  m.firmware = RegisterString{RegisterKind::kInput, 110, 5};
  m.quality_critical = 2;
  m.max_gap = 16;
  // [unverified] OM30 measuring rate up to ~1.5 kHz over RS485 is bounded by the bus anyway.
  m.max_rate_hz = 0;
  return m;
}

double decode_field(const RegisterField& f, std::span<const std::uint16_t> regs) {
  if (regs.size() < static_cast<std::size_t>(register_count(f.type))) return kNaN;
  double raw = 0;
  std::uint32_t bits = 0;
  switch (f.type) {
    case FieldType::kU16:
      bits = regs[0];
      raw = bits;
      break;
    case FieldType::kI16:
      bits = regs[0];
      raw = static_cast<std::int16_t>(regs[0]);
      break;
    case FieldType::kU32:
      bits = combine(f, regs);
      raw = bits;
      break;
    case FieldType::kI32:
      bits = combine(f, regs);
      raw = static_cast<std::int32_t>(bits);
      break;
    case FieldType::kF32:
      raw = std::bit_cast<float>(combine(f, regs));
      break;
  }
  if (f.bit >= 0 && f.bit < 32 && f.type != FieldType::kF32) raw = (bits >> f.bit) & 1U;
  return raw * f.scale + f.offset;
}

void encode_field(const RegisterField& f, double value, std::span<std::uint16_t> regs) {
  if (regs.size() < static_cast<std::size_t>(register_count(f.type))) return;
  const double raw = (value - f.offset) / f.scale;
  std::uint32_t bits = 0;
  switch (f.type) {
    case FieldType::kU16:
    case FieldType::kU32:
      bits = std::isfinite(raw) && raw > 0 ? static_cast<std::uint32_t>(std::llround(raw)) : 0;
      break;
    case FieldType::kI16:
    case FieldType::kI32:
      bits = std::isfinite(raw)
                 ? static_cast<std::uint32_t>(static_cast<std::int32_t>(std::llround(raw)))
                 : 0;
      break;
    case FieldType::kF32:
      bits = std::bit_cast<std::uint32_t>(static_cast<float>(raw));
      break;
  }
  if (f.bit >= 0 && f.type != FieldType::kF32) bits = (bits != 0 ? 1U : 0U) << f.bit;
  if (register_count(f.type) == 1) {
    regs[0] = static_cast<std::uint16_t>(bits);
  } else if (f.word_order == WordOrder::kLowFirst) {
    regs[0] = static_cast<std::uint16_t>(bits);
    regs[1] = static_cast<std::uint16_t>(bits >> 16);
  } else {
    regs[0] = static_cast<std::uint16_t>(bits >> 16);
    regs[1] = static_cast<std::uint16_t>(bits);
  }
}

std::string decode_string(std::span<const std::uint16_t> regs) {
  std::string s;
  s.reserve(regs.size() * 2);
  for (const std::uint16_t r : regs) {
    for (const unsigned c : {unsigned(r >> 8), unsigned(r & 0xFF)}) {
      if (c == 0) {
        s.push_back('\0');
      } else {
        s.push_back(c >= 0x20 && c < 0x7F ? static_cast<char>(c) : '?');
      }
    }
  }
  // Cut at the first NUL (C-string padding), then trim trailing spaces.
  if (const auto nul = s.find('\0'); nul != std::string::npos) s.resize(nul);
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

MapDecoder::MapDecoder(RegisterMap map) : map_(std::move(map)) {
  map_.validate();
  // Plan: per register kind, fields sorted by address; a block grows while the next field
  // starts within max_gap registers of its end and the block stays <= 125 registers.
  std::vector<int> order(map_.fields.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const auto& fa = map_.fields[a];
    const auto& fb = map_.fields[b];
    if (fa.kind != fb.kind) return fa.kind < fb.kind;
    return fa.address < fb.address;
  });
  std::vector<std::pair<int, std::size_t>> placed;  // field index, block index
  for (const int i : order) {
    const auto& f = map_.fields[i];
    const int start = f.address;
    const int end = start + register_count(f.type);  // exclusive
    if (!blocks_.empty()) {
      RegisterBlock& b = blocks_.back();
      const int b_end = b.address + b.count;
      if (b.kind == f.kind && start <= b_end + map_.max_gap && end - b.address <= 125) {
        b.count = static_cast<std::uint16_t>(std::max(b_end, end) - b.address);
        placed.emplace_back(i, blocks_.size() - 1);
        continue;
      }
    }
    blocks_.push_back({f.kind, f.address, static_cast<std::uint16_t>(end - start)});
    placed.emplace_back(i, blocks_.size() - 1);
  }
  std::vector<std::size_t> block_offset(blocks_.size());
  for (std::size_t b = 0; b < blocks_.size(); ++b) {
    block_offset[b] = image_size_;
    image_size_ += blocks_[b].count;
  }
  for (const auto& [i, b] : placed) {
    const auto& f = map_.fields[i];
    const Slot slot{i, block_offset[b] + (f.address - blocks_[b].address)};
    if (f.name == "distance") distance_ = slot;
    if (f.name == "status") status_ = slot;
    if (f.name == "quality") quality_ = slot;
    if (f.name == "alarm") alarm_ = slot;
    if (f.name == "timestamp_s") ts_s_ = slot;
    if (f.name == "timestamp_us") ts_us_ = slot;
  }
}

Measurement MapDecoder::decode(std::span<const std::uint16_t> image) const {
  Measurement m;
  m.value_mm = kNaN;
  if (image.size() < image_size_) {
    m.status = SensorStatus::kDeviceError;  // cannot happen with a correct caller
    return m;
  }
  auto value = [&](const Slot& s) {
    return decode_field(map_.fields[s.field], image.subspan(s.offset));
  };
  auto as_code = [](double v) {
    return v >= 0 && v < 4294967296.0 ? static_cast<std::uint32_t>(v) : 0xFFFFFFFFU;
  };
  if (ts_s_.field >= 0) {
    const double s = value(ts_s_);
    const double us = ts_us_.field >= 0 ? value(ts_us_) : 0;
    // Whole seconds in integer nanoseconds (a double would lose ns after ~104 days). Each part
    // stays under 4e18 ns (about 126 years), so their sum fits in int64 (a fuzzer found
    // 2.3e18 + 8.5e18 with the former bounds of 9e9 s and 9e15 us).
    if (std::isfinite(s) && std::isfinite(us) && std::fabs(s) < 4e9 && std::fabs(us) < 4e15) {
      const double whole = std::floor(s);
      m.t_device = Timestamp{static_cast<std::int64_t>(whole) * 1'000'000'000 +
                             std::llround((s - whole) * 1e9 + us * 1e3)};
    }
  }
  const double d = value(distance_);
  if (!std::isfinite(d)) {
    m.status = SensorStatus::kNoTarget;
    return m;
  }
  for (const Slot* s : {&alarm_, &status_}) {
    if (s->field < 0) continue;
    const double v = value(*s);
    if (v != 0) {
      m.status = SensorStatus::kAlarm;
      // The whole register (e.g. every output bit of Baumer IR 201), not just the alarm bit.
      m.device_code = map_.fields[s->field].bit >= 0 ? image[s->offset] : as_code(v);
      return m;
    }
  }
  if (quality_.field >= 0) {
    const double q = value(quality_);
    if (!(q < map_.quality_critical)) {
      m.status = SensorStatus::kAlarm;
      m.device_code = as_code(q);
      return m;
    }
  }
  m.status = SensorStatus::kOk;
  m.value_mm = d;
  return m;
}

}  // namespace scanmesh::drivers::modbus_sensor
