// libFuzzer target for the Panasonic HL-G1 codec: the decoder must take any bytes, in any chunking,
// without crashing, and give the same replies however the bytes are split.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "fuzz_support.hpp"
#include "scanmesh/drivers/panasonic_hlg1/codec.hpp"

namespace hlg1 = scanmesh::drivers::panasonic_hlg1;

namespace {

void check(const hlg1::Reply& r) {
  if (r.unit > 99 || r.data_size > hlg1::kMaxData) std::abort();
  if (r.kind == hlg1::ReplyKind::kError && r.error_code > 99) std::abort();
  if (r.has_value && (r.counts > 9999999 || r.counts < -9999999)) std::abort();
  if (!std::isfinite(r.value_mm())) std::abort();
}

std::uint64_t digest(const hlg1::Reply& r) {
  return static_cast<std::uint64_t>(r.kind) + static_cast<std::uint64_t>(r.counts) + r.data_size;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  scanmesh::fuzz::check_any_chunking<hlg1::Decoder>(data, size, check, digest);
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
