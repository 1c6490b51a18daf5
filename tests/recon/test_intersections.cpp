// Self-intersection check: hand-made pairs for every case the test distinguishes, a clean closed
// mesh, and the grid's path for triangles that span many cells.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <cmath>

#include "scanmesh/recon/intersections.hpp"

using scanmesh::recon::find_self_intersections;
using scanmesh::recon::Mesh;
using scanmesh::recon::Triangle;
using scanmesh::recon::Vec3;

namespace {

/// Two triangles given by their corners; corners closer than 1e-12 share one vertex index.
Mesh pair_of(const std::array<Vec3, 3>& s, const std::array<Vec3, 3>& t) {
  Mesh m;
  auto index = [&](const Vec3& p) {
    for (std::uint32_t i = 0; i < m.vertices.size(); ++i)
      if ((m.vertices[i] - p).norm() < 1e-12) return i;
    m.vertices.push_back(p);
    return static_cast<std::uint32_t>(m.vertices.size() - 1);
  };
  m.triangles.push_back({index(s[0]), index(s[1]), index(s[2])});
  m.triangles.push_back({index(t[0]), index(t[1]), index(t[2])});
  return m;
}

std::size_t crossing_pairs(const Mesh& m) { return find_self_intersections(m).pairs; }

/// A closed latitude-longitude sphere: poles and rings-1 rings of `sectors` vertices.
Mesh uv_sphere(double r, std::uint32_t rings, std::uint32_t sectors) {
  Mesh m;
  const double pi = std::acos(-1.0);
  m.vertices.emplace_back(0, 0, r);
  for (std::uint32_t k = 1; k < rings; ++k)
    for (std::uint32_t j = 0; j < sectors; ++j) {
      const double th = pi * k / rings, ph = 2 * pi * j / sectors;
      m.vertices.emplace_back(r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph),
                              r * std::cos(th));
    }
  m.vertices.emplace_back(0, 0, -r);
  const auto south = static_cast<std::uint32_t>(m.vertices.size() - 1);
  auto at = [&](std::uint32_t k, std::uint32_t j) { return 1 + (k - 1) * sectors + j % sectors; };
  for (std::uint32_t j = 0; j < sectors; ++j) {
    m.triangles.push_back({0, at(1, j), at(1, j + 1)});
    m.triangles.push_back({south, at(rings - 1, j + 1), at(rings - 1, j)});
    for (std::uint32_t k = 1; k + 1 < rings; ++k) {
      m.triangles.push_back({at(k, j), at(k + 1, j), at(k + 1, j + 1)});
      m.triangles.push_back({at(k, j), at(k + 1, j + 1), at(k, j + 1)});
    }
  }
  return m;
}

}  // namespace

TEST_CASE("find_self_intersections: each kind of pair", "[recon][intersections]") {
  const Vec3 o(0, 0, 0), x(1, 0, 0), y(0, 1, 0);
  const std::array<Vec3, 3> base{o, x, y};  // in z = 0
  SECTION("disjoint, parallel, and apart") {
    CHECK(crossing_pairs(pair_of(base, {Vec3(0, 0, 1), Vec3(1, 0, 1), Vec3(0, 1, 1)})) == 0);
    CHECK(crossing_pairs(pair_of(base, {Vec3(2, 2, -1), Vec3(3, 2, -1), Vec3(2, 2, 1)})) == 0);
  }
  SECTION("crossing through the face") {
    const Mesh m = pair_of(base, {Vec3(0.2, 0.2, -1), Vec3(0.3, 0.2, 1), Vec3(0.2, 0.3, 1)});
    CHECK(scanmesh::recon::triangles_intersect(m.vertices, m.triangles[0], m.triangles[1]));
    CHECK(scanmesh::recon::triangles_intersect(m.vertices, m.triangles[1], m.triangles[0]));
    const auto r = find_self_intersections(m);
    CHECK(r.pairs == 1);
    CHECK(r.triangles == 2);
    REQUIRE(r.examples.size() == 1);
    CHECK(r.examples[0] == std::array<std::uint32_t, 2>{0, 1});
  }
  SECTION("one corner touching the other's face") {
    CHECK(crossing_pairs(pair_of(base, {Vec3(0.2, 0.2, 0), Vec3(0.3, 0.2, 1), Vec3(0.2, 0.3, 1)})) ==
          1);
  }
  SECTION("sharing a vertex") {
    // only the vertex: a fan around it
    const Mesh fan = pair_of(base, {o, Vec3(-1, 0, 0.5), Vec3(0, -1, 0.5)});
    CHECK(crossing_pairs(fan) == 0);
    CHECK_FALSE(scanmesh::recon::triangles_intersect(fan.vertices, fan.triangles[0], fan.triangles[1]));
    // the other triangle goes on through the face
    CHECK(crossing_pairs(pair_of(base, {o, Vec3(0.5, 0.2, 1), Vec3(0.4, 0.4, -1)})) == 1);
    // in the same plane: a wedge beside it, and one overlapping it
    CHECK(crossing_pairs(pair_of(base, {o, y, Vec3(-1, -1, 0)})) == 0);
    CHECK(crossing_pairs(pair_of(base, {o, Vec3(1, 1, 0), Vec3(-0.5, 1, 0)})) == 1);
  }
  SECTION("overlapping in the plane, apart in height by less than a clearance") {
    // Two triangles of one flat face, one 1e-7 above the other, one corner 0.05 inside the other
    // (from a simulated knife-edge scan): apart in double precision, so only the clearance the
    // front passes (on_plane) finds them; written as float they are a fold.
    const double h = 1e-7;
    const Mesh m = pair_of(base, {Vec3(0.45, 0.45, h), Vec3(1.5, 0.5, h), Vec3(0.5, 1.5, h)});
    CHECK_FALSE(scanmesh::recon::triangles_intersect(m.vertices, m.triangles[0], m.triangles[1]));
    CHECK(scanmesh::recon::triangles_intersect(m.vertices, m.triangles[0], m.triangles[1], 1e-5));
    CHECK(scanmesh::recon::triangles_intersect(m.vertices, m.triangles[1], m.triangles[0], 1e-5));
    // the same pair side by side (no overlap in the plane) stays apart
    const Mesh side = pair_of(base, {Vec3(0.55, 0.55, h), Vec3(1.5, 0.5, h), Vec3(0.5, 1.5, h)});
    CHECK_FALSE(scanmesh::recon::triangles_intersect(side.vertices, side.triangles[0], side.triangles[1], 1e-5));
    // A fan neighbour on a slightly bent surface, one far corner within the clearance of the
    // other plane and one not: decided in 3D as before (taking only that corner as on the
    // plane put it on the planes' meeting line, far from where it is: fandisk lost triangles).
    const Mesh fan = pair_of(base, {o, Vec3(-1, 0.1, 5e-6), Vec3(-0.1, -1, 3e-5)});
    CHECK_FALSE(scanmesh::recon::triangles_intersect(fan.vertices, fan.triangles[0], fan.triangles[1], 1e-5));
  }
  SECTION("touching within a clearance") {
    using scanmesh::recon::triangles_touch;
    // an edge passing 1e-7 above another triangle's edge, no common vertex
    const Mesh edges = pair_of(base, {Vec3(0.5, -0.5, 1e-7), Vec3(0.5, 0.5, 1e-7), Vec3(1.5, 0, 1)});
    CHECK_FALSE(scanmesh::recon::triangles_intersect(edges.vertices, edges.triangles[0], edges.triangles[1]));
    CHECK(triangles_touch(edges.vertices, edges.triangles[0], edges.triangles[1], 1e-5));
    CHECK_FALSE(triangles_touch(edges.vertices, edges.triangles[0], edges.triangles[1], 1e-8));
    // a corner 1e-7 above the face
    const Mesh corner = pair_of(base, {Vec3(0.2, 0.2, 1e-7), Vec3(0.3, 0.2, 1), Vec3(0.2, 0.3, 1)});
    CHECK(triangles_touch(corner.vertices, corner.triangles[0], corner.triangles[1], 1e-5));
    CHECK_FALSE(triangles_touch(corner.vertices, corner.triangles[0], corner.triangles[1], 1e-8));
    // fan neighbours meet only at their shared vertex: not touching, however close to it
    const Mesh fan = pair_of(base, {o, Vec3(-1, 0.01, 0), Vec3(-0.5, -1, 0)});
    CHECK_FALSE(triangles_touch(fan.vertices, fan.triangles[0], fan.triangles[1], 1e-3));
    // a neighbour's far corner near this triangle's edge is touching even beside a shared vertex
    const Mesh beside = pair_of(base, {o, Vec3(0.5, -1e-7, 0), Vec3(0.5, -1, 0)});
    CHECK(triangles_touch(beside.vertices, beside.triangles[0], beside.triangles[1], 1e-5));
    // across a shared edge: triangles_intersect's case (folds), never touching
    const Mesh hinge = pair_of(base, {o, x, Vec3(0.5, 1e-7, 1e-7)});
    CHECK_FALSE(triangles_touch(hinge.vertices, hinge.triangles[0], hinge.triangles[1], 1e-5));
  }
  SECTION("nearly coplanar, sharing a vertex, edges collinear through it") {
    // Two triangles of one flat face meeting only at a corner, their bottom edges on one line;
    // the second tilts by 1e-9 rad, so the tolerance zeroed one of its heights but not the
    // other, and the planes' meeting line was taken as real: reported as crossing. (Coordinates
    // of a pair from a simulated line scan, and the same shape made by hand.)
    const Vec3 a(38.821023500000003, 4.0463221100000002, 22.870633999999999),
        b(39.122436800000003, 4.0344795500000004, 22.8923117),
        c(39.083554100000001, 4.0360072599999999, 22.989509200000001),
        d(39.375269799999998, 4.0245457199999999, 23.010489400000001),
        e(39.423406999999997, 4.0226544000000004, 22.913957499999999);
    CHECK(crossing_pairs(pair_of({a, b, c}, {b, d, e})) == 0);
    CHECK(crossing_pairs(pair_of(base, {x, Vec3(1.86, 0.3, -0.9e-9), Vec3(2, 0, -1.8e-9)})) == 0);
    // the same tilt, but the second triangle reaching back over the first: found
    CHECK(crossing_pairs(pair_of(base, {x, Vec3(0.5, 0.3, -0.9e-9), Vec3(2, 0, -1.8e-9)})) == 1);
  }
  SECTION("sharing an edge") {
    // a ridge, a flat continuation, and a fold back onto the first triangle
    CHECK(crossing_pairs(pair_of(base, {x, o, Vec3(0.5, -1, 1)})) == 0);
    CHECK(crossing_pairs(pair_of(base, {x, o, Vec3(0.5, -1, 0)})) == 0);
    CHECK(crossing_pairs(pair_of(base, {x, o, Vec3(0.3, 0.3, 0)})) == 1);
  }
  SECTION("coplanar, no shared vertex") {
    CHECK(crossing_pairs(pair_of(base, {Vec3(0.1, 0.1, 0), Vec3(2, 0.1, 0), Vec3(0.1, 2, 0)})) == 1);
    CHECK(crossing_pairs(pair_of(base, {Vec3(2, 0, 0), Vec3(3, 0, 0), Vec3(2, 1, 0)})) == 0);
  }
  SECTION("the same triangle twice, and degenerate triangles left to analyze()") {
    Mesh m = pair_of(base, base);
    m.triangles[1] = {m.triangles[0][0], m.triangles[0][2], m.triangles[0][1]};
    CHECK(crossing_pairs(m) == 1);
    Mesh d = pair_of(base, {Vec3(0.2, 0.2, -1), Vec3(0.2, 0.2, 1), Vec3(0.2, 0.2, 2)});  // a line
    CHECK(crossing_pairs(d) == 0);
  }
}

TEST_CASE("find_self_intersections: a closed mesh has none; a sheet pushed through it is found",
          "[recon][intersections]") {
  Mesh sphere = uv_sphere(10.0, 24, 48);
  CHECK(crossing_pairs(sphere) == 0);
  // One large sheet through the middle: each of its two triangles spans many grid cells (the
  // path for long triangles) and crosses the sphere along its equator.
  const auto base = static_cast<std::uint32_t>(sphere.vertices.size());
  sphere.vertices.insert(sphere.vertices.end(), {Vec3(-20, -20, 0.1), Vec3(20, -20, 0.1),
                                                 Vec3(20, 20, 0.1), Vec3(-20, 20, 0.1)});
  const std::size_t sphere_triangles = sphere.triangles.size();
  sphere.triangles.push_back({base, base + 1, base + 2});
  sphere.triangles.push_back({base, base + 2, base + 3});
  const auto r = find_self_intersections(sphere, scanmesh::recon::kAllPairs);
  // The plane z = 0.1 crosses one band of 48 quads (96 triangles) around the equator.
  CHECK(r.triangles == 96 + 2);
  CHECK(r.pairs == r.examples.size());
  CHECK(r.pairs >= 96);
  for (const auto& [a, b] : r.examples) CHECK(b >= sphere_triangles);
  // Only what was added: the same pairs.
  CHECK(find_self_intersections(sphere, 0, sphere_triangles).pairs == r.pairs);
}

// The grid numbers its cells densely over the occupied box and sorts (cell, triangle) keys packed
// into one integer; tiny triangles at the far corners of a huge box need over 60 bits for the
// cell alone, so with enough triangles the keys no longer fit and the pairs are sorted instead.
// Both paths find the same crossings, with and without `from`.
TEST_CASE("find_self_intersections: a sparse box too large for packed keys", "[recon][intersections]") {
  // Two tiny triangles crossing each other at `at`: the first of each pair is listed in the
  // first half of the triangles, the second in the second half, so only sorting by cell brings
  // a pair together.
  auto crossing_x = [](Mesh& m, std::vector<Triangle>& second, const Vec3& at) {
    const auto b = static_cast<std::uint32_t>(m.vertices.size());
    m.vertices.insert(m.vertices.end(), {at + Vec3(-1, -1, 0), at + Vec3(1, -1, 0), at + Vec3(0, 1, 0),
                                         at + Vec3(0, 0, -1), at + Vec3(0, 0, 1), at + Vec3(0, 2, 0)});
    m.triangles.push_back({b, b + 1, b + 2});
    second.push_back({b + 3, b + 4, b + 5});
  };
  for (const std::uint32_t far_pairs : {1u, 40u}) {  // 4 and 82 triangles: 2 and 7 bits of id
    INFO(far_pairs << " crossing pairs at the far corner");
    Mesh m;
    std::vector<Triangle> second;
    crossing_x(m, second, Vec3(0, 0, 0));
    for (std::uint32_t k = 0; k < far_pairs; ++k)
      crossing_x(m, second, Vec3(1e9, 1e9 - 10.0 * k, 1e9 + 10.0 * k));
    const std::size_t n = m.triangles.size();
    m.triangles.insert(m.triangles.end(), second.begin(), second.end());
    const auto all = find_self_intersections(m, scanmesh::recon::kAllPairs);
    CHECK(all.pairs == n);
    CHECK(all.triangles == 2 * n);
    for (const auto& [a, b] : all.examples) CHECK(b == a + n);  // each tiny pair, nothing else
    // Only the last triangle is new: its pair alone.
    CHECK(find_self_intersections(m, 0, m.triangles.size() - 1).pairs == 1);
  }
}

// Two sheets over one surface (a small component grown among points a larger one left under its
// triangles) are not one surface: the smaller of a crossing pair goes, the rest stays in order.
TEST_CASE("remove_crossing_components drops the smaller of two crossing components",
          "[recon][intersections]") {
  Mesh m;
  // 0: a square in z = 0 (2 triangles); 1: a smaller triangle piercing it; 2: a triangle apart
  m.vertices = {Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(2, 2, 0), Vec3(0, 2, 0),
                Vec3(0.5, 0.5, -1), Vec3(1, 0.6, 1), Vec3(0.6, 1, 1),
                Vec3(5, 5, 0), Vec3(6, 5, 0), Vec3(5, 6, 0)};
  m.triangles = {{4, 5, 6}, {0, 1, 2}, {7, 8, 9}, {0, 2, 3}};
  REQUIRE(find_self_intersections(m).pairs == 2);  // it crosses both halves of the square
  CHECK(scanmesh::recon::remove_crossing_components(m.vertices, m.triangles) == 1);
  CHECK(m.triangles == std::vector<Triangle>{{0, 1, 2}, {7, 8, 9}, {0, 2, 3}});
  CHECK(find_self_intersections(m).pairs == 0);
  // nothing crosses now, and a single component is left alone whatever it does to itself
  CHECK(scanmesh::recon::remove_crossing_components(m.vertices, m.triangles) == 0);
  Mesh one = m;
  one.triangles = {{0, 1, 2}, {0, 2, 3}};
  CHECK(scanmesh::recon::remove_crossing_components(one.vertices, one.triangles) == 0);
  CHECK(one.triangles.size() == 2);
}
