// bench_codecs: parse throughput of every device codec, against the fastest rate its device can
// send. Target (issue 4): every codec at least 50x faster than its device, and the ILD1420
// binary stream at least 100 MB/s. Prints one line per protocol and a PASS/MISS verdict.
// SPDX-License-Identifier: MIT
#include <cstdio>
#include <vector>

#include "codecs/bench_codec.hpp"

namespace scanmesh::bench {

namespace {
std::vector<CodecBench>& registry() {
  static std::vector<CodecBench> benches;  // filled before main() by the codecs/*.cpp files
  return benches;
}
}  // namespace

bool register_codec_bench(CodecBench bench) {
  registry().push_back(std::move(bench));
  return true;
}

}  // namespace scanmesh::bench

int main() {
  using namespace scanmesh::bench;
  std::printf("bench_codecs (%s build, single thread)\n", SCANMESH_BENCH_BUILD_TYPE);
  std::printf("%-22s %10s %14s %12s %14s  %s\n", "protocol", "MB/s", "samples/s", "x device",
              "target", "what");
  bool all_pass = true;
  for (const CodecBench& bench : registry()) {
    const CodecFigures f = bench();
    const double mbps = f.bytes / f.seconds / 1e6;
    const double sps = f.samples / f.seconds;
    const double factor = f.device_samples_per_s > 0 ? sps / f.device_samples_per_s
                                                     : (f.bytes / f.seconds) / f.device_bytes_per_s;
    bool pass = factor >= 50;
    if (f.required_mb_per_s > 0 && mbps < f.required_mb_per_s) pass = false;
    if (f.required_samples_per_s > 0 && sps < f.required_samples_per_s) pass = false;
    all_pass = all_pass && pass;
    char target[64];
    if (f.required_samples_per_s > 0)
      std::snprintf(target, sizeof target, ">=50x,>=%.0fM/s %s", f.required_samples_per_s / 1e6,
                    pass ? "PASS" : "MISS");
    else if (f.required_mb_per_s > 0)
      std::snprintf(target, sizeof target, ">=50x,>=%.0fMB/s %s", f.required_mb_per_s,
                    pass ? "PASS" : "MISS");
    else
      std::snprintf(target, sizeof target, ">=50x %s", pass ? "PASS" : "MISS");
    std::printf("%-22s %10.1f %14.0f %12.0f %14s  %s\n", f.protocol.c_str(), mbps, sps, factor,
                target, f.what.c_str());
  }
  std::printf("overall: %s\n", all_pass ? "PASS" : "MISS");
  return 0;
}
