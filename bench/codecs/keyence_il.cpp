// Codec throughput of the KEYENCE DL-RS1A / IL protocol: M0 replies of one amplifier
// ("M0,+12.345" CR LF).
// SPDX-License-Identifier: MIT
#include <cstdint>
#include <cstdio>
#include <string>

#include "codecs/bench_codec.hpp"
#include "scanmesh/drivers/keyence_il/codec.hpp"
#include "scanmesh/drivers/keyence_il/device.hpp"

namespace scanmesh::bench {
namespace {

CodecFigures bench_keyence_il() {
  namespace il = drivers::keyence_il;
  std::string stream;
  const std::size_t replies_in_stream = 350000;  // about 4 MB
  stream.reserve(replies_in_stream * 12);
  for (std::size_t i = 0; i < replies_in_stream; ++i) {
    char line[32];
    const double v = -20.0 + static_cast<double>(i % 40000) * 1e-3;
    std::snprintf(line, sizeof line, "M0,%c%06.3f\r\n", v < 0 ? '-' : '+', v < 0 ? -v : v);
    stream += line;
  }
  const int rounds = 8;
  std::uint64_t replies = 0;
  double sum = 0;
  // Fed in serial-port-sized chunks.
  const double seconds =
      time_decoder<il::Decoder>(stream, rounds, 256, [&](const il::Reply& reply) {
        ++replies;
        sum += reply.readings[0].value;
      });
  do_not_optimize(sum);
  CodecFigures f;
  f.protocol = "keyence-il";
  f.what = "M0 replies, one amplifier, 12 bytes each";
  f.bytes = static_cast<double>(stream.size()) * rounds;
  f.samples = static_cast<double>(replies);
  f.seconds = seconds;
  f.device_bytes_per_s = il::kMaxBaud / 10.0;            // 115200 baud 8N1
  f.device_samples_per_s = f.device_bytes_per_s / 12.0;  // 960 replies/s (replies only)
  return f;
}

const bool registered = register_codec_bench(bench_keyence_il);

}  // namespace
}  // namespace scanmesh::bench
