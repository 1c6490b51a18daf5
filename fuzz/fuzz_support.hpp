// Shared body of the codec fuzz targets: decodes the input whole and again in pseudo-random
// chunks, checks every reply, and aborts unless both runs give the same replies.
// SPDX-License-Identifier: MIT
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

namespace scanmesh::fuzz {

/// Feeds data to a fresh Decoder at once, then in chunks of 1..16 bytes drawn from a generator
/// seeded by the input itself. check(reply) aborts on an invalid reply; digest(reply) folds a
/// reply into a hash. Aborts unless both runs agree on replies, malformed count and hash.
template <class Decoder, class Check, class Digest>
void check_any_chunking(const std::uint8_t* data, std::size_t size, Check check, Digest digest) {
  struct Tally {
    std::uint64_t replies = 0;
    std::uint64_t malformed = 0;
    std::uint64_t hash = 0;
  };
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  auto feed = [&](Decoder& d, std::string_view chunk, Tally& t) {
    d.feed(
        chunk,
        [&](const auto& r) {
          check(r);
          ++t.replies;
          t.hash = t.hash * 31 + digest(r);
        },
        [&](const char*) { ++t.malformed; });
  };
  Tally whole;
  Tally split;
  {
    Decoder d;
    feed(d, bytes, whole);
  }
  {
    std::uint32_t state = size > 0 ? data[0] * 2654435761u + static_cast<std::uint32_t>(size) : 1;
    Decoder d;
    std::size_t pos = 0;
    while (pos < size) {
      state = state * 1664525u + 1013904223u;
      const std::size_t n = std::min<std::size_t>(1 + (state >> 28), size - pos);
      feed(d, bytes.substr(pos, n), split);
      pos += n;
    }
  }
  if (whole.replies != split.replies || whole.malformed != split.malformed ||
      whole.hash != split.hash)
    std::abort();
}

}  // namespace scanmesh::fuzz
