// Codec throughput of the KEYENCE LK-G protocol: the timed auto-output stream ("T1,+01.2345"
// CR), the fastest way the controller delivers values.
// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstdint>
#include <string>

#include "codecs/bench_codec.hpp"
#include "scanmesh/drivers/keyence_lkg/codec.hpp"
#include "scanmesh/drivers/keyence_lkg/device.hpp"

namespace scanmesh::bench {
namespace {

CodecFigures bench_keyence_lkg() {
  namespace lkg = drivers::keyence_lkg;
  // About 4 MB of records: a slowly varying profile with a few over-range and alarm values.
  std::string stream;
  const std::size_t records = 350000;
  stream.reserve(records * 12);
  for (std::size_t i = 0; i < records; ++i) {
    char field[lkg::kValueWidth];
    const double v = (i % 97 == 0) ? 1e9 : (i % 89 == 0) ? std::nan("") : 5.0 + (i % 2000) * 1e-3;
    lkg::format_value(v, 4, field);
    stream += (i % 2 == 0) ? "T1," : "T2,";
    stream.append(field, lkg::kValueWidth);
    stream += '\r';
  }
  const int rounds = 8;
  std::uint64_t replies = 0;
  double sum = 0;
  // Fed in serial-port-sized chunks.
  const double seconds =
      time_decoder<lkg::Decoder>(stream, rounds, 256, [&](const lkg::Reply& reply) {
        ++replies;
        if (reply.readings[0].status == drivers::SensorStatus::kOk) sum += reply.readings[0].value;
      });
  do_not_optimize(sum);
  CodecFigures f;
  f.protocol = "keyence-lkg";
  f.what = "auto-output records T<out>,<value> CR, 12 bytes each";
  f.bytes = static_cast<double>(stream.size()) * rounds;
  f.samples = static_cast<double>(replies);
  f.seconds = seconds;
  f.device_bytes_per_s = lkg::kMaxBaud / 10.0;           // 115200 baud 8N1
  f.device_samples_per_s = f.device_bytes_per_s / 12.0;  // 960 records/s
  return f;
}

const bool registered = register_codec_bench(bench_keyence_lkg);

}  // namespace
}  // namespace scanmesh::bench
