// libFuzzer target for the KEYENCE LK-G codec: the decoder must take any bytes, in any chunking,
// without crashing, and give the same replies however the bytes are split.
// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "fuzz_support.hpp"
#include "scanmesh/drivers/keyence_lkg/codec.hpp"

namespace lkg = scanmesh::drivers::keyence_lkg;
using scanmesh::drivers::SensorStatus;

namespace {

void check(const lkg::Reply& r) {
  if (r.count > r.readings.size()) std::abort();
  for (std::size_t i = 0; i < r.count; ++i) {
    const auto& reading = r.readings[i];
    // kOk carries a finite number; every other status carries NaN, never a made-up value.
    if ((reading.status == SensorStatus::kOk) != std::isfinite(reading.value)) std::abort();
  }
  if (r.kind == lkg::ReplyKind::kError && r.error_code > 99) std::abort();
}

std::uint64_t digest(const lkg::Reply& r) { return static_cast<std::uint64_t>(r.kind) + r.count; }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  scanmesh::fuzz::check_any_chunking<lkg::Decoder>(data, size, check, digest);
  // The single-field parser on the raw input.
  lkg::Reading reading;
  if (lkg::parse_value(bytes, reading) &&
      (reading.status == SensorStatus::kOk) != std::isfinite(reading.value))
    std::abort();
  return 0;
}
