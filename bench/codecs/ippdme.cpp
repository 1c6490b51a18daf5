// Codec throughput of the I++ DME protocol: replies as a CMM server sends them while a client
// polls and probes (position data, move reports, probed points with normals, & and %). Target
// (issue 53): at least 1 million replies per second on one core.
// SPDX-License-Identifier: MIT
#include <cstdint>
#include <cstdio>
#include <string>

#include "codecs/bench_codec.hpp"
#include "scanmesh/drivers/ippdme/codec.hpp"

namespace scanmesh::bench {
namespace {

CodecFigures bench_ippdme() {
  namespace ipp = drivers::ippdme;
  std::string stream;
  const std::size_t n = 150000;
  stream.reserve(n * 4 * 40);
  char line[200];
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned tag = 1 + static_cast<unsigned>(i % 99999);
    const double x = 100.0 + 0.0137 * static_cast<double>(i % 9000);
    std::snprintf(line, sizeof line, "%05u &\r\n", tag);
    stream += line;
    if (i % 3 == 0)
      std::snprintf(line, sizeof line, "%05u # X(%.4f), Y(-25.5000), Z(12.0310), IJK(0, 0.6, 0.8)\r\n", tag, x);
    else
      std::snprintf(line, sizeof line, "E0001 # X(%.4f), Y(50.1250), Z(-3.5000)\r\n", x);
    stream += line;
    std::snprintf(line, sizeof line, "%05u %%\r\n", tag);
    stream += line;
  }
  const int rounds = 8;
  std::uint64_t replies = 0;
  double sum = 0;
  const double seconds = time_decoder<ipp::Decoder>(stream, rounds, 1024, [&](const ipp::Reply& r) {
    ++replies;
    if (r.item_count > 0) sum += r.items[0].v[0];
  });
  do_not_optimize(sum);
  CodecFigures f;
  f.protocol = "ippdme";
  f.what = "replies: & / # X(),Y(),Z()[,IJK()] / E0001 move reports / %, ~20-60 bytes";
  f.bytes = static_cast<double>(stream.size()) * rounds;
  f.samples = static_cast<double>(replies);
  f.seconds = seconds;
  f.device_bytes_per_s = 12.5e6;    // 100 Mbit/s Ethernet
  f.device_samples_per_s = 1000;    // a server's move reports and replies: 1 kHz at the most
  f.required_samples_per_s = 1e6;
  return f;
}

const bool registered = register_codec_bench(bench_ippdme);

}  // namespace
}  // namespace scanmesh::bench
