// Tests of the simulated scanner: BVH queries against brute force, sensor accuracy and noise,
// triangulation shadowing, sample density under acceleration limits, determinism, the stream
// format and replay.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <catch2/catch.hpp>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/sim/bvh.hpp"
#include "scanmesh/sim/motion.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/replay.hpp"
#include "scanmesh/sim/rng.hpp"
#include "scanmesh/sim/simulated_sensor.hpp"
#include "scanmesh/sim/simulator.hpp"
#include "scanmesh/sim/stream.hpp"

namespace {

using namespace scanmesh;
using recon::Vec3;
using sim::SampleCause;
using sim::SensorStatus;

/// An axis-aligned closed box (12 triangles, outward).
recon::Mesh box_mesh(const Vec3& lo, const Vec3& hi) {
  recon::Mesh m;
  for (int k = 0; k < 8; ++k)
    m.vertices.emplace_back((k & 1) ? hi.x() : lo.x(), (k & 2) ? hi.y() : lo.y(),
                            (k & 4) ? hi.z() : lo.z());
  m.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                 {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return m;
}

/// Brute-force nearest hit (t, triangle) for checking the BVH.
bool brute_hit(const recon::Mesh& m, const Vec3& o, const Vec3& d, double t_max, double& t_out,
               std::uint32_t& tri_out) {
  bool found = false;
  t_out = t_max;
  for (std::uint32_t i = 0; i < m.triangles.size(); ++i) {
    const auto& t = m.triangles[i];
    const Vec3 a = m.vertices[t[0]], e1 = m.vertices[t[1]] - a, e2 = m.vertices[t[2]] - a;
    const Vec3 p = d.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-300) continue;
    const Vec3 s = o - a;
    const double u = s.dot(p) / det;
    const Vec3 q = s.cross(e1);
    const double v = d.dot(q) / det;
    if (u < 0 || v < 0 || u + v > 1) continue;
    const double tt = e2.dot(q) / det;
    if (tt >= 0 && tt < t_out) {
      t_out = tt;
      tri_out = i;
      found = true;
    }
  }
  return found;
}

double point_triangle_distance(const recon::Mesh& m, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : m.triangles) {
    // Sample-free exact distance via the BVH of a one-triangle mesh would be circular; use
    // the projection and the edges directly.
    const Vec3 a = m.vertices[t[0]], b = m.vertices[t[1]], c = m.vertices[t[2]];
    const Vec3 n = (b - a).cross(c - a).normalized();
    const Vec3 q = p - n * (p - a).dot(n);
    const double w0 = (b - q).cross(c - q).dot(n), w1 = (c - q).cross(a - q).dot(n),
                 w2 = (a - q).cross(b - q).dot(n);
    double d;
    if (w0 >= 0 && w1 >= 0 && w2 >= 0) {
      d = std::abs((p - a).dot(n));
    } else {
      auto seg = [&](const Vec3& x, const Vec3& y) {
        const double s = std::clamp((p - x).dot(y - x) / (y - x).squaredNorm(), 0.0, 1.0);
        return (p - (x + (y - x) * s)).norm();
      };
      d = std::min({seg(a, b), seg(b, c), seg(c, a)});
    }
    best = std::min(best, d);
  }
  return best;
}

/// The measured points of a scan with the truth of the sample each came from.
struct Paired {
  std::vector<sim::MeasuredPoint> points;
  std::vector<sim::SampleTruth> truth;
};

Paired pair_points(const sim::Simulator& s, const sim::SimulatedScan& scan) {
  Paired out;
  sim::PointStats st;
  out.points = sim::points_from_samples(s.optics(), s.calibration(), scan.stage, scan.sensor,
                                        scan.probe, &st);
  REQUIRE(st.no_pose == 0);
  std::map<std::pair<std::uint64_t, std::uint32_t>, std::size_t> index;
  for (std::size_t i = 0; i < scan.sensor.size(); ++i)
    index[{scan.sensor[i].seq, scan.sensor[i].index}] = i;
  for (const auto& p : out.points) {
    if (p.probe) {
      out.truth.push_back(scan.probe_truth[p.seq]);
    } else {
      out.truth.push_back(scan.truth[index.at({p.seq, p.index})]);
    }
  }
  return out;
}

sim::SimConfig point_config(sim::PathKind path, double spacing, double line_spacing) {
  sim::SimConfig c;
  c.sensor = sim::default_sensor(sim::SensorKind::kPoint);
  c.sensor.rate_hz = 100;
  c.path.kind = path;
  c.path.spacing_mm = spacing;
  c.path.line_spacing_mm = line_spacing;
  return c;
}

std::string stream_text(const sim::Simulator& s) {
  std::ostringstream out;
  sim::StreamWriter w(out, sim::stream_header(s));
  s.run(w);
  w.finish();
  return out.str();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Random numbers

TEST_CASE("The library's Mersenne Twister is std::mt19937_64", "[sim]") {
  for (const std::uint64_t seed : {0ULL, 1ULL, 5489ULL, 0xFFFFFFFFFFFFFFFFULL}) {
    std::mt19937_64 ref(seed);
    sim::Mt19937_64 ours(seed);
    for (int i = 0; i < 2000; ++i) REQUIRE(ours() == ref());
  }
}

// ---------------------------------------------------------------------------------------------
// BVH

TEST_CASE("BVH nearest hits, shadow rays and closest points match brute force", "[sim]") {
  const recon::Mesh mesh = sim::make_part("container");
  const sim::Bvh bvh(mesh);
  sim::Rng rng(7);
  int hits = 0;
  for (int i = 0; i < 300; ++i) {
    const Vec3 o(rng.uniform() * 120 - 20, rng.uniform() * 80 - 20, rng.uniform() * 80 - 10);
    const Vec3 target(rng.uniform() * 80, rng.uniform() * 40, rng.uniform() * 36);
    const Vec3 d = (target - o).normalized();
    double t_ref = 0;
    std::uint32_t tri_ref = 0;
    const bool ref = brute_hit(mesh, o, d, 1e9, t_ref, tri_ref);
    sim::Bvh::Hit hit;
    const bool got = bvh.intersect(o, d, 0, 1e9, hit);
    REQUIRE(got == ref);
    if (got) {
      ++hits;
      CHECK(hit.t == Approx(t_ref).margin(1e-9));
      CHECK(bvh.occluded(o, d, 0, t_ref + 1e-6));
      CHECK_FALSE(bvh.occluded(o, d, 0, t_ref * (1 - 1e-9) - 1e-9));
    }
    const auto c = bvh.closest_point(o);
    CHECK(c.distance == Approx(point_triangle_distance(mesh, o)).margin(1e-9));
  }
  CHECK(hits > 100);
}

TEST_CASE("BVH on degenerate input", "[sim]") {
  recon::Mesh one = box_mesh(Vec3(0, 0, 0), Vec3(1, 1, 1));
  one.triangles.resize(1);
  const sim::Bvh bvh(one);  // a single leaf
  sim::Bvh::Hit hit;
  CHECK(bvh.intersect(Vec3(0.2, 0.5, 5), Vec3(0, 0, -1), 0, 100, hit));
  CHECK(hit.t == Approx(5));
  CHECK_FALSE(bvh.intersect(Vec3(5, 5, 5), Vec3(0, 0, -1), 0, 100, hit));
  const sim::Bvh empty(recon::Mesh{});
  CHECK_FALSE(empty.intersect(Vec3(0, 0, 0), Vec3(0, 0, 1), 0, 1, hit));
  recon::Mesh bad = one;
  bad.triangles[0][1] = 99;
  CHECK_THROWS_AS(sim::Bvh(bad), ConfigError);
}

TEST_CASE("Sphere cast touches a plane, an edge and a corner", "[sim]") {
  const sim::Bvh bvh(box_mesh(Vec3(0, 0, 0), Vec3(10, 10, 10)));
  sim::Bvh::SphereHit h;
  // Face: centre above the top face moving down.
  REQUIRE(bvh.sphere_cast(Vec3(5, 5, 20), Vec3(0, 0, -1), 2, 100, h));
  CHECK(h.t == Approx(8));
  CHECK((h.contact - Vec3(5, 5, 10)).norm() < 1e-9);
  // Edge: centre beyond the x = 10 edge of the top face.
  REQUIRE(bvh.sphere_cast(Vec3(11, 5, 20), Vec3(0, 0, -1), 2, 100, h));
  CHECK(h.t == Approx(10 - std::sqrt(3.0)));
  CHECK((h.contact - Vec3(10, 5, 10)).norm() < 1e-9);
  // Miss.
  CHECK_FALSE(bvh.sphere_cast(Vec3(13, 5, 20), Vec3(0, 0, -1), 2, 100, h));
}

// ---------------------------------------------------------------------------------------------
// Motion

TEST_CASE("Trapezoid profile and its inverse", "[sim]") {
  const sim::Trapezoid tr(10, 5, 10);  // accelerates over 1.25 on each end
  CHECK(tr.accel_time_s() == Approx(0.5));
  CHECK(tr.duration_s() == Approx(0.5 * 2 + 7.5 / 5));
  for (double s = 0; s <= 10; s += 0.37)
    CHECK(tr.position(tr.time_at(s)) == Approx(s).margin(1e-12));
  const sim::Trapezoid tri(1, 100, 4);  // never reaches cruise
  CHECK(tri.peak_velocity() == Approx(2));
  CHECK(tri.position(tri.duration_s()) == 1);
}

// ---------------------------------------------------------------------------------------------
// Accuracy and noise

TEST_CASE("Zero-noise samples lie on the reference surface", "[sim]") {
  struct Case {
    const char* part;
    sim::SensorKind sensor;
    sim::PathKind path;
  };
  for (const Case c : {Case{"container", sim::SensorKind::kPoint, sim::PathKind::kSerpentine},
                       Case{"steps", sim::SensorKind::kLine, sim::PathKind::kRaster},
                       Case{"cylinder", sim::SensorKind::kLine, sim::PathKind::kRotary},
                       Case{"sphere", sim::SensorKind::kPoint, sim::PathKind::kViews}}) {
    CAPTURE(c.part, sim::to_string(c.sensor), sim::to_string(c.path));
    const sim::Scene scene(sim::make_part(c.part));
    sim::SimConfig cfg;
    cfg.sensor = sim::default_sensor(c.sensor);
    cfg.sensor.profile_points = 64;
    cfg.sensor.rate_hz = c.path == sim::PathKind::kRotary ? 50 : 200;
    cfg.path.kind = c.path;
    cfg.path.spacing_mm = c.sensor == sim::SensorKind::kLine ? 0.8 : 0.6;
    cfg.path.line_spacing_mm = c.path == sim::PathKind::kRotary ? 10 : 3;
    cfg.path.views = 3;
    const sim::Simulator s(scene, cfg);
    const auto scan = sim::simulate(s);
    const Paired p = pair_points(s, scan);
    REQUIRE(p.points.size() > 300);
    const double scale = (scene.hi() - scene.lo()).norm();
    double worst = 0;
    for (std::size_t i = 0; i < p.points.size(); ++i) {
      REQUIRE(p.truth[i].cause == SampleCause::kOk);
      worst = std::max(worst, (p.points[i].point_mm - p.truth[i].surface_point_mm).norm());
      worst = std::max(worst, scene.bvh().closest_point(p.points[i].point_mm).distance);
    }
    CHECK(worst <= 1e-9 * scale);
  }
}

TEST_CASE("Noisy samples stay within the configured noise of the surface", "[sim]") {
  const sim::Scene scene(sim::make_part("container"));
  for (const auto kind : {sim::SensorKind::kPoint, sim::SensorKind::kLine}) {
    sim::SimConfig cfg = point_config(sim::PathKind::kSerpentine, 0.5, 2);
    cfg.sensor = sim::default_sensor(kind);
    cfg.sensor.rate_hz = 100;
    cfg.sensor.profile_points = 50;
    cfg.imperfections.range_noise_mm = 0.01;
    cfg.imperfections.spike_probability = 0.01;
    cfg.imperfections.dropout_probability = 0.05;
    const sim::Simulator s(scene, cfg);
    const auto scan = sim::simulate(s);
    const Paired p = pair_points(s, scan);
    double sum2 = 0;
    std::size_t n = 0, spikes = 0;
    for (std::size_t i = 0; i < p.points.size(); ++i) {
      if (p.truth[i].cause == SampleCause::kSpike) {
        ++spikes;
        continue;
      }
      REQUIRE(p.truth[i].cause == SampleCause::kOk);
      const double along = (p.points[i].point_mm - p.truth[i].surface_point_mm).norm();
      const double dist = scene.bvh().closest_point(p.points[i].point_mm).distance;
      CHECK(dist <= along + 1e-9);  // displaced along the ray: never farther than the noise
      CHECK(along <= 6 * 0.01);
      sum2 += along * along;
      ++n;
    }
    REQUIRE(n > 1000);
    CHECK(std::sqrt(sum2 / n) == Approx(0.01).epsilon(0.1));
    CHECK(spikes == scan.stats.cause(SampleCause::kSpike));
    CHECK(scan.stats.cause(SampleCause::kDropout) > 0);
  }
}

TEST_CASE("Stage latency shifts points along the motion", "[sim]") {
  const sim::Scene scene(box_mesh(Vec3(0, 0, 0), Vec3(40, 40, 10)));
  sim::SimConfig cfg = point_config(sim::PathKind::kRaster, 0.2, 5);
  cfg.sensor.rate_hz = 100;                                          // 20 mm/s
  cfg.imperfections.sensor_latency = std::chrono::milliseconds(10);  // sample looks 10 ms late
  const sim::Simulator s(scene, cfg);
  const auto scan = sim::simulate(s);
  const Paired p = pair_points(s, scan);
  std::size_t cruise = 0;
  for (std::size_t i = 0; i < p.points.size(); ++i) {
    const Vec3 err = p.points[i].point_mm - p.truth[i].surface_point_mm;
    CHECK(std::abs(err.z()) < 1e-9);                         // flat top: only an in-plane shift
    if (std::abs(std::abs(err.x()) - 0.2) < 1e-9) ++cruise;  // 20 mm/s * 10 ms
  }
  CHECK(cruise > p.points.size() / 2);
}

// ---------------------------------------------------------------------------------------------
// Shadowing

TEST_CASE("Triangulation shadow: a missing strip behind each step", "[sim]") {
  const sim::Scene scene(sim::make_part("steps"));  // treads z = 10, 20, 30; risers at x = 20, 40
  for (const double side : {1.0, -1.0}) {
    CAPTURE(side);
    sim::SimConfig cfg = point_config(sim::PathKind::kRaster, 0.05, 3);
    cfg.sensor.rate_hz = 1000;
    cfg.sensor.baseline_dir = Vec3(side, 0, 0);  // receiver towards +x (behind the risers) or -x
    const sim::Simulator s(scene, cfg);
    const auto scan = sim::simulate(s);
    // Geometry: emitter height and baseline of the receiver (straight down the beam).
    const double z_e = s.plan().trajectory.pose_at(s.plan().trajectory.start()).z_mm;
    const double b = s.optics().receiver().norm();
    // One line through the middle of the part (y = 15 lies between lines, take the nearest).
    double y_line = 0, best = 1e9;
    for (const auto& t : scan.truth)
      if (std::isfinite(t.surface_point_mm.y()) && std::abs(t.surface_point_mm.y() - 15) < best) {
        best = std::abs(t.surface_point_mm.y() - 15);
        y_line = t.surface_point_mm.y();
      }
    for (const double tread : {10.0, 20.0}) {
      const double riser_x = tread == 10 ? 20 : 40;
      // A spot (x, tread) is hidden when the line to the receiver passes below the next tread's
      // edge: x > riser - 10 * b / (z_e - tread).
      const double strip = 10 * b / (z_e - tread);
      double shadow_lo = 1e9, shadow_hi = -1e9, ok_hi = -1e9;
      for (const auto& t : scan.truth) {
        const Vec3& q = t.surface_point_mm;
        if (!std::isfinite(q.x()) || std::abs(q.y() - y_line) > 1e-9 ||
            std::abs(q.z() - tread) > 1e-9 || q.x() <= riser_x - 20 + 0.5 || q.x() >= riser_x)
          continue;
        if (t.cause == SampleCause::kShadowed) {
          shadow_lo = std::min(shadow_lo, q.x());
          shadow_hi = std::max(shadow_hi, q.x());
        } else if (t.cause == SampleCause::kOk) {
          ok_hi = std::max(ok_hi, q.x());
        }
      }
      if (side > 0) {
        CHECK(shadow_lo == Approx(riser_x - strip).margin(0.06));
        CHECK(shadow_hi == Approx(riser_x).margin(0.06));
        CHECK(ok_hi < shadow_lo);
      } else {
        CHECK(shadow_hi == -1e9);  // nothing hidden on the treads
        CHECK(ok_hi == Approx(riser_x).margin(0.06));
      }
    }
  }
}

TEST_CASE("Grazing incidence and measuring range make samples missing", "[sim]") {
  const sim::Scene scene(sim::make_part("sphere"));
  sim::SimConfig cfg = point_config(sim::PathKind::kRaster, 0.5, 2);
  cfg.sensor.max_incidence_rad = 1.0;  // 57 degrees
  const sim::Simulator s(scene, cfg);
  const auto scan = sim::simulate(s);
  std::size_t grazing = 0;
  for (std::size_t i = 0; i < scan.truth.size(); ++i) {
    const auto& t = scan.truth[i];
    if (t.cause == SampleCause::kGrazing) {
      ++grazing;
      // Beam -z: incidence = angle between the normal and z (radial up to the facets' tilt).
      const Vec3 n = t.surface_point_mm.normalized();
      CHECK(std::abs(n.z()) < std::cos(1.0) + 0.05);
      CHECK(scan.sensor[i].status == SensorStatus::kNoTarget);
    }
    if (t.cause == SampleCause::kOk) {
      CHECK(std::abs(t.surface_point_mm.normalized().z()) >= std::cos(1.0) - 0.05);
    }
  }
  CHECK(grazing > 50);
  // A short range (z 17 .. 25): the sphere below z = 17 is out of range.
  cfg.sensor.range_mm = 8;
  const auto scan2 = sim::simulate(sim::Simulator(scene, cfg));
  CHECK(scan2.stats.cause(SampleCause::kOutOfRange) > 0);
  for (std::size_t i = 0; i < scan2.truth.size(); ++i)
    if (scan2.truth[i].cause == SampleCause::kOutOfRange)
      CHECK(scan2.sensor[i].status == SensorStatus::kOverRange);
}

// ---------------------------------------------------------------------------------------------
// Density

namespace {

/// Surface points of valid samples grouped by scan line (y), each sorted along x.
std::map<double, std::vector<double>> lines_of(const sim::SimulatedScan& scan) {
  std::map<double, std::vector<double>> lines;
  for (std::size_t i = 0; i < scan.truth.size(); ++i)
    if (scan.truth[i].cause == SampleCause::kOk)
      lines[std::round(scan.truth[i].surface_point_mm.y() * 1e6) / 1e6].push_back(
          scan.truth[i].surface_point_mm.x());
  for (auto& [y, xs] : lines) std::sort(xs.begin(), xs.end());
  return lines;
}

}  // namespace

TEST_CASE("Raster spacing 1:5 gives 1:5 point spacing", "[sim]") {
  const sim::Scene scene(box_mesh(Vec3(0, 0, 0), Vec3(30, 30, 5)));
  sim::SimConfig cfg = point_config(sim::PathKind::kSerpentine, 0.2, 1.0);
  cfg.sensor.rate_hz = 250;  // 50 mm/s
  const auto scan = sim::simulate(sim::Simulator(scene, cfg));
  const auto lines = lines_of(scan);
  REQUIRE(lines.size() >= 30);
  std::vector<double> along;
  for (const auto& [y, xs] : lines)
    for (std::size_t i = 1; i < xs.size(); ++i)
      if (xs[i] > 10 && xs[i] < 20) along.push_back(xs[i] - xs[i - 1]);  // cruise region
  std::vector<double> across;
  for (auto it = std::next(lines.begin()); it != lines.end(); ++it)
    across.push_back(it->first - std::prev(it)->first);
  std::sort(along.begin(), along.end());
  for (const double d : along) CHECK(d == Approx(0.2).margin(1e-9));
  for (const double d : across) CHECK(d == Approx(1.0).margin(1e-9));
  CHECK(across.front() / along[along.size() / 2] == Approx(5).epsilon(1e-6));
}

TEST_CASE("Acceleration limits make the line ends denser", "[sim]") {
  const sim::Scene scene(box_mesh(Vec3(0, 0, 0), Vec3(30, 10, 5)));
  sim::SimConfig cfg = point_config(sim::PathKind::kRaster, 0.2, 20);
  cfg.sensor.rate_hz = 100;                  // 20 mm/s, T = 10 ms
  cfg.path.limits.linear_accel_mm_s2 = 100;  // ramps of 0.2 s over 2 mm
  cfg.path.margin_mm = 0;                    // the ramps are on the part
  const auto scan = sim::simulate(sim::Simulator(scene, cfg));
  const auto lines = lines_of(scan);
  REQUIRE(!lines.empty());
  const auto& xs = lines.begin()->second;
  REQUIRE(xs.size() > 150);
  // Spacing during the ramp: a T^2 (k + 1/2) after k samples from rest at the line start.
  const double a = 100, t = 0.01;
  for (std::size_t k = 0; k + 1 < 20; ++k)
    CHECK(xs[k + 1] - xs[k] == Approx(a * t * t * (static_cast<double>(k) + 0.5)).margin(1e-9));
  // Samples per mm: twice as many in the 2 mm ramps as in the cruise.
  auto count_in = [&](double lo, double hi) {
    return std::count_if(xs.begin(), xs.end(), [&](double x) { return x >= lo && x < hi; });
  };
  const auto start = count_in(0, 2), middle = count_in(14, 16), end = count_in(28, 30.0001);
  CHECK(middle == 10);
  CHECK(start == Approx(2 * middle).margin(1));
  CHECK(end == Approx(2 * middle).margin(1));
}

// ---------------------------------------------------------------------------------------------
// Probe

TEST_CASE("Touch probe contacts lie on the surface", "[sim]") {
  const sim::Scene scene(sim::make_part("steps"));
  sim::SimConfig cfg;
  cfg.sensor = sim::default_sensor(sim::SensorKind::kProbe);
  cfg.sensor.tip_radius_mm = 1;
  cfg.sensor.probe_speed_mm_s = 20;
  cfg.path.kind = sim::PathKind::kSerpentine;
  cfg.path.spacing_mm = 4.5;
  cfg.path.line_spacing_mm = 10;
  cfg.stage_rate_hz = 100;
  const sim::Simulator s(scene, cfg);
  const auto scan = sim::simulate(s);
  const Paired p = pair_points(s, scan);
  REQUIRE(p.points.size() > 20);
  std::size_t flat = 0;
  for (std::size_t i = 0; i < p.points.size(); ++i) {
    const Vec3& contact = p.truth[i].surface_point_mm;
    CHECK(scene.bvh().closest_point(contact).distance < 1e-9);
    // On a tread (not within a tip radius of a riser) the compensated point is the contact.
    const double x = contact.x();
    if (std::abs(x - 20) > 1.5 && std::abs(x - 40) > 1.5 && x > 1.5 && x < 58.5) {
      ++flat;
      CHECK((p.points[i].point_mm - contact).norm() < 1e-6);
    }
  }
  CHECK(flat > 10);
}

// ---------------------------------------------------------------------------------------------
// Determinism

TEST_CASE("Same seed, same bytes, and each imperfection has its own random stream", "[sim]") {
  const sim::Scene scene(sim::make_part("steps"));
  sim::SimConfig cfg = point_config(sim::PathKind::kSerpentine, 0.5, 3);
  cfg.imperfections.seed = 42;
  cfg.imperfections.range_noise_mm = 0.02;
  cfg.imperfections.dropout_probability = 0.1;
  cfg.imperfections.spike_probability = 0.01;
  cfg.imperfections.missing_probability = 0.01;
  cfg.imperfections.stage_noise_mm = 0.001;
  cfg.imperfections.device_clock_offset = std::chrono::seconds(-1);
  cfg.threads = 1;
  const std::string a = stream_text(sim::Simulator(scene, cfg));
  cfg.threads = 3;  // the thread count never changes the output
  const std::string b = stream_text(sim::Simulator(scene, cfg));
  CHECK(a == b);
  cfg.imperfections.seed = 43;
  CHECK(stream_text(sim::Simulator(scene, cfg)) != a);

  // Changing the dropout probability moves no noise value.
  cfg.imperfections.seed = 42;
  const auto base = sim::simulate(sim::Simulator(scene, cfg));
  cfg.imperfections.dropout_probability = 0.3;
  const auto more = sim::simulate(sim::Simulator(scene, cfg));
  REQUIRE(base.sensor.size() == more.sensor.size());
  std::size_t compared = 0;
  for (std::size_t i = 0; i < base.sensor.size(); ++i) {
    if (base.sensor[i].status == SensorStatus::kOk && more.sensor[i].status == SensorStatus::kOk) {
      CHECK(base.sensor[i].value_mm == more.sensor[i].value_mm);
      ++compared;
    }
  }
  CHECK(compared > 100);
  CHECK(more.stats.cause(SampleCause::kDropout) > base.stats.cause(SampleCause::kDropout));
}

TEST_CASE("Missing samples leave sequence gaps", "[sim]") {
  const sim::Scene scene(sim::make_part("sphere"));
  sim::SimConfig cfg = point_config(sim::PathKind::kRaster, 0.5, 2);
  cfg.imperfections.missing_probability = 0.05;
  const auto scan = sim::simulate(sim::Simulator(scene, cfg));
  std::uint64_t gaps = 0;
  for (std::size_t i = 1; i < scan.sensor.size(); ++i)
    gaps += scan.sensor[i].seq - scan.sensor[i - 1].seq - 1;
  gaps += scan.sensor.front().seq;
  CHECK(gaps > 0);
  CHECK(gaps <= scan.stats.missing);
  CHECK(scan.stats.missing ==
        Approx(0.05 * (scan.stats.measurements + scan.stats.missing)).epsilon(0.2));
}

// ---------------------------------------------------------------------------------------------
// Stream and replay

TEST_CASE("A recorded stream reproduces the same points", "[sim]") {
  const sim::Scene scene(sim::make_part("container"));
  for (const auto kind : {sim::SensorKind::kPoint, sim::SensorKind::kLine}) {
    sim::SimConfig cfg = point_config(sim::PathKind::kSerpentine, 0.7, 3);
    cfg.sensor = sim::default_sensor(kind);
    cfg.sensor.rate_hz = 100;
    cfg.sensor.profile_points = 40;
    cfg.imperfections.range_noise_mm = 0.01;
    cfg.imperfections.stage_noise_mm = 0.001;
    cfg.imperfections.device_clock_offset = std::chrono::milliseconds(5);
    const sim::Simulator s(scene, cfg);
    const auto scan = sim::simulate(s);
    const auto direct =
        sim::points_from_samples(s.optics(), s.calibration(), scan.stage, scan.sensor);
    const std::string text = stream_text(s);
    const sim::RecordedStream rec = sim::parse_stream(text, "mem");
    CHECK(rec.complete);
    CHECK(rec.sensor.size() == scan.sensor.size());
    CHECK(rec.stage.size() == scan.stage.size());
    const auto replayed = sim::points_from_stream(rec);
    REQUIRE(replayed.size() == direct.size());
    for (std::size_t i = 0; i < direct.size(); ++i) {
      REQUIRE(replayed[i].seq == direct[i].seq);
      REQUIRE(replayed[i].point_mm == direct[i].point_mm);  // bit for bit
    }
    // Replaying through the Replayer into a recorder gives the same samples again.
    sim::VirtualClock clock(sim::Timestamp{5'000'000'000});
    sim::Replayer rp(rec, clock);
    sim::ScanRecorder out;
    rp.run_all(out);
    CHECK(out.scan().sensor.size() == rec.sensor.size());
    const auto again =
        sim::points_from_samples(s.optics(), s.calibration(), out.scan().stage, out.scan().sensor);
    REQUIRE(again.size() == direct.size());
    for (std::size_t i = 0; i < direct.size(); ++i)
      REQUIRE(again[i].point_mm == direct[i].point_mm);
    // Writing what was read gives the same bytes.
    std::ostringstream copy;
    sim::StreamWriter w(copy, rec.header);
    sim::Replayer rp2(rec, clock);
    rp2.run_all(w);
    w.finish();
    CHECK(copy.str() == text);
  }
}

TEST_CASE("Replay follows the virtual clock at the recorded speed", "[sim]") {
  const sim::Scene scene(box_mesh(Vec3(0, 0, 0), Vec3(10, 10, 5)));
  sim::SimConfig cfg = point_config(sim::PathKind::kRaster, 0.5, 5);
  cfg.sensor.rate_hz = 100;
  const sim::Simulator s(scene, cfg);
  const sim::RecordedStream rec = sim::parse_stream(stream_text(s), "mem");
  const sim::Timestamp first = rec.stage.front().t;
  const sim::Timestamp last = rec.stage.back().t;

  for (const double speed : {1.0, 4.0}) {
    CAPTURE(speed);
    sim::VirtualClock clock(sim::Timestamp{0});
    sim::Replayer rp(rec, clock, {speed, true});
    sim::ScanRecorder out;
    CHECK(rp.poll(out) == 2);  // the first stage sample and the first measurement, both at t0
    const auto step = std::chrono::milliseconds(10);
    std::size_t polls = 1;
    while (!rp.done()) {
      const auto due = rp.next_due();
      REQUIRE(due);
      CHECK(*due > clock.now());  // everything already due was delivered
      clock.advance(step);
      rp.poll(out);
      ++polls;
    }
    const double recorded_s = static_cast<double>((last - first).count()) * 1e-9;
    CHECK(static_cast<double>(polls - 1) * 0.01 == Approx(recorded_s / speed).margin(0.011));
    // Rebased: the delivered times are the replay clock's due times.
    CHECK(out.scan().stage.front().t == sim::Timestamp{0});
    const auto span = out.scan().stage.back().t - out.scan().stage.front().t;
    CHECK(static_cast<double>(span.count()) ==
          Approx(static_cast<double>((last - first).count()) / speed).margin(1));
  }
}

TEST_CASE("Stream reader rejects damaged files", "[sim]") {
  const sim::Scene scene(box_mesh(Vec3(0, 0, 0), Vec3(10, 10, 5)));
  sim::SimConfig cfg = point_config(sim::PathKind::kRaster, 0.5, 5);
  cfg.sensor.rate_hz = 100;
  const std::string text = stream_text(sim::Simulator(scene, cfg));
  REQUIRE(text.rfind("# scanmesh-stream v1\n", 0) == 0);
  // Truncated: no end record.
  const std::string cut = text.substr(0, text.size() / 2);
  const std::string cut_lines = cut.substr(0, cut.rfind('\n') + 1);
  CHECK_THROWS_AS(sim::parse_stream(cut_lines, "cut"), InputError);
  const auto partial = sim::parse_stream(cut_lines, "cut", {true});
  CHECK_FALSE(partial.complete);
  CHECK(!partial.stage.empty());
  // One changed digit: checksum mismatch.
  std::string bad = text;
  const std::size_t pos = bad.find("\nP ") + 3;
  bad[pos] = bad[pos] == '1' ? '2' : '1';
  CHECK_THROWS_WITH(sim::parse_stream(bad, "bad"), Catch::Contains("checksum"));
  // Other versions and garbage.
  std::string v2 = text;
  v2[19] = '2';
  CHECK_THROWS_WITH(sim::parse_stream(v2, "v2"), Catch::Contains("version 2"));
  CHECK_THROWS_AS(sim::parse_stream("hello\n", "junk"), InputError);
  CHECK_THROWS_AS(sim::parse_stream("", "empty"), InputError);
  std::string extra = text + "S 1 2 - 0.5 ok\n";
  CHECK_THROWS_WITH(sim::parse_stream(extra, "extra"), Catch::Contains("after the end record"));
}

TEST_CASE("Configuration errors are reported together", "[sim]") {
  const sim::Scene scene(sim::make_part("sphere"));
  sim::SimConfig cfg;
  cfg.sensor.standoff_mm = -1;
  cfg.sensor.rate_hz = 0;
  cfg.imperfections.dropout_probability = 2;
  try {
    sim::Simulator s(scene, cfg);
    FAIL("no error");
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    CHECK_THAT(msg, Catch::Contains("standoff_mm") && Catch::Contains("rate_hz") &&
                        Catch::Contains("dropout_probability"));
  }
  // A line speed above the stage's limit.
  sim::SimConfig fast = point_config(sim::PathKind::kRaster, 1.0, 2);
  fast.sensor.rate_hz = 10000;
  CHECK_THROWS_WITH(sim::Simulator(scene, fast), Catch::Contains("above the stage's limit"));
  // A profiler whose receiver sits in its laser plane cannot triangulate.
  sim::SimConfig line;
  line.sensor = sim::default_sensor(sim::SensorKind::kLine);
  line.sensor.baseline_dir = line.sensor.fan_dir;
  CHECK_THROWS_WITH(sim::Simulator(scene, line), Catch::Contains("laser plane"));
}

namespace {

/// A short point-sensor raster over the sphere with lost measurements (seq gaps).
sim::SimulatedScan small_scan_with_gaps() {
  const sim::Scene scene(sim::make_part("sphere"));
  sim::SimConfig cfg;
  cfg.sensor = sim::default_sensor(sim::SensorKind::kPoint);
  cfg.sensor.rate_hz = 200;
  cfg.path.kind = sim::PathKind::kRaster;
  cfg.path.spacing_mm = 0.5;
  cfg.path.line_spacing_mm = 8;
  cfg.imperfections.missing_probability = 0.05;
  cfg.imperfections.seed = 3;
  return sim::simulate(sim::Simulator(scene, cfg));
}

struct Collected {
  std::mutex m;
  std::condition_variable cv;
  std::vector<sim::SensorSample> samples;
  drivers::SensorCallbacks callbacks() {
    return {.on_sample =
                [this](const sim::SensorSample& s) {
                  std::lock_guard lock(m);
                  samples.push_back(s);
                  cv.notify_all();
                },
            .on_state = {}};
  }
  bool wait_for(std::size_t n, std::chrono::seconds limit) {
    std::unique_lock lock(m);
    return cv.wait_for(lock, limit, [&] { return samples.size() >= n; });
  }
};

}  // namespace

TEST_CASE("The simulated sensor delivers a scan through the driver interface", "[sim]") {
  const sim::SimulatedScan scan = small_scan_with_gaps();
  REQUIRE(scan.sensor.size() > 500);
  REQUIRE(scan.stats.missing > 0);
  sim::SimulatedSensor sensor(scan.sensor, {.name = "sim0", .speed = 0});
  CHECK_THROWS_AS(sensor.start({}), drivers::DeviceError);  // open() first
  sensor.open();
  Collected c;
  sensor.start(c.callbacks());
  REQUIRE(c.wait_for(scan.sensor.size(), std::chrono::seconds(10)));
  sensor.stop();
  REQUIRE(c.samples.size() == scan.sensor.size());
  for (std::size_t i = 0; i < scan.sensor.size(); ++i) {
    CHECK(c.samples[i].seq == scan.sensor[i].seq);
    CHECK(c.samples[i].t_host == scan.sensor[i].t_host);  // speed 0 keeps the recorded times
    CHECK(c.samples[i].status == scan.sensor[i].status);
    if (scan.sensor[i].status == SensorStatus::kOk)
      CHECK(c.samples[i].value_mm == scan.sensor[i].value_mm);
  }
  CHECK(sensor.stats().samples == scan.sensor.size());
  CHECK(sensor.stats().gaps == scan.stats.missing);
  CHECK(sensor.done());
  CHECK(sensor.identify().model == "simulated displacement sensor");
}

TEST_CASE("The simulated sensor paces live, stops cleanly and resumes", "[sim]") {
  const sim::SimulatedScan scan = small_scan_with_gaps();
  // 60 samples at 200 Hz = 0.3 s of scanning, played 3x faster: about 0.1 s.
  std::vector<sim::SensorSample> part(scan.sensor.begin(), scan.sensor.begin() + 60);
  sim::SimulatedSensor sensor(part, {.name = "sim0", .speed = 3});
  sensor.open();
  Collected c;
  sensor.start(c.callbacks());
  REQUIRE(c.wait_for(30, std::chrono::seconds(5)));
  sensor.stop();
  std::size_t after_stop = 0;
  {
    std::lock_guard lock(c.m);
    after_stop = c.samples.size();
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(60));
  {
    std::lock_guard lock(c.m);
    CHECK(c.samples.size() == after_stop);  // no callback after stop()
  }
  sensor.start(c.callbacks());  // resumes after the last delivered sample
  REQUIRE(c.wait_for(part.size(), std::chrono::seconds(5)));
  sensor.stop();
  REQUIRE(c.samples.size() == part.size());
  for (std::size_t i = 0; i < part.size(); ++i) CHECK(c.samples[i].seq == part[i].seq);
  // Live times: monotonic, and the first half spaced about like the scan / 3 (generous bounds:
  // this is pacing, not a speed measurement).
  for (std::size_t i = 1; i < part.size(); ++i)
    CHECK(c.samples[i].t_host >= c.samples[i - 1].t_host);
  const double rec = static_cast<double>((part[29].t_host - part[0].t_host).count());
  const double live = static_cast<double>((c.samples[29].t_host - c.samples[0].t_host).count());
  CHECK(live >= 0.8 * rec / 3);
  CHECK(live <= 3.0 * rec / 3 + 300e6);  // late only when the machine is very busy
  CHECK_THROWS_AS(sim::SimulatedSensor(part, {.name = "x", .speed = -1}), ConfigError);
}
