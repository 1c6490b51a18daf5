// Hole filling on request: loops closed by a minimum-weight patch of their own vertices, the
// mesh kept manifold and consistently oriented, existing edges never repeated, larger loops and
// non-manifold meshes left alone.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <vector>

#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/fill.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "support/shapes.hpp"

namespace {

using scanmesh::recon::analyze;
using scanmesh::recon::fill_holes;
using scanmesh::recon::FillOptions;
using scanmesh::recon::Mesh;
using scanmesh::recon::Triangle;
using scanmesh::recon::Vec3;

}  // namespace

TEST_CASE("fill_holes closes two tetrahedron faces with the other two, never repeating the "
          "shared edge",
          "[recon][fill]") {
  // Faces (a, c, b) and (a, d, c) of a tetrahedron, outward: the loop a-b-c-d has the chord a-c
  // in the mesh already, so the only valid patch uses b-d: the tetrahedron's other two faces.
  Mesh m;
  m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  // a = 0, b = 1, c = 3, d = 2: outward faces of the tetrahedron (0,1,2,3) are (0,2,1), (0,1,3),
  // (0,3,2), (1,2,3).
  m.triangles = {Triangle{0, 1, 3}, Triangle{0, 3, 2}};
  REQUIRE(analyze(m).boundary_loops == 1);
  FillOptions opt;
  opt.max_edges = 4;
  const auto stats = fill_holes(m, opt);
  CHECK(stats.filled == 1);
  CHECK(stats.kept == 0);
  CHECK(stats.triangles == 2);
  const auto r = analyze(m);
  CHECK(r.boundary_loops == 0);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.orientation_consistent);
  CHECK(r.genus == 0);
  CHECK(r.edges == 6);
  CHECK(r.signed_volume == Approx(1.0 / 6.0));
}

TEST_CASE("fill_holes never repeats an edge the mesh has, whatever the vertex numbering",
          "[recon][fill]") {
  // A flat square as two triangles on the diagonal a-c. Both patches of its rim are flat and
  // face the other way, so the weights tie; the one on a-c would repeat that edge (and both
  // triangles). Every numbering of the four corners must give the patch on b-d.
  const Vec3 corner[4] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)};
  std::array<std::uint32_t, 4> label{0, 1, 2, 3};
  int numberings = 0;
  do {
    Mesh m;
    m.vertices.resize(4);
    for (int k = 0; k < 4; ++k) m.vertices[label[k]] = corner[k];
    const std::uint32_t a = label[0], b = label[1], c = label[2], d = label[3];
    m.triangles = {Triangle{a, b, c}, Triangle{a, c, d}};
    FillOptions opt;
    opt.max_edges = 4;
    INFO("labels " << a << b << c << d);
    REQUIRE(fill_holes(m, opt).filled == 1);
    const auto r = analyze(m);
    CHECK(r.boundary_loops == 0);
    CHECK(r.non_manifold_edges == 0);
    CHECK(r.duplicate_triangles == 0);
    CHECK(r.edges == 6);
    ++numberings;
  } while (std::next_permutation(label.begin(), label.end()));
  CHECK(numberings == 24);
}

TEST_CASE("fill_holes closes a reconstructed sphere's cap with a flat, outward patch",
          "[recon][fill]") {
  const double radius = 10, cut = 7;
  std::vector<Vec3> pts;
  for (const Vec3& p : scanmesh::test::sphere_points(6000, radius))
    if (p.z() < cut) pts.push_back(p);
  Mesh m = scanmesh::recon::reconstruct(pts).mesh;
  const auto before = analyze(m, true);
  REQUIRE(before.boundary_loops == 1);
  const std::size_t loop_edges = before.boundary_loop_lengths[0];
  const std::size_t triangles = m.triangles.size();

  SECTION("a loop longer than the limit stays open, the mesh unchanged") {
    FillOptions opt;
    opt.max_edges = loop_edges - 1;
    const auto stats = fill_holes(m, opt);
    CHECK(stats.filled == 0);
    CHECK(stats.kept == 1);
    CHECK(m.triangles.size() == triangles);
  }
  SECTION("a loop within the limit is closed") {
    FillOptions opt;
    opt.max_edges = loop_edges;
    const auto stats = fill_holes(m, opt);
    CHECK(stats.filled == 1);
    // A triangulation of an n-gon has n - 2 triangles: no new vertex.
    CHECK(stats.triangles == loop_edges - 2);
    CHECK(m.triangles.size() == triangles + loop_edges - 2);
    const auto r = analyze(m);
    CHECK(r.boundary_loops == 0);
    CHECK(r.non_manifold_edges == 0);
    CHECK(r.non_manifold_vertices == 0);
    CHECK(r.orientation_consistent);
    CHECK(r.genus == 0);
    CHECK(r.signed_volume > 0);
    // The patch lies near the cut plane, faces up (out of the sphere) and covers the cap's disk.
    double area = 0;
    for (std::size_t t = triangles; t < m.triangles.size(); ++t) {
      const Triangle& tri = m.triangles[t];
      const Vec3 n = (m.vertices[tri[1]] - m.vertices[tri[0]])
                         .cross(m.vertices[tri[2]] - m.vertices[tri[0]]);
      CHECK(n.z() > 0);
      area += 0.5 * n.norm();
      for (std::uint32_t v : tri) CHECK(m.vertices[v].z() == Approx(cut).margin(1.0));
    }
    const double disk = std::numbers::pi * (radius * radius - cut * cut);
    CHECK(area == Approx(disk).epsilon(0.1));
  }
}

TEST_CASE("fill_holes leaves a non-manifold mesh and a lone triangle alone, and checks its limit",
          "[recon][fill]") {
  // Three triangles on one edge: every loop is kept.
  Mesh m;
  m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1)};
  m.triangles = {Triangle{0, 1, 2}, Triangle{1, 0, 3}, Triangle{0, 1, 4}};
  FillOptions opt;
  opt.max_edges = 10;
  const auto stats = fill_holes(m, opt);
  CHECK(stats.filled == 0);
  CHECK(stats.kept > 0);
  CHECK(m.triangles.size() == 3);
  // A lone triangle's rim stays open: its patch would be the triangle turned over.
  Mesh lone;
  lone.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  lone.triangles = {Triangle{0, 1, 2}};
  const auto lone_stats = fill_holes(lone, opt);
  CHECK(lone_stats.filled == 0);
  CHECK(lone_stats.kept == 1);
  CHECK(lone.triangles.size() == 1);
  opt.max_edges = FillOptions::kLimit + 1;
  CHECK(opt.validate().size() == 1);
  scanmesh::recon::ReconstructOptions ro;
  ro.fill.max_edges = FillOptions::kLimit + 1;
  CHECK_FALSE(ro.validate().empty());
}
