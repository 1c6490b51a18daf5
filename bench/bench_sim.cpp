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

#include "scanmesh/sim/simulator.hpp"
#include "scanmesh/sim/stream.hpp"

#ifndef SCANMESH_BENCH_BUILD_TYPE
#define SCANMESH_BENCH_BUILD_TYPE "unknown"
#endif

namespace {

using namespace scanmesh;
using recon::Vec3;

/// A closed geodesic sphere of radius about 30 mm with bumps: every icosahedron face split into
/// f x f triangles (20 f^2 in all), well shaped everywhere.
recon::Mesh geodesic_sphere(int f) {
  const double g = (1 + std::sqrt(5.0)) / 2;
  const Vec3 ico[12] = {Vec3(-1, g, 0), Vec3(1, g, 0), Vec3(-1, -g, 0), Vec3(1, -g, 0),
                        Vec3(0, -1, g), Vec3(0, 1, g), Vec3(0, -1, -g), Vec3(0, 1, -g),
                        Vec3(g, 0, -1), Vec3(g, 0, 1), Vec3(-g, 0, -1), Vec3(-g, 0, 1)};
  const int faces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                            {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                            {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                            {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  recon::Mesh m;
  std::map<std::array<long long, 3>, std::uint32_t> index;  // weld shared face borders
  auto vertex = [&](const Vec3& p) {
    const Vec3 u = p.normalized();
    const std::array<long long, 3> key{std::llround(u.x() * 1e9), std::llround(u.y() * 1e9),
                                       std::llround(u.z() * 1e9)};
    const auto it = index.find(key);
    if (it != index.end()) return it->second;
    const double theta = std::acos(u.z()), phi = std::atan2(u.y(), u.x());
    const double r = 30.0 + 1.5 * std::sin(7 * theta) * std::sin(5 * phi);
    m.vertices.push_back(u * r + Vec3(0, 0, 32));
    return index[key] = static_cast<std::uint32_t>(m.vertices.size() - 1);
  };
  for (const auto& fc : faces) {
    const Vec3 a = ico[fc[0]], b = ico[fc[1]], c = ico[fc[2]];
    auto at = [&](int i, int j) {
      return a + (b - a) * (double(i) / f) + (c - a) * (double(j) / f);
    };
    for (int i = 0; i < f; ++i)
      for (int j = 0; j < f - i; ++j) {
        m.triangles.push_back({vertex(at(i, j)), vertex(at(i + 1, j)), vertex(at(i, j + 1))});
        if (i + j + 1 < f)
          m.triangles.push_back(
              {vertex(at(i + 1, j)), vertex(at(i + 1, j + 1)), vertex(at(i, j + 1))});
      }
  }
  return m;
}

/// A closed UV sphere of radius about 30 mm with bumps, 2 * lon * (lat - 1) triangles: long thin
/// triangles in fans of `lon` at the poles (a hard case for any BVH).
recon::Mesh bumpy_sphere(int lat, int lon) {
  recon::Mesh m;
  auto radius = [](double theta, double phi) {
    return 30.0 + 1.5 * std::sin(7 * theta) * std::sin(5 * phi);
  };
  auto point = [&](double theta, double phi) {
    const double r = radius(theta, phi);
    return Vec3(r * std::sin(theta) * std::cos(phi), r * std::sin(theta) * std::sin(phi),
                r * std::cos(theta) + 32);
  };
  m.vertices.push_back(point(0, 0));  // north pole
  for (int i = 1; i < lat; ++i)
    for (int j = 0; j < lon; ++j)
      m.vertices.push_back(point(std::numbers::pi * i / lat, 2 * std::numbers::pi * j / lon));
  m.vertices.push_back(point(std::numbers::pi, 0));  // south pole
  const auto south = static_cast<std::uint32_t>(m.vertices.size() - 1);
  auto ring = [&](int i, int j) {
    return static_cast<std::uint32_t>(1 + (i - 1) * lon + ((j % lon) + lon) % lon);
  };
  for (int j = 0; j < lon; ++j) m.triangles.push_back({0, ring(1, j), ring(1, j + 1)});
  for (int i = 1; i < lat - 1; ++i)
    for (int j = 0; j < lon; ++j) {
      m.triangles.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      m.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  for (int j = 0; j < lon; ++j)
    m.triangles.push_back({south, ring(lat - 1, j + 1), ring(lat - 1, j)});
  return m;
}

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
  MeshCase meshes[] = {{"geodesic bumpy sphere", geodesic_sphere(71)},
                       {"UV bumpy sphere (pole fans)", bumpy_sphere(201, 250)}};
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
