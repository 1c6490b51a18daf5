// Noise removal: a noisy scan of a box comes out with flatter faces and its edges where they
// were, a noisy sphere closer to the sphere and no smaller, an open patch keeps its border; the
// triangles never change, nothing crosses, and a clean mesh is left exactly as it is.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <vector>

#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/denoise.hpp"
#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "support/shapes.hpp"

namespace {

using scanmesh::recon::analyze;
using scanmesh::recon::denoise_mesh;
using scanmesh::recon::DenoiseOptions;
using scanmesh::recon::DenoiseStats;
using scanmesh::recon::Mesh;
using scanmesh::recon::Vec3;

constexpr double kSide = 10, kStep = 0.5;

/// The box [0, kSide]^3's faces, half a step in from every edge (support/shapes.hpp).
std::vector<Vec3> box_points() { return scanmesh::test::box_face_points(kSide, kStep); }

/// Distance from p to the surface of the box [0, kSide]^3.
double box_distance(const Vec3& p) {
  const Vec3 c = Vec3::Constant(0.5 * kSide);
  const Vec3 q = (p - c).cwiseAbs() - Vec3::Constant(0.5 * kSide);
  const double outside = q.cwiseMax(0.0).norm();
  return outside > 0 ? outside : -q.maxCoeff();
}

/// Root mean square of the distances of the vertices that triangles use to a surface.
template <class Distance>
double rms_of(const Mesh& m, Distance distance) {
  std::vector<char> used(m.vertices.size(), 0);
  for (const auto& t : m.triangles)
    for (auto v : t) used[v] = 1;
  double s = 0;
  std::size_t n = 0;
  for (std::size_t v = 0; v < m.vertices.size(); ++v)
    if (used[v]) {
      const double d = distance(m.vertices[v]);
      s += d * d;
      ++n;
    }
  return std::sqrt(s / static_cast<double>(n));
}

/// Mean distance from points every 0.05 along the box's 12 edges to the mesh.
double edge_mean(const Mesh& m) {
  const scanmesh::recon::SurfaceDistance surface(m);
  double s = 0;
  std::size_t n = 0;
  const int steps = static_cast<int>(kSide / 0.05);
  for (int axis = 0; axis < 3; ++axis)
    for (const double a : {0.0, kSide})
      for (const double b : {0.0, kSide})
        for (int i = 0; i <= steps; ++i) {
          Vec3 p;
          p[axis] = i * 0.05;
          p[(axis + 1) % 3] = a;
          p[(axis + 2) % 3] = b;
          s += surface.distance(p);
          ++n;
        }
  return s / static_cast<double>(n);
}

void check_same_topology(const Mesh& before, const Mesh& after) {
  REQUIRE(after.triangles == before.triangles);
  REQUIRE(after.vertices.size() == before.vertices.size());
  const auto r0 = analyze(before), r1 = analyze(after);
  CHECK(r1.boundary_loops == r0.boundary_loops);
  CHECK(r1.genus == r0.genus);
  CHECK(r1.components == r0.components);
  CHECK(r1.orientation_consistent);
  CHECK(scanmesh::recon::find_self_intersections(after).pairs == 0);
}

Mesh mesh_all_points(const std::vector<Vec3>& points) {
  scanmesh::recon::ReconstructOptions ro;
  ro.cube_mode = scanmesh::recon::ReconstructOptions::CubeMode::kNone;
  return scanmesh::recon::reconstruct(points, ro).mesh;
}

}  // namespace

TEST_CASE("denoise: a noisy box's faces come out flatter, its edges where they were",
          "[denoise]") {
  auto points = box_points();
  scanmesh::test::add_noise(points, 0.02, 11);  // 4 % of the spacing
  const Mesh before = mesh_all_points(points);
  Mesh after = before;
  const DenoiseStats st = denoise_mesh(after);
  const double rms0 = rms_of(before, box_distance), rms1 = rms_of(after, box_distance);
  const double e0 = edge_mean(before), e1 = edge_mean(after);
  INFO("rms " << rms0 << " -> " << rms1 << "; edges " << e0 << " -> " << e1 << "; moved "
              << st.moved << " (" << st.refused << " refused, " << st.clamped
              << " clamped), mean " << st.mean_move << "; noise " << st.noise_deg
              << " deg, range " << st.feature_deg << " deg");
  CHECK(rms0 > 0.015);
  CHECK(rms1 < 0.5 * rms0);
  // The edges are not rounded off: they stay as far from the mesh as the bevels had them.
  CHECK(e1 < e0 + 0.01);
  CHECK(st.moved > 0.9 * static_cast<double>(after.vertices.size()));
  CHECK(st.max_move < 0.5 * kStep);
  CHECK(st.feature_deg == Approx(DenoiseOptions::kAutoFactor * st.noise_deg));
  check_same_topology(before, after);
}

TEST_CASE("denoise: a noisy sphere comes closer to the sphere and no smaller", "[denoise]") {
  constexpr double kR = 10;
  auto points = scanmesh::test::sphere_points(6000, kR);
  scanmesh::test::add_noise(points, 0.04, 5);  // about 4 % of the spacing
  const Mesh before = mesh_all_points(points);
  Mesh after = before;
  denoise_mesh(after);
  auto off = [&](const Vec3& p) { return p.norm() - kR; };
  const double rms0 = rms_of(before, off), rms1 = rms_of(after, off);
  double mean_r = 0;
  for (const Vec3& p : after.vertices) mean_r += p.norm();
  mean_r /= static_cast<double>(after.vertices.size());
  INFO("rms " << rms0 << " -> " << rms1 << "; mean radius " << mean_r);
  CHECK(rms1 < 0.6 * rms0);
  CHECK(std::abs(mean_r - kR) < 0.01);  // a quarter of the noise: no shrinking
  check_same_topology(before, after);
}

TEST_CASE("denoise: an open noisy patch keeps its border and gets flatter", "[denoise]") {
  std::vector<Vec3> points;
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 40; ++j) points.emplace_back(i * 0.5, j * 0.5, 0.0);
  scanmesh::test::add_noise(points, 0.02, 3);
  const Mesh before = mesh_all_points(points);
  Mesh after = before;
  denoise_mesh(after);
  auto height = [](const Vec3& p) { return p.z(); };
  CHECK(rms_of(after, height) < 0.5 * rms_of(before, height));
  check_same_topology(before, after);
  CHECK(analyze(after).boundary_loops == 1);
}

TEST_CASE("denoise: a mesh without noise is left exactly as it is", "[denoise]") {
  const Mesh before = mesh_all_points(box_points());
  Mesh after = before;
  const DenoiseStats st = denoise_mesh(after);
  CHECK(st.noise_mm == 0);
  CHECK(st.moved == 0);
  CHECK(after.vertices == before.vertices);
  CHECK(after.triangles == before.triangles);
}

TEST_CASE("denoise: a clean curved surface barely moves; a given noise bounds every move",
          "[denoise]") {
  const Mesh sphere = mesh_all_points(scanmesh::test::sphere_points(4000, 10));
  Mesh m = sphere;
  const DenoiseStats st = denoise_mesh(m);
  INFO("noise " << st.noise_mm << ", max move " << st.max_move);
  CHECK(st.noise_mm < 1e-3);  // the quadric fits absorb the curvature
  CHECK(st.max_move <= DenoiseOptions{}.noise_moves * st.noise_mm + 1e-12);
  CHECK(st.max_move < 1e-3);  // a thousandth of the radius, a 500th of the spacing

  auto points = box_points();
  scanmesh::test::add_noise(points, 0.02, 4);
  const Mesh box = mesh_all_points(points);
  Mesh given = box;
  DenoiseOptions o;
  o.noise_mm = 0.005;  // a quarter of the real noise: every move within 3 times that
  const DenoiseStats sg = denoise_mesh(given, o);
  CHECK(sg.noise_mm == 0.005);
  CHECK(sg.max_move <= 0.015 + 1e-12);
  CHECK(sg.clamped > 0);
  Mesh measured = box;
  const DenoiseStats sm = denoise_mesh(measured);
  INFO("measured noise " << sm.noise_mm);
  CHECK(sm.noise_mm > 0.01);  // the quadric residual's lower quartile: a little under 0.02
  CHECK(sm.noise_mm < 0.025);
  CHECK(rms_of(measured, box_distance) < rms_of(given, box_distance));
}

TEST_CASE("denoise: bad options are refused; lone triangles and empty meshes are left alone",
          "[denoise]") {
  Mesh m = scanmesh::test::tetrahedron();
  DenoiseOptions o;
  o.feature_deg = -1;
  CHECK_THROWS_AS(denoise_mesh(m, o), std::invalid_argument);
  o = {};
  o.feature_deg = 90;
  CHECK_THROWS_AS(denoise_mesh(m, o), std::invalid_argument);
  o = {};
  o.normal_iterations = 0;
  CHECK_THROWS_AS(denoise_mesh(m, o), std::invalid_argument);
  o = {};
  o.vertex_iterations = DenoiseOptions::kMaxIterations + 1;
  CHECK_THROWS_AS(denoise_mesh(m, o), std::invalid_argument);
  o = {};
  o.max_move = 0;
  CHECK_THROWS_AS(denoise_mesh(m, o), std::invalid_argument);
  o = {};
  o.noise_mm = -1;
  CHECK_THROWS_AS(denoise_mesh(m, o), std::invalid_argument);
  o = {};
  o.noise_moves = 0;
  CHECK_THROWS_AS(denoise_mesh(m, o), std::invalid_argument);
  CHECK(DenoiseOptions{}.validate().empty());

  Mesh bad = m;
  bad.triangles.push_back({0, 1, 99});
  CHECK_THROWS_AS(denoise_mesh(bad), std::invalid_argument);

  // Coordinates whose squares overflow (fuzz: an OBJ with a vertex at 1e300), or not finite:
  // a clear error naming the vertex, the mesh unchanged.
  auto points = box_points();
  scanmesh::test::add_noise(points, 0.02, 2);
  const Mesh noisy = mesh_all_points(points);
  for (const double far : {1e300, std::numeric_limits<double>::quiet_NaN()}) {
    Mesh huge = noisy;
    huge.vertices[7].x() = far;
    const Mesh kept = huge;
    CHECK_THROWS_WITH(denoise_mesh(huge), Catch::Contains("vertex #7"));
    CHECK(huge.triangles == kept.triangles);
  }

  Mesh empty;
  CHECK(denoise_mesh(empty).moved == 0);
  Mesh lone;
  lone.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  lone.triangles = {{0, 1, 2}};
  const Mesh copy = lone;
  CHECK(denoise_mesh(lone).moved == 0);
  CHECK(lone.vertices == copy.vertices);
}
