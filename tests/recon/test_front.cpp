// Reconstruction of synthetic clouds with known topology, degenerate inputs and determinism.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "support/shapes.hpp"

using scanmesh::GeometryError;
using scanmesh::recon::analyze;
using scanmesh::recon::MeshReport;
using scanmesh::recon::reconstruct;
using scanmesh::recon::ReconstructOptions;
using scanmesh::recon::ReconstructResult;
using scanmesh::recon::Vec3;
namespace test = scanmesh::test;

namespace {

/// The invariants every output must satisfy (issue #2, "output guarantees").
void require_valid(const ReconstructResult& r, const MeshReport& rep) {
  REQUIRE(rep.triangles > 0);
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.non_manifold_vertices == 0);
  CHECK(rep.orientation_consistent);
  CHECK(rep.degenerate_triangles == 0);
  CHECK(rep.duplicate_triangles == 0);
  CHECK(rep.referenced_vertices == r.mesh.vertices.size());
  CHECK(static_cast<double>(r.mesh.vertices.size()) >= 0.99 * static_cast<double>(r.reduced_points));
}

/// Largest distance of a triangle centroid from the sphere of radius rad at c.
double max_centroid_error(const scanmesh::recon::Mesh& m, double rad, const Vec3& c) {
  double worst = 0;
  for (const auto& t : m.triangles) {
    const Vec3 g = (m.vertices[t[0]] + m.vertices[t[1]] + m.vertices[t[2]]) / 3.0;
    worst = std::max(worst, std::abs((g - c).norm() - rad));
  }
  return worst;
}

}  // namespace

TEST_CASE("closed sphere: no boundary, genus 0, outward, close to the surface", "[recon]") {
  const auto pts = test::sphere_points(20000, 10.0);
  const auto r = reconstruct(pts);
  const auto rep = analyze(r.mesh);
  require_valid(r, rep);
  CHECK(rep.boundary_loops == 0);
  CHECK(rep.components == 1);
  CHECK(rep.genus == 0);
  CHECK(rep.signed_volume > 0);  // outward
  // Volume within 1% of the ball's; chords cut inside by less than a fraction of the spacing.
  CHECK(rep.signed_volume == Approx(4.0 / 3.0 * M_PI * 1000.0).epsilon(0.01));
  CHECK(max_centroid_error(r.mesh, 10.0, Vec3::Zero()) < 0.5 * r.cube_mm);
  CHECK(rep.frac_min_angle_below_10 < 0.001);
}

TEST_CASE("sphere with one cap removed has exactly one boundary loop", "[recon]") {
  std::vector<Vec3> pts;
  for (const Vec3& p : test::sphere_points(20000, 10.0))
    if (p.z() < 7.0) pts.push_back(p);
  std::vector<std::string> stages;
  const auto r = reconstruct(pts, {}, [&](std::string_view s) { stages.emplace_back(s); });
  const auto rep = analyze(r.mesh);
  require_valid(r, rep);
  CHECK(rep.boundary_loops == 1);
  CHECK(rep.components == 1);
  CHECK(rep.genus == 0);
  // The loop runs along the cut: every boundary vertex is near z = 7.
  CHECK(rep.boundary_loop_lengths.front() > 50);
  // A border is no sampling gap: the gap stage is not even entered.
  CHECK(r.gaps.filled == 0);
  CHECK(std::find(stages.begin(), stages.end(), "gaps") == stages.end());
  CHECK(std::find(stages.begin(), stages.end(), "front") != stages.end());
}

TEST_CASE("open cylinder as a 5:1 anisotropic raster scan has exactly two loops", "[recon]") {
  // Rings every 1 mm along the axis, samples every 0.2 mm along each ring.
  const auto pts = test::cylinder_raster(10.0, 20.0, 0.2, 1.0);
  const auto r = reconstruct(pts);
  const auto rep = analyze(r.mesh);
  require_valid(r, rep);
  CHECK(rep.boundary_loops == 2);
  CHECK(rep.components == 1);
  CHECK(rep.genus == 0);
  // No triangle spans more than two scan lines.
  CHECK(rep.max_edge_length < 2.5);
}

TEST_CASE("open cylinder as a 40:1 raster scan (a point sensor's lines) has exactly two loops",
          "[recon]") {
  // Rings every 2 mm, samples every 0.05 mm along each ring: the next ring lies beyond the
  // spacing estimate's first reach, and before stop 38 no point was meshed at all.
  const auto pts = test::cylinder_raster(10.0, 40.0, 0.05, 2.0);
  const auto r = reconstruct(pts);
  const auto rep = analyze(r.mesh);
  require_valid(r, rep);
  CHECK(r.spacing.cross_mm == Approx(2.0).epsilon(0.02));
  CHECK(rep.boundary_loops == 2);
  CHECK(rep.components == 1);
  CHECK(rep.genus == 0);
  CHECK(r.outliers.empty());
  CHECK(rep.max_edge_length < 5.0);  // no triangle spans more than two rings
}

// Exactly collinear points (a scan line) put a front vertex exactly on a new triangle's edge, or
// a candidate exactly on a front edge: the front's edge tests must count touching as crossing.
// With strict signs these surfaces came out with hundreds of crossing pairs and 15-36 loops.
TEST_CASE("straight scan lines (exactly collinear points) mesh without overlaps", "[recon]") {
  for (std::uint32_t seed : {0u, 1u, 2u}) {
    ReconstructOptions opt;
    opt.cube_mode = ReconstructOptions::CubeMode::kNone;
    const auto r = reconstruct(test::ruled_scan_lines(1.0, 1.5, seed), opt);
    const auto rep = analyze(r.mesh);
    INFO("seed " << seed);
    require_valid(r, rep);
    CHECK(scanmesh::recon::find_self_intersections(r.mesh).pairs == 0);
    CHECK(rep.boundary_loops == 1);
    CHECK(rep.components == 1);
  }
}

TEST_CASE("open scans face their sensors when the directions are given", "[recon]") {
  // Two bowls far apart, the left one scanned from below, the right one from above.
  std::vector<Vec3> pts, towards;
  for (int i = -20; i <= 20; ++i)
    for (int j = -20; j <= 20; ++j) {
      const double x = 0.3 * i, y = 0.3 * j, z = 0.05 * (x * x + y * y);
      pts.emplace_back(x - 20, y, z);
      towards.emplace_back(0, 0, -1);
      pts.emplace_back(x + 20, y, z);
      towards.emplace_back(0, 0, 1);
    }
  auto facing_down = [](const ReconstructResult& r, bool left) {
    std::size_t down = 0, total = 0;
    for (const auto& t : r.mesh.triangles) {
      const Vec3& a = r.mesh.vertices[t[0]];
      if ((a.x() < 0) != left) continue;
      const Vec3 n = (r.mesh.vertices[t[1]] - a).cross(r.mesh.vertices[t[2]] - a);
      down += n.z() < 0 ? 1 : 0;
      ++total;
    }
    return static_cast<double>(down) / static_cast<double>(total);
  };
  const ReconstructResult faced = reconstruct(pts, {}, {}, towards);
  const MeshReport r = analyze(faced.mesh);
  CHECK(r.components == 2);
  CHECK(r.boundary_loops == 2);
  CHECK(r.orientation_consistent);
  CHECK(facing_down(faced, true) == 1.0);   // towards the sensor below
  CHECK(facing_down(faced, false) == 0.0);  // towards the sensor above
  // Without the directions both face +z, the convention for open parts.
  const ReconstructResult plain = reconstruct(pts);
  CHECK(facing_down(plain, true) == 0.0);
  CHECK(facing_down(plain, false) == 0.0);
  // One direction per point, or none.
  CHECK_THROWS_AS(reconstruct(pts, {}, {}, std::span(towards).first(5)), scanmesh::ConfigError);
}

TEST_CASE("cube with sharp edges closes", "[recon]") {
  const auto pts = test::cube_points(10.0, 0.25);
  const auto r = reconstruct(pts);
  const auto rep = analyze(r.mesh);
  require_valid(r, rep);
  CHECK(rep.boundary_loops == 0);
  CHECK(rep.components == 1);
  CHECK(rep.genus == 0);
  CHECK(rep.signed_volume == Approx(1000.0).epsilon(0.01));
}

// The crossing guard tests new triangles against everything near them only around turning
// points (a point within reach whose normal is more than 60 degrees away): none on a smooth
// sphere, a band along a cube's edges, every point of a plate whose two faces are 1.6 spacings
// apart. No output crosses itself.
TEST_CASE("turning points: none on a sphere, a cube's edges, all of a thin plate", "[recon]") {
  const auto sphere = reconstruct(test::sphere_points(20000, 10.0));
  CHECK(sphere.turning_points == 0);
  CHECK(scanmesh::recon::find_self_intersections(sphere.mesh).pairs == 0);

  const auto cube = reconstruct(test::cube_points(10.0, 0.25));
  INFO("cube: " << cube.turning_points << " turning of " << cube.reduced_points);
  CHECK(cube.turning_points > 0);
  CHECK(cube.turning_points < cube.reduced_points / 2);
  CHECK(scanmesh::recon::find_self_intersections(cube.mesh).pairs == 0);

  // A 10 x 10 plate 0.4 thick sampled every 0.25 on all six faces.
  std::vector<Vec3> plate;
  const double h = 0.25, t = 0.4;
  for (int i = 0; i <= 40; ++i)
    for (int j = 0; j <= 40; ++j) {
      plate.emplace_back(i * h, j * h, 0.0);
      plate.emplace_back(i * h, j * h, t);
    }
  for (int i = 0; i <= 40; ++i)
    for (double z : {t / 3, 2 * t / 3}) {
      plate.emplace_back(i * h, 0.0, z);
      plate.emplace_back(i * h, 10.0, z);
      if (i > 0 && i < 40) {
        plate.emplace_back(0.0, i * h, z);
        plate.emplace_back(10.0, i * h, z);
      }
    }
  ReconstructOptions opt;
  opt.cube_mode = ReconstructOptions::CubeMode::kNone;  // every point
  const auto r = reconstruct(plate, opt);
  const auto rep = analyze(r.mesh);
  INFO("plate: " << r.turning_points << " turning of " << r.reduced_points << ", genus " << rep.genus
                 << ", loops " << rep.boundary_loops);
  CHECK(r.turning_points == r.reduced_points);
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.non_manifold_vertices == 0);
  CHECK(rep.orientation_consistent);
  CHECK(scanmesh::recon::find_self_intersections(r.mesh).pairs == 0);
}

// The touching clearance grows with the coordinates (float roundings of the largest one) but is
// capped by the spacing: a part far from the origin (machine coordinates) meshes as at home.
TEST_CASE("a sphere far from the origin closes as it does at the origin", "[recon]") {
  const auto r = reconstruct(test::sphere_points(20000, 10.0, Vec3(1e6, -1e6, 2e6)));
  const auto rep = analyze(r.mesh);
  require_valid(r, rep);
  CHECK(rep.boundary_loops == 0);
  CHECK(rep.components == 1);
  CHECK(rep.genus == 0);
}

TEST_CASE("two separate objects give two closed components", "[recon]") {
  auto pts = test::sphere_points(5000, 5.0, Vec3(0, 0, 0));
  const auto b = test::sphere_points(5000, 5.0, Vec3(20, 0, 0));
  pts.insert(pts.end(), b.begin(), b.end());
  const auto r = reconstruct(pts);
  const auto rep = analyze(r.mesh);
  require_valid(r, rep);
  CHECK(rep.components == 2);
  CHECK(rep.boundary_loops == 0);
  CHECK(rep.signed_volume > 0);
}

// A closed surface needs many bulk patches (each within a 30-degree cone): they meet
// everywhere, and the front still closes the sphere without a seam left open.
TEST_CASE("noisy sphere still closes", "[recon]") {
  auto pts = test::sphere_points(20000, 10.0);
  test::add_noise(pts, 0.03, 7);
  const auto r = reconstruct(pts);
  const auto rep = analyze(r.mesh);
  require_valid(r, rep);
  CHECK(rep.boundary_loops == 0);
  CHECK(rep.components == 1);
  CHECK(rep.genus == 0);
  CHECK(max_centroid_error(r.mesh, 10.0, Vec3::Zero()) < r.cube_mm);
  CHECK(find_self_intersections(r.mesh).pairs == 0);
  CHECK(r.bulk_patches >= 8);
  CHECK(r.bulk_triangles > r.mesh.triangles.size() / 2);
}

TEST_CASE("cube options: none keeps every distinct point, a fixed cube reduces", "[recon]") {
  auto pts = test::sphere_points(8000, 10.0);
  pts.push_back(pts.front());  // an exact duplicate collapses even without reduction
  ReconstructOptions none;
  none.cube_mode = ReconstructOptions::CubeMode::kNone;
  const auto rn = reconstruct(pts, none);
  CHECK(rn.reduced_points == 8000);
  ReconstructOptions fixed;
  fixed.cube_mode = ReconstructOptions::CubeMode::kFixed;
  fixed.cube_mm = 1.0;
  const auto rf = reconstruct(pts, fixed);
  CHECK(rf.reduced_points < 8000);
  CHECK(rf.cube_mm == 1.0);
  CHECK(analyze(rf.mesh).boundary_loops == 0);
}

TEST_CASE("a scan whose every reading repeats many times meshes like its distinct points",
          "[recon]") {
  // A point sensor at rest streams the same reading (and quantised readings repeat): each point
  // 40 times over. The copies used to hide every neighbour from the spacing estimate, which
  // then failed the scan ("cube size too small"; without cubes "too far for one grid").
  const auto distinct = test::sphere_points(3000, 10.0);
  std::vector<Vec3> pts;
  for (int copy = 0; copy < 40; ++copy) pts.insert(pts.end(), distinct.begin(), distinct.end());
  for (const auto mode : {ReconstructOptions::CubeMode::kAuto, ReconstructOptions::CubeMode::kNone}) {
    ReconstructOptions opt;
    opt.cube_mode = mode;
    const auto r = reconstruct(pts, opt);
    const auto rep = analyze(r.mesh);
    require_valid(r, rep);
    CHECK(rep.boundary_loops == 0);
    CHECK(rep.components == 1);
    CHECK(rep.genus == 0);
    CHECK(r.cube_mm == reconstruct(distinct, opt).cube_mm);
    if (mode == ReconstructOptions::CubeMode::kNone) CHECK(r.reduced_points == distinct.size());
  }
}

// The bulk: planar Delaunay patches (normals within a 30-degree cone) give most triangles of a
// gently curved surface; the front starts from their borders, zips the seams between patches
// and meshes the rest. Same guarantees, a fraction of the front's work.
// Stale queue entries run edges again; an edge that found no candidate (most often a sliver
// gap of three edges waiting for the end) is not scanned again while the front only grows.
// Debug builds (the sanitizer job) still scan and assert that nothing is found.
TEST_CASE("a jittered height field meshes whole from the bulk's Delaunay patches; the front "
          "closes the seams and does not rescan edges without candidates",
          "[recon]") {
  ReconstructOptions opt;
  opt.cube_mode = ReconstructOptions::CubeMode::kNone;
  const auto pts = test::jittered_height_field(120, 7);
  ReconstructOptions no_bulk = opt;
  no_bulk.front.bulk = false;
  const auto plain = reconstruct(pts, no_bulk);
  {  // the front alone
    const auto rep = analyze(plain.mesh);
    require_valid(plain, rep);
    CHECK(rep.boundary_loops == 1);
    CHECK(rep.components == 1);
    CHECK(rep.genus == 0);
    CHECK(plain.bulk_triangles == 0);
    CHECK(plain.skipped_evaluations > 0);
  }
  // One patch; then many (at most 500 points each), so that the front has seams to close.
  for (const std::size_t patch_points : {std::size_t{1} << 17, std::size_t{500}}) {
    INFO("patches of at most " << patch_points << " points");
    opt.front.bulk_patch_points = patch_points;
    const auto r = reconstruct(pts, opt);
    const auto rep = analyze(r.mesh);
    require_valid(r, rep);
    CHECK(rep.boundary_loops == 1);
    CHECK(rep.components == 1);
    CHECK(rep.genus == 0);
    CHECK(find_self_intersections(r.mesh).pairs == 0);
    CHECK(r.mesh.vertices.size() == pts.size());  // every point used
    if (patch_points > pts.size()) {
      CHECK(r.bulk_patches == 1);
      CHECK(r.skipped_evaluations > 0);
    } else {
      CHECK(r.bulk_patches >= pts.size() / patch_points);
    }
    CHECK(r.bulk_triangles > r.mesh.triangles.size() * 8 / 10);
    CHECK(r.edge_evaluations * 3 < plain.edge_evaluations);
  }
}

TEST_CASE("reconstruction is deterministic", "[recon]") {
  auto pts = test::sphere_points(6000, 10.0);
  test::add_noise(pts, 0.02, 3);
  const auto a = reconstruct(pts);
  const auto b = reconstruct(pts);
  REQUIRE(a.mesh.vertices.size() == b.mesh.vertices.size());
  CHECK(a.mesh.triangles == b.mesh.triangles);
  CHECK(a.mesh.vertices == b.mesh.vertices);
}

TEST_CASE("the observer hears the stages and the front's steps in order; the mesh is the same",
          "[recon]") {
  const auto pts = test::sphere_points(6000, 10.0);
  std::vector<std::string> heard;
  const auto observed = reconstruct(pts, ReconstructOptions{}, [&](std::string_view stage) {
    heard.emplace_back(stage);
  });
  const std::vector<std::string> expected{
      "reduce",       "normals",       "front",           "front/setup",
      "front/turning", "front/bulk",   "front/growth",    "front/repairs",
      "front/fan check", "front/orientation", "refine",   "output",
      "done"};
  CHECK(heard == expected);
  const auto plain = reconstruct(pts);
  CHECK(observed.mesh.triangles == plain.mesh.triangles);
  CHECK(observed.mesh.vertices == plain.mesh.vertices);
}

TEST_CASE("degenerate inputs give clear errors", "[recon]") {
  using Catch::Matchers::Contains;
  const std::vector<Vec3> empty;
  CHECK_THROWS_WITH(reconstruct(empty), Contains("empty"));
  CHECK_THROWS_WITH(reconstruct(std::vector<Vec3>{Vec3(1, 2, 3)}), Contains("distinct"));
  CHECK_THROWS_WITH(reconstruct(std::vector<Vec3>{Vec3(0, 0, 0), Vec3(1, 0, 0)}),
                    Contains("distinct"));
  std::vector<Vec3> same(100, Vec3(1, 1, 1));
  CHECK_THROWS_WITH(reconstruct(same), Contains("distinct"));
  std::vector<Vec3> line;
  for (int i = 0; i < 100; ++i) line.emplace_back(i, 2.0 * i, -i);
  CHECK_THROWS_WITH(reconstruct(line), Contains("collinear"));
  auto nan = test::sphere_points(100);
  nan[17].y() = std::numeric_limits<double>::quiet_NaN();
  CHECK_THROWS_WITH(reconstruct(nan), Contains("non-finite") && Contains("#17"));
  auto inf = test::sphere_points(100);
  inf[3].x() = std::numeric_limits<double>::infinity();
  CHECK_THROWS_AS(reconstruct(inf), GeometryError);
  // Three points make exactly one triangle.
  const auto tri = reconstruct(std::vector<Vec3>{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)});
  CHECK(tri.mesh.triangles.size() == 1);
  ReconstructOptions bad;
  bad.cube_mode = ReconstructOptions::CubeMode::kFixed;
  bad.cube_mm = -1;
  CHECK_THROWS_AS(reconstruct(test::sphere_points(100), bad), scanmesh::ConfigError);
  // A patch cone of 90 degrees or more would not make the patch a height field.
  for (const double cone : {0.0, 90.0, 120.0}) {
    ReconstructOptions wide;
    wide.front.bulk_patch_cone_deg = cone;
    CHECK_THROWS_WITH(reconstruct(test::sphere_points(100), wide), Contains("bulk_patch_cone_deg"));
  }
}

TEST_CASE("coordinates the geometry cannot square give clear errors", "[recon]") {
  using Catch::Matchers::Contains;
  std::vector<Vec3> huge, tiny;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) {
      huge.emplace_back(1e300 * i, 1e300 * j, 0);
      tiny.emplace_back(1e-300 * i, 1e-300 * j, 1e-301 * std::sin(i));
    }
  CHECK_THROWS_WITH(reconstruct(huge), Contains("beyond +-1e100") && Contains("#1)"));
  CHECK_THROWS_WITH(reconstruct(tiny), Contains("spans only") && Contains("scale the input"));
}

// A flat, slightly wavy plate of 60 x 60 points at spacing 1.
static std::vector<Vec3> plate_points() {
  std::vector<Vec3> pts;
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 60; ++j) pts.emplace_back(i, j + 0.3 * (i % 2), 0.4 * std::sin(0.2 * i));
  return pts;
}

TEST_CASE("stray readings far outside the cloud become outliers, not a failed scan", "[recon]") {
  using Catch::Matchers::Contains;
  const auto plate = plate_points();
  const auto ref = reconstruct(plate);
  // A glitched reading and a sensor's out-of-range sentinel: without the split, the extent
  // needs over 2 million cubes per axis and the whole scan failed.
  auto pts = plate;
  pts.insert(pts.begin() + 1000, Vec3(1e9, 1e9, 1e9));
  pts.emplace_back(0, 0, 9.9e37);
  std::vector<Vec3> sensor(pts.size(), Vec3(0, 0, 1));
  for (const auto cube : {ReconstructOptions::CubeMode::kAuto, ReconstructOptions::CubeMode::kNone}) {
    ReconstructOptions opt;
    opt.cube_mode = cube;
    const auto r = reconstruct(pts, opt, {}, sensor);
    const MeshReport rep = analyze(r.mesh);
    require_valid(r, rep);
    CHECK(r.input_points == plate.size() + 2);
    CHECK(r.far_points == 2);
    REQUIRE(r.outliers.size() >= 2);
    // The far points are the last outliers, as they were read.
    CHECK(r.outliers[r.outliers.size() - 2] == Vec3(1e9, 1e9, 1e9));
    CHECK(r.outliers.back() == Vec3(0, 0, 9.9e37));
    CHECK(rep.boundary_loops == 1);
    CHECK(rep.components == 1);
    if (cube == ReconstructOptions::CubeMode::kAuto) {
      // The rest is meshed exactly as without the strays.
      CHECK(r.mesh.vertices == ref.mesh.vertices);
      CHECK(r.mesh.triangles == ref.mesh.triangles);
    }
  }
  // More than 1 % far away is not stray readings: a clear error, nothing dropped silently.
  auto many = plate;
  for (int k = 0; k < 40; ++k) many.emplace_back(1e7 + k, 5, 5);
  CHECK_THROWS_WITH(reconstruct(many), Contains("40 of 3640 points") &&
                                           Contains("far outside the body"));
  // A cloud that fits is never split, however far apart its parts: two plates 10^4 apart.
  auto two = plate;
  for (const Vec3& p : plate) two.push_back(p + Vec3(1e4, 0, 0));
  const auto r2 = reconstruct(two);
  CHECK(r2.far_points == 0);
  CHECK(analyze(r2.mesh).components == 2);
}

TEST_CASE("without cubes, a long scan keeps every point", "[recon]") {
  // 5,000 spacings long: the duplicate collapse's grid (a thousandth of the spacing) would need
  // 5 million cells per axis; it takes the cell that fits instead (here 0.0033 spacings).
  std::vector<Vec3> strip;
  for (int i = 0; i < 5000; ++i)
    for (int j = 0; j < 6; ++j) strip.emplace_back(i, j, 50 * std::sin(0.001 * i));
  ReconstructOptions none;
  none.cube_mode = ReconstructOptions::CubeMode::kNone;
  const auto r = reconstruct(strip, none);
  const MeshReport rep = analyze(r.mesh);
  require_valid(r, rep);
  CHECK(r.reduced_points == strip.size());
  CHECK(r.mesh.vertices.size() == strip.size());
  CHECK(rep.boundary_loops == 1);
  // Beyond 150,000 spacings the collapse would merge real points: a clear error instead.
  std::vector<Vec3> far_apart = plate_points();
  for (int k = 0; k < 60; ++k) far_apart.emplace_back(2e5 + k, 0, 0);
  for (int k = 0; k < 3600; ++k) far_apart.push_back(far_apart[k] + Vec3(4e5, 0, 0));
  CHECK_THROWS_WITH(reconstruct(far_apart, none), Catch::Matchers::Contains("150,000 times"));
}

// A detail pass beside an overview pass: most of the points sample one part of the surface
// densely, the rest is sampled `ratio` times more coarsely. With the spacing capped at 2.5 times
// the whole cloud's median, the coarse part fell apart beyond about 5 times (at 6: 683 pieces
// and 1,467 points left out of a 100,000-point plate); the cap now follows the median of the
// region around each point.
static std::vector<Vec3> two_density_plate(double ratio) {
  auto height = [](double x, double y) { return 2.0 * std::sin(x / 15) * std::cos(y / 20); };
  auto jitter = [](std::uint32_t k) {  // deterministic, in [-0.5, 0.5)
    k ^= k >> 16;
    k *= 0x7feb352dU;
    k ^= k >> 15;
    k *= 0x846ca68bU;
    k ^= k >> 16;
    return static_cast<double>(k) / 4294967296.0 - 0.5;
  };
  std::vector<Vec3> pts;
  std::uint32_t k = 0;
  const double h = 0.2;
  for (int i = 0; i < 100; ++i)  // dense: x in [0, 20), 25,000 points
    for (int j = 0; j < 250; ++j) {
      const double x = i * h + 0.2 * h * jitter(k++), y = j * h + 0.2 * h * jitter(k++);
      pts.emplace_back(x, y, height(x, y));
    }
  const double coarse = ratio * h;
  for (double x0 = 20; x0 < 50; x0 += coarse)  // coarse: x in [20, 50)
    for (double y0 = 0; y0 < 50; y0 += coarse) {
      const double x = x0 + 0.2 * coarse * jitter(k++), y = y0 + 0.2 * coarse * jitter(k++);
      pts.emplace_back(x, y, height(x, y));
    }
  return pts;
}

TEST_CASE("a region sampled many times more coarsely than the rest connects", "[recon]") {
  for (const double ratio : {6.0, 12.0, 15.0}) {
    CAPTURE(ratio);
    const auto pts = two_density_plate(ratio);
    const auto r = reconstruct(pts);
    const MeshReport rep = analyze(r.mesh);
    require_valid(r, rep);
    CHECK(rep.components == 1);
    CHECK(r.outliers.empty());
    CHECK(r.mesh.vertices.size() == r.reduced_points);
    CHECK(scanmesh::recon::find_self_intersections(r.mesh).pairs == 0);
    // The plate's border, and at most a gap along the seam between the two samplings (a row of
    // 0.2 spacings meeting one of `ratio` times that cannot be joined with angles of 8 degrees
    // or more everywhere: the front leaves slits, a coarse edge with the dense row's points
    // along it, which zip_slits closes, and fans of many dense points onto a coarse one, which
    // the gap closing takes up to 64 edges). Measured 1 loop at each ratio; 1, 2 and 4 with
    // gaps of at most 8 edges; at 6 and 12, 4 and 4 before the zipping, 4 and 9 while the gap
    // closing took a loop's spacing as the mean over its vertices.
    CHECK(rep.boundary_loops <= 2);
    CHECK(r.zip.zipped >= 1);
    // No triangle longer than the coarse region's own reach (relaxed radius factor 2.6, a
    // candidate up to 1.5 spacings further, the jitter).
    double longest = 0;
    for (const auto& t : r.mesh.triangles)
      for (int e = 0; e < 3; ++e)
        longest = std::max(longest, (r.mesh.vertices[t[e]] - r.mesh.vertices[t[(e + 1) % 3]]).norm());
    CHECK(longest < 2.6 * 1.5 * 1.2 * ratio * 0.2);
  }
}

// Stray readings scattered in the air over a plate are sparse too, as sparse as their
// neighbours: they must not count as a sparsely sampled region (their scatter is no plane).
// With a cap taken from the grid cells around each point they did, and meshed into pieces of
// their own with triangles of their own spacing (about 10 here). A few of them still mesh
// together at the cloud's cap (recon/README, Known limits, Spikes).
TEST_CASE("stray readings in the air over a scan keep the cloud's spacing cap", "[recon]") {
  auto pts = plate_points();
  const std::size_t plate = pts.size();
  std::uint32_t k = 12345;
  auto next = [&k] {  // deterministic, in [0, 1)
    k = k * 1664525U + 1013904223U;
    return static_cast<double>(k >> 8) / 16777216.0;
  };
  for (int i = 0; i < 150; ++i) pts.emplace_back(60 * next(), 60 * next(), 3 + 40 * next());
  const auto r = reconstruct(pts);
  const MeshReport rep = analyze(r.mesh);
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.orientation_consistent);
  std::size_t on_plate = 0;
  for (const Vec3& v : r.mesh.vertices) on_plate += std::abs(v.z()) <= 1.0 ? 1 : 0;
  CHECK(on_plate >= plate - 2);
  // The plate's spacing is about 1.1: no edge beyond the relaxed reach at its cap
  // (2.6 x 1.5 x 2.5 x 1.1 = 10.7).
  double longest = 0;
  for (const auto& t : r.mesh.triangles)
    for (int e = 0; e < 3; ++e)
      longest = std::max(longest, (r.mesh.vertices[t[e]] - r.mesh.vertices[t[(e + 1) % 3]]).norm());
  CHECK(longest < 10.7);
}

TEST_CASE("a lone triangle of stray points beside the part is dropped, its points outliers",
          "[recon]") {
  // Three readings close together, well off a sphere (a sensor's spikes that landed near each
  // other): a seed triangle there cannot grow.
  auto pts = test::sphere_points(20000, 10.0);
  const Vec3 stray[3] = {Vec3(16, 0, 0), Vec3(16.3, 0, 0), Vec3(16.15, 0.26, 0)};
  pts.insert(pts.end(), std::begin(stray), std::end(stray));
  const auto r = reconstruct(pts);
  const auto rep = analyze(r.mesh);
  require_valid(r, rep);
  CHECK(r.dropped_specks == 1);
  CHECK(rep.components == 1);
  CHECK(rep.boundary_loops == 0);
  for (const Vec3& s : stray) {
    CHECK(std::count(r.outliers.begin(), r.outliers.end(), s) == 1);
    CHECK(std::count(r.mesh.vertices.begin(), r.mesh.vertices.end(), s) == 0);
  }

  // A cloud that is only such a triangle keeps it (every point: the auto cube would merge two).
  const std::vector<Vec3> alone(std::begin(stray), std::end(stray));
  ReconstructOptions none;
  none.cube_mode = ReconstructOptions::CubeMode::kNone;
  const auto a = reconstruct(alone, none);
  CHECK(a.mesh.triangles.size() == 1);
  CHECK(a.dropped_specks == 0);
}
