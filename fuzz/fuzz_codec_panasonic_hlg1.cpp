// libFuzzer target for the Panasonic HL-G1 codec: the decoder must take any bytes, in any chunking,
// without crashing, and give the same replies however the bytes are split.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "scanmesh/drivers/panasonic_hlg1/codec.hpp"

namespace hlg1 = scanmesh::drivers::panasonic_hlg1;

namespace {

void check(const hlg1::Reply& r) {
  if (r.unit > 99 || r.data_size > hlg1::kMaxData) std::abort();
  if (r.kind == hlg1::ReplyKind::kError && r.error_code > 99) std::abort();
  if (r.has_value && (r.counts > 9999999 || r.counts < -9999999)) std::abort();
  if (!std::isfinite(r.value_mm())) std::abort();
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
    hlg1::Decoder d;
    d.feed(
        bytes,
        [&](const hlg1::Reply& r) {
          check(r);
          ++whole.replies;
          whole.hash = whole.hash * 31 + static_cast<std::uint64_t>(r.kind) +
                       static_cast<std::uint64_t>(r.counts) + r.data_size;
        },
        [&](const char*) { ++whole.malformed; });
  }
  {
    // Chunk sizes 1..16 from a generator seeded by the input itself.
    std::uint32_t state = size > 0 ? data[0] * 2654435761u + static_cast<std::uint32_t>(size) : 1;
    hlg1::Decoder d;
    std::size_t pos = 0;
    while (pos < size) {
      state = state * 1664525u + 1013904223u;
      const std::size_t n = std::min<std::size_t>(1 + (state >> 28), size - pos);
      d.feed(
          bytes.substr(pos, n),
          [&](const hlg1::Reply& r) {
            check(r);
            ++split.replies;
            split.hash = split.hash * 31 + static_cast<std::uint64_t>(r.kind) +
                         static_cast<std::uint64_t>(r.counts) + r.data_size;
          },
          [&](const char*) { ++split.malformed; });
      pos += n;
    }
  }
  if (whole.replies != split.replies || whole.malformed != split.malformed ||
      whole.hash != split.hash)
    std::abort();
  // The value parser and the request encoder on the raw input.
  std::int32_t counts = 0;
  if (hlg1::parse_counts(bytes, counts) && (counts > 9999999 || counts < -9999999)) std::abort();
  char out[64];
  const std::size_t n =
      hlg1::encode_request(size > 0 ? data[0] : 0, bytes.substr(0, 3),
                           bytes.substr(std::min<std::size_t>(3, size)), true, out);
  if (n > sizeof out) std::abort();
  return 0;
}
