// Tests of point-to-surface distances and deviation statistics against analytic values and a
// brute-force reference.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/deviation.hpp"

namespace {

using scanmesh::recon::deviation;
using scanmesh::recon::DeviationReport;
using scanmesh::recon::DistanceStats;
using scanmesh::recon::Mesh;
using scanmesh::recon::stats_of;
using scanmesh::recon::SurfaceDistance;
using scanmesh::recon::Triangle;
using scanmesh::recon::Vec3;

/// Unit cube [0,1]^3, two outward triangles per face.
Mesh cube() {
  Mesh m;
  for (int i = 0; i < 8; ++i) m.vertices.emplace_back(i & 1, (i >> 1) & 1, (i >> 2) & 1);
  const std::uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                     {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
  }
  return m;
}

/// Icosphere of the given radius: icosahedron subdivided `levels` times, outward oriented.
Mesh sphere(double radius, int levels) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  Mesh m;
  m.vertices = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  m.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                 {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                 {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                 {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (Vec3& v : m.vertices) v.normalize();
  for (int level = 0; level < levels; ++level) {
    std::vector<Triangle> next;
    std::vector<std::pair<std::uint64_t, std::uint32_t>> mids;  // sorted edge key -> vertex
    auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
      const std::uint64_t key = (std::uint64_t{std::min(a, b)} << 32) | std::max(a, b);
      for (const auto& [k, v] : mids) {
        if (k == key) return v;
      }
      const auto v = static_cast<std::uint32_t>(m.vertices.size());
      m.vertices.push_back((m.vertices[a] + m.vertices[b]).normalized());
      mids.emplace_back(key, v);
      return v;
    };
    for (const Triangle& tri : m.triangles) {
      const std::uint32_t ab = midpoint(tri[0], tri[1]), bc = midpoint(tri[1], tri[2]),
                          ca = midpoint(tri[2], tri[0]);
      next.push_back({tri[0], ab, ca});
      next.push_back({tri[1], bc, ab});
      next.push_back({tri[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    m.triangles = std::move(next);
  }
  for (Vec3& v : m.vertices) v *= radius;
  return m;
}

double segment_distance(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - (a + s * ab)).norm();
}

/// Independent reference: plane projection when it falls inside, else the nearest edge.
double brute_force_distance(const Mesh& m, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const Triangle& t : m.triangles) {
    const Vec3 &a = m.vertices[t[0]], &b = m.vertices[t[1]], &c = m.vertices[t[2]];
    const Vec3 n = (b - a).cross(c - a).normalized();
    const Vec3 q = p - n * n.dot(p - a);
    const bool inside = (b - a).cross(q - a).dot(n) >= 0 && (c - b).cross(q - b).dot(n) >= 0 &&
                        (a - c).cross(q - c).dot(n) >= 0;
    const double d = inside ? std::abs(n.dot(p - a))
                            : std::min({segment_distance(p, a, b), segment_distance(p, b, c),
                                        segment_distance(p, c, a)});
    best = std::min(best, d);
  }
  return best;
}

}  // namespace

TEST_CASE("SurfaceDistance: single triangle, face, edge and vertex regions", "[recon]") {
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}};
  const SurfaceDistance sd(m);
  // Face region: straight above or below the interior.
  CHECK(sd.distance(Vec3(0.2, 0.2, 0.7)) == Approx(0.7));
  CHECK(sd.signed_distance(Vec3(0.2, 0.2, 0.7)) == Approx(0.7));
  CHECK(sd.signed_distance(Vec3(0.2, 0.2, -0.3)) == Approx(-0.3));
  // Edge regions.
  CHECK(sd.distance(Vec3(0.5, -1, 0)) == Approx(1.0));                // edge v0-v1
  CHECK(sd.distance(Vec3(-2, 0.5, 0)) == Approx(2.0));                // edge v2-v0
  CHECK(sd.distance(Vec3(1, 1, 0)) == Approx(std::sqrt(0.5)));        // edge v1-v2
  CHECK(sd.distance(Vec3(1, 1, 1)) == Approx(std::sqrt(0.5 + 1.0)));  // edge v1-v2, above
  // Vertex regions.
  CHECK(sd.distance(Vec3(-1, -1, 0)) == Approx(std::sqrt(2.0)));            // v0
  CHECK(sd.distance(Vec3(2, -1, 0)) == Approx(std::sqrt(2.0)));             // v1
  CHECK(sd.distance(Vec3(-0.5, 3, 2)) == Approx(std::sqrt(0.25 + 4 + 4)));  // v2
  // On the surface.
  CHECK(sd.distance(Vec3(0.25, 0.25, 0)) == Approx(0.0).margin(1e-15));
  CHECK(sd.signed_distance(Vec3(0.25, 0.25, 0)) == Approx(0.0).margin(1e-15));
}

TEST_CASE("SurfaceDistance: unit cube against analytic distances and signs", "[recon]") {
  const SurfaceDistance sd(cube());
  struct Case {
    Vec3 p;
    double expected;  // signed: negative inside
  };
  const Case cases[] = {
      {{0.5, 0.5, 2.0}, 1.0},              // above the top face
      {{0.5, 0.5, 0.5}, -0.5},             // centre
      {{0.5, 0.5, 0.9}, -0.1},             // inside near the top
      {{0.9, 0.9, 0.5}, -0.1},             // inside near a vertical edge
      {{2.0, 2.0, 0.5}, std::sqrt(2.0)},   // outside an edge
      {{1.1, 1.1, 0.5}, std::sqrt(0.02)},  // just outside an edge (edge pseudo-normal)
      {{2.0, 2.0, 2.0}, std::sqrt(3.0)},   // outside a corner
      {{1.1, 1.1, 1.1}, std::sqrt(0.03)},  // just outside a corner (vertex pseudo-normal)
      {{-0.05, 0.5, 0.5}, 0.05},           // outside a face
      {{0.02, 0.03, 0.04}, -0.02},         // inside near a corner
      {{0.5, 0.0, 0.5}, 0.0},              // on a face
  };
  for (const Case& c : cases) {
    INFO("p = " << c.p.transpose());
    CHECK(sd.distance(c.p) == Approx(std::abs(c.expected)).margin(1e-12));
    CHECK(sd.signed_distance(c.p) == Approx(c.expected).margin(1e-12));
  }
}

TEST_CASE("SurfaceDistance: agrees with brute force on a sphere", "[recon]") {
  const Mesh m = sphere(1.0, 2);  // 320 triangles
  const SurfaceDistance sd(m);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int i = 0; i < 500; ++i) {
    const Vec3 p(u(rng), u(rng), u(rng));
    const double expected = brute_force_distance(m, p);
    INFO("p = " << p.transpose());
    REQUIRE(sd.distance(p) == Approx(expected).margin(1e-12));
    // Sign: the polyhedron is convex, so inside is where every face plane has p behind it.
    bool inside = true;
    for (const Triangle& t : m.triangles) {
      const Vec3 &a = m.vertices[t[0]], &b = m.vertices[t[1]], &c = m.vertices[t[2]];
      if ((b - a).cross(c - a).dot(p - a) > 0) inside = false;
    }
    if (expected > 1e-9) CHECK((sd.signed_distance(p) < 0) == inside);
  }
}

TEST_CASE("SurfaceDistance: degenerate triangles and moved objects", "[recon]") {
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}};
  m.triangles = {{0, 1, 2}, {3, 3, 3}};  // collinear, and a single point
  SurfaceDistance sd(m);
  CHECK(sd.distance(Vec3(1.5, 1, 0)) == Approx(1.0));
  CHECK(sd.distance(Vec3(4, 0, 0)) == Approx(1.0));
  CHECK(std::isfinite(sd.signed_distance(Vec3(1.5, 1, 0))));
  SurfaceDistance moved(std::move(sd));
  CHECK(moved.distance(Vec3(-1, 0, 0)) == Approx(1.0));
}

TEST_CASE("SurfaceDistance: empty surface or bad index is a GeometryError", "[recon]") {
  Mesh empty;
  empty.vertices = {{0, 0, 0}};
  CHECK_THROWS_AS(SurfaceDistance(empty), scanmesh::GeometryError);
  Mesh bad = cube();
  bad.triangles.push_back({0, 1, 8});
  CHECK_THROWS_AS(SurfaceDistance(bad), scanmesh::GeometryError);
}

TEST_CASE("stats_of: known vectors", "[recon]") {
  const DistanceStats s = stats_of({1, 2, 3, 4});
  CHECK(s.count == 4);
  CHECK(s.mean == Approx(2.5));
  CHECK(s.rms == Approx(std::sqrt(7.5)));
  CHECK(s.max == 4);
  CHECK(s.p95 == 4);  // nearest rank: ceil(0.95 * 4) = 4th value

  std::vector<double> hundred;
  for (int i = 100; i >= 1; --i) hundred.push_back(i);
  const DistanceStats h = stats_of(hundred);
  CHECK(h.count == 100);
  CHECK(h.p95 == 95);
  CHECK(h.max == 100);
  CHECK(h.mean == Approx(50.5));

  const DistanceStats none = stats_of({});
  CHECK(none.count == 0);
  CHECK(none.max == 0);

  const DistanceStats nan = stats_of({std::nan(""), 2.0, std::numeric_limits<double>::infinity()});
  CHECK(nan.count == 1);
  CHECK(nan.mean == 2.0);
  CHECK(nan.p95 == 2.0);
}

TEST_CASE("deviation: a mesh against itself is zero", "[recon]") {
  const Mesh m = sphere(2.0, 2);
  const DeviationReport r = deviation(m, m);
  CHECK(r.mesh_to_ref.count == m.vertices.size() + m.triangles.size());
  CHECK(r.ref_to_mesh.count == m.vertices.size() + m.triangles.size());
  CHECK(r.mesh_to_ref.max == Approx(0.0).margin(1e-12));
  CHECK(r.hausdorff().max == Approx(0.0).margin(1e-12));
  REQUIRE(r.vertex_signed_distance.size() == m.vertices.size());
  for (double d : r.vertex_signed_distance) CHECK(d == Approx(0.0).margin(1e-12));
}

TEST_CASE("deviation: sphere against a slightly larger sphere", "[recon]") {
  const Mesh inner = sphere(1.0, 4);  // 5120 triangles, edge about 0.06
  const Mesh outer = sphere(1.02, 4);
  const DeviationReport r = deviation(inner, outer);
  // The flat faces sag inwards by about edge^2 / (8 r) ~ 5e-4 on both meshes, so every distance
  // is 0.02 give or take a millimetre's worth.
  CHECK(r.mesh_to_ref.mean == Approx(0.02).margin(2e-3));
  CHECK(r.mesh_to_ref.rms == Approx(0.02).margin(2e-3));
  CHECK(r.mesh_to_ref.max == Approx(0.02).margin(2e-3));
  CHECK(r.ref_to_mesh.mean == Approx(0.02).margin(2e-3));
  CHECK(r.hausdorff().max == Approx(0.02).margin(2e-3));
  CHECK(r.hausdorff().max == std::max(r.mesh_to_ref.max, r.ref_to_mesh.max));
  // The inner sphere's vertices are inside the outer one: negative signed distances.
  for (double d : r.vertex_signed_distance) CHECK(d == Approx(-0.02).margin(2e-3));

  const DeviationReport back = deviation(outer, inner);
  for (double d : back.vertex_signed_distance) CHECK(d == Approx(0.02).margin(2e-3));
}

TEST_CASE("deviation: unreferenced vertices get a value but are not sampled", "[recon]") {
  Mesh m = cube();
  m.vertices.emplace_back(0.5, 0.5, 3.0);  // stray point, used by no triangle
  const DeviationReport r = deviation(m, cube());
  CHECK(r.mesh_to_ref.count == 8 + 12);
  CHECK(r.mesh_to_ref.max == Approx(0.0).margin(1e-12));
  REQUIRE(r.vertex_signed_distance.size() == 9);
  CHECK(r.vertex_signed_distance[8] == Approx(2.0));
}

TEST_CASE("deviation: a point set against a surface", "[recon]") {
  Mesh points;
  points.vertices = {{0.5, 0.5, 1.5}, {0.5, 0.5, 0.75}};
  const DeviationReport r = deviation(points, cube());
  CHECK(r.mesh_to_ref.count == 2);
  CHECK(r.mesh_to_ref.max == Approx(0.5));
  CHECK(r.ref_to_mesh.count == 0);  // no surface to measure against
  CHECK(r.vertex_signed_distance[1] == Approx(-0.25));
}
