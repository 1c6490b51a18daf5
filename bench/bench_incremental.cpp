// bench_incremental: the incremental reconstruction fed simulated serpentine raster scans, one
// scan line a batch (noise on), of 100k, 1M and 10M raw points, on one thread; prints a table
// of throughput, latency, snapshot and delta costs and heap per kept point (issue 57's figures),
// and the ten merged bunny scans streamed in scan order when SCANMESH_DATA is set.
// Usage: bench_incremental [SIZE...]   (raw point counts; default 100000 1000000 10000000)
// SPDX-License-Identifier: MIT
#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <random>
#include <string>
#include <vector>

#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/incremental.hpp"
#include "support/data.hpp"

namespace {

using scanmesh::recon::Vec3;
namespace recon = scanmesh::recon;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

/// This thread's CPU time: the machine is shared, wall times include other processes' turns.
double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

std::size_t heap_in_use() { return mallinfo2().uordblks + mallinfo2().hblkhd; }

/// One serpentine scan line of a bumpy surface: `per_line` samples 0.03 apart along x, lines
/// 0.3 apart along y (about 10 raw points a cube), Gaussian range noise 0.005 (seeded).
void scan_line(std::size_t line, std::size_t per_line, std::mt19937& rng, std::vector<Vec3>& out) {
  std::normal_distribution<double> noise(0.0, 0.005);
  out.clear();
  const double y = 0.3 * static_cast<double>(line);
  for (std::size_t i = 0; i < per_line; ++i) {
    const std::size_t k = line % 2 == 0 ? i : per_line - 1 - i;
    const double x = 0.03 * static_cast<double>(k);
    const double z = 2.0 * std::sin(0.11 * x) * std::cos(0.07 * y) + 0.5 * std::sin(0.9 * x + 0.3 * y);
    out.emplace_back(x, y, z + noise(rng));
  }
}

struct Row {
  std::string name;
  std::size_t raw = 0, kept = 0, triangles = 0;
  double seconds = 0, max_batch = 0, p99_settle = 0, snapshot_ms = 0, delta_ms_per_10k = 0;
  double max_batch_cpu = 0, delta_cpu_ms_per_10k = 0;
  double heap_per_kept = 0, heap_final_per_kept = 0, finish = 0;
  double cpu_seconds = 0;  // this process's CPU time (the machine is shared: wall time varies)
};

/// Feeds `lines` of `per_line` points and measures; `consume` takes a delta after every batch.
template <class Source>
Row run(const std::string& name, const recon::IncrementalOptions& options, std::size_t batches,
        Source&& next_batch) {
  Row row;
  row.name = name;
  const std::size_t heap0 = heap_in_use();
  const std::clock_t cpu0 = std::clock();
  const auto start = Clock::now();
  recon::IncrementalReconstructor rec(options, [start] { return seconds_since(start); });
  std::vector<Vec3> pts, dirs;
  double delta_seconds = 0, delta_cpu = 0;
  std::size_t delta_triangles = 0;
  for (std::size_t b = 0; b < batches; ++b) {
    next_batch(b, pts, dirs);
    const auto t = Clock::now();
    const double c = thread_cpu_seconds();
    if (dirs.empty()) {
      rec.add(pts);
    } else {
      rec.add(pts, dirs, recon::SensorData::kDirection);
    }
    row.max_batch_cpu = std::max(row.max_batch_cpu, thread_cpu_seconds() - c);
    row.max_batch = std::max(row.max_batch, seconds_since(t));
    row.raw += pts.size();
    const auto d0 = Clock::now();
    const double dc = thread_cpu_seconds();
    const recon::MeshDelta d = rec.take_delta();
    delta_cpu += thread_cpu_seconds() - dc;
    delta_seconds += seconds_since(d0);
    delta_triangles += d.added.size();
  }
  // The reconstructor's own heap while the scan runs (everything but the final result).
  const std::size_t heap_streaming = heap_in_use() - std::min(heap_in_use(), heap0);
  const auto f0 = Clock::now();
  const recon::IncrementalResult res = rec.finish();
  row.finish = seconds_since(f0);
  row.seconds = seconds_since(start);
  row.cpu_seconds = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
  const std::size_t heap = heap_in_use() - std::min(heap_in_use(), heap0);
  const auto d0 = Clock::now();
  const double dc = thread_cpu_seconds();
  const recon::MeshDelta last = rec.take_delta();
  delta_cpu += thread_cpu_seconds() - dc;
  delta_seconds += seconds_since(d0);
  delta_triangles += last.added.size();
  const auto s0 = Clock::now();
  constexpr int kSnapshots = 100;
  for (int i = 0; i < kSnapshots; ++i) {
    const recon::MeshSnapshot s = rec.snapshot();
    if (s.triangle_count() == 0) std::abort();
  }
  row.snapshot_ms = 1e3 * seconds_since(s0) / kSnapshots;
  row.kept = res.mesh.vertices.size() + res.outliers.size();
  row.triangles = res.mesh.triangles.size();
  row.p99_settle = res.stats.settle_to_mesh_p99_seconds;
  row.delta_ms_per_10k =
      delta_triangles > 0 ? 1e3 * delta_seconds / (static_cast<double>(delta_triangles) / 1e4) : 0;
  row.delta_cpu_ms_per_10k =
      delta_triangles > 0 ? 1e3 * delta_cpu / (static_cast<double>(delta_triangles) / 1e4) : 0;
  row.heap_per_kept =
      row.kept > 0 ? static_cast<double>(heap_streaming) / static_cast<double>(row.kept) : 0;
  row.heap_final_per_kept = row.kept > 0 ? static_cast<double>(heap) / static_cast<double>(row.kept) : 0;
  return row;
}

void print(const Row& r, double cpu_ns_at_100k) {
  const double ns = 1e9 * r.seconds / static_cast<double>(r.raw);
  const double cpu_ns = 1e9 * r.cpu_seconds / static_cast<double>(r.raw);
  std::printf("%-16s %9zu %8zu %9.0f %9.0f %7.0f %7.0f %6.2f %7.1f %7.1f %7.1f %7.3f %7.3f %7.3f %6.0f %6.0f %6.2f\n",
              r.name.c_str(), r.raw, r.kept, r.raw / r.cpu_seconds, r.kept / r.cpu_seconds, ns, cpu_ns,
              cpu_ns_at_100k > 0 ? cpu_ns / cpu_ns_at_100k : 1.0, 1e3 * r.max_batch,
              1e3 * r.max_batch_cpu, 1e3 * r.p99_settle, r.snapshot_ms, r.delta_ms_per_10k,
              r.delta_cpu_ms_per_10k, r.heap_per_kept, r.heap_final_per_kept, r.finish);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::size_t> sizes;
  // [--blocks-per-step N] [SIZE...]: the option trades the largest batch against the cost per point.
  recon::IncrementalOptions options;
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) == "--blocks-per-step" && i + 1 < argc) {
      options.max_blocks_per_step = std::strtoull(argv[++i], nullptr, 10);
      continue;
    }
    sizes.push_back(std::strtoull(argv[i], nullptr, 10));
  }
  if (sizes.empty()) sizes = {100000, 1000000, 10000000};
  std::printf("bench_incremental (%s build): serpentine raster, 2,000 points a line = one batch, "
              "noise 0.005, one thread\n",
              SCANMESH_BENCH_BUILD_TYPE);
  std::printf("targets: >= 5M raw pts/s; ns/pt at 10M <= 1.25 x at 100k; batch <= 5 ms; settle->delta "
              "p99 < 50 ms; take_delta < 1 ms / 10k triangles; snapshot < 2 ms at 1M triangles; "
              "<= 200 heap bytes / kept point\n");
  std::printf("raw/s, kept/s: per CPU second of this process; ns/raw wall and CPU; x100k: CPU ns against the\n"
              "first size; batch: largest add() wall and CPU (this thread) ms; p99: settle->delta ms (wall);\n"
              "snap: snapshot() ms; dlt/10k: take_delta() ms per 10k added triangles, wall and CPU; B/kept: heap\n"
              "per kept point while streaming (before finish) and after finish with the result held\n");
  std::printf("%-16s %9s %8s %9s %9s %7s %7s %6s %7s %7s %7s %7s %7s %7s %6s %6s %6s\n", "scan", "raw",
              "kept", "raw/s", "kept/s", "ns/raw", "cpu ns", "x100k", "batch", "batch", "p99", "snap",
              "dlt10k", "dlt10k", "B/kept", "B/fin", "fin s");
  std::printf("%-16s %9s %8s %9s %9s %7s %7s %6s %7s %7s %7s %7s %7s %7s %6s %6s %6s\n", "", "", "", "",
              "", "wall", "cpu", "cpu", "wall", "cpu", "wall", "", "wall", "cpu", "", "", "");
  double ns_100k = 0;
  for (const std::size_t n : sizes) {
    constexpr std::size_t kPerLine = 2000;
    const std::size_t lines = std::max<std::size_t>(1, n / kPerLine);
    std::mt19937 rng(57);
    const Row r = run("raster " + std::to_string(n), options, lines,
                      [&](std::size_t b, std::vector<Vec3>& pts, std::vector<Vec3>& dirs) {
                        scan_line(b, kPerLine, rng, pts);
                        dirs.clear();
                      });
    if (ns_100k == 0) ns_100k = 1e9 * r.cpu_seconds / static_cast<double>(r.raw);
    print(r, ns_100k);
  }
  // The ten merged bunny scans, one after another, 4,096 points a batch.
  const auto conf = scanmesh::test::shared_file("bunny/data/bun.conf");
  if (conf) {
    std::vector<Vec3> all, towards;
    for (const auto& e : scanmesh::meshio::read_conf(*conf)) {
      const auto c = scanmesh::meshio::read_points(e.file);
      const Vec3 s = e.to_world(Vec3::UnitZ()) - e.to_world(Vec3::Zero());
      for (const Vec3& p : c.points) {
        all.push_back(e.to_world(p));
        towards.push_back(s);
      }
    }
    constexpr std::size_t kBatch = 4096;
    const Row r = run("bunny 10 scans", options, (all.size() + kBatch - 1) / kBatch,
                      [&](std::size_t b, std::vector<Vec3>& pts, std::vector<Vec3>& dirs) {
                        const std::size_t i = b * kBatch, m = std::min(kBatch, all.size() - i);
                        pts.assign(all.begin() + static_cast<std::ptrdiff_t>(i),
                                   all.begin() + static_cast<std::ptrdiff_t>(i + m));
                        dirs.assign(towards.begin() + static_cast<std::ptrdiff_t>(i),
                                    towards.begin() + static_cast<std::ptrdiff_t>(i + m));
                      });
    print(r, 0);
  } else {
    std::printf("(SCANMESH_DATA not set: the merged bunny scans are skipped)\n");
  }
  return 0;
}
