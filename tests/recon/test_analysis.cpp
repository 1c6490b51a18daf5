// Tests of the mesh topology and quality report on hand-built meshes with known answers.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <random>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "support/shapes.hpp"

namespace {

using scanmesh::recon::analyze;
using scanmesh::recon::Mesh;
using scanmesh::recon::MeshReport;
using scanmesh::recon::Triangle;
using scanmesh::recon::Vec3;

using scanmesh::test::tetrahedron;

/// Octahedron with vertices at distance 1 on the axes, outward oriented; volume 4/3.
Mesh octahedron() {
  Mesh m;
  m.vertices = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  m.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                 {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  return m;
}

/// Unit cube [0,1]^3, two outward triangles per face (12 triangles).
Mesh cube() {
  Mesh m;
  for (int i = 0; i < 8; ++i) m.vertices.emplace_back(i & 1, (i >> 1) & 1, (i >> 2) & 1);
  // Faces as quads (a, b, c, d) counter-clockwise seen from outside.
  const std::uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                     {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
  }
  return m;
}

/// Torus with major radius r_major and minor radius r_minor on an nu x nv grid, outward.
Mesh torus(std::uint32_t nu, std::uint32_t nv, double r_major, double r_minor) {
  Mesh m;
  for (std::uint32_t i = 0; i < nu; ++i) {
    for (std::uint32_t j = 0; j < nv; ++j) {
      const double u = 2 * std::numbers::pi * i / nu, v = 2 * std::numbers::pi * j / nv;
      m.vertices.emplace_back((r_major + r_minor * std::cos(v)) * std::cos(u),
                              (r_major + r_minor * std::cos(v)) * std::sin(u),
                              r_minor * std::sin(v));
    }
  }
  auto id = [&](std::uint32_t i, std::uint32_t j) { return (i % nu) * nv + (j % nv); };
  for (std::uint32_t i = 0; i < nu; ++i) {
    for (std::uint32_t j = 0; j < nv; ++j) {
      m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  return m;
}

Mesh concat(const Mesh& a, const Mesh& b) {
  Mesh m = a;
  const auto base = static_cast<std::uint32_t>(a.vertices.size());
  m.vertices.insert(m.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (Triangle t : b.triangles) m.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  return m;
}

}  // namespace

TEST_CASE("analyze: empty mesh gives an all-zero report", "[recon]") {
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}};
  const MeshReport r = analyze(m);
  CHECK(r.vertices == 2);
  CHECK(r.referenced_vertices == 0);
  CHECK(r.triangles == 0);
  CHECK(r.edges == 0);
  CHECK(r.components == 0);
  CHECK(r.boundary_loops == 0);
  CHECK(r.euler_characteristic == 0);
  CHECK(r.orientation_consistent);
}

TEST_CASE("analyze: tetrahedron is closed, genus 0, chi 2, volume 1/6", "[recon]") {
  const MeshReport r = analyze(tetrahedron());
  CHECK(r.vertices == 4);
  CHECK(r.referenced_vertices == 4);
  CHECK(r.triangles == 4);
  CHECK(r.degenerate_triangles == 0);
  CHECK(r.duplicate_triangles == 0);
  CHECK(r.edges == 6);
  CHECK(r.boundary_edges == 0);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.non_manifold_vertices == 0);
  CHECK(r.inconsistent_edges == 0);
  CHECK(r.orientation_consistent);
  CHECK(r.boundary_loops == 0);
  CHECK(r.boundary_loop_lengths.empty());
  CHECK(r.components == 1);
  CHECK(r.euler_characteristic == 2);
  CHECK(r.genus == 0);
  CHECK(r.signed_volume == Approx(1.0 / 6.0));
  // Three right isosceles faces (45, 45, 90) and one equilateral face.
  CHECK(r.min_angle_deg == Approx(45.0));
  CHECK(r.max_angle_deg == Approx(90.0));
  CHECK(r.mean_angle_deg == Approx(60.0));
  CHECK(r.frac_min_angle_below_10 == 0.0);
  CHECK(r.frac_min_angle_below_20 == 0.0);
  CHECK(r.max_edge_length == Approx(std::sqrt(2.0)));
  CHECK(r.mean_edge_length == Approx((3.0 + 3.0 * std::sqrt(2.0)) / 6.0));
}

TEST_CASE("analyze: inward orientation gives negative volume, still consistent", "[recon]") {
  Mesh m = tetrahedron();
  for (Triangle& t : m.triangles) std::swap(t[1], t[2]);
  const MeshReport r = analyze(m);
  CHECK(r.orientation_consistent);
  CHECK(r.signed_volume == Approx(-1.0 / 6.0));
}

TEST_CASE("analyze: octahedron with one flipped triangle is inconsistent", "[recon]") {
  Mesh m = octahedron();
  const MeshReport ok = analyze(m);
  CHECK(ok.orientation_consistent);
  CHECK(ok.signed_volume == Approx(4.0 / 3.0));
  CHECK(ok.euler_characteristic == 2);

  std::swap(m.triangles[3][0], m.triangles[3][1]);
  const MeshReport r = analyze(m);
  CHECK_FALSE(r.orientation_consistent);
  CHECK(r.inconsistent_edges == 3);  // all three edges of the flipped triangle
  CHECK(r.boundary_edges == 0);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.components == 1);
  CHECK(r.euler_characteristic == 2);
  CHECK(r.signed_volume == Approx(4.0 / 3.0 - 2.0 / 6.0));
}

TEST_CASE("analyze: cube with a missing face has one boundary loop of 4", "[recon]") {
  Mesh m = cube();
  const MeshReport closed = analyze(m);
  CHECK(closed.edges == 18);
  CHECK(closed.boundary_loops == 0);
  CHECK(closed.signed_volume == Approx(1.0));
  CHECK(closed.genus == 0);

  m.triangles.resize(10);  // drop the last face (x = 1)
  const MeshReport r = analyze(m);
  CHECK(r.triangles == 10);
  CHECK(r.edges == 17);
  CHECK(r.boundary_edges == 4);
  CHECK(r.boundary_loops == 1);
  REQUIRE(r.boundary_loop_lengths.size() == 1);
  CHECK(r.boundary_loop_lengths[0] == 4);
  CHECK(r.euler_characteristic == 1);
  CHECK(r.genus == 0);
  CHECK(r.non_manifold_vertices == 0);
  CHECK(r.orientation_consistent);
}

TEST_CASE("analyze: two holes give two loops, sorted by length", "[recon]") {
  Mesh m = cube();
  // Remove one triangle of face z=0 (loop of 3) and the whole face z=1 (loop of 4).
  m.triangles.erase(m.triangles.begin() + 2, m.triangles.begin() + 4);
  m.triangles.erase(m.triangles.begin() + 0);
  const MeshReport r = analyze(m);
  CHECK(r.boundary_loops == 2);
  CHECK(r.boundary_loop_lengths == std::vector<std::size_t>{4, 3});
  // The face's rim: four unit edges; the triangle's: two unit edges and a diagonal.
  REQUIRE(r.boundary_loop_perimeters.size() == 2);
  CHECK(r.boundary_loop_perimeters[0] == Approx(4.0));
  CHECK(r.boundary_loop_perimeters[1] == Approx(2.0 + std::sqrt(2.0)));
  CHECK(r.genus == 0);
}

TEST_CASE("analyze: torus built by code has genus 1", "[recon]") {
  const Mesh m = torus(24, 12, 3.0, 1.0);
  const MeshReport r = analyze(m);
  CHECK(r.vertices == 24 * 12);
  CHECK(r.triangles == 2 * 24 * 12);
  CHECK(r.edges == 3 * 24 * 12);
  CHECK(r.boundary_edges == 0);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.non_manifold_vertices == 0);
  CHECK(r.orientation_consistent);
  CHECK(r.components == 1);
  CHECK(r.euler_characteristic == 0);
  CHECK(r.genus == 1);
  // A polyhedral torus is a little smaller than the smooth one (2 pi^2 R r^2).
  const double smooth = 2 * std::numbers::pi * std::numbers::pi * 3.0;
  CHECK(r.signed_volume > 0.9 * smooth);
  CHECK(r.signed_volume < smooth);
}

TEST_CASE("analyze: two triangles sharing only a vertex make one non-manifold vertex", "[recon]") {
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}};
  m.triangles = {{0, 1, 2}, {0, 3, 4}};
  const MeshReport r = analyze(m);
  CHECK(r.non_manifold_vertices == 1);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.components == 2);  // edge-connected components
  CHECK(r.boundary_edges == 6);
  // The pinch vertex splits the boundary into one loop per triangle.
  CHECK(r.boundary_loop_lengths == std::vector<std::size_t>{3, 3});
}

TEST_CASE("analyze: two closed fans touching at a vertex are non-manifold", "[recon]") {
  // Two tetrahedra glued at one vertex: every edge is manifold, but the shared vertex has two
  // closed fans (no boundary edge reveals it).
  Mesh m = concat(tetrahedron(), tetrahedron(Vec3(-1, -1, -1)));
  // Make the second tetrahedron use vertex 0 instead of its own vertex 5 (which stays unused).
  for (Triangle& t : m.triangles) {
    for (auto& v : t) {
      if (v == 5) v = 0;
    }
  }
  const MeshReport r = analyze(m);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.boundary_edges == 0);
  CHECK(r.non_manifold_vertices == 1);
  CHECK(r.components == 2);
  CHECK(r.referenced_vertices == 7);
}

TEST_CASE("analyze: three triangles on one edge make a non-manifold edge", "[recon]") {
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0.5, 1, 0}, {0.5, -1, 0}, {0.5, 0, 1}};
  m.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  const MeshReport r = analyze(m);
  CHECK(r.edges == 7);
  CHECK(r.non_manifold_edges == 1);
  CHECK(r.boundary_edges == 6);
  CHECK(r.components == 1);
  // The ends of the non-manifold edge are reported through the edge, not again as vertices.
  CHECK(r.non_manifold_vertices == 0);
  // Every boundary edge is in exactly one loop.
  std::size_t sum = 0;
  for (std::size_t len : r.boundary_loop_lengths) sum += len;
  CHECK(sum == 6);
}

TEST_CASE("analyze: duplicate and degenerate triangles are counted", "[recon]") {
  Mesh m = tetrahedron();
  m.triangles.push_back({2, 1, 0});  // same vertex set as {0, 2, 1}, opposite orientation
  m.triangles.push_back({1, 3, 0});  // same as {0, 1, 3}, a rotation of it
  m.triangles.push_back({0, 0, 1});  // repeated index
  m.vertices.emplace_back(0.5, 0, 0);
  m.triangles.push_back({0, 4, 1});  // zero area: collinear
  const MeshReport r = analyze(m);
  CHECK(r.triangles == 8);
  CHECK(r.duplicate_triangles == 2);
  CHECK(r.degenerate_triangles == 2);
  // The duplicates put a third triangle on their edges.
  CHECK(r.non_manifold_edges > 0);
  // Angle statistics ignore degenerate triangles.
  CHECK(r.min_angle_deg == Approx(45.0));
}

TEST_CASE("analyze: two disjoint tetrahedra are two components", "[recon]") {
  const Mesh m = concat(tetrahedron(), tetrahedron(Vec3(5, 0, 0)));
  const MeshReport r = analyze(m);
  CHECK(r.components == 2);
  CHECK(r.euler_characteristic == 4);
  CHECK(r.genus == 0);
  CHECK(r.non_manifold_vertices == 0);
  CHECK(r.signed_volume == Approx(2.0 / 6.0));
}

TEST_CASE("analyze: unreferenced vertices and angle fractions", "[recon]") {
  Mesh m;
  // A sliver with a 5.71 degree angle (atan(0.1)) and an equilateral triangle.
  m.vertices = {{0, 0, 0},
                {1, 0, 0},
                {1, 0.1, 0},
                {5, 5, 5},
                {10, 0, 0},
                {11, 0, 0},
                {10.5, std::sqrt(3.0) / 2, 0}};
  m.triangles = {{0, 1, 2}, {4, 5, 6}};
  const MeshReport r = analyze(m);
  CHECK(r.vertices == 7);
  CHECK(r.referenced_vertices == 6);
  CHECK(r.min_angle_deg == Approx(std::atan(0.1) * 180 / std::numbers::pi));
  CHECK(r.max_angle_deg == Approx(90.0));
  CHECK(r.frac_min_angle_below_10 == Approx(0.5));
  CHECK(r.frac_min_angle_below_20 == Approx(0.5));
  CHECK(r.components == 2);
  CHECK(r.boundary_loops == 2);
}

TEST_CASE("analyze: out-of-range vertex index is a GeometryError", "[recon]") {
  Mesh m = tetrahedron();
  m.triangles.push_back({0, 1, 9});
  CHECK_THROWS_AS(analyze(m), scanmesh::GeometryError);
}

TEST_CASE("analyze: large shuffled torus stays consistent", "[recon]") {
  Mesh m = torus(300, 200, 3.0, 1.0);
  // Reverse the triangle order: the result must not depend on it.
  std::reverse(m.triangles.begin(), m.triangles.end());
  const MeshReport r = analyze(m);
  CHECK(r.triangles == 120000);
  CHECK(r.edges == 180000);
  CHECK(r.genus == 1);
  CHECK(r.components == 1);
  CHECK(r.orientation_consistent);
}

TEST_CASE("analyze: random triangle soups keep the report's invariants", "[recon]") {
  std::mt19937 rng(11);
  for (int round = 0; round < 200; ++round) {
    Mesh m;
    const int nv = 4 + round % 12;
    std::uniform_real_distribution<double> coord(-1, 1);
    for (int i = 0; i < nv; ++i) m.vertices.emplace_back(coord(rng), coord(rng), coord(rng));
    std::uniform_int_distribution<std::uint32_t> vertex(0, static_cast<std::uint32_t>(nv - 1));
    const int nt = 1 + round % 30;
    for (int i = 0; i < nt; ++i) m.triangles.push_back({vertex(rng), vertex(rng), vertex(rng)});
    const MeshReport r = analyze(m);
    std::size_t loop_edges = 0;
    for (std::size_t len : r.boundary_loop_lengths) loop_edges += len;
    INFO("round " << round);
    CHECK(loop_edges == r.boundary_edges);
    CHECK(std::is_sorted(r.boundary_loop_lengths.rbegin(), r.boundary_loop_lengths.rend()));
    CHECK(r.boundary_edges + r.non_manifold_edges <= r.edges);
    CHECK(r.components <= r.triangles);
    CHECK(r.orientation_consistent == (r.inconsistent_edges == 0));
    CHECK(r.referenced_vertices <= r.vertices);
  }
}
