// Codec throughput of the Panasonic HL-G1 protocol: RMD replies with BCC ("%01$RMD+0025000"
// BCC CR), BCC check included.
// SPDX-License-Identifier: MIT
#include <cstdint>
#include <cstdio>
#include <string>

#include "codecs/bench_codec.hpp"
#include "scanmesh/drivers/panasonic_hlg1/codec.hpp"
#include "scanmesh/drivers/panasonic_hlg1/device.hpp"

namespace scanmesh::bench {
namespace {

CodecFigures bench_panasonic_hlg1() {
  namespace hlg1 = drivers::panasonic_hlg1;
  std::string stream;
  const std::size_t replies_in_stream = 230000;  // about 4 MB
  stream.reserve(replies_in_stream * 18);
  for (std::size_t i = 0; i < replies_in_stream; ++i) {
    char body[32];
    const long counts = static_cast<long>(i % 200000) - 100000;
    std::snprintf(body, sizeof body, "%%01$RMD%c%07ld", counts < 0 ? '-' : '+',
                  counts < 0 ? -counts : counts);
    const std::uint8_t x = hlg1::bcc(body);
    char bcc[4];
    std::snprintf(bcc, sizeof bcc, "%02X", x);
    stream += body;
    stream += bcc;
    stream += '\r';
  }
  const int rounds = 8;
  std::uint64_t replies = 0;
  double sum = 0;
  // Fed in serial-port-sized chunks.
  const double seconds =
      time_decoder<hlg1::Decoder>(stream, rounds, 256, [&](const hlg1::Reply& reply) {
        ++replies;
        sum += reply.value_mm();
      });
  do_not_optimize(sum);
  CodecFigures f;
  f.protocol = "panasonic-hlg1";
  f.what = "RMD replies with BCC, 18 bytes each";
  f.bytes = static_cast<double>(stream.size()) * rounds;
  f.samples = static_cast<double>(replies);
  f.seconds = seconds;
  f.device_bytes_per_s = hlg1::kMaxBaud / 10.0;          // 115200 baud 8N1
  f.device_samples_per_s = f.device_bytes_per_s / 18.0;  // 640 replies/s (replies only)
  return f;
}

const bool registered = register_codec_bench(bench_panasonic_hlg1);

}  // namespace
}  // namespace scanmesh::bench
