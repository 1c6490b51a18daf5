// A live progress line on stderr for scans and replays: samples, points, triangles, rate, lag.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cstdio>
#include <string>

#include "scanmesh/acquisition/pipeline.hpp"

namespace scanmesh::cli {

class ProgressBar {
 public:
  explicit ProgressBar(bool enabled) : enabled_(enabled) {}
  void show(const acq::PipelineStats& s) {
    if (!enabled_) return;
    const double t = std::chrono::duration<double>(s.elapsed).count();
    const double rate = t > 0 ? static_cast<double>(s.samples_received) / t : 0.0;
    std::fprintf(stderr,
                 "\r%-9s %10llu samples %10llu points %9llu triangles %9.0f samples/s lag %llu   ",
                 std::string(acq::to_string(s.state)).c_str(),
                 static_cast<unsigned long long>(s.samples_received),
                 static_cast<unsigned long long>(s.points),
                 static_cast<unsigned long long>(s.mesh.triangles), rate,
                 static_cast<unsigned long long>(s.meshing_lag));
    std::fflush(stderr);
    shown_ = true;
  }
  void done(const acq::PipelineStats& s) {
    if (!enabled_) return;
    show(s);
    std::fputc('\n', stderr);
  }

 private:
  bool enabled_;
  bool shown_ = false;
};

}  // namespace scanmesh::cli
