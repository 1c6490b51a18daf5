// libFuzzer target for the KEYENCE LK-G codec: the decoder must take any bytes, in any chunking,
// without crashing, and give the same replies however the bytes are split.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

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

struct Tally {
  std::uint64_t replies = 0;
  std::uint64_t malformed = 0;
  std::uint64_t hash = 0;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  Tally whole;
  Tally split;
  {
    lkg::Decoder d;
    d.feed(
        bytes,
        [&](const lkg::Reply& r) {
          check(r);
          ++whole.replies;
          whole.hash = whole.hash * 31 + static_cast<std::uint64_t>(r.kind) + r.count;
        },
        [&](const char*) { ++whole.malformed; });
  }
  {
    // Chunk sizes 1..16 from a generator seeded by the input itself.
    std::uint32_t state = size > 0 ? data[0] * 2654435761u + static_cast<std::uint32_t>(size) : 1;
    lkg::Decoder d;
    std::size_t pos = 0;
    while (pos < size) {
      state = state * 1664525u + 1013904223u;
      const std::size_t n = std::min<std::size_t>(1 + (state >> 28), size - pos);
      d.feed(
          bytes.substr(pos, n),
          [&](const lkg::Reply& r) {
            check(r);
            ++split.replies;
            split.hash = split.hash * 31 + static_cast<std::uint64_t>(r.kind) + r.count;
          },
          [&](const char*) { ++split.malformed; });
      pos += n;
    }
  }
  if (whole.replies != split.replies || whole.malformed != split.malformed ||
      whole.hash != split.hash)
    std::abort();
  // The single-field parser on the raw input.
  lkg::Reading reading;
  if (lkg::parse_value(bytes, reading) &&
      (reading.status == SensorStatus::kOk) != std::isfinite(reading.value))
    std::abort();
  return 0;
}
