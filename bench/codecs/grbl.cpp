// Codec throughput of the GRBL protocol: status reports as a controller sends them while moving
// (`<Run|MPos:...|FS:...>`, now and then with WCO and Pn), interleaved with `ok`. Target (issue
// 53): at least 1 million status reports per second on one core.
// SPDX-License-Identifier: MIT
#include <cstdint>
#include <cstdio>
#include <string>

#include "codecs/bench_codec.hpp"
#include "scanmesh/drivers/grbl/codec.hpp"
#include "scanmesh/drivers/grbl/device.hpp"

namespace scanmesh::bench {
namespace {

CodecFigures bench_grbl() {
  namespace grbl = drivers::grbl;
  std::string stream;
  const std::size_t reports = 200000;
  stream.reserve(reports * 70);
  char line[160];
  for (std::size_t i = 0; i < reports; ++i) {
    const double x = -120.0 + 0.013 * static_cast<double>(i % 20000);
    const double y = 35.5 - 0.007 * static_cast<double>(i % 5000);
    std::snprintf(line, sizeof line, "<Run|MPos:%.3f,%.3f,%.3f|FS:%d,0%s%s>\r\n", x, y, -4.25,
                  1500 + static_cast<int>(i % 7), (i % 10 == 0) ? "|WCO:0.000,0.000,-12.500" : "",
                  (i % 13 == 0) ? "|Pn:P" : "");
    stream += line;
    if (i % 4 == 0) stream += "ok\r\n";
  }
  const int rounds = 10;
  std::uint64_t status = 0;
  double sum = 0;
  const double seconds = time_decoder<grbl::Decoder>(stream, rounds, 256, [&](const grbl::Reply& r) {
    if (r.kind == grbl::ReplyKind::kStatus) {
      ++status;
      sum += r.status.pos.v[0];
    }
  });
  do_not_optimize(sum);
  CodecFigures f;
  f.protocol = "grbl";
  f.what = "status reports <Run|MPos:x,y,z|FS:f,s[|WCO][|Pn]> CR LF, ~50 bytes, with ok lines";
  f.bytes = static_cast<double>(stream.size()) * rounds;
  f.samples = static_cast<double>(status);
  f.seconds = seconds;
  f.device_bytes_per_s = grbl::kDefaultBaud / 10.0;
  f.device_samples_per_s = 50;  // reports at 10 Hz recommended, 50 Hz at the most
  f.required_samples_per_s = 1e6;
  return f;
}

const bool registered = register_codec_bench(bench_grbl);

}  // namespace
}  // namespace scanmesh::bench
