// Simulated-scanner benchmark: samples per second for the point sensor and the line profiler
// scanning a 100k-triangle mesh (target: 5 million per second), plus BVH build time and the
// cost of writing the stream file.
// SPDX-License-Identifier: MIT
#include <time.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <numbers>
#include <ostream>
#include <streambuf>
#include <string>
#include <thread>
#include <utility>

#include "bench_meshes.hpp"
#include "scanmesh/sim/simulator.hpp"
#include "scanmesh/sim/stream.hpp"

#ifndef SCANMESH_BENCH_BUILD_TYPE
#define SCANMESH_BENCH_BUILD_TYPE "unknown"
#endif

namespace {

using namespace scanmesh;
using recon::Vec3;

class CountingSink : public sim::SampleSink {
 public:
  void on_sensor(std::span<const sim::SensorSample> s) override {
    samples += s.size();
    for (const auto& x : s) ok += x.status == sim::SensorStatus::kOk ? 1 : 0;
  }
  void on_stage(const sim::StageSample&) override { ++stage; }
  std::uint64_t samples = 0, ok = 0, stage = 0;
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// CPU time of this process (single-threaded here): the figure that does not depend on what else
/// the machine is running.
double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

/// A stream buffer that only counts the bytes written to it.
class CountingBuffer : public std::streambuf {
 public:
  std::uint64_t bytes = 0;

 protected:
  int_type overflow(int_type ch) override {
    if (ch != traits_type::eof()) ++bytes;
    return traits_type::not_eof(ch);
  }
  std::streamsize xsputn(const char*, std::streamsize n) override {
    bytes += static_cast<std::uint64_t>(n);
    return n;
  }
};

struct Result {
  double wall_rate = 0;
  double cpu_rate = 0;
};

Result run_case(const sim::Scene& scene, const char* name, sim::SimConfig config,
                std::uint32_t threads) {
  config.threads = threads;
  const sim::Simulator simulator(scene, config);
  CountingSink sink;
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = cpu_seconds();
  const sim::SimStats st = simulator.run(sink);
  const double s = seconds_since(t0);
  const double cpu = cpu_seconds() - c0;
  Result r{static_cast<double>(st.samples) / s, static_cast<double>(st.samples) / cpu};
  std::printf(
      "  %-26s %-9s %9llu samples (%4.1f%% ok), %9llu rays: wall %6.3f s = %5.2f M samples/s "
      "(%5.2f M rays/s), CPU %6.3f s\n",
      name, threads == 1 ? "1 thread" : "all cores", static_cast<unsigned long long>(st.samples),
      100.0 * static_cast<double>(sink.ok) / static_cast<double>(st.samples),
      static_cast<unsigned long long>(st.rays), s, r.wall_rate / 1e6,
      static_cast<double>(st.rays) / s / 1e6, cpu);
  return r;
}

double stream_rate(const sim::Scene& scene, const sim::SimConfig& config, double& megabytes) {
  const sim::Simulator simulator(scene, config);
  CountingBuffer buffer;
  std::ostream out(&buffer);
  sim::StreamWriter writer(out, sim::stream_header(simulator));
  const auto t0 = std::chrono::steady_clock::now();
  const sim::SimStats st = simulator.run(writer);
  writer.finish();
  megabytes = static_cast<double>(buffer.bytes) / 1e6;
  return static_cast<double>(st.samples) / seconds_since(t0);
}

}  // namespace

int main(int argc, char** argv) {
  const bool quick = argc > 1 && std::strcmp(argv[1], "--quick") == 0;
  double load[3] = {0, 0, 0};
  if (FILE* f = std::fopen("/proc/loadavg", "r")) {
    if (std::fscanf(f, "%lf %lf %lf", &load[0], &load[1], &load[2]) != 3) load[0] = -1;
    std::fclose(f);
  }
  std::printf("bench_sim (build type %s)%s: %u hardware threads, load average %.2f\n",
              SCANMESH_BENCH_BUILD_TYPE, quick ? " [quick]" : "",
              std::thread::hardware_concurrency(), load[0]);

  const double scale = quick ? 4 : 1;  // --quick: 16x fewer point samples, 4x fewer profiles
  sim::SimConfig point;
  point.sensor = sim::default_sensor(sim::SensorKind::kPoint);
  point.sensor.rate_hz = 10000;
  point.path.kind = sim::PathKind::kSerpentine;
  point.path.spacing_mm = 0.02 * scale;
  point.path.line_spacing_mm = 0.05 * scale;
  point.path.limits.linear_velocity_mm_s = 1000;
  point.imperfections.range_noise_mm = 0.002;
  point.imperfections.dropout_probability = 0.01;
  point.imperfections.spike_probability = 0.001;

  sim::SimConfig line;
  line.sensor = sim::default_sensor(sim::SensorKind::kLine);
  line.sensor.profile_points = 1000;
  line.sensor.rate_hz = 1000;
  line.path.kind = sim::PathKind::kSerpentine;
  line.path.spacing_mm = 0.05 * scale;
  line.imperfections = point.imperfections;

  struct MeshCase {
    const char* name;
    recon::Mesh mesh;
  };
  MeshCase meshes[] = {{"geodesic bumpy sphere", bench::geodesic_sphere(71)},
                       {"UV bumpy sphere (pole fans)", bench::bumpy_sphere(201, 250)}};
  bool pass = true;
  for (std::size_t m = 0; m < 2; ++m) {
    const std::size_t tris = meshes[m].mesh.triangles.size();
    const auto t0 = std::chrono::steady_clock::now();
    const sim::Scene scene(std::move(meshes[m].mesh));
    std::printf("%s: %zu triangles, BVH %zu nodes built in %.1f ms\n", meshes[m].name, tris,
                scene.bvh().node_count(), seconds_since(t0) * 1e3);
    for (const auto& [name, cfg] : {std::pair{"point sensor, serpentine", point},
                                    std::pair{"line profiler, serpentine", line}}) {
      run_case(scene, name, cfg, 1);
      const Result all = run_case(scene, name, cfg, 0);
      if (m == 0) {
        pass = pass && all.wall_rate >= 5e6;
        double mb = 0;
        const double rate = stream_rate(scene, cfg, mb);
        std::printf("  %-26s %-9s writing the stream too: %5.2f M samples/s (%.1f MB)\n", name,
                    "all cores", rate / 1e6, mb);
      }
    }
  }
  std::printf("target: >= 5 M samples/s on a 100k-triangle mesh (geodesic, all cores): %s\n",
              pass ? "PASS" : "MISS");
  return 0;
}
