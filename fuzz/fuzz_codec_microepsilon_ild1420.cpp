// libFuzzer target for the Micro-Epsilon ILD1420 codec: the binary stream decoder and the ASCII
// reply parser must take any bytes, in any chunking, without crashing, and give the same result
// however the bytes are split; decoded blocks never carry a made-up value.
// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

#include "scanmesh/drivers/microepsilon_ild1420/codec.hpp"

namespace ild = scanmesh::drivers::microepsilon_ild1420;
using scanmesh::drivers::SensorStatus;

namespace {

/// Chunk sizes derived from the input itself (1..16 bytes).
std::vector<std::size_t> chunks(std::span<const std::uint8_t> in) {
  std::vector<std::size_t> out;
  std::size_t done = 0;
  std::size_t k = 0;
  while (done < in.size()) {
    const std::size_t n = std::min<std::size_t>(1 + (in[k++ % in.size()] & 0x0F), in.size() - done);
    out.push_back(n);
    done += n;
  }
  return out;
}

void check_block(const ild::RawBlock& b, const ild::BlockLayout& layout) {
  if (b.count == 0 || b.count > ild::kMaxBlockValues) std::abort();
  for (int i = 0; i < b.count; ++i)
    if (b.words[i] > 0x3FFFF) std::abort();
  for (const bool mastering : {false, true}) {
    const ild::DecodedBlock d = ild::decode_block(b, layout, {10, mastering});
    if ((d.status == SensorStatus::kOk) != std::isfinite(d.value_mm)) std::abort();
    if (d.status == SensorStatus::kOk && (d.value_mm < -6 || d.value_mm > 40)) std::abort();
    if (d.counter && *d.counter > 0x3FFFF) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::size_t per_block = 1 + (data[0] % ild::kMaxBlockValues);
  const std::span<const std::uint8_t> in(data + 1, size - 1);
  ild::BlockLayout layout;
  layout.values.assign(per_block, ild::BlockValue::kOther);
  layout.values[0] = ild::BlockValue::kDistance;
  if (per_block >= 4) {
    layout.values[1] = ild::BlockValue::kCounter;
    layout.values[2] = ild::BlockValue::kTimestampLow;
    layout.values[3] = ild::BlockValue::kTimestampHigh;
  }

  // Binary stream: whole vs chunked.
  std::vector<std::uint32_t> whole_words, chunk_words;
  ild::StreamDecoder whole(per_block), chunked(per_block);
  whole.feed(in, [&](const ild::RawBlock& b) {
    check_block(b, layout);
    whole_words.insert(whole_words.end(), b.words.begin(), b.words.begin() + b.count);
  });
  std::size_t pos = 0;
  for (const std::size_t n : chunks(in)) {
    chunked.feed(in.subspan(pos, n), [&](const ild::RawBlock& b) {
      chunk_words.insert(chunk_words.end(), b.words.begin(), b.words.begin() + b.count);
    });
    pos += n;
  }
  if (whole_words != chunk_words || whole.malformed() != chunked.malformed()) std::abort();

  // ASCII replies: whole vs chunked; the bytes after the prompt are accounted for exactly.
  ild::ReplyParser a, b;
  const std::size_t used_a = a.feed(in);
  if (used_a > in.size()) std::abort();
  std::size_t used_b = 0;
  for (const std::size_t n : chunks(in)) {
    if (b.done()) break;
    used_b += b.feed(in.subspan(used_b, std::min(n, in.size() - used_b)));
  }
  if (a.done() != b.done()) std::abort();
  if (a.done()) {
    if (used_a != used_b) std::abort();
    if (a.reply().lines != b.reply().lines || a.reply().error != b.reply().error) std::abort();
    if (a.take_after_prompt().size() > 3) std::abort();
    (void)ild::parse_info(a.reply());
  } else {
    a.flush();
    b.flush();
    if (a.done() != b.done()) std::abort();
  }
  return 0;
}
