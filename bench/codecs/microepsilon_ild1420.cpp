// Codec throughput of the Micro-Epsilon ILD1420 binary stream: 3-byte L/M/H distance values
// (with a little line noise and error codes), decoded and scaled. Target: >= 100 MB/s.
// SPDX-License-Identifier: MIT
#include <chrono>
#include <cstdint>
#include <span>
#include <vector>

#include "codecs/bench_codec.hpp"
#include "scanmesh/drivers/microepsilon_ild1420/codec.hpp"

namespace scanmesh::bench {
namespace {

CodecFigures bench_microepsilon_ild1420() {
  namespace ild = drivers::microepsilon_ild1420;
  // About 4.5 MB: 1.5 M values, a slow ramp with an error code every 101st value and one
  // garbage byte every 10007 values (so the resync path is exercised too).
  std::vector<std::uint8_t> stream;
  const std::size_t values = 1'500'000;
  stream.reserve(values * 3 + values / 10000);
  for (std::size_t i = 0; i < values; ++i) {
    const std::uint32_t x = (i % 101 == 0) ? ild::kNoPeak : 643 + (i * 7) % 64000;
    const auto b = ild::encode_word(x, true);
    stream.insert(stream.end(), b.begin(), b.end());
    if (i % 10007 == 0) stream.push_back(0x41);
  }
  const ild::BlockLayout layout;
  const ild::Scaling scaling{10, false};
  const int rounds = 10;
  std::uint64_t blocks = 0;
  double sum = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < rounds; ++r) {
    ild::StreamDecoder decoder(1);
    // Fed in serial-read-sized chunks.
    for (std::size_t pos = 0; pos < stream.size(); pos += 4096) {
      const std::size_t n = std::min<std::size_t>(4096, stream.size() - pos);
      decoder.feed(std::span(stream).subspan(pos, n), [&](const ild::RawBlock& raw) {
        const ild::DecodedBlock d = ild::decode_block(raw, layout, scaling);
        ++blocks;
        if (d.status == drivers::SensorStatus::kOk) sum += d.value_mm;
      });
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  do_not_optimize(sum);
  CodecFigures f;
  f.protocol = "microepsilon-ild1420";
  f.what = "binary L/M/H stream, distance-only blocks, decoded + scaled";
  f.bytes = static_cast<double>(stream.size()) * rounds;
  f.samples = static_cast<double>(blocks);
  f.seconds = seconds;
  f.device_bytes_per_s = 1'000'000 / 10.0;  // RS422 at its 1 MBaud maximum, 8N1
  f.device_samples_per_s = 4000;            // 4 kHz maximum measuring rate (< 33 k values/s link)
  f.required_mb_per_s = 100;
  return f;
}

const bool registered = register_codec_bench(bench_microepsilon_ild1420);

}  // namespace
}  // namespace scanmesh::bench
