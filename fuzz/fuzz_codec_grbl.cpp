// libFuzzer target for the GRBL codec: the decoder must take any bytes, in any chunking, without
// crashing, give the same replies however the bytes are split, and never a report with more
// axes than it holds or a non-finite position.
// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "fuzz_support.hpp"
#include "scanmesh/drivers/grbl/codec.hpp"

namespace grbl = scanmesh::drivers::grbl;

namespace {

void check_axes(const grbl::AxisValues& a) {
  if (a.count > grbl::kMaxAxes) std::abort();
  for (int k = 0; k < a.count; ++k)
    if (!std::isfinite(a.v[k])) std::abort();
}

void check(const grbl::Reply& r) {
  switch (r.kind) {
    case grbl::ReplyKind::kStatus:
      if (r.status.pos.count == 0) std::abort();
      check_axes(r.status.pos);
      if (r.status.has_wco) check_axes(r.status.wco);
      if (r.status.substate > 9) std::abort();
      break;
    case grbl::ReplyKind::kProbe:
      if (r.probe.pos.count == 0) std::abort();
      check_axes(r.probe.pos);
      break;
    case grbl::ReplyKind::kError:
    case grbl::ReplyKind::kAlarm:
      if (r.code < 0 || r.code > 9999) std::abort();
      (void)grbl::error_text(r.code);
      (void)grbl::alarm_text(r.code);
      break;
    default:
      break;
  }
}

std::uint64_t digest(const grbl::Reply& r) {
  std::uint64_t h = static_cast<std::uint64_t>(r.kind) * 131 + static_cast<std::uint64_t>(r.code);
  if (r.kind == grbl::ReplyKind::kStatus)
    h = h * 31 + r.status.pos.count + static_cast<std::uint64_t>(r.status.state);
  return h + r.text.size();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  scanmesh::fuzz::check_any_chunking<grbl::Decoder>(data, size, check, digest);
  grbl::AxisValues a;
  if (grbl::parse_axes(std::string_view(reinterpret_cast<const char*>(data), size), a))
    check_axes(a);
  return 0;
}
