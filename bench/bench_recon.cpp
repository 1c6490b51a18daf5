// Reconstruction benchmark: times each pipeline stage on real scans and a 2M-point synthetic scan,
// measures the heap peak, and prints a table, the targets (PASS/MISS) and optionally JSON lines.
// SPDX-License-Identifier: MIT
#include <malloc.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <limits>
#include <new>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/fill.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "support/data.hpp"

#ifndef SCANMESH_BENCH_BUILD_TYPE
#define SCANMESH_BENCH_BUILD_TYPE "unknown"
#endif

// ---------------------------------------------------------------------------------------------
// Heap accounting. A benchmark program may replace the global allocation functions (library code
// never does). Sizes are taken from malloc_usable_size, so unsized deletes are exact and the
// figure is what the allocator really hands out. Eigen's own aligned_malloc (dynamic-size
// matrices) goes to malloc directly and is not seen; recon only uses small, short-lived ones.
namespace {

std::atomic<std::int64_t> g_heap_current{0};
std::atomic<std::int64_t> g_heap_peak{0};
std::atomic<std::int64_t> g_heap_allocs{0};

void note_alloc(void* p) {
  const auto size = static_cast<std::int64_t>(malloc_usable_size(p));
  const std::int64_t now = g_heap_current.fetch_add(size, std::memory_order_relaxed) + size;
  g_heap_allocs.fetch_add(1, std::memory_order_relaxed);
  std::int64_t peak = g_heap_peak.load(std::memory_order_relaxed);
  while (now > peak && !g_heap_peak.compare_exchange_weak(peak, now, std::memory_order_relaxed)) {
  }
}

void note_free(void* p) {
  if (p == nullptr) return;
  g_heap_current.fetch_sub(static_cast<std::int64_t>(malloc_usable_size(p)),
                           std::memory_order_relaxed);
}

void* tracked_alloc(std::size_t n) {
  void* p = std::malloc(n == 0 ? 1 : n);
  if (p != nullptr) note_alloc(p);
  return p;
}

void* tracked_aligned_alloc(std::size_t n, std::align_val_t al) {
  const auto a = std::max(static_cast<std::size_t>(al), sizeof(void*));
  void* p = nullptr;
  if (posix_memalign(&p, a, n == 0 ? 1 : n) != 0) return nullptr;
  note_alloc(p);
  return p;
}

void tracked_free(void* p) noexcept {
  note_free(p);
  std::free(p);
}

/// Heap bytes in use now, and the peak since the last reset.
std::int64_t heap_current() { return g_heap_current.load(std::memory_order_relaxed); }
std::int64_t heap_peak() { return g_heap_peak.load(std::memory_order_relaxed); }
std::int64_t heap_allocs() { return g_heap_allocs.load(std::memory_order_relaxed); }
void heap_reset_peak() { g_heap_peak.store(heap_current(), std::memory_order_relaxed); }

}  // namespace

void* operator new(std::size_t n) {
  if (void* p = tracked_alloc(n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  if (void* p = tracked_alloc(n)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return tracked_alloc(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return tracked_alloc(n); }
void* operator new(std::size_t n, std::align_val_t al) {
  if (void* p = tracked_aligned_alloc(n, al)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t al) {
  if (void* p = tracked_aligned_alloc(n, al)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  return tracked_aligned_alloc(n, al);
}
void* operator new[](std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  return tracked_aligned_alloc(n, al);
}
void operator delete(void* p) noexcept { tracked_free(p); }
void operator delete[](void* p) noexcept { tracked_free(p); }
void operator delete(void* p, std::size_t) noexcept { tracked_free(p); }
void operator delete[](void* p, std::size_t) noexcept { tracked_free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { tracked_free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { tracked_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { tracked_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { tracked_free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { tracked_free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { tracked_free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { tracked_free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  tracked_free(p);
}

// ---------------------------------------------------------------------------------------------
namespace {

namespace recon = scanmesh::recon;
namespace meshio = scanmesh::meshio;
using Clock = std::chrono::steady_clock;
using recon::Vec3;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double seconds_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

/// One measured repetition of a case (or the best over repetitions).
struct Figures {
  std::size_t input_points = 0, reduced_points = 0, triangles = 0;
  std::size_t edge_evaluations = 0, points_scanned = 0, skipped_evaluations = 0;
  std::size_t bulk_patches = 0, bulk_triangles = 0;
  double cube_mm = 0;
  // Seconds. read is NaN for generated inputs (gen holds the generation time instead).
  double read_s = kNaN, gen_s = kNaN, reduce_s = kNaN, normals_s = kNaN, front_s = kNaN,
         refine_s = kNaN, output_s = kNaN, gaps_s = kNaN, total_s = kNaN;
  /// The front's steps as the observer names them (without "front/"), in order, seconds each.
  struct Step {
    char name[24];  // cut to fit
    double seconds;
  };
  std::vector<Step> front_steps;
  std::size_t closed_gaps = 0;  ///< sampling gaps closed by the reconstruction (stage "gaps")
  std::size_t inserted = 0, slivers = 0, sliver_flips = 0;
  // Hole filling on request (after the measured reconstruction, on its mesh): every loop of at
  // most FillOptions::kLimit edges.
  double fill_s = kNaN;
  // Self-intersection check of the output (before filling): pairs found and its time.
  std::size_t crossing_pairs = 0;
  double crossing_s = kNaN;
  std::size_t loops = 0, filled = 0, faired = 0, fill_vertices = 0;
  std::int64_t peak_case_bytes = 0;   ///< heap peak over the case (load + reconstruct) - baseline
  std::int64_t peak_recon_bytes = 0;  ///< heap peak inside reconstruct() - heap at its start
  std::int64_t recon_allocs = 0;      ///< allocations made inside reconstruct()
};

/// How a case gets its points.
struct Loaded {
  std::vector<Vec3> points;
  bool generated = false;
};

struct Case {
  std::string name;
  std::string description;
  recon::ReconstructOptions::CubeMode cube = recon::ReconstructOptions::CubeMode::kAuto;
  /// Returns nullopt when the data is not available (SCANMESH_DATA unset).
  std::optional<Loaded> (*load)() = nullptr;
};

std::optional<Loaded> load_xyz(const std::string& rel) {
  const auto file = scanmesh::test::shared_file(rel);
  if (!file) return std::nullopt;
  Loaded l;
  l.points = meshio::read_points(*file).points;
  return l;
}

std::optional<Loaded> load_bunny() {
  return load_xyz("bunny/reconstruction/bun_zipper_vertices.xyz");
}

std::optional<Loaded> load_bunny_merged() {
  const auto conf = scanmesh::test::shared_file("bunny/data/bun.conf");
  if (!conf) return std::nullopt;
  Loaded l;
  for (const meshio::ConfEntry& e : meshio::read_conf(*conf)) {
    const recon::PointCloud c = meshio::read_points(e.file);
    l.points.reserve(l.points.size() + c.points.size());
    for (const Vec3& p : c.points) l.points.push_back(e.to_world(p));
  }
  return l;
}

/// --no-bulk: every case meshed by the front alone (FrontOptions::bulk off), for A/B runs.
bool g_no_bulk = false;

std::optional<Loaded> load_igea() { return load_xyz("igea/igea_vertices.xyz"); }

/// A gently curved height field z = f(x, y) (a few long-wavelength sines, smallest radius of
/// curvature about 250 mm) over a 1415 mm square, sampled on a 1 mm grid jittered by up to
/// +-0.3 mm in x and y, with Gaussian noise of 0.02 mm in z. Seeded: the same cloud every run.
constexpr int kSynthSide = 1415;  // 1415^2 = 2,002,225 points
std::optional<Loaded> load_synthetic() {
  Loaded l;
  l.generated = true;
  l.points.reserve(static_cast<std::size_t>(kSynthSide) * kSynthSide);
  std::mt19937_64 rng(0x5CA7'4E5Bu);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  std::normal_distribution<double> noise(0.0, 0.02);
  constexpr double kTwoPi = 2 * std::numbers::pi;
  for (int j = 0; j < kSynthSide; ++j)
    for (int i = 0; i < kSynthSide; ++i) {
      const double x = i + jitter(rng), y = j + jitter(rng);
      const double z = 25 * std::sin(kTwoPi * x / 500) + 15 * std::sin(kTwoPi * y / 350) +
                       8 * std::sin(kTwoPi * (x + y) / 700);
      l.points.emplace_back(x, y, z + noise(rng));
    }
  return l;
}

std::vector<Case> all_cases() {
  using CM = recon::ReconstructOptions::CubeMode;
  return {
      {"bunny", "bun_zipper_vertices.xyz (Stanford bunny, 35,947 pts)", CM::kAuto, &load_bunny},
      {"bunny-merged", "bun.conf: 10 registered raw scans merged", CM::kAuto, &load_bunny_merged},
      {"igea", "igea_vertices.xyz (134,345 pts)", CM::kAuto, &load_igea},
      {"synthetic-2m", "generated height field, 1415^2 jittered grid, seeded noise", CM::kNone,
       &load_synthetic},
  };
}

const char* cube_name(recon::ReconstructOptions::CubeMode m) {
  switch (m) {
    case recon::ReconstructOptions::CubeMode::kAuto:
      return "auto";
    case recon::ReconstructOptions::CubeMode::kFixed:
      return "fixed";
    case recon::ReconstructOptions::CubeMode::kNone:
      return "none";
  }
  return "?";
}

/// Runs one repetition: load (timed), reconstruct with stage timestamps, heap figures.
Figures run_once(const Case& c, bool& available) {
  Figures f;
  const std::int64_t base = heap_current();
  heap_reset_peak();
  const auto t_load0 = Clock::now();
  std::optional<Loaded> loaded = c.load();
  const auto t_load1 = Clock::now();
  if (!loaded) {
    available = false;
    return f;
  }
  available = true;
  if (loaded->generated)
    f.gen_s = seconds_between(t_load0, t_load1);
  else
    f.read_s = seconds_between(t_load0, t_load1);
  const std::int64_t peak_load = heap_peak();

  recon::ReconstructOptions opt;
  opt.cube_mode = c.cube;
  opt.front.bulk = !g_no_bulk;
  // Stage start times, filled by the observer; index by position in kStages.
  static constexpr std::string_view kStages[] = {"reduce", "normals", "front", "refine",
                                                  "output", "gaps",    "done"};
  Clock::time_point marks[std::size(kStages)];
  bool seen[std::size(kStages)] = {};
  // The front's steps: each runs until the next call of the observer.
  bool in_step = false;
  Clock::time_point step_start;
  f.front_steps.reserve(16);  // no allocation inside the measured call
  const recon::StageObserver observer = [&](std::string_view stage) {
    const auto now = Clock::now();
    if (in_step) f.front_steps.back().seconds = seconds_between(step_start, now);
    in_step = stage.starts_with("front/");
    if (in_step) {
      Figures::Step& s = f.front_steps.emplace_back(Figures::Step{{}, 0.0});
      stage.substr(6).copy(s.name, sizeof s.name - 1);
      step_start = now;
      return;
    }
    for (std::size_t i = 0; i < std::size(kStages); ++i)
      if (stage == kStages[i]) {
        marks[i] = now;
        seen[i] = true;
      }
  };

  const std::int64_t recon_base = heap_current();
  heap_reset_peak();
  const std::int64_t allocs0 = heap_allocs();
  const auto t0 = Clock::now();
  std::optional<recon::ReconstructResult> res;
  res.emplace(recon::reconstruct(loaded->points, opt, observer));
  const auto t1 = Clock::now();
  const std::int64_t peak_recon = heap_peak();
  f.recon_allocs = heap_allocs() - allocs0;

  f.total_s = seconds_between(t0, t1);
  auto span = [&](std::size_t a, std::size_t b) {
    return seen[a] && seen[b] ? seconds_between(marks[a], marks[b]) : kNaN;
  };
  f.reduce_s = span(0, 1);
  f.normals_s = span(1, 2);
  f.front_s = span(2, 3);
  f.refine_s = span(3, 4);
  // "gaps" runs only when the front left a sampling gap
  f.output_s = seen[5] ? span(4, 5) : span(4, 6);
  f.gaps_s = seen[5] ? span(5, 6) : 0.0;
  f.closed_gaps = res->gaps.filled;
  f.inserted = res->refine.inserted;
  f.slivers = res->refine.slivers;
  f.sliver_flips = res->refine.sliver_flips;
  f.input_points = res->input_points;
  f.reduced_points = res->reduced_points;
  f.triangles = res->mesh.triangles.size();
  f.edge_evaluations = res->edge_evaluations;
  f.points_scanned = res->points_scanned;
  f.skipped_evaluations = res->skipped_evaluations;
  f.bulk_patches = res->bulk_patches;
  f.bulk_triangles = res->bulk_triangles;
  f.cube_mm = res->cube_mm;
  f.peak_case_bytes = std::max(peak_load, peak_recon) - base;
  f.peak_recon_bytes = peak_recon - recon_base;

  // Quality and its cost: triangle pairs of the output that cross (CAD rejects them).
  const auto t_check = Clock::now();
  f.crossing_pairs = recon::find_self_intersections(res->mesh).pairs;
  f.crossing_s = seconds_between(t_check, Clock::now());

  recon::FillOptions fill;
  fill.max_edges = recon::FillOptions::kLimit;
  const auto t2 = Clock::now();
  const recon::FillStats filled = recon::fill_holes(res->mesh, fill);
  f.fill_s = seconds_between(t2, Clock::now());
  f.loops = filled.filled + filled.kept;
  f.filled = filled.filled;
  f.faired = filled.faired;
  f.fill_vertices = filled.vertices;
  return f;
}

double min_nan(double a, double b) {
  if (std::isnan(a)) return b;
  if (std::isnan(b)) return a;
  return std::min(a, b);
}

/// Best time per column (each column independently) and the largest heap figures.
void keep_best(Figures& best, const Figures& f, bool first) {
  if (first) {
    best = f;
    return;
  }
  best.read_s = min_nan(best.read_s, f.read_s);
  best.gen_s = min_nan(best.gen_s, f.gen_s);
  best.reduce_s = min_nan(best.reduce_s, f.reduce_s);
  best.normals_s = min_nan(best.normals_s, f.normals_s);
  // The steps of the fastest front, so that they add up to its time.
  if (f.front_s < best.front_s)
    best.front_steps = f.front_steps;
  best.front_s = min_nan(best.front_s, f.front_s);
  best.refine_s = min_nan(best.refine_s, f.refine_s);
  best.output_s = min_nan(best.output_s, f.output_s);
  best.total_s = min_nan(best.total_s, f.total_s);
  best.fill_s = min_nan(best.fill_s, f.fill_s);
  best.crossing_s = min_nan(best.crossing_s, f.crossing_s);
  best.peak_case_bytes = std::max(best.peak_case_bytes, f.peak_case_bytes);
  best.peak_recon_bytes = std::max(best.peak_recon_bytes, f.peak_recon_bytes);
}

std::int64_t max_rss_bytes() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<std::int64_t>(ru.ru_maxrss) * 1024;  // Linux reports kilobytes
}

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      if (colon != std::string::npos) {
        auto start = line.find_first_not_of(" \t", colon + 1);
        return start == std::string::npos ? "" : line.substr(start);
      }
    }
  return "unknown";
}

std::string fmt_ms(double s) {
  if (std::isnan(s)) return "-";
  char buf[32];
  const double ms = s * 1e3;
  std::snprintf(buf, sizeof buf, ms < 10 ? "%.2f" : ms < 1000 ? "%.1f" : "%.0f", ms);
  return buf;
}

/// Points per second with an SI suffix ("1.23M").
std::string fmt_rate(double points, double s) {
  if (std::isnan(s) || !(s > 0)) return "-";
  const double r = points / s;
  char buf[32];
  if (r >= 1e9)
    std::snprintf(buf, sizeof buf, "%.2fG", r / 1e9);
  else if (r >= 1e6)
    std::snprintf(buf, sizeof buf, "%.2fM", r / 1e6);
  else if (r >= 1e3)
    std::snprintf(buf, sizeof buf, "%.1fk", r / 1e3);
  else
    std::snprintf(buf, sizeof buf, "%.0f", r);
  return buf;
}

double per_point(std::int64_t bytes, std::size_t points) {
  return points == 0 ? kNaN : static_cast<double>(bytes) / static_cast<double>(points);
}

std::string json_num(double v) {
  if (std::isnan(v) || std::isinf(v)) return "null";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::string json_ms(double s) { return json_num(s * 1e3); }
std::string json_rate(double points, double s) {
  return std::isnan(s) || !(s > 0) ? "null" : json_num(points / s);
}

struct Outcome {
  const Case* c = nullptr;
  enum class Status { kRan, kSkipped, kFailed } status = Status::kSkipped;
  std::string message;
  Figures best;
  std::int64_t max_rss = 0;
};

void print_header() {
  std::printf("%-13s %9s %9s | %9s %7s | %9s %7s | %9s %7s | %9s %7s | %9s %7s | %7s %7s | %8s\n",
              "case", "input", "reduced", "read ms", "pt/s", "reduce ms", "pt/s", "normals ms",
              "pt/s", "front ms", "pt/s", "total ms", "pt/s", "heap", "recon", "maxRSS");
  std::printf("%-13s %9s %9s | %9s %7s | %9s %7s | %9s %7s | %9s %7s | %9s %7s | %7s %7s | %8s\n",
              "", "points", "points", "", "(in)", "", "(in)", "", "(red)", "", "(red)", "", "(in)",
              "B/red", "B/red", "MiB");
}

void print_row(const Outcome& o) {
  const Figures& f = o.best;
  const auto in = static_cast<double>(f.input_points);
  const auto red = static_cast<double>(f.reduced_points);
  std::printf(
      "%-13s %9zu %9zu | %9s %7s | %9s %7s | %9s %7s | %9s %7s | %9s %7s | %7.1f %7.1f | %8.1f\n",
      o.c->name.c_str(), f.input_points, f.reduced_points, fmt_ms(f.read_s).c_str(),
      fmt_rate(in, f.read_s).c_str(), fmt_ms(f.reduce_s).c_str(), fmt_rate(in, f.reduce_s).c_str(),
      fmt_ms(f.normals_s).c_str(), fmt_rate(red, f.normals_s).c_str(), fmt_ms(f.front_s).c_str(),
      fmt_rate(red, f.front_s).c_str(), fmt_ms(f.total_s).c_str(), fmt_rate(in, f.total_s).c_str(),
      per_point(f.peak_case_bytes, f.reduced_points),
      per_point(f.peak_recon_bytes, f.reduced_points),
      static_cast<double>(o.max_rss) / (1024.0 * 1024.0));
  char cube[48];
  if (f.cube_mm > 0)
    std::snprintf(cube, sizeof cube, "auto -> %.4g", f.cube_mm);
  else
    std::snprintf(cube, sizeof cube, "%s", cube_name(o.c->cube));
  std::printf(
      "%-13s   cube %s; insertion %s ms (%zu points; %zu slivers, %zu flips to mend them); "
      "output %s ms; sampling gaps %zu closed in %s ms; %zu triangles (%.1f %% from %zu bulk "
      "patches); %.1f edge evals (%.1f "
      "skipped: no candidate before) and %.1f points scanned per reduced pt; heap peak %.1f MiB",
      "", cube, fmt_ms(f.refine_s).c_str(), f.inserted, f.slivers, f.sliver_flips,
      fmt_ms(f.output_s).c_str(), f.closed_gaps, fmt_ms(f.gaps_s).c_str(), f.triangles,
      f.triangles > 0 ? 100.0 * static_cast<double>(f.bulk_triangles) / static_cast<double>(f.triangles) : kNaN,
      f.bulk_patches,
      red > 0 ? static_cast<double>(f.edge_evaluations) / red : kNaN,
      red > 0 ? static_cast<double>(f.skipped_evaluations) / red : kNaN,
      red > 0 ? static_cast<double>(f.points_scanned) / red : kNaN,
      static_cast<double>(f.peak_case_bytes) / (1024.0 * 1024.0));
  if (!std::isnan(f.gen_s)) std::printf("; generated (not read) in %s ms", fmt_ms(f.gen_s).c_str());
  std::printf("\n%-13s   front steps, ms:", "");
  for (std::size_t i = 0; i < f.front_steps.size(); ++i)
    std::printf("%s %s %s", i == 0 ? "" : ",", f.front_steps[i].name,
                fmt_ms(f.front_steps[i].seconds).c_str());
  std::printf("\n%-13s   hole filling on request (loops up to %zu edges, after the above): %s ms, "
              "%zu of %zu loops closed (%zu faired), %zu new vertices\n",
              "", recon::FillOptions::kLimit, fmt_ms(f.fill_s).c_str(), f.filled, f.loops,
              f.faired, f.fill_vertices);
  std::printf("%-13s   self-intersection check of the output: %zu crossing triangle pairs, %s ms\n",
              "", f.crossing_pairs, fmt_ms(f.crossing_s).c_str());
}

std::string json_line(const Outcome& o, int repeat) {
  const Figures& f = o.best;
  const auto in = static_cast<double>(f.input_points);
  const auto red = static_cast<double>(f.reduced_points);
  std::string s = "{\"case\":\"" + o.c->name + "\"";
  if (o.status == Outcome::Status::kSkipped) return s + ",\"status\":\"skipped\"}";
  if (o.status == Outcome::Status::kFailed) {
    std::string msg;
    for (char ch : o.message) {
      if (ch == '"' || ch == '\\') msg += '\\';
      if (static_cast<unsigned char>(ch) >= 0x20) msg += ch;
    }
    return s + ",\"status\":\"failed\",\"error\":\"" + msg + "\"}";
  }
  s += ",\"status\":\"ran\",\"repeat\":" + std::to_string(repeat);
  s += ",\"cube\":\"" + std::string(cube_name(o.c->cube)) + "\",\"cube_mm\":" + json_num(f.cube_mm);
  s += ",\"input_points\":" + std::to_string(f.input_points);
  s += ",\"reduced_points\":" + std::to_string(f.reduced_points);
  s += ",\"triangles\":" + std::to_string(f.triangles);
  s += ",\"read_ms\":" + json_ms(f.read_s) + ",\"read_pts_per_s\":" + json_rate(in, f.read_s);
  s += ",\"generate_ms\":" + json_ms(f.gen_s);
  s += ",\"reduce_ms\":" + json_ms(f.reduce_s) +
       ",\"reduce_pts_per_s\":" + json_rate(in, f.reduce_s);
  s += ",\"normals_ms\":" + json_ms(f.normals_s) +
       ",\"normals_pts_per_s\":" + json_rate(red, f.normals_s);
  s += ",\"front_ms\":" + json_ms(f.front_s) + ",\"front_pts_per_s\":" + json_rate(red, f.front_s);
  s += ",\"front_steps_ms\":{";
  for (std::size_t i = 0; i < f.front_steps.size(); ++i)
    s += (i == 0 ? "\"" : ",\"") + std::string(f.front_steps[i].name) + "\":" +
         json_ms(f.front_steps[i].seconds);
  s += "}";
  s += ",\"insertion_ms\":" + json_ms(f.refine_s) + ",\"inserted_points\":" + std::to_string(f.inserted);
  s += ",\"output_ms\":" + json_ms(f.output_s);
  s += ",\"gaps_ms\":" + json_ms(f.gaps_s) + ",\"closed_gaps\":" + std::to_string(f.closed_gaps);
  s += ",\"fill_ms\":" + json_ms(f.fill_s) + ",\"filled_holes\":" + std::to_string(f.filled) +
       ",\"fill_vertices\":" + std::to_string(f.fill_vertices);
  s += ",\"crossing_pairs\":" + std::to_string(f.crossing_pairs) +
       ",\"crossing_check_ms\":" + json_ms(f.crossing_s);
  s += ",\"total_ms\":" + json_ms(f.total_s) + ",\"total_pts_per_s\":" + json_rate(in, f.total_s);
  s += ",\"peak_heap_bytes\":" + std::to_string(f.peak_case_bytes);
  s += ",\"peak_heap_bytes_per_reduced_point\":" +
       json_num(per_point(f.peak_case_bytes, f.reduced_points));
  s += ",\"recon_peak_heap_bytes\":" + std::to_string(f.peak_recon_bytes);
  s += ",\"recon_allocations\":" + std::to_string(f.recon_allocs);
  s += ",\"edge_evaluations\":" + std::to_string(f.edge_evaluations);
  s += ",\"points_scanned\":" + std::to_string(f.points_scanned);
  s += ",\"skipped_evaluations\":" + std::to_string(f.skipped_evaluations);
  s += ",\"bulk_patches\":" + std::to_string(f.bulk_patches);
  s += ",\"bulk_triangles\":" + std::to_string(f.bulk_triangles);
  s += ",\"max_rss_bytes\":" + std::to_string(o.max_rss) + "}";
  return s;
}

void usage(const char* argv0) {
  std::printf(
      "usage: %s [--case NAME]... [--repeat N] [--json] [--no-bulk]\n"
      "  --case NAME   run only this case (repeatable): bunny, bunny-merged, igea, synthetic-2m\n"
      "  --repeat N    repetitions per case, best time reported (default 3)\n"
      "  --json        also print the results as JSON lines\n"
      "  --no-bulk     the front alone, without the planar Delaunay patches (for comparison)\n"
      "Real scans are read from $SCANMESH_DATA; without it those cases are skipped.\n",
      argv0);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> selected;
  int repeat = 3;
  bool json = false;
  const std::vector<Case> cases = all_cases();
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "--help" || a == "-h") {
      usage(argv[0]);
      return 0;
    } else if (a == "--json") {
      json = true;
    } else if (a == "--no-bulk") {
      g_no_bulk = true;
    } else if ((a == "--case" || a == "--repeat") && i + 1 < argc) {
      const std::string v = argv[++i];
      if (a == "--case") {
        const bool known =
            std::any_of(cases.begin(), cases.end(), [&](const Case& c) { return c.name == v; });
        if (!known) {
          std::fprintf(stderr, "unknown case '%s'\n", v.c_str());
          usage(argv[0]);
          return 2;
        }
        selected.push_back(v);
      } else {
        char* end = nullptr;
        const long n = std::strtol(v.c_str(), &end, 10);
        if (end == v.c_str() || *end != '\0' || n < 1 || n > 1000) {
          std::fprintf(stderr, "--repeat must be an integer in [1, 1000], got '%s'\n", v.c_str());
          return 2;
        }
        repeat = static_cast<int>(n);
      }
    } else {
      std::fprintf(stderr, "unknown or incomplete argument '%s'\n", argv[i]);
      usage(argv[0]);
      return 2;
    }
  }

  const long nproc = sysconf(_SC_NPROCESSORS_ONLN);
  const char* data = std::getenv("SCANMESH_DATA");
#ifdef NDEBUG
  const char* asserts = "off";
#else
  const char* asserts = "ON";
#endif
  std::printf("bench_recon: machine: nproc %ld, CPU '%s'; build type %s (assertions %s), %s\n",
              nproc, cpu_model().c_str(), SCANMESH_BENCH_BUILD_TYPE, asserts, __VERSION__);
  std::printf("SCANMESH_DATA=%s; best of %d run(s) per column; reconstruction is single-threaded\n",
              data != nullptr && *data != '\0' ? data : "(unset)", repeat);
  std::printf(
      "total = the reconstruct() call (input check, reduce, normals, front, output); "
      "read not included.\nThroughput: read/reduce/total per input point, normals/front "
      "per reduced point.\nheap = heap peak over the case (input + reconstruct) per reduced "
      "point; recon = peak inside reconstruct() above its start; maxRSS = process max so "
      "far.\n\n");
  print_header();
  std::fflush(stdout);

  std::vector<Outcome> outcomes;
  bool any_failed = false;
  for (const Case& c : cases) {
    if (!selected.empty() && std::find(selected.begin(), selected.end(), c.name) == selected.end())
      continue;
    Outcome o;
    o.c = &c;
    try {
      for (int r = 0; r < repeat; ++r) {
        bool available = false;
        const Figures f = run_once(c, available);
        if (!available) {
          o.status = Outcome::Status::kSkipped;
          o.message = "SCANMESH_DATA is unset: real-data case skipped";
          break;
        }
        o.status = Outcome::Status::kRan;
        keep_best(o.best, f, r == 0);
      }
    } catch (const std::exception& e) {
      o.status = Outcome::Status::kFailed;
      o.message = e.what();
      any_failed = true;
    }
    o.max_rss = max_rss_bytes();
    if (o.status == Outcome::Status::kRan)
      print_row(o);
    else
      std::printf("%-13s %s: %s\n", c.name.c_str(),
                  o.status == Outcome::Status::kSkipped ? "SKIPPED" : "FAILED", o.message.c_str());
    std::fflush(stdout);
    outcomes.push_back(std::move(o));
  }

  // Targets.
  auto find = [&](std::string_view name) -> const Outcome* {
    for (const Outcome& o : outcomes)
      if (o.c->name == name && o.status == Outcome::Status::kRan) return &o;
    return nullptr;
  };
  std::printf("\nTargets:\n");
  auto target = [&](const char* what, const Outcome* o, double value, double limit, bool below,
                    const char* unit) {
    if (o == nullptr || std::isnan(value)) {
      std::printf("  %-58s NOT RUN\n", what);
      return;
    }
    const bool pass = below ? value < limit : value >= limit;
    std::printf("  %-58s %s  (measured %.4g %s)\n", what, pass ? "PASS" : "MISS", value, unit);
  };
  const Outcome* bunny = find("bunny");
  const Outcome* merged = find("bunny-merged");
  const Outcome* synth = find("synthetic-2m");
  target("bunny: whole reconstruct < 60 ms", bunny, bunny ? bunny->best.total_s * 1e3 : kNaN, 60,
         true, "ms");
  target("bunny-merged: whole reconstruct < 1 s", merged,
         merged ? merged->best.total_s * 1e3 : kNaN, 1000, true, "ms");
  target("synthetic-2m: front >= 1,000,000 reduced pts/s (cube none)", synth,
         synth && synth->best.front_s > 0
             ? static_cast<double>(synth->best.reduced_points) / synth->best.front_s
             : kNaN,
         1e6, false, "pts/s");
  target("synthetic-2m: heap peak < 200 B per reduced point", synth,
         synth ? per_point(synth->best.peak_case_bytes, synth->best.reduced_points) : kNaN, 200,
         true, "B/pt");

  if (json) {
    std::printf("\n");
    std::printf(
        "{\"machine\":{\"nproc\":%ld,\"cpu\":\"%s\",\"build_type\":\"%s\"},\"repeat\":%d}\n", nproc,
        cpu_model().c_str(), SCANMESH_BENCH_BUILD_TYPE, repeat);
    for (const Outcome& o : outcomes) std::printf("%s\n", json_line(o, repeat).c_str());
  }
  return any_failed ? 1 : 0;
}
