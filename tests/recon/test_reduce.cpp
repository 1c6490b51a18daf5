// Unit tests of the reduction stages (cube reduction, thinning, spacing), the PCA frames with
// their orientation propagation, and the point grid, against brute-force references.
// SPDX-License-Identifier: MIT
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <queue>
#include <random>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/normals.hpp"
#include "scanmesh/recon/reduce.hpp"
#include "support/shapes.hpp"

using scanmesh::GeometryError;
using scanmesh::recon::Vec3;
namespace recon = scanmesh::recon;

namespace {

std::vector<Vec3> random_box(std::size_t n, double size, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, size);
  std::vector<Vec3> pts(n);
  for (Vec3& p : pts) p = Vec3(u(rng), u(rng), u(rng));
  return pts;
}

/// Clusters of points around random centres in a large box: the cubes' rows are too many for a
/// dense index, so the hashed code paths run.
std::vector<Vec3> sparse_clusters(std::size_t clusters, std::size_t per, double size, double spread,
                                  std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, size), v(-spread, spread);
  std::vector<Vec3> pts;
  for (std::size_t c = 0; c < clusters; ++c) {
    const Vec3 centre(u(rng), u(rng), u(rng));
    for (std::size_t i = 0; i < per; ++i) pts.push_back(centre + Vec3(v(rng), v(rng), v(rng)));
  }
  return pts;
}

/// Two noisy parallel sheets 0.3 apart: a shell like merged views, where cube representatives
/// clash across cube faces.
std::vector<Vec3> noisy_double_sheet(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 8.0);
  std::normal_distribution<double> noise(0.0, 0.08);
  std::vector<Vec3> pts(n);
  for (std::size_t i = 0; i < n; ++i)
    pts[i] = Vec3(u(rng), u(rng), 3.0 + (i % 2 == 0 ? 0.0 : 0.3) + noise(rng));
  return pts;
}

Vec3 bbox_min(const std::vector<Vec3>& pts) {
  Vec3 lo = pts[0];
  for (const Vec3& p : pts) lo = lo.cwiseMin(p);
  return lo;
}

/// Reference cube reduction: the documented rule, written plainly.
std::vector<std::uint32_t> brute_cube_reduce(const std::vector<Vec3>& pts, double cube) {
  const Vec3 lo = bbox_min(pts);
  const double inv = 1.0 / cube;
  struct Best {
    std::uint32_t index;
    double d2;
  };
  std::vector<std::pair<std::array<std::uint64_t, 3>, Best>> cubes;
  std::vector<std::pair<std::array<std::uint64_t, 3>, std::uint32_t>> keyed;
  for (std::uint32_t i = 0; i < pts.size(); ++i) {
    const Vec3 g = (pts[i] - lo) * inv;
    keyed.push_back({{static_cast<std::uint64_t>(g.x()), static_cast<std::uint64_t>(g.y()),
                      static_cast<std::uint64_t>(g.z())},
                     i});
  }
  std::sort(keyed.begin(), keyed.end());  // by cube, then by index
  std::vector<std::uint32_t> kept;
  for (std::size_t a = 0; a < keyed.size();) {
    std::size_t b = a;
    std::uint32_t best = keyed[a].second;
    double best_d2 = std::numeric_limits<double>::infinity();
    for (; b < keyed.size() && keyed[b].first == keyed[a].first; ++b) {
      const auto& c = keyed[b].first;
      const Vec3 centre = lo + (Vec3(static_cast<double>(c[0]), static_cast<double>(c[1]),
                                     static_cast<double>(c[2])) +
                                Vec3::Constant(0.5)) *
                                   cube;
      const double d2 = (pts[keyed[b].second] - centre).squaredNorm();
      if (d2 < best_d2) {  // indices ascend within a cube: the lower one wins ties
        best_d2 = d2;
        best = keyed[b].second;
      }
    }
    kept.push_back(best);
    a = b;
  }
  std::sort(kept.begin(), kept.end());
  return kept;
}

/// Reference greedy thinning: O(n^2).
std::vector<std::uint32_t> brute_thin(const std::vector<Vec3>& pts,
                                      const std::vector<std::uint32_t>& priority, double dist) {
  std::vector<std::uint32_t> kept;
  for (const std::uint32_t i : priority) {
    bool clash = false;
    for (const std::uint32_t j : kept)
      clash = clash || (pts[j] - pts[i]).squaredNorm() < dist * dist;
    if (!clash) kept.push_back(i);
  }
  std::sort(kept.begin(), kept.end());
  return kept;
}

/// The priority of cube_reduce_thin: distance to the own cube centre (in cube units), index
/// breaking ties.
std::vector<std::uint32_t> cube_priority(const std::vector<Vec3>& pts,
                                         const std::vector<std::uint32_t>& kept, double cube) {
  const Vec3 lo = bbox_min(pts);
  std::vector<std::pair<double, std::uint32_t>> order;
  for (const std::uint32_t i : kept) {
    const Vec3 g = (pts[i] - lo) / cube;
    const Vec3 c = (g.array().floor() + 0.5).matrix();
    order.emplace_back((g - c).squaredNorm(), i);
  }
  std::sort(order.begin(), order.end());
  std::vector<std::uint32_t> prio;
  for (const auto& o : order) prio.push_back(o.second);
  return prio;
}

/// Indices of the k nearest other points by (distance, index), brute force.
std::vector<std::uint32_t> brute_knn(const std::vector<Vec3>& pts, std::size_t i, std::size_t k) {
  std::vector<std::pair<double, std::uint32_t>> d;
  for (std::uint32_t j = 0; j < pts.size(); ++j)
    if (j != i) d.emplace_back((pts[j] - pts[i]).squaredNorm(), j);
  std::partial_sort(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(k), d.end());
  std::vector<std::uint32_t> out;
  for (std::size_t q = 0; q < k; ++q) out.push_back(d[q].second);
  return out;
}

/// The reference orientation propagation: a lazy priority queue of every edge pushed (cost,
/// from << 32 | to), popped cheapest first, from the highest point of each component.
std::vector<Eigen::Vector3f> reference_orientation(
    const std::vector<Vec3>& pts, std::vector<Eigen::Vector3f> normal,
    const std::vector<std::vector<std::uint32_t>>& knn) {
  const std::size_t n = pts.size();
  std::vector<std::uint8_t> done(n, 0);
  std::vector<std::uint32_t> by_z(n);
  std::iota(by_z.begin(), by_z.end(), 0u);
  std::sort(by_z.begin(), by_z.end(), [&](std::uint32_t a, std::uint32_t b) {
    return pts[a].z() != pts[b].z() ? pts[a].z() > pts[b].z() : a < b;
  });
  using Item = std::pair<float, std::uint64_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  auto push = [&](std::uint32_t i) {
    for (const std::uint32_t j : knn[i]) {
      if (done[j]) continue;
      const float c = 1.0f - std::abs(normal[i].dot(normal[j]));
      queue.emplace(c, (static_cast<std::uint64_t>(i) << 32) | j);
    }
  };
  for (const std::uint32_t start : by_z) {
    if (done[start]) continue;
    if (normal[start].z() < 0) normal[start] = -normal[start];
    done[start] = 1;
    push(start);
    while (!queue.empty()) {
      const auto [cost, pair] = queue.top();
      queue.pop();
      const auto from = static_cast<std::uint32_t>(pair >> 32);
      const auto to = static_cast<std::uint32_t>(pair & 0xffffffffu);
      if (done[to]) continue;
      if (normal[from].dot(normal[to]) < 0) normal[to] = -normal[to];
      done[to] = 1;
      push(to);
    }
  }
  return normal;
}

}  // namespace

// --- cube reduction ---------------------------------------------------------------------------

TEST_CASE("cube_reduce keeps exactly the point nearest each cube centre", "[recon]") {
  SECTION("dense rows of cubes") {
    const auto pts = random_box(4000, 10.0, 1);
    for (const double cube : {0.35, 0.7, 1.9})
      CHECK(recon::cube_reduce(pts, cube) == brute_cube_reduce(pts, cube));
  }
  SECTION("sparse extent (hashed cubes)") {
    const auto pts = sparse_clusters(150, 6, 5000.0, 1.5, 2);
    for (const double cube : {0.5, 1.0})
      CHECK(recon::cube_reduce(pts, cube) == brute_cube_reduce(pts, cube));
  }
}

TEST_CASE("cube_reduce breaks ties by the lower index and is deterministic", "[recon]") {
  // Cube [0, 1)^3 (the corner point sets the origin): indices 1 and 2 lie 0.25 from its centre
  // on either side, 3 and 4 coincide in the next cube.
  const std::vector<Vec3> pts = {{0, 0, 0},       {0.75, 0.5, 0.5}, {0.25, 0.5, 0.5},
                                 {1.5, 0.5, 0.5}, {1.5, 0.5, 0.5},  {2.9, 0.1, 0.1}};
  const auto kept = recon::cube_reduce(pts, 1.0);
  CHECK(kept == std::vector<std::uint32_t>{1, 3, 5});
  CHECK(recon::cube_reduce(pts, 1.0) == kept);
  const auto cloud = random_box(3000, 5.0, 3);
  CHECK(recon::cube_reduce(cloud, 0.4) == recon::cube_reduce(cloud, 0.4));
  CHECK(recon::cube_reduce_thin(cloud, 0.4) == recon::cube_reduce_thin(cloud, 0.4));
}

TEST_CASE("cube_reduce rejects bad cube sizes", "[recon]") {
  const auto pts = random_box(100, 1.0, 4);
  for (const double bad : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                           std::numeric_limits<double>::infinity()}) {
    CHECK_THROWS_AS(recon::cube_reduce(pts, bad), GeometryError);
    CHECK_THROWS_AS(recon::cube_reduce_thin(pts, bad), GeometryError);
  }
  CHECK_THROWS_AS(recon::cube_reduce(pts, 1e-9), GeometryError);  // over 2 million per axis
  CHECK(recon::cube_reduce({}, 1.0).empty());
  CHECK(recon::cube_reduce(std::vector<Vec3>{{1, 2, 3}}, 1.0) == std::vector<std::uint32_t>{0});
}

// --- thinning -----------------------------------------------------------------------------------

TEST_CASE("thin_min_distance guarantees the distance and keeps the first in priority order",
          "[recon]") {
  const auto pts = random_box(1500, 10.0, 5);
  std::vector<std::uint32_t> prio(pts.size());
  std::iota(prio.begin(), prio.end(), 0u);
  std::shuffle(prio.begin(), prio.end(), std::mt19937(6));
  const double dist = 0.6;
  const auto kept = recon::thin_min_distance(pts, prio, dist);
  REQUIRE(std::is_sorted(kept.begin(), kept.end()));
  CHECK(std::binary_search(kept.begin(), kept.end(), prio[0]));
  for (std::size_t a = 0; a < kept.size(); ++a)
    for (std::size_t b = a + 1; b < kept.size(); ++b)
      REQUIRE((pts[kept[a]] - pts[kept[b]]).norm() >= dist);
  // Every dropped point has a kept point within the distance that comes earlier.
  std::vector<std::size_t> rank(pts.size());
  for (std::size_t r = 0; r < prio.size(); ++r) rank[prio[r]] = r;
  for (std::uint32_t i = 0; i < pts.size(); ++i) {
    if (std::binary_search(kept.begin(), kept.end(), i)) continue;
    bool covered = false;
    for (const std::uint32_t j : kept)
      covered = covered || (rank[j] < rank[i] && (pts[j] - pts[i]).norm() < dist);
    REQUIRE(covered);
  }
  CHECK(kept == brute_thin(pts, prio, dist));
}

TEST_CASE("cube_reduce_thin is cube_reduce thinned at 0.65 cube in cube-centre order", "[recon]") {
  SECTION("noisy double sheet (dense rows)") {
    const auto pts = noisy_double_sheet(2500, 7);
    for (const double cube : {0.3, 0.5}) {
      const auto reps = recon::cube_reduce(pts, cube);
      const auto expected = brute_thin(pts, cube_priority(pts, reps, cube), 0.65 * cube);
      REQUIRE(expected.size() < reps.size());  // the case exercises clashes
      CHECK(recon::cube_reduce_thin(pts, cube) == expected);
    }
  }
  SECTION("sparse extent") {
    const auto pts = sparse_clusters(120, 8, 5000.0, 1.0, 8);
    const double cube = 0.5;
    const auto reps = recon::cube_reduce(pts, cube);
    CHECK(recon::cube_reduce_thin(pts, cube) ==
          brute_thin(pts, cube_priority(pts, reps, cube), 0.65 * cube));
  }
}

// --- projection ----------------------------------------------------------------------------------

namespace {

/// A point sensor's serpentine raster over the cap of a sphere of radius r at the origin (lines
/// along y, `line` apart, `step` along them; |x|, |y| up to 0.75 r), with Gaussian range noise.
std::vector<Vec3> sphere_raster(double r, double line, double step, double noise) {
  std::mt19937 rng(7);
  std::normal_distribution<double> gauss(0.0, noise);
  std::vector<Vec3> pts;
  for (double x = -0.75 * r; x <= 0.75 * r; x += line)
    for (double y = -0.75 * r; y <= 0.75 * r; y += step) {
      const double z2 = r * r - x * x - y * y;
      if (z2 > 0) pts.emplace_back(x, y, std::sqrt(z2) + gauss(rng));
    }
  return pts;
}

}  // namespace

TEST_CASE("project_to_local_planes: the quadric stays on a sparsely scanned sphere, the plane sinks",
          "[recon]") {
  // bench_quality's point-sensor scans of the sphere (lines 2.5 mm apart, 0.5 mm along them,
  // auto cube about 1.9 mm): the plane through a ball of 1.5 cubes lies about radius^2 / (4 R)
  // = 0.1 mm inside the sphere, five times the noise.
  const double r = 20, cube = 1.9, radius = 1.5 * cube;
  const auto pts = sphere_raster(r, 2.5, 0.5, 0.02);
  const auto kept = recon::cube_reduce_thin(pts, cube);
  REQUIRE(kept.size() > 100);
  auto signed_mean = [&](const std::vector<Vec3>& out, double& rms) {
    double sum = 0, sum2 = 0;
    std::size_t m = 0;
    for (const Vec3& q : out) {
      if (std::hypot(q.x(), q.y()) > 0.6 * r) continue;  // away from the cap's rim
      const double d = q.norm() - r;
      sum += d;
      sum2 += d * d;
      ++m;
    }
    REQUIRE(m > 50);
    rms = std::sqrt(sum2 / static_cast<double>(m));
    return sum / static_cast<double>(m);
  };
  double rms_plane = 0, rms_quadric = 0;
  const double plane = signed_mean(recon::project_to_local_planes(pts, kept, radius, 0.5 * cube,
                                                                  /*second_order=*/false),
                                   rms_plane);
  const double quadric = signed_mean(
      recon::project_to_local_planes(pts, kept, radius, 0.5 * cube, /*second_order=*/true),
      rms_quadric);
  INFO("plane " << plane << " rms " << rms_plane << ", quadric " << quadric << " rms " << rms_quadric);
  CHECK(plane < -0.08);
  CHECK(std::abs(quadric) < 0.02);
  // Where the sphere falls steeply, a ball holds a single scan line: no quadric, the plane.
  CHECK(rms_quadric < 0.35 * rms_plane);
}

TEST_CASE("project_to_local_planes: on a noisy plane the quadric is not used", "[recon]") {
  // Curvature the noise alone suggests fails the F test: both orders give the same points.
  std::mt19937 rng(3);
  std::normal_distribution<double> gauss(0.0, 0.05);
  std::vector<Vec3> pts;
  for (int j = 0; j < 60; ++j)
    for (int i = 0; i < 60; ++i) pts.emplace_back(0.2 * i, 0.2 * j, gauss(rng));
  const double cube = 0.4;
  const auto kept = recon::cube_reduce_thin(pts, cube);
  const auto first = recon::project_to_local_planes(pts, kept, 1.5 * cube, 0.5 * cube, false);
  const auto second = recon::project_to_local_planes(pts, kept, 1.5 * cube, 0.5 * cube, true);
  REQUIRE(first.size() == second.size());
  std::size_t same = 0;
  for (std::size_t i = 0; i < first.size(); ++i) same += first[i] == second[i] ? 1 : 0;
  CHECK(same >= first.size() - first.size() / 200);  // at most 0.5 % by chance
}

TEST_CASE("project_to_local_planes: the quadric only where the bend is gentle against the ball",
          "[recon]") {
  // A noise-free cylinder scanned in rings 0.5 apart, 0.1 along them (cylinder_raster): its
  // quadric fits almost exactly (the F test passes everywhere), so only the curvature decides.
  // Tighter than two balls (a fillet, a crease the sampling barely resolves) the plane stays;
  // gentler, the quadric puts the point back on the surface, which the plane misses inwards.
  const double cube = 0.6, radius = 1.5 * cube;
  for (const double bend : {1.5, 4.0}) {  // cylinder radius, in balls
    const double rc = bend * radius;
    const auto pts = scanmesh::test::cylinder_raster(rc, 12, 0.1, 0.5);
    const auto kept = recon::cube_reduce_thin(pts, cube);
    const auto first = recon::project_to_local_planes(pts, kept, radius, 0.5 * cube, false);
    const auto second = recon::project_to_local_planes(pts, kept, radius, 0.5 * cube, true);
    REQUIRE(first.size() == second.size());
    std::size_t inner = 0, same = 0;
    double off_first = 0, off_second = 0;
    for (std::size_t i = 0; i < first.size(); ++i) {
      if (first[i].z() < 2 || first[i].z() > 10) continue;  // away from the open ends
      ++inner;
      same += first[i] == second[i] ? 1 : 0;
      off_first += std::abs(std::hypot(first[i].x(), first[i].y()) - rc);
      off_second += std::abs(std::hypot(second[i].x(), second[i].y()) - rc);
    }
    INFO("bend " << bend << " balls: " << same << " of " << inner << " unchanged");
    REQUIRE(inner > 20);
    if (bend < 2) {
      CHECK(same == inner);
    } else {
      CHECK(same == 0);
      CHECK(off_second < 0.2 * off_first);
    }
  }
}

// --- spacing -------------------------------------------------------------------------------------

TEST_CASE("estimate_spacing on a regular grid: nearest and cross are the step", "[recon]") {
  std::vector<Vec3> pts;
  const double step = 0.5;
  for (int j = 0; j < 30; ++j)
    for (int i = 0; i < 30; ++i) pts.emplace_back(i * step, j * step, 2.0);
  const auto s = recon::estimate_spacing(pts);
  CHECK(s.nearest_mm == Approx(step).epsilon(1e-9));
  CHECK(s.cross_mm == Approx(step).epsilon(1e-9));
  CHECK(s.thickness_mm < 1e-9);
  CHECK(s.sampled == pts.size());  // fewer points than samples: every point
  CHECK(recon::auto_cube_size(s) == Approx(step).epsilon(1e-9));
}

TEST_CASE("estimate_spacing of a cloud of repeated readings is that of its distinct points",
          "[recon]") {
  // A point sensor at rest streams the same reading: every point of the grid 40 times over.
  // The copies used to hide every neighbour (nearest 0, and then "cube too small").
  std::vector<Vec3> distinct, repeated;
  const double step = 0.5;
  for (int j = 0; j < 30; ++j)
    for (int i = 0; i < 30; ++i) distinct.emplace_back(i * step, j * step, 0.1 * std::sin(0.3 * i));
  for (int copy = 0; copy < 40; ++copy) repeated.insert(repeated.end(), distinct.begin(), distinct.end());
  const auto d = recon::estimate_spacing(distinct), r = recon::estimate_spacing(repeated);
  CHECK(d.nearest_mm > 0.4);
  CHECK(r.nearest_mm == d.nearest_mm);
  CHECK(r.cross_mm == d.cross_mm);
  CHECK(r.thickness_mm == d.thickness_mm);
  CHECK(recon::auto_cube_size(r) == recon::auto_cube_size(d));
  // A few copies leave most neighbourhoods seeing other points: no second pass needed, and the
  // spacing still right.
  std::vector<Vec3> twice = distinct;
  twice.insert(twice.end(), distinct.begin(), distinct.end());
  CHECK(recon::estimate_spacing(twice).nearest_mm == Approx(d.nearest_mm).epsilon(0.05));
}

TEST_CASE("estimate_spacing on an anisotropic raster: cross is the line spacing", "[recon]") {
  std::vector<Vec3> pts;
  for (int line = 0; line < 12; ++line)
    for (int i = 0; i < 120; ++i) pts.emplace_back(i * 0.1, line * 1.0, 0.01 * std::sin(i * 0.05));
  const auto s = recon::estimate_spacing(pts);
  CHECK(s.nearest_mm == Approx(0.1).epsilon(0.01));
  CHECK(s.cross_mm == Approx(1.0).epsilon(0.01));
  CHECK(recon::auto_cube_size(s) == Approx(0.75).epsilon(0.01));
  CHECK(recon::estimate_spacing(pts).cross_mm == s.cross_mm);  // deterministic
}

// A shell thicker than 0.3 cross spacings: noise (Gaussian, the same at every scale) sets a cube
// that swallows it; two layers (a wall thinner than the spacing, seen from both sides) leave the
// cube to the sampling, as does structure that shrinks with the neighbourhood (the casting, a
// real-scan test).
TEST_CASE("auto cube: a thick shell of noise is swallowed but a two-layer wall is not", "[recon]") {
  const double step = 0.5;
  SECTION("noise of 0.6 spacings") {
    std::vector<Vec3> pts;
    for (int j = 0; j < 60; ++j)
      for (int i = 0; i < 60; ++i) pts.emplace_back(i * step, j * step, 0.0);
    scanmesh::test::add_noise(pts, 0.3, 7);
    const auto s = recon::estimate_spacing(pts);
    INFO("nearest " << s.nearest_mm << " cross " << s.cross_mm << " thickness " << s.thickness_mm
                    << " few " << s.thickness_few_mm << " shape " << s.thickness_shape);
    REQUIRE(s.thickness_mm > 0.3 * s.cross_mm);  // the case exercises the thick shell
    CHECK(s.thickness_few_mm / s.thickness_mm == Approx(0.85).margin(0.1));
    CHECK(s.thickness_shape == Approx(0.8).margin(0.05));
    CHECK(recon::auto_cube_size(s) == Approx(14 * s.thickness_mm).epsilon(1e-12));
  }
  SECTION("two faces 0.7 spacings apart") {
    std::vector<Vec3> pts;
    for (int j = 0; j < 60; ++j)
      for (int i = 0; i < 60; ++i) {
        pts.emplace_back(i * step, j * step, 0.175);
        pts.emplace_back((i + 0.5) * step, (j + 0.5) * step, -0.175);
      }
    const auto s = recon::estimate_spacing(pts);
    INFO("nearest " << s.nearest_mm << " cross " << s.cross_mm << " thickness " << s.thickness_mm
                    << " few " << s.thickness_few_mm << " shape " << s.thickness_shape);
    REQUIRE(s.thickness_mm > 0.3 * s.cross_mm);
    CHECK(s.thickness_shape > 0.9);
    CHECK(recon::auto_cube_size(s) == Approx(std::max(s.nearest_mm, 0.75 * s.cross_mm)).epsilon(1e-12));
  }
}

// --- frames --------------------------------------------------------------------------------------

TEST_CASE("estimate_frames: sphere normals are radial and all outward", "[recon]") {
  const auto pts = scanmesh::test::sphere_points(3000, 10.0);
  recon::PointGrid grid;
  grid.build(pts, 2.5 * 0.65);  // spacing about 0.65
  const auto f = recon::estimate_frames(pts, grid);
  REQUIRE(f.normal.size() == pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Vec3 radial = pts[i].normalized();
    REQUIRE(f.normal[i].cast<double>().dot(radial) > 0.999);
    REQUIRE(f.flatness[i] < 0.01);
  }
}

TEST_CASE("estimate_frames: plane normals are +z, grid spacing is the step", "[recon]") {
  // Hexagonal grid: the 6 nearest neighbours of an interior point are exactly one step away.
  std::vector<Vec3> pts;
  const double step = 0.4;
  for (int j = 0; j < 40; ++j)
    for (int i = 0; i < 40; ++i)
      pts.emplace_back((i + 0.5 * (j % 2)) * step, j * step * std::sqrt(3.0) / 2, 1.0);
  recon::PointGrid grid;
  grid.build(pts, 2.5 * step);
  const auto f = recon::estimate_frames(pts, grid);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    REQUIRE(f.normal[i].z() > 0.9999f);
    REQUIRE(f.flatness[i] < 1e-9f);
    const Vec3& p = pts[i];
    const bool interior =
        p.x() > 1.5 * step && p.x() < 37.5 * step && p.y() > 1.5 * step && p.y() < 33 * step;
    if (interior) REQUIRE(f.spacing[i] == Approx(step).epsilon(1e-6));
  }
}

TEST_CASE("estimate_frames: PCA over the exact k nearest, propagation as the reference",
          "[recon]") {
  // A noisy wavy sheet folded into a thin plate: nearby opposite sides make the propagation
  // order matter.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(0.0, 5.0);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::vector<Vec3> pts;
  for (int i = 0; i < 500; ++i) {
    const double x = u(rng), y = u(rng);
    pts.emplace_back(x, y, 0.3 * std::sin(x) * std::cos(0.7 * y) + noise(rng));
    pts.emplace_back(x, y + 0.05, 1.2 + 0.2 * std::cos(x) + noise(rng));
  }
  recon::PointGrid grid;
  grid.build(pts, 1.5);  // far above the spacing (about 0.25): the 27 cells hold the true kNN
  const int k = 12;
  recon::NormalOptions opt;
  opt.neighbours = k;
  const auto f = recon::estimate_frames(pts, grid, opt);
  std::vector<std::vector<std::uint32_t>> knn(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    knn[i] = brute_knn(pts, i, k);
    Vec3 mean = pts[i];
    for (const std::uint32_t j : knn[i]) mean += pts[j];
    mean /= static_cast<double>(k + 1);
    Eigen::Matrix3d cov = (pts[i] - mean) * (pts[i] - mean).transpose();
    double spacing = 0;
    for (std::size_t q = 0; q < knn[i].size(); ++q) {
      cov += (pts[knn[i][q]] - mean) * (pts[knn[i][q]] - mean).transpose();
      if (q < 6) spacing += (pts[knn[i][q]] - pts[i]).norm() / 6;
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    REQUIRE(std::abs(f.normal[i].cast<double>().dot(es.eigenvectors().col(0))) > 1 - 1e-6);
    REQUIRE(f.spacing[i] == Approx(spacing).epsilon(1e-6));
    const Vec3 ev = es.eigenvalues().cwiseMax(0.0);
    REQUIRE(f.flatness[i] == Approx(ev[0] / ev.sum()).margin(1e-7));
  }
  // Orientation: the reference propagation over the same graph gives the same signs.
  const auto ref = reference_orientation(pts, f.normal, knn);
  std::size_t flipped = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) flipped += ref[i].dot(f.normal[i]) < 0 ? 1 : 0;
  CHECK(flipped == 0);
}

TEST_CASE("estimate_frames: duplicates and sparse points match the brute-force neighbours",
          "[recon]") {
  // Groups of coincident points (zero distances, index ties) next to a sparse fringe whose 27
  // cells hold too few points.
  std::vector<Vec3> pts;
  for (int j = 0; j < 12; ++j)
    for (int i = 0; i < 12; ++i)
      for (int copy = 0; copy < ((i + j) % 3 == 0 ? 14 : 1); ++copy)
        pts.emplace_back(i * 0.5, j * 0.5, 0.05 * std::sin(i + 2.0 * j));
  for (int i = 0; i < 8; ++i) pts.emplace_back(20.0 + 3.0 * i, 0.0, 0.1 * i * i);
  recon::PointGrid grid;
  grid.build(pts, 1.25);
  const std::size_t k = 12;
  const auto f = recon::estimate_frames(pts, grid);
  for (std::size_t i = 0; i < 144 * 5; ++i) {  // the grid part (the fringe has other rings)
    if (pts[i].x() > 10) continue;
    const auto nb = brute_knn(pts, i, k);
    double spacing = 0;
    for (std::size_t q = 0; q < 6; ++q) spacing += (pts[nb[q]] - pts[i]).norm() / 6;
    REQUIRE(f.spacing[i] == Approx(spacing).margin(1e-6));
  }
  for (const auto& n : f.normal) REQUIRE(std::abs(n.norm() - 1.0f) < 1e-5f);
}

TEST_CASE("estimate_frames: a view point orients every normal towards it", "[recon]") {
  const auto pts = scanmesh::test::sphere_points(800, 5.0);
  recon::PointGrid grid;
  grid.build(pts, 2.0);
  recon::NormalOptions opt;
  opt.view_point = Vec3(0, 0, 100);
  const auto f = recon::estimate_frames(pts, grid, opt);
  for (std::size_t i = 0; i < pts.size(); ++i)
    REQUIRE(f.normal[i].cast<double>().dot(*opt.view_point - pts[i]) >= 0);
}

TEST_CASE("estimate_frames: each part the propagation orients faces its own sensors",
          "[recon]") {
  // Two bowls (paraboloid caps) far apart, each scanned from its own side: the left one from
  // below, the right one from above. Without sensor directions both face +z at their highest
  // point (inwards for the left bowl's inside, as the convention goes).
  std::vector<Vec3> pts, towards;
  for (int i = -12; i <= 12; ++i)
    for (int j = -12; j <= 12; ++j) {
      const double x = 0.5 * i, y = 0.5 * j, z = 0.05 * (x * x + y * y);
      pts.emplace_back(x - 20, y, z);
      towards.emplace_back(0.1, 0, -1);  // sensor below (not exactly along the axis)
      pts.emplace_back(x + 20, y, z);
      towards.emplace_back(0, 0.2, 1);  // sensor above
    }
  recon::PointGrid grid;
  grid.build(pts, 1.25);
  const auto plain = recon::estimate_frames(pts, grid);
  const auto faced = recon::estimate_frames(pts, grid, {}, towards);
  std::size_t plain_up = 0, facing = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    plain_up += plain.normal[i].z() > 0 ? 1 : 0;
    facing += faced.normal[i].cast<double>().dot(towards[i]) > 0 ? 1 : 0;
    // The same axes: only signs differ.
    REQUIRE(std::abs(std::abs(plain.normal[i].dot(faced.normal[i])) - 1.0f) < 1e-5f);
  }
  CHECK(plain_up == pts.size());
  CHECK(facing == pts.size());
  // A wrong count of directions is ignored (the plain propagation).
  const auto ignored = recon::estimate_frames(pts, grid, {}, std::span(towards).first(3));
  for (std::size_t i = 0; i < pts.size(); ++i) REQUIRE(ignored.normal[i] == plain.normal[i]);
}

// --- grid
// ------------------------------------------------------------------------------------------

TEST_CASE("PointGrid visits every point within the cell radius, in cell order", "[recon]") {
  struct Cloud {
    std::vector<Vec3> pts;
    double cell;
  };
  // A compact box (every cell's first slot in one array), a long bar (rows indexed, cells
  // searched within a row: the box has too many cells) and sparse clusters (hashed rows).
  std::vector<Vec3> bar = random_box(3000, 4.0, 13);
  for (Vec3& p : bar) p.x() *= 1000.0;
  const std::vector<Cloud> clouds = {{random_box(3000, 10.0, 10), 0.7},
                                     {bar, 0.7},
                                     {sparse_clusters(100, 5, 3000.0, 2.0, 11), 1.0}};
  for (const Cloud& c : clouds) {
    recon::PointGrid grid;
    grid.build(c.pts, c.cell);
    const auto& order = grid.order();
    // order(): a permutation sorted by (cell z, y, x, index), cells counted from min - cell.
    REQUIRE(order.size() == c.pts.size());
    const Vec3 origin = bbox_min(c.pts) - Vec3::Constant(c.cell);
    const double inv = 1.0 / c.cell;
    auto key = [&](std::uint32_t i) {
      const Vec3 g = (c.pts[i] - origin) * inv;
      return std::make_tuple(std::floor(g.z()), std::floor(g.y()), std::floor(g.x()), i);
    };
    for (std::size_t s = 1; s < order.size(); ++s) REQUIRE(key(order[s - 1]) < key(order[s]));

    std::mt19937 rng(12);
    std::uniform_int_distribution<std::size_t> pick(0, c.pts.size() - 1);
    std::normal_distribution<double> jitter(0.0, c.cell);
    for (int q = 0; q < 200; ++q) {
      const Vec3 p = c.pts[pick(rng)] + Vec3(jitter(rng), jitter(rng), jitter(rng));
      std::vector<std::uint32_t> seen;
      grid.for_each_near(p, 1, [&](std::uint32_t j) { seen.push_back(j); });
      std::set<std::uint32_t> unique(seen.begin(), seen.end());
      REQUIRE(unique.size() == seen.size());
      const double radius = c.cell * (0.3 + 0.5 * (q % 5));
      std::set<std::uint32_t> in_ranges;
      grid.for_each_range_within(p, radius, [&](std::uint32_t b, std::uint32_t e) {
        for (std::uint32_t s = b; s < e; ++s) in_ranges.insert(order[s]);
      });
      for (std::uint32_t j = 0; j < c.pts.size(); ++j) {
        const double d = (c.pts[j] - p).norm();
        if (d <= c.cell) REQUIRE(unique.count(j) == 1);
        if (d <= radius) REQUIRE(in_ranges.count(j) == 1);
      }
    }
  }
}

TEST_CASE("PointGrid::renumber_in_order is the grid built on the points permuted into its order",
          "[recon]") {
  std::vector<Vec3> bar = random_box(2000, 4.0, 21);
  for (Vec3& p : bar) p.x() *= 1000.0;
  const std::vector<std::pair<std::vector<Vec3>, double>> clouds = {
      {random_box(2000, 10.0, 20), 0.7}, {bar, 0.7}, {sparse_clusters(80, 5, 3000.0, 2.0, 22), 1.0}};
  for (const auto& [pts, cell] : clouds) {
    recon::PointGrid grid;
    grid.build(pts, cell);
    std::vector<Vec3> sorted(pts.size());
    for (std::size_t s = 0; s < pts.size(); ++s) sorted[s] = pts[grid.order()[s]];
    grid.renumber_in_order();
    recon::PointGrid fresh;
    fresh.build(sorted, cell);
    REQUIRE(grid.order() == fresh.order());
    for (std::size_t s = 0; s < pts.size(); ++s) REQUIRE(grid.order()[s] == s);
    // Same answers to the queries on the permuted points.
    for (std::size_t q = 0; q < sorted.size(); q += 97) {
      std::vector<std::uint32_t> a, b;
      grid.for_each_near(sorted[q], 1, [&](std::uint32_t j) { a.push_back(j); });
      fresh.for_each_near(sorted[q], 1, [&](std::uint32_t j) { b.push_back(j); });
      REQUIRE(a == b);
      REQUIRE(!a.empty());
    }
  }
}
