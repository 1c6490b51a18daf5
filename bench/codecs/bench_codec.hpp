// Registry of codec throughput benchmarks: each file under bench/codecs/ registers one protocol.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace scanmesh::bench {

/// What one protocol's benchmark measured and what the fastest device of that protocol sends.
struct CodecFigures {
  std::string protocol;             ///< driver name, e.g. "keyence-lkg"
  std::string what;                 ///< what was parsed, e.g. "M0 replies, 2 values each"
  double bytes = 0;                 ///< bytes parsed in the timed run
  double samples = 0;               ///< samples (values) decoded in the timed run
  double seconds = 0;               ///< wall time of the timed run
  double device_bytes_per_s = 0;    ///< fastest byte rate the device can send (baud/10 for 8N1)
  double device_samples_per_s = 0;  ///< fastest sample rate of the device over that link
  double required_mb_per_s = 0;     ///< an absolute target if the issue sets one (0 = none)
  double required_samples_per_s = 0;  ///< an absolute rate target (reports/s; 0 = none)
};

using CodecBench = std::function<CodecFigures()>;

/// Adds a benchmark; call it from a namespace-scope initialiser in each codecs/*.cpp file.
bool register_codec_bench(CodecBench bench);

/// Keeps the optimiser from discarding a result.
template <class T>
inline void do_not_optimize(const T& value) {
  asm volatile("" : : "g"(&value) : "memory");
}

/// Times `rounds` passes of a fresh line-protocol Decoder over stream, fed in pieces of `chunk`
/// bytes (a serial read); on_reply(reply) sees every reply, malformed input is ignored. Returns
/// the wall time in seconds.
template <class Decoder, class OnReply>
double time_decoder(std::string_view stream, int rounds, std::size_t chunk, OnReply on_reply) {
  const auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < rounds; ++r) {
    Decoder decoder;
    for (std::size_t pos = 0; pos < stream.size(); pos += chunk)
      decoder.feed(stream.substr(pos, chunk), on_reply, [](const char*) {});
  }
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace scanmesh::bench
