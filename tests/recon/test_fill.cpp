// Hole filling on request: loops closed by a minimum-weight patch of their own vertices, refined
// to the density around the hole and faired (or flat, on request), the mesh kept manifold and
// consistently oriented, existing edges never repeated, larger loops and non-manifold meshes
// left alone.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <array>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <numbers>
#include <numeric>
#include <random>
#include <stdexcept>
#include <vector>

#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/fill.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "loop_measure.hpp"
#include "support/shapes.hpp"

namespace {

using scanmesh::recon::analyze;
using scanmesh::recon::fill_holes;
using scanmesh::recon::FillOptions;
using scanmesh::recon::FillStats;
using scanmesh::recon::find_self_intersections;
using scanmesh::recon::Mesh;
using scanmesh::recon::Triangle;
using scanmesh::recon::Vec3;

/// After filling its one hole: a closed, manifold, outward sphere (genus 0).
void check_closed_outward_sphere(const Mesh& m) {
  const auto r = analyze(m);
  CHECK(r.boundary_loops == 0);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.non_manifold_vertices == 0);
  CHECK(r.orientation_consistent);
  CHECK(r.genus == 0);
  CHECK(r.signed_volume > 0);
}

/// The reconstruction of 6000 points of a sphere with the cap above z = cut left out: one hole.
/// The hole's border is the front's (no bulk patches): the figures below were measured on it,
/// and the bulk moves the loop's vertices (the fill of its loop has one longer edge, 4.2 times
/// the loop's mean edge instead of 3.3).
Mesh capless_sphere(double radius, double cut) {
  std::vector<Vec3> pts;
  for (const Vec3& p : scanmesh::test::sphere_points(6000, radius))
    if (p.z() < cut) pts.push_back(p);
  scanmesh::recon::ReconstructOptions opt;
  opt.front.bulk = false;
  return scanmesh::recon::reconstruct(pts, opt).mesh;
}

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

TEST_CASE("fill_holes with a perimeter limit closes a loop only when it is short for the "
          "spacing of its vertices",
          "[recon][fill]") {
  // The tetrahedron's open half again: its loop a-b-c-d has a perimeter of 2 + 2 sqrt(2) = 4.83.
  auto half_tetrahedron = [] {
    Mesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
    m.triangles = {Triangle{0, 1, 3}, Triangle{0, 3, 2}};
    return m;
  };
  FillOptions opt;
  opt.max_edges = 4;
  opt.refine = false;
  opt.max_perimeter_spacings = 10;
  {
    Mesh m = half_tetrahedron();
    const std::vector<float> fine(4, 0.4f);  // limit 4: a hole, kept
    const auto stats = fill_holes(m, opt, fine);
    CHECK(stats.filled == 0);
    CHECK(stats.kept == 1);
    CHECK(stats.crossing == 0);
    CHECK(m.triangles.size() == 2);
  }
  {
    Mesh m = half_tetrahedron();
    const std::vector<float> coarse(4, 0.5f);  // limit 5: a sampling gap, closed
    const auto stats = fill_holes(m, opt, coarse);
    CHECK(stats.filled == 1);
    CHECK(analyze(m).boundary_loops == 0);
  }
  {
    Mesh m = half_tetrahedron();
    const std::vector<float> mixed{0.2f, 0.2f, 0.2f, 1.4f};  // the mean decides: 0.5
    CHECK(fill_holes(m, opt, mixed).filled == 1);
  }
  Mesh m = half_tetrahedron();
  CHECK_THROWS_AS(fill_holes(m, opt), std::invalid_argument);  // the limit needs the spacing
  CHECK(m.triangles.size() == 2);
}

TEST_CASE("fill_holes with a width limit closes the narrow hole and keeps the wide one",
          "[recon][fill]") {
  // A sphere of radius 10 with two holes: a cap above z = 8 (12 wide) and a small
  // one around -x beyond x = -9.5 (3.1 in radius: 6.2 wide).
  std::vector<Vec3> pts;
  for (const Vec3& p : scanmesh::test::sphere_points(6000, 10.0))
    if (p.z() < 8 && p.x() > -9.5) pts.push_back(p);
  const Mesh open = scanmesh::recon::reconstruct(pts, {}).mesh;
  const auto before = analyze(open, true);
  REQUIRE(before.boundary_loops == 2);
  // Each loop's width as fill_holes measures it: the largest distance between two vertices.
  std::vector<double> width;
  for (const auto& loop : before.loops) {
    double w = 0;
    for (const std::uint32_t a : loop.vertices)
      for (const std::uint32_t b : loop.vertices)
        w = std::max(w, (open.vertices[a] - open.vertices[b]).norm());
    CHECK(scanmesh::recon::loop_width(open, loop.vertices) == Approx(w).epsilon(1e-12));
    // With a stop: a pair beyond it, as soon as one is found.
    CHECK(scanmesh::recon::loop_width(open, loop.vertices, 0.5 * w) > 0.5 * w);
    width.push_back(w);
  }
  std::sort(width.begin(), width.end());
  // (the rims run through the samples nearest the cuts, a spacing of 0.46 or less inside them,
  // where the sphere is a little wider)
  CHECK(width[0] > 6.2);
  CHECK(width[0] < 7.5);
  CHECK(width[1] > 12.0);
  CHECK(width[1] < 13.0);
  FillOptions opt;
  opt.max_edges = FillOptions::kLimit;
  {  // between the two: the narrow hole is closed, the wide one kept with its rim
    Mesh m = open;
    opt.max_width = 0.5 * (width[0] + width[1]);
    const FillStats stats = fill_holes(m, opt);
    CHECK(stats.filled == 1);
    CHECK(stats.kept == 1);
    CHECK(stats.crossing == 0);
    const auto after = analyze(m, true);
    REQUIRE(after.boundary_loops == 1);
    CHECK(after.loops[0].vertices.size() ==
          std::max(before.loops[0].vertices.size(), before.loops[1].vertices.size()));
    CHECK(after.genus == 0);
    CHECK(after.orientation_consistent);
  }
  {  // the narrow hole's width (up to rounding): closed, the limit is inclusive; under: kept
    Mesh m = open;
    opt.max_width = width[0] * (1 + 1e-12);
    CHECK(fill_holes(m, opt).filled == 1);
    m = open;
    opt.max_width = width[0] * (1 - 1e-9);
    CHECK(fill_holes(m, opt).filled == 0);
    CHECK(m.triangles.size() == open.triangles.size());
  }
  {  // over both: closed, outward, genus 0
    Mesh m = open;
    opt.max_width = width[1] + 1;
    CHECK(fill_holes(m, opt).filled == 2);
    check_closed_outward_sphere(m);
  }
  {  // the edge count still holds: both limits must pass
    Mesh m = open;
    opt.max_width = width[1] + 1;
    opt.max_edges = std::min(before.loops[0].vertices.size(), before.loops[1].vertices.size()) - 1;
    CHECK(fill_holes(m, opt).filled == 0);
  }
  // The limit is validated: a size of 0 or more (0: none), never NaN or infinite.
  FillOptions v;
  CHECK(v.validate().empty());
  v.max_width = 5;
  CHECK(v.validate().empty());
  for (const double bad : {-1.0, std::numeric_limits<double>::quiet_NaN(),
                           std::numeric_limits<double>::infinity()}) {
    v.max_width = bad;
    const auto errors = v.validate();
    REQUIRE(errors.size() == 1);
    CHECK_THAT(errors[0], Catch::Contains("width"));
  }
}

TEST_CASE("fill_holes never repeats an edge the mesh has, whatever the vertex numbering",
          "[recon][fill]") {
  // Two triangles on the diagonal a-c. The rim's patch on a-c would repeat that edge (and both
  // triangles turned over); the one on b-d is the only fill. Square flat: that patch lies on the
  // square itself, face to face with it (a closed mesh of no volume, whose triangles overlap),
  // so nothing is added. Square folded along a-c (b and d raised): the patch on b-d closes a
  // tetrahedron. Every numbering of the four corners must give the same.
  for (const double lift : {0.0, 0.5}) {
    const Vec3 corner[4] = {Vec3(0, 0, 0), Vec3(1, 0, lift), Vec3(1, 1, 0), Vec3(0, 1, lift)};
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
      INFO("lift " << lift << ", labels " << a << b << c << d);
      const FillStats stats = fill_holes(m, opt);
      const auto r = analyze(m);
      CHECK(r.non_manifold_edges == 0);
      CHECK(r.duplicate_triangles == 0);
      CHECK(find_self_intersections(m).pairs == 0);
      if (lift == 0) {
        CHECK(stats.filled == 0);
        CHECK(stats.kept == 1);
        CHECK(m.triangles.size() == 2);
      } else {
        CHECK(stats.filled == 1);
        CHECK(r.boundary_loops == 0);
        CHECK(r.edges == 6);
        CHECK(r.signed_volume != Approx(0.0).margin(1e-9));
      }
      ++numberings;
    } while (std::next_permutation(label.begin(), label.end()));
    CHECK(numberings == 24);
  }
}

TEST_CASE("fill_holes never lets a patch cross the mesh: such a loop stays open",
          "[recon][fill]") {
  // A flat frame in z = 0: the square [-2, 2]^2 with the hole [-1, 1]^2, eight triangles.
  Mesh m;
  m.vertices = {Vec3(-2, -2, 0), Vec3(2, -2, 0), Vec3(2, 2, 0), Vec3(-2, 2, 0),
                Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0), Vec3(-1, 1, 0)};
  for (std::uint32_t k = 0; k < 4; ++k) {
    const std::uint32_t o0 = k, o1 = (k + 1) % 4, i0 = 4 + k, i1 = 4 + (k + 1) % 4;
    m.triangles.push_back({o0, o1, i1});
    m.triangles.push_back({o0, i1, i0});
  }
  FillOptions opt;
  opt.max_edges = 4;
  SECTION("alone: the hole is closed; the outer rim's patch would cover the frame") {
    const FillStats stats = fill_holes(m, opt);
    CHECK(stats.filled == 1);
    CHECK(stats.kept == 1);
    CHECK(stats.crossing == 1);
    CHECK(analyze(m).boundary_loops == 1);
    CHECK(find_self_intersections(m).pairs == 0);
  }
  SECTION("a sheet through the hole: its patch would cut the sheet, so the hole stays") {
    const auto s = static_cast<std::uint32_t>(m.vertices.size());
    m.vertices.insert(m.vertices.end(), {Vec3(0, -0.5, -1), Vec3(0, 0.5, -1), Vec3(0, 0.5, 1),
                                         Vec3(0, -0.5, 1)});
    m.triangles.push_back({s, s + 1, s + 2});
    m.triangles.push_back({s, s + 2, s + 3});
    const std::size_t before = m.triangles.size();
    for (const bool refine : {true, false}) {
      opt.refine = refine;
      Mesh copy = m;
      const FillStats stats = fill_holes(copy, opt);
      CHECK(stats.filled == 0);
      CHECK(stats.kept == 3);
      CHECK(stats.crossing == 3);
      CHECK(copy.triangles.size() == before);
      CHECK(copy.vertices.size() == m.vertices.size());
    }
  }
}

TEST_CASE("fill_holes closes a reconstructed sphere's cap with a flat, outward patch",
          "[recon][fill]") {
  const double radius = 10, cut = 7;
  Mesh m = capless_sphere(radius, cut);
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
  SECTION("a loop within the limit is closed flat, on request") {
    FillOptions opt;
    opt.max_edges = loop_edges;
    opt.refine = false;
    const auto stats = fill_holes(m, opt);
    CHECK(stats.filled == 1);
    CHECK(stats.vertices == 0);
    // A triangulation of an n-gon has n - 2 triangles: no new vertex.
    CHECK(stats.triangles == loop_edges - 2);
    CHECK(m.triangles.size() == triangles + loop_edges - 2);
    check_closed_outward_sphere(m);
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

namespace {

/// Mean length of the mesh edges at the vertices of the mesh's first boundary loop.
double mean_edge_at_loop(const Mesh& m) {
  const auto report = analyze(m, true);
  std::vector<char> on_loop(m.vertices.size(), 0);
  for (std::uint32_t v : report.loops.at(0).vertices) on_loop[v] = 1;
  double sum = 0;
  std::size_t count = 0;
  for (const Triangle& tri : m.triangles)
    for (int k = 0; k < 3; ++k)
      if (on_loop[tri[k]] || on_loop[tri[(k + 1) % 3]]) {
        sum += (m.vertices[tri[(k + 1) % 3]] - m.vertices[tri[k]]).norm();
        ++count;
      }
  return sum / static_cast<double>(count);
}

}  // namespace

TEST_CASE("fill_holes refines a sphere's missing cap to the mesh's density and fairs it back "
          "towards the sphere",
          "[recon][fill]") {
  const double radius = 10, cut = 7;  // the cap: 45.6 degrees from the pole, 3 units high
  Mesh m = capless_sphere(radius, cut);
  const auto before = analyze(m, true);
  REQUIRE(before.boundary_loops == 1);
  const std::size_t n = before.boundary_loop_lengths[0];
  const std::size_t vertices = m.vertices.size(), triangles = m.triangles.size();
  const double edge = mean_edge_at_loop(m);
  const std::vector<Vec3> old_vertices = m.vertices;

  FillOptions opt;
  opt.max_edges = n;
  const auto stats = fill_holes(m, opt);
  REQUIRE(stats.filled == 1);
  CHECK(stats.vertices > 0);
  CHECK(m.vertices.size() == vertices + stats.vertices);
  // Euler: a disk patch with V inner vertices over an n-loop has n - 2 + 2V triangles.
  CHECK(stats.triangles == n - 2 + 2 * stats.vertices);
  CHECK(m.triangles.size() == triangles + stats.triangles);
  // The mesh's own vertices never move.
  for (std::size_t v = 0; v < vertices; ++v) REQUIRE(m.vertices[v] == old_vertices[v]);
  check_closed_outward_sphere(m);
  const auto r = analyze(m);
  CHECK(r.duplicate_triangles == 0);
  CHECK(r.degenerate_triangles == 0);
  // The patch's edges are as long as the mesh's around the hole, its triangles face out of the
  // sphere, and the faired vertices rise with the sphere: the flat patch lies 3 units (the
  // cap's height) below the pole.
  double worst = 0, top = 0;
  for (std::size_t v = vertices; v < m.vertices.size(); ++v) {
    worst = std::max(worst, std::abs(m.vertices[v].norm() - radius));
    top = std::max(top, m.vertices[v].z());
  }
  std::vector<double> lengths;
  for (std::size_t t = triangles; t < m.triangles.size(); ++t) {
    const Triangle& tri = m.triangles[t];
    const Vec3 normal = (m.vertices[tri[1]] - m.vertices[tri[0]])
                            .cross(m.vertices[tri[2]] - m.vertices[tri[0]]);
    const Vec3 centre = (m.vertices[tri[0]] + m.vertices[tri[1]] + m.vertices[tri[2]]) / 3.0;
    CHECK(normal.dot(centre) > 0);
    for (int k = 0; k < 3; ++k)
      lengths.push_back((m.vertices[tri[(k + 1) % 3]] - m.vertices[tri[k]]).norm());
  }
  std::sort(lengths.begin(), lengths.end());
  double mean = 0;
  for (double len : lengths) mean += len / static_cast<double>(lengths.size());
  const double p95 = lengths[lengths.size() * 95 / 100];
  INFO("loop " << n << " edges; mesh edges at the loop " << edge << ", patch edges mean " << mean
               << " p95 " << p95 << " longest " << lengths.back() << "; new vertices "
               << stats.vertices << "; top " << top << ", farthest from the sphere " << worst);
  // Liepa's split rule settles triangles whose centroid lies within sigma / sqrt(2) of a
  // corner: right triangles up to about 3 sigma along the hypotenuse remain. Measured: mean
  // 1.15, 95th percentile 2.0, longest 3.3 times the mesh's mean edge at the loop.
  CHECK(mean > 0.6 * edge);
  CHECK(mean < 1.5 * edge);
  CHECK(p95 < 2.5 * edge);
  CHECK(lengths.back() < 4 * edge);
  CHECK(top > radius - 0.25 * (radius - cut));
  CHECK(worst < 0.25 * (radius - cut));
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

namespace {

/// Two flat sheets 0.7 apart, each a 5 x 5 grid of unit squares split along their diagonal:
/// below (z = 0) one triangle missing (a gap), above (z = 0.7) the triangle over it replaced by a
/// spike of three triangles down to a point `s` of the lower sheet lying in that gap: the
/// front's mistake across a thin wall. Returns the index of s.
std::uint32_t spiked_sheets(Mesh& m, const Vec3& s) {
  auto id = [](std::uint32_t sheet, std::uint32_t i, std::uint32_t j) {
    return sheet * 25 + j * 5 + i;
  };
  for (std::uint32_t sheet = 0; sheet < 2; ++sheet)
    for (std::uint32_t j = 0; j < 5; ++j)
      for (std::uint32_t i = 0; i < 5; ++i) m.vertices.emplace_back(i, j, 0.7 * sheet);
  const auto spike = static_cast<std::uint32_t>(m.vertices.size());
  m.vertices.push_back(s);
  for (std::uint32_t sheet = 0; sheet < 2; ++sheet)
    for (std::uint32_t j = 0; j < 4; ++j)
      for (std::uint32_t i = 0; i < 4; ++i) {
        const Triangle low = {id(sheet, i, j), id(sheet, i + 1, j), id(sheet, i + 1, j + 1)};
        if (i == 2 && j == 2 && sheet == 0) {  // the gap
        } else if (i == 2 && j == 2) {         // the spike
          m.triangles.push_back({low[0], low[1], spike});
          m.triangles.push_back({low[1], low[2], spike});
          m.triangles.push_back({low[2], low[0], spike});
        } else {
          m.triangles.push_back(low);
        }
        m.triangles.push_back({id(sheet, i, j), id(sheet, i + 1, j + 1), id(sheet, i, j + 1)});
      }
  return spike;
}

}  // namespace

TEST_CASE("untangle_gaps removes a spike through a gap, closes both sheets and puts the point "
          "back into its own sheet",
          "[recon][fill]") {
  // s in the middle of the gap (a face split) or on its diagonal (an edge split, with the
  // lower sheet's triangle across it).
  const auto [s_at, fan] = GENERATE(table<Vec3, std::size_t>(
      {{Vec3(2.0 + 2.0 / 3.0, 2.0 + 1.0 / 3.0, 0), 3}, {Vec3(2.5, 2.5, 0), 4}}));
  Mesh m;
  const std::uint32_t s = spiked_sheets(m, s_at);
  const std::vector<float> spacing(m.vertices.size(), 1.0f);
  FillOptions opt;
  opt.max_edges = 8;
  opt.refine = false;
  opt.max_perimeter_spacings = 10;
  REQUIRE(analyze(m).boundary_loops == 3);
  const FillStats first = fill_holes(m, opt, spacing);
  CHECK(first.filled == 0);
  CHECK(first.crossing == 1);
  REQUIRE(first.crossed.size() == 1);
  CHECK(first.crossed[0].size() == 3);

  const scanmesh::recon::UntangleStats u =
      scanmesh::recon::untangle_gaps(m, opt, spacing, first);
  CHECK(u.removed == 3);
  CHECK(u.closed == 1);
  CHECK(u.reinserted == 1);
  const auto r = analyze(m);
  CHECK(r.boundary_loops == 2);  // the two sheets' borders
  CHECK(r.components == 2);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.non_manifold_vertices == 0);
  CHECK(r.orientation_consistent);
  CHECK(r.referenced_vertices == m.vertices.size());
  CHECK(find_self_intersections(m).pairs == 0);
  // Each sheet flat again, s in the lower one.
  std::size_t at_s = 0;
  for (const Triangle& t : m.triangles) {
    const double z = m.vertices[t[0]].z();
    CHECK(m.vertices[t[1]].z() == z);
    CHECK(m.vertices[t[2]].z() == z);
    if (t[0] == s || t[1] == s || t[2] == s) ++at_s;
  }
  CHECK(at_s == fan);
  CHECK(m.triangles.size() == 2 * 32 + 2);  // one split into three, or two into two each
}

TEST_CASE("untangle_gaps leaves a gap alone when untangling it would drop a point",
          "[recon][fill]") {
  // The frame of the crossing test with a sheet through its hole: removing the sheet's two
  // triangles would close the hole but leave the sheet's four points out of the mesh.
  Mesh m;
  m.vertices = {Vec3(-2, -2, 0), Vec3(2, -2, 0), Vec3(2, 2, 0), Vec3(-2, 2, 0),
                Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0), Vec3(-1, 1, 0),
                Vec3(0, -0.5, -1), Vec3(0, 0.5, -1), Vec3(0, 0.5, 1), Vec3(0, -0.5, 1)};
  for (std::uint32_t k = 0; k < 4; ++k) {
    const std::uint32_t o0 = k, o1 = (k + 1) % 4, i0 = 4 + k, i1 = 4 + (k + 1) % 4;
    m.triangles.push_back({o0, o1, i1});
    m.triangles.push_back({o0, i1, i0});
  }
  m.triangles.push_back({8, 9, 10});
  m.triangles.push_back({8, 10, 11});
  const std::vector<float> spacing(m.vertices.size(), 1.0f);
  FillOptions opt;
  opt.max_edges = 4;
  opt.refine = false;
  const FillStats first = fill_holes(m, opt, spacing);
  CHECK(first.crossing == 3);
  CHECK_FALSE(first.crossed.empty());
  const Mesh before = m;
  const scanmesh::recon::UntangleStats u =
      scanmesh::recon::untangle_gaps(m, opt, spacing, first);
  CHECK(u.removed == 0);
  CHECK(u.closed == 0);
  CHECK(m.triangles == before.triangles);
  CHECK(m.vertices.size() == before.vertices.size());
}

namespace {

/// A flat grid of n x n unit squares (vertex j * (n + 1) + i at (i, j, 0)), each split along its
/// diagonal (v, v + 1, v + n + 2 and v, v + n + 2, v + n + 1), without the square at (hole_i,
/// hole_j) when hole_i < n.
Mesh flat_grid(std::uint32_t n, std::uint32_t hole_i = ~0u, std::uint32_t hole_j = ~0u) {
  Mesh m;
  for (std::uint32_t j = 0; j <= n; ++j)
    for (std::uint32_t i = 0; i <= n; ++i) m.vertices.emplace_back(i, j, 0);
  for (std::uint32_t j = 0; j < n; ++j)
    for (std::uint32_t i = 0; i < n; ++i) {
      if (i == hole_i && j == hole_j) continue;
      const std::uint32_t v = j * (n + 1) + i;
      m.triangles.push_back({v, v + 1, v + n + 2});
      m.triangles.push_back({v, v + n + 2, v + n + 1});
    }
  return m;
}

/// The result of a gap closing whose one gap was left open because its patch would cross the
/// triangles `crossed` of m (as untangle_gaps takes it).
FillStats crossing_gap(const Mesh& m, const std::vector<Triangle>& crossed) {
  FillStats first;
  first.crossing = 1;
  std::vector<std::uint32_t>& ids = first.crossed.emplace_back();
  for (const Triangle& t : crossed) {
    const auto it = std::find(m.triangles.begin(), m.triangles.end(), t);
    REQUIRE(it != m.triangles.end());
    ids.push_back(static_cast<std::uint32_t>(it - m.triangles.begin()));
  }
  std::sort(ids.begin(), ids.end());
  return first;
}

/// The options of the gap closing (no new vertex, perimeter at most 10 spacings).
FillOptions gap_options() {
  FillOptions opt;
  opt.max_edges = 8;
  opt.refine = false;
  opt.max_perimeter_spacings = 10;
  return opt;
}

/// untangle_gaps with the gap closing's options over the unit spacing of the flat grids.
scanmesh::recon::UntangleStats untangle_unit(Mesh& m, const FillStats& first) {
  const std::vector<float> spacing(m.vertices.size(), 1.0f);
  return scanmesh::recon::untangle_gaps(m, gap_options(), spacing, first);
}

}  // namespace

TEST_CASE("untangle_gaps widens a removal that would split a vertex's fan, and refuses what "
          "no fill mends",
          "[recon][fill]") {
  // A flat 4 x 4 grid of unit squares split along their diagonals; the "gap" is given by the
  // triangles its patch would cross. Around the interior vertex 12 (at 2, 2) the six triangles
  // run 13-18, 18-17, 17-11, 11-6, 6-7, 7-13; around the border vertex 2 three run 1-7, 7-8,
  // 8-3. Removing two of 12's that are not neighbours leaves that vertex two fans: the smaller
  // one goes too (widened), and the trial then closes only the hole it made (no fewer loops),
  // so it is refused. Removing the middle one of 2's splits it the same way, but the widened
  // removal opens the border loop, which no fill closes: not tried (unfillable). Removing two
  // neighbours (a quad hole inside, a notch at the border) is tried as it is and refused.
  Mesh m = flat_grid(4);
  const auto [removed, widened, unfillable] =
      GENERATE(table<std::vector<Triangle>, std::size_t, std::size_t>({
          {{Triangle{12, 13, 18}, Triangle{11, 12, 17}}, 1, 0},  // apart around vertex 12
          {{Triangle{2, 8, 7}}, 0, 1},  // the middle of border vertex 2's fan
          {{Triangle{12, 13, 18}, Triangle{12, 18, 17}}, 0, 0},  // neighbours: a quad hole
          {{Triangle{1, 2, 7}, Triangle{1, 7, 6}}, 0, 0},  // neighbours at the border: a notch
      }));
  const FillStats first = crossing_gap(m, removed);
  const Mesh before = m;
  const scanmesh::recon::UntangleStats u = untangle_unit(m, first);
  INFO("removed " << removed.size() << " triangles, the first " << removed[0][0] << "-"
                  << removed[0][1] << "-" << removed[0][2]);
  CHECK(u.widened == widened);
  CHECK(u.unfillable == unfillable);
  CHECK(u.split_fans == 0);
  CHECK(u.removed == 0);
  CHECK(u.closed == 0);
  CHECK(u.dropped.empty());
  CHECK(u.renumber.empty());
  CHECK(m.triangles == before.triangles);
  CHECK(m.vertices == before.vertices);
}

TEST_CASE("untangle_gaps refuses, without a trial, a removal that splits a fan into large ones",
          "[recon][fill]") {
  // A disk of 40 triangles around its centre; removing two opposite ones leaves the centre two
  // fans of 19: taking in the smaller one would remove more than kUntangleMaxTriangles.
  Mesh m;
  constexpr std::uint32_t kN = 40;
  m.vertices.emplace_back(0, 0, 0);
  for (std::uint32_t k = 0; k < kN; ++k) {
    const double a = 2 * std::numbers::pi * k / kN;
    m.vertices.emplace_back(std::cos(a), std::sin(a), 0);
  }
  for (std::uint32_t k = 0; k < kN; ++k) m.triangles.push_back({0, 1 + k, 1 + (k + 1) % kN});
  const FillStats first = crossing_gap(m, {m.triangles[0], m.triangles[kN / 2]});
  const Mesh before = m;
  const scanmesh::recon::UntangleStats u = untangle_unit(m, first);
  CHECK(u.split_fans == 1);
  CHECK(u.widened == 0);
  CHECK(u.removed == 0);
  CHECK(m.triangles == before.triangles);
}

namespace {

/// A flat 6 x 6 grid of unit squares (vertex j * 7 + i at (i, j, 0), squares split along
/// their diagonals) with the square at (3, 3) left out (a gap, 24-25-32-31) and a flap on the
/// gap's edge 24-25, above the gap: one triangle 24-25-s1, a second around vertex 24,
/// 24-s1-s2, and beyond them s2-s1-s3, s4-s3-s1 and s3-s4-s5, 0.6-1.0 above the grid's plane
/// (as a fold of another sheet meshed onto a gap's rim). Returns the flap's vertices.
std::vector<std::uint32_t> flapped_grid(Mesh& m, int flap_triangles) {
  m = flat_grid(6, 3, 3);
  std::vector<std::uint32_t> flap;
  auto add = [&](double x, double y, double z) {
    flap.push_back(static_cast<std::uint32_t>(m.vertices.size()));
    m.vertices.emplace_back(x, y, z);
  };
  add(3.5, 3.3, 0.6);
  m.triangles.push_back({24, 25, flap[0]});
  if (flap_triangles >= 2) {
    add(3.2, 3.6, 0.7);
    m.triangles.push_back({24, flap[0], flap[1]});
  }
  if (flap_triangles >= 3) {
    add(3.6, 3.7, 0.8);
    m.triangles.push_back({flap[1], flap[0], flap[2]});
  }
  if (flap_triangles >= 4) {
    add(3.8, 3.4, 0.9);
    m.triangles.push_back({flap[3], flap[2], flap[0]});
  }
  if (flap_triangles >= 5) {
    add(3.9, 3.9, 1.0);
    m.triangles.push_back({flap[2], flap[3], flap[4]});
  }
  return flap;
}

}  // namespace

TEST_CASE("untangle_gaps takes out a flap whose removal the gap needs, its vertices then "
          "dropped",
          "[recon][fill]") {
  // Removing 17-25-24 alone would leave vertex 24 (and 25) a fan in the grid and the flap's
  // fan: the flap goes too, and so does a third triangle beyond it that the removal would cut
  // loose (a speck). The flap's vertices lie on no patch and leave the mesh; the gap and the
  // removed triangle make one 5-edge loop, closed.
  const int flap_triangles = GENERATE(1, 2, 3);
  Mesh m;
  const std::vector<std::uint32_t> flap = flapped_grid(m, flap_triangles);
  REQUIRE(analyze(m).boundary_loops == 2);
  REQUIRE(analyze(m).non_manifold_vertices == 0);
  REQUIRE(find_self_intersections(m).pairs == 0);
  const Mesh before = m;
  const scanmesh::recon::UntangleStats u = untangle_unit(m, crossing_gap(m, {{17, 25, 24}}));
  CHECK(u.widened == 1);
  CHECK(u.unfillable == 0);
  CHECK(u.split_fans == 0);
  CHECK(u.removed == 1 + static_cast<std::size_t>(flap_triangles));
  CHECK(u.closed == 1);
  CHECK(u.reinserted == 0);
  // The flap's vertices, the last ones, are gone and reported; the grid's keep their indices.
  REQUIRE(u.dropped.size() == flap.size());
  for (std::size_t k = 0; k < flap.size(); ++k) CHECK(u.dropped[k] == before.vertices[flap[k]]);
  REQUIRE(u.renumber.size() == before.vertices.size());
  for (std::uint32_t v = 0; v < 49; ++v) CHECK(u.renumber[v] == v);
  for (std::uint32_t v : flap) CHECK(u.renumber[v] == scanmesh::recon::kNoVertex);
  REQUIRE(m.vertices.size() == 49);
  CHECK(std::equal(m.vertices.begin(), m.vertices.end(), before.vertices.begin()));
  const auto r = analyze(m);
  CHECK(r.boundary_loops == 1);
  CHECK(r.components == 1);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.non_manifold_vertices == 0);
  CHECK(r.orientation_consistent);
  CHECK(r.referenced_vertices == m.vertices.size());
  CHECK(r.genus == 0);
  CHECK(find_self_intersections(m).pairs == 0);
  // The grid's 70 triangles less 17-25-24, and the 5-edge loop's three: a flat square again.
  CHECK(m.triangles.size() == 72);
  for (const Triangle& t : m.triangles) CHECK(m.vertices[t[0]].z() == 0);
}

TEST_CASE("untangle_gaps leaves a flap that a removal would cut a piece off", "[recon][fill]") {
  // Beyond the two flap triangles around vertex 24, three more: removing the two would leave
  // them a piece of their own, larger than a speck, so the trial is refused (as many
  // components).
  Mesh m;
  (void)flapped_grid(m, 5);
  REQUIRE(analyze(m).orientation_consistent);
  REQUIRE(analyze(m).boundary_loops == 2);
  const Mesh before = m;
  const scanmesh::recon::UntangleStats u = untangle_unit(m, crossing_gap(m, {{17, 25, 24}}));
  CHECK(u.widened == 1);
  CHECK(u.removed == 0);
  CHECK(u.closed == 0);
  CHECK(u.dropped.empty());
  CHECK(m.triangles == before.triangles);
  CHECK(m.vertices == before.vertices);
}

TEST_CASE("untangle_gaps does not try a widened removal whose loop no fill closes",
          "[recon][fill]") {
  // The flap on the grid's border edge 3-4 instead, the patch taken to cross 3-4-11 across it:
  // the removal opens the border loop (24 edges), which the gap closing never closes.
  Mesh m = flat_grid(6);
  m.vertices.emplace_back(3.5, -0.8, 0.6);
  m.triangles.push_back({4, 3, 49});
  const Mesh before = m;
  const scanmesh::recon::UntangleStats u = untangle_unit(m, crossing_gap(m, {{3, 4, 11}}));
  CHECK(u.unfillable == 1);
  CHECK(u.widened == 0);
  CHECK(u.removed == 0);
  CHECK(m.triangles == before.triangles);
  CHECK(m.vertices == before.vertices);
}

namespace {

/// A dense strip (columns x = -0.2 and x = 0, rows 0.2 apart from y = -0.2 to 1.2) and a coarse
/// point w to its right, joined to the x = 0 column by three triangles: across the rows below
/// y = 0 and above y = 1, and one whose long edge runs from y = 1 down to y = 0. The column's
/// points between lie `offset` to the left of that edge, so the two sides leave a slit (the
/// loop a0 -> a1 -> ... -> a5 -> a0), as where a coarse row meets a dense one.
Mesh slit_mesh(double offset) {
  Mesh m;
  for (int i = -1; i <= 6; ++i) {
    const double y = 0.2 * i;
    m.vertices.emplace_back(-0.2, y, 0);                                       // b(i)
    m.vertices.emplace_back(i >= 1 && i <= 4 ? -offset : 0.0, y, 0.0);        // a(i)
  }
  auto b = [](int i) { return static_cast<std::uint32_t>(2 * (i + 1)); };
  auto a = [](int i) { return static_cast<std::uint32_t>(2 * (i + 1) + 1); };
  for (int i = -1; i < 6; ++i) {
    m.triangles.push_back({b(i), a(i), a(i + 1)});
    m.triangles.push_back({b(i), a(i + 1), b(i + 1)});
  }
  m.vertices.emplace_back(1.0, 0.5, 0.0);  // w = 16
  m.triangles.push_back({a(0), a(-1), 16});
  m.triangles.push_back({a(5), a(0), 16});
  m.triangles.push_back({a(6), a(5), 16});
  return m;
}

}  // namespace

TEST_CASE("zip_slits splits the coarse triangle at the dense row's points along its edge",
          "[recon][fill]") {
  Mesh m = slit_mesh(0.03);
  REQUIRE(analyze(m).boundary_loops == 2);  // the outer border and the slit
  const std::vector<float> spacing(m.vertices.size(), 0.2f);
  const auto triangles = m.triangles.size();
  const auto st = scanmesh::recon::zip_slits(m, spacing);
  CHECK(st.zipped == 1);
  CHECK(st.split_points == 4);
  CHECK(st.refused == 0);
  const auto r = analyze(m);
  CHECK(r.boundary_loops == 1);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.non_manifold_vertices == 0);
  CHECK(r.orientation_consistent);
  CHECK(r.components == 1);
  CHECK(m.triangles.size() == triangles + 4);  // one triangle became a fan of five
  CHECK(m.vertices.size() == 17);              // no vertex added or moved
  CHECK(find_self_intersections(m).pairs == 0);
  // Every fan triangle has the coarse point as its apex and faces +z as the strip does.
  std::size_t fan = 0;
  for (const Triangle& t : m.triangles) {
    if (t[0] != 16 && t[1] != 16 && t[2] != 16) continue;
    ++fan;
    const Vec3 n = (m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]);
    CHECK(n.z() > 0);
  }
  CHECK(fan == 7);  // the fan of five and the two triangles beyond the slit
}

TEST_CASE("zip_slits leaves a loop whose points lie off the edge: a hole, not a slit",
          "[recon][fill]") {
  // 0.15 off the line, beyond half the spacing (0.1): the column bends away from the edge.
  Mesh m = slit_mesh(0.15);
  const Mesh before = m;
  const std::vector<float> spacing(m.vertices.size(), 0.2f);
  const auto st = scanmesh::recon::zip_slits(m, spacing);
  CHECK(st.zipped == 0);
  CHECK(m.triangles == before.triangles);
  CHECK(analyze(m).boundary_loops == 2);
  // A band of 0 zips nothing either; too few spacings is an error.
  Mesh near = slit_mesh(0.03);
  CHECK(scanmesh::recon::zip_slits(near, spacing, 0.0).zipped == 0);
  CHECK_THROWS_AS(scanmesh::recon::zip_slits(near, std::vector<float>(3, 0.2f)), std::invalid_argument);
}

namespace {

/// An n x n grid of unit squares in the plane z = 0, each split along its diagonal, with the
/// triangles `skip` (by index: 2 per square, row by row) left out, the vertices numbered in a
/// shuffled order when `seed` is not 0; every vertex on a loop is kBoundary.
struct GridWithHoles {
  std::vector<Vec3> points;
  std::vector<Triangle> triangles;
  std::vector<scanmesh::recon::VertexState> state;
};
GridWithHoles grid_with_holes(std::uint32_t n, const std::vector<std::size_t>& skip,
                              unsigned seed = 0) {
  GridWithHoles g;
  const std::uint32_t w = n + 1;
  std::vector<std::uint32_t> label(w * w);
  std::iota(label.begin(), label.end(), 0u);
  if (seed != 0) std::shuffle(label.begin(), label.end(), std::mt19937(seed));
  g.points.resize(label.size());
  for (std::uint32_t y = 0; y < w; ++y)
    for (std::uint32_t x = 0; x < w; ++x) g.points[label[y * w + x]] = Vec3(x, y, 0);
  for (std::uint32_t y = 0; y < n; ++y)
    for (std::uint32_t x = 0; x < n; ++x) {
      const std::uint32_t a = label[y * w + x], b = label[y * w + x + 1], c = label[(y + 1) * w + x + 1],
                          d = label[(y + 1) * w + x];
      g.triangles.push_back({a, b, c});
      g.triangles.push_back({a, c, d});
    }
  for (auto it = skip.rbegin(); it != skip.rend(); ++it)
    g.triangles.erase(g.triangles.begin() + static_cast<std::ptrdiff_t>(*it));
  // Boundary: a vertex with an edge in one triangle only.
  std::vector<std::array<std::uint32_t, 2>> edges;
  for (const Triangle& t : g.triangles)
    for (int k = 0; k < 3; ++k) edges.push_back({std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])});
  std::sort(edges.begin(), edges.end());
  g.state.assign(g.points.size(), scanmesh::recon::VertexState::kDone);
  for (std::size_t i = 0; i < edges.size(); ++i) {
    const bool single = (i == 0 || edges[i - 1] != edges[i]) && (i + 1 == edges.size() || edges[i + 1] != edges[i]);
    if (single)
      for (std::uint32_t v : edges[i]) g.state[v] = scanmesh::recon::VertexState::kBoundary;
  }
  return g;
}

}  // namespace

TEST_CASE("check_loops finds a small loop as a sampling gap and a long border as none, walking "
          "every loop once",
          "[recon][fill]") {
  using scanmesh::recon::detail::check_loops;
  constexpr double kFactor = 10;  // perimeter limit in spacings
  SECTION("the border of a 6 x 6 grid alone: 24 unit edges, no gap at any edge limit") {
    const GridWithHoles g = grid_with_holes(6, {});
    const std::vector<float> spacing(g.points.size(), 1.0f);
    for (std::size_t max_edges : {8, 24, 64})
      CHECK_FALSE(check_loops(g.points, g.triangles, g.state, spacing, max_edges, kFactor, 0).gap);
    // With a spacing of 3, 24 edges of 1 are within 10 spacings: a gap once 24 edges are allowed.
    const std::vector<float> coarse(g.points.size(), 3.0f);
    CHECK_FALSE(check_loops(g.points, g.triangles, g.state, coarse, 23, kFactor, 0).gap);
    CHECK(check_loops(g.points, g.triangles, g.state, coarse, 24, kFactor, 0).gap);
  }
  SECTION("one square missing in the middle: a 4-edge gap inside the border") {
    const std::size_t sq = 2 * (3 * 6 + 3);  // square (3, 3)
    const GridWithHoles g = grid_with_holes(6, {sq, sq + 1});
    const std::vector<float> spacing(g.points.size(), 1.0f);
    CHECK(check_loops(g.points, g.triangles, g.state, spacing, 8, kFactor, 0).gap);
    CHECK_FALSE(check_loops(g.points, g.triangles, g.state, spacing, 3, kFactor, 0).gap);
    // Its perimeter (4) is over twice the spacing: no gap under that limit.
    CHECK_FALSE(check_loops(g.points, g.triangles, g.state, spacing, 8, 2.0, 0).gap);
  }
  SECTION("two missing triangles touching at one vertex: each is a 3-edge gap, found whichever "
          "loop the walk through the shared vertex follows") {
    // Squares (2, 2) and (3, 3) share the corner (3, 3): their triangles {a, c, d} of (2, 2)
    // and {a, b, c} of (3, 3) meet there only (and the other halves likewise). Under some
    // numberings the walk from the first edge of one hole turns into the other at the shared
    // vertex and does not come back to its start.
    for (const auto& skip : {std::vector<std::size_t>{2 * (2 * 6 + 2) + 1, 2 * (3 * 6 + 3)},
                             std::vector<std::size_t>{2 * (2 * 6 + 2), 2 * (3 * 6 + 3) + 1}})
      for (unsigned seed = 0; seed < 16; ++seed) {
        CAPTURE(skip, seed);
        const GridWithHoles g = grid_with_holes(6, skip, seed);
        const std::vector<float> spacing(g.points.size(), 1.0f);
        CHECK(check_loops(g.points, g.triangles, g.state, spacing, 8, kFactor, 0).gap);
        CHECK_FALSE(check_loops(g.points, g.triangles, g.state, spacing, 2, kFactor, 0).gap);
      }
  }
}

TEST_CASE("untangle_gaps tries at most kMaxUntangledGaps gaps and counts the others",
          "[recon][fill]") {
  // Each try checks the whole mesh again: a scan with hundreds of such gaps took minutes.
  // 20 copies of the spiked sheets side by side: the first 16 gaps are untangled, 4 stay open.
  constexpr std::uint32_t kCopies = 20;
  static_assert(kCopies > scanmesh::recon::kMaxUntangledGaps);
  Mesh m;
  for (std::uint32_t c = 0; c < kCopies; ++c) {
    Mesh one;
    spiked_sheets(one, Vec3(2.0 + 2.0 / 3.0, 2.0 + 1.0 / 3.0, 0));
    const auto offset = static_cast<std::uint32_t>(m.vertices.size());
    for (const Vec3& v : one.vertices) m.vertices.push_back(v + Vec3(10.0 * c, 0, 0));
    for (const Triangle& t : one.triangles)
      m.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  }
  const std::vector<float> spacing(m.vertices.size(), 1.0f);
  FillOptions opt;
  opt.max_edges = 8;
  opt.refine = false;
  opt.max_perimeter_spacings = 10;
  const FillStats first = fill_holes(m, opt, spacing);
  REQUIRE(first.crossing == kCopies);
  const scanmesh::recon::UntangleStats u =
      scanmesh::recon::untangle_gaps(m, opt, spacing, first);
  CHECK(u.closed == scanmesh::recon::kMaxUntangledGaps);
  CHECK(u.skipped == kCopies - scanmesh::recon::kMaxUntangledGaps);
  CHECK(u.removed == 3 * scanmesh::recon::kMaxUntangledGaps);
  const auto r = analyze(m);
  CHECK(r.boundary_loops == 2 * kCopies + u.skipped);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.orientation_consistent);
  CHECK(find_self_intersections(m).pairs == 0);
}
