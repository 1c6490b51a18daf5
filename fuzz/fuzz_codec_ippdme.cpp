// libFuzzer target for the I++ DME codec: the decoder must take any bytes, in any chunking,
// without crashing, give the same replies however the bytes are split, and only well-formed
// tags, markers, items and error fields.
// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "fuzz_support.hpp"
#include "scanmesh/drivers/ippdme/codec.hpp"

namespace ipp = scanmesh::drivers::ippdme;

namespace {

void check(const ipp::Reply& r) {
  if (r.tag.event ? r.tag.number > 9999 : (r.tag.number < 1 || r.tag.number > 99999)) std::abort();
  if (r.item_count > ipp::kMaxItems) std::abort();
  for (int k = 0; k < r.item_count; ++k) {
    const ipp::Item& it = r.items[k];
    if (it.count > ipp::kMaxArgs) std::abort();
    for (int a = 0; a < it.count; ++a)
      if (!std::isfinite(it.v[a])) std::abort();
  }
  if (r.marker == ipp::Marker::kError &&
      (r.severity < 0 || r.severity > 9 || r.code < 0 || r.code > 9999))
    std::abort();
  (void)ipp::error_text(r.code);
}

std::uint64_t digest(const ipp::Reply& r) {
  return r.tag.number * 7 + static_cast<std::uint64_t>(r.marker) * 3 + r.item_count +
         static_cast<std::uint64_t>(r.code);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  scanmesh::fuzz::check_any_chunking<ipp::Decoder>(data, size, check, digest);
  double v = 0;
  if (ipp::parse_number(std::string_view(reinterpret_cast<const char*>(data), size), v) &&
      !std::isfinite(v))
    std::abort();
  return 0;
}
