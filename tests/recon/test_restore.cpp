// Features in the projection: balls across a sharp edge are found, the front meshes their
// projected points and the output keeps the measured ones where the mesh stays valid.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "restore.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "scanmesh/recon/reduce.hpp"
#include "support/shapes.hpp"

using scanmesh::recon::Vec3;
namespace recon = scanmesh::recon;

namespace {

/// Distance from p to the surface of the box [0, s]^3.
double box_distance(const Vec3& p, double s) {
  const Vec3 lo = -p, hi = p - Vec3::Constant(s);
  const Vec3 out = lo.cwiseMax(hi).cwiseMax(0.0);
  if (out.squaredNorm() > 0) return out.norm();
  return std::min(p.minCoeff(), (Vec3::Constant(s) - p).minCoeff());
}

/// A 90-degree edge along y: the face z = 0 over x in [-4, 0] and the face x = 0 over z in
/// [-4, 0], sampled every `step` with Gaussian noise.
std::vector<Vec3> edge_points(double step, double noise) {
  std::mt19937 rng(11);
  std::normal_distribution<double> gauss(0.0, noise);
  std::vector<Vec3> pts;
  const int n = static_cast<int>(std::round(4.0 / step));
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const double y = j * step, u = -i * step;
      pts.emplace_back(u, y, gauss(rng));             // top face
      if (i > 0) pts.emplace_back(gauss(rng), y, u);  // side face
    }
  return pts;
}

}  // namespace

TEST_CASE("project_to_local_planes: the balls across a sharp edge are features", "[recon]") {
  // Balls of 1.5 cubes that reach over the edge hold both faces: their plane cuts the corner
  // (it lies up to half a cube inside), where the measured point is on the surface.
  const double noise = 0.005, cube = 0.3, radius = 1.5 * cube;
  const auto pts = edge_points(0.1, noise);
  const auto kept = recon::cube_reduce_thin(pts, cube);
  std::vector<std::uint32_t> features;
  const auto out =
      recon::project_to_local_planes(pts, kept, radius, 0.5 * cube, true, 8 * noise, &features);
  REQUIRE(std::is_sorted(features.begin(), features.end()));
  std::vector<std::uint8_t> is_feature(kept.size(), 0);
  for (std::uint32_t f : features) is_feature[f] = 1;
  auto to_edge = [](const Vec3& p) {
    return std::hypot(std::min(p.x(), 0.0), std::min(p.z(), 0.0));
  };
  auto to_faces = [](const Vec3& p) {
    return std::min(std::hypot(std::max(p.x(), 0.0), p.z()),
                    std::hypot(p.x(), std::max(p.z(), 0.0)));
  };
  std::size_t near = 0, near_features = 0, far = 0, far_features = 0;
  double cut = 0;  // how far inside the projections of the features near the edge lie
  for (std::size_t i = 0; i < kept.size(); ++i) {
    const Vec3& p = pts[kept[i]];
    if (p.y() < radius || p.y() > 4 - radius) continue;  // away from the open ends
    if (p.x() < -4 + radius || p.z() < -4 + radius) continue;
    const double d = to_edge(p);
    if (d < 0.3 * cube) {
      ++near;
      near_features += is_feature[i];
      if (is_feature[i]) cut = std::max(cut, to_faces(out[i]));
    } else if (d > radius + 0.1) {
      ++far;
      far_features += is_feature[i];
    }
  }
  INFO(near_features << " of " << near << " near the edge, " << far_features << " of " << far
                     << " away from it; the projections cut up to " << cut);
  REQUIRE(near > 5);
  REQUIRE(far > 50);
  CHECK(near_features == near);
  CHECK(far_features == 0);
  CHECK(cut > 0.1 * cube);
  // Without the bound (the default argument) nothing is reported.
  recon::project_to_local_planes(pts, kept, radius, 0.5 * cube, true,
                                 std::numeric_limits<double>::infinity(), &features);
  CHECK(features.empty());
}

TEST_CASE("restore_positions: moves that keep the mesh valid, not those that fold it", "[recon]") {
  // A flat 5 x 5 grid, two triangles a cell.
  recon::Mesh m;
  for (int j = 0; j < 5; ++j)
    for (int i = 0; i < 5; ++i) m.vertices.emplace_back(i, j, 0);
  for (std::uint32_t j = 0; j < 4; ++j)
    for (std::uint32_t i = 0; i < 4; ++i) {
      const std::uint32_t a = j * 5 + i;
      m.triangles.push_back({a, a + 1, a + 6});
      m.triangles.push_back({a, a + 6, a + 5});
    }
  const auto triangles = m.triangles;
  // Vertex 12 (the centre) a little up: valid. Vertex 6 over its neighbour 8: its triangles
  // would fold over the ones beside them. Vertex 18 far up: they would tilt by over 60 degrees.
  const std::vector<std::pair<std::uint32_t, Vec3>> targets{
      {6, Vec3(3.2, 1.1, 0.0)}, {12, Vec3(2.1, 1.9, 0.3)}, {18, Vec3(3, 3, 5)}};
  CHECK(recon::detail::restore_positions(m, targets) == 1);
  CHECK(m.vertices[12] == Vec3(2.1, 1.9, 0.3));
  CHECK(m.vertices[6] == Vec3(1, 1, 0));
  CHECK(m.vertices[18] == Vec3(3, 3, 0));
  CHECK(m.triangles == triangles);
  CHECK(recon::find_self_intersections(m).pairs == 0);
}

TEST_CASE("reconstruct: a noisy box keeps its sharp edges and corners", "[recon]") {
  // The front meshes the projected points (the same triangles with and without the features'
  // measured points); the output has the measured points at the edges and corners, which the
  // projection rounded off by up to half a cube.
  const double s = 10, noise = 0.01;
  auto pts = scanmesh::test::cube_points(s, 0.25);
  std::mt19937 rng(5);
  std::normal_distribution<double> gauss(0.0, noise);
  for (Vec3& p : pts) p += Vec3(gauss(rng), gauss(rng), gauss(rng));
  recon::ReconstructOptions rounded;
  rounded.project_flat_factor = 0;
  const auto a = recon::reconstruct(pts);
  const auto b = recon::reconstruct(pts, rounded);
  CHECK(a.mesh.triangles == b.mesh.triangles);
  CHECK(b.features == 0);
  INFO(a.restored << " of " << a.features << " features restored");
  CHECK(a.features > a.reduced_points / 20);
  CHECK(a.restored >= a.features * 95 / 100);
  const auto rep = recon::analyze(a.mesh);
  CHECK(rep.boundary_loops == 0);
  CHECK(rep.non_manifold_edges == 0);
  CHECK(recon::find_self_intersections(a.mesh).pairs == 0);
  // Vertices within a cube of an edge (two coordinates near a face): their mean distance to
  // the box, and the farthest vertex anywhere.
  auto at_edges = [&](const recon::Mesh& m, double& worst) {
    double sum = 0;
    std::size_t n = 0;
    worst = 0;
    for (const Vec3& v : m.vertices) {
      const double d = box_distance(v, s);
      worst = std::max(worst, d);
      int near_faces = 0;
      for (int k = 0; k < 3; ++k) near_faces += std::min(v[k], s - v[k]) < a.cube_mm ? 1 : 0;
      if (near_faces < 2) continue;
      sum += d;
      ++n;
    }
    REQUIRE(n > 100);
    return sum / static_cast<double>(n);
  };
  double worst_a = 0, worst_b = 0;
  const double mean_a = at_edges(a.mesh, worst_a), mean_b = at_edges(b.mesh, worst_b);
  INFO("at the edges: mean " << mean_a << " (rounded " << mean_b << "), farthest vertex " << worst_a
                             << " (rounded " << worst_b << ")");
  CHECK(mean_a < noise);
  CHECK(mean_b > 2 * mean_a);
  CHECK(worst_a < 6 * noise);
}
