// libFuzzer target for the generic Modbus sensor codec: register maps built from the input
// (validation must reject or accept without crashing; profile-free), request planning, and the
// decoding of arbitrary register images. A kOk measurement always carries a finite value.
// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <span>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/modbus_sensor/codec.hpp"

namespace mb = scanmesh::drivers::modbus_sensor;
using scanmesh::drivers::RegisterKind;
using scanmesh::drivers::SensorStatus;

namespace {

struct Input {
  const std::uint8_t* p;
  std::size_t n;
  std::uint8_t u8() {
    if (n == 0) return 0;
    --n;
    return *p++;
  }
  std::uint16_t u16() { return static_cast<std::uint16_t>(u8() | (u8() << 8)); }
  double f64() {
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(u8()) << (8 * i);
    double d;
    std::memcpy(&d, &v, sizeof d);
    return d;
  }
};

constexpr const char* kNames[] = {"distance",    "status",       "quality", "alarm",
                                  "timestamp_s", "timestamp_us", "bogus"};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Input in{data, size};
  mb::RegisterMap map;
  const int nfields = in.u8() % 8;
  for (int i = 0; i < nfields; ++i) {
    mb::RegisterField f;
    f.name = kNames[in.u8() % 7];
    f.kind = (in.u8() & 1) ? RegisterKind::kHolding : RegisterKind::kInput;
    const std::uint8_t shape = in.u8();
    f.address = (shape & 0x80) ? in.u16() : static_cast<std::uint16_t>(in.u8());
    f.type = static_cast<mb::FieldType>(shape % 5);
    f.word_order = (shape & 0x08) ? mb::WordOrder::kHighFirst : mb::WordOrder::kLowFirst;
    f.scale = (shape & 0x10) ? in.f64() : 1.0;
    f.offset = (shape & 0x20) ? in.f64() : 0.0;
    f.bit = (shape & 0x40) ? static_cast<int>(in.u8() % 40) - 4 : -1;
    map.fields.push_back(f);
  }
  map.max_gap = in.u8() % 120;
  map.quality_critical = in.u8() % 4;
  try {
    const mb::MapDecoder dec(map);
    std::size_t total = 0;
    for (const auto& b : dec.blocks()) {
      if (b.count == 0 || b.count > 125) std::abort();
      total += b.count;
    }
    if (total != dec.image_size()) std::abort();
    std::vector<std::uint16_t> image(dec.image_size());
    for (auto& r : image) r = in.u16();
    const mb::Measurement m = dec.decode(image);
    if ((m.status == SensorStatus::kOk) != std::isfinite(m.value_mm)) std::abort();
    // A short image is refused, never read past.
    if (!image.empty()) (void)dec.decode(std::span(image).first(image.size() - 1));
  } catch (const scanmesh::ConfigError&) {
    // rejected map: fine
  }
  // Raw field and string decoding on the rest of the input.
  std::vector<std::uint16_t> regs;
  while (in.n >= 2) regs.push_back(in.u16());
  for (int t = 0; t < 5; ++t) {
    mb::RegisterField f;
    f.type = static_cast<mb::FieldType>(t);
    (void)mb::decode_field(f, regs);
  }
  const std::string s = mb::decode_string(regs);
  if (s.size() > regs.size() * 2) std::abort();
  return 0;
}
