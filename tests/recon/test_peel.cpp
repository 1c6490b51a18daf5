// Border chords peeled: a border triangle whose border edge runs past a measured point (an
// obtuse angle at an inner vertex) is removed, so the border passes through the samples.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "peel.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "support/shapes.hpp"

using scanmesh::recon::Vec3;
namespace recon = scanmesh::recon;

namespace {

/// A strip of a flat scan: a border row Q0..Q4 that bulges into the mesh (Qi.y = 0.3 (1 -
/// (x/2)^2)), a row R0..R4 above it, and the front's chords below the bulge: the fan (Q0, Q4,
/// Q2), (Q0, Q2, Q1), (Q2, Q4, Q3) in the plane, whose border edge Q0 -> Q4 passes 0.3 below Q2.
recon::Mesh bulging_border() {
  recon::Mesh m;
  for (int i = 0; i < 5; ++i) {
    const double x = i - 2.0;
    m.vertices.emplace_back(x, 0.3 * (1 - x * x / 4), 0);  // Q_i = i
  }
  for (int i = 0; i < 5; ++i) m.vertices.emplace_back(i - 2.0, 1.5, 0);  // R_i = 5 + i
  for (std::uint32_t i = 0; i < 4; ++i) {
    m.triangles.push_back({i, i + 1, 5 + i + 1});
    m.triangles.push_back({i, 5 + i + 1, 5 + i});
  }
  m.triangles.push_back({0, 4, 2});
  m.triangles.push_back({0, 2, 1});
  m.triangles.push_back({2, 4, 3});
  return m;
}

/// Whether v is on a border: the report's boundary loops list their vertices.
bool on_border(const recon::MeshReport& rep, std::uint32_t v) {
  for (const auto& loop : rep.loops)
    for (std::uint32_t x : loop.vertices)
      if (x == v) return true;
  return false;
}

}  // namespace

TEST_CASE("a fan of chords under a bulging border is peeled until the border meets every sample",
          "[recon][peel]") {
  recon::Mesh m = bulging_border();
  const recon::MeshReport before = recon::analyze(m, true);
  REQUIRE(before.boundary_loops == 1);
  CHECK_FALSE(on_border(before, 1));
  CHECK_FALSE(on_border(before, 2));
  CHECK_FALSE(on_border(before, 3));
  // (Q0, Q4, Q2) has 163 degrees at Q2; once it is gone, (Q0, Q2, Q1) has 172 at Q1 and
  // (Q2, Q4, Q3) 172 at Q3.
  CHECK(recon::detail::peel_border_chords(m, 120) == 3);
  REQUIRE(m.triangles.size() == 8);
  const recon::Mesh strip = bulging_border();  // its first 8 triangles are the strip's
  for (std::uint32_t i = 0; i < 8; ++i) CHECK(m.triangles[i] == strip.triangles[i]);
  const recon::MeshReport after = recon::analyze(m, true);
  CHECK(after.boundary_loops == 1);
  CHECK(after.components == 1);
  CHECK(after.genus == 0);
  CHECK(after.non_manifold_vertices == 0);
  CHECK(after.non_manifold_edges == 0);
  CHECK(after.orientation_consistent);
  CHECK(after.referenced_vertices == 10);
  for (std::uint32_t q = 0; q < 5; ++q) CHECK(on_border(after, q));
}

TEST_CASE("peeling stops at the bound and leaves closed meshes and inner apexes alone",
          "[recon][peel]") {
  SECTION("the first chord's apex angle (163 degrees) is under the bound") {
    recon::Mesh m = bulging_border();
    CHECK(recon::detail::peel_border_chords(m, 165) == 0);
    CHECK(m.triangles == bulging_border().triangles);
  }
  SECTION("off") {
    recon::Mesh m = bulging_border();
    CHECK(recon::detail::peel_border_chords(m, 0) == 0);
    CHECK(m.triangles.size() == 11);
  }
  SECTION("a closed mesh has no border") {
    recon::Mesh m = scanmesh::test::tetrahedron();
    const std::size_t n = m.triangles.size();
    CHECK(recon::detail::peel_border_chords(m, 90.5) == 0);
    CHECK(m.triangles.size() == n);
  }
  SECTION("an apex on the border (two border edges) is never peeled") {
    // A lone obtuse triangle: every vertex is on the border.
    recon::Mesh m;
    m.vertices = {Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(0, 0.1, 0)};
    m.triangles = {{0, 1, 2}};
    CHECK(recon::detail::peel_border_chords(m, 120) == 0);
    CHECK(m.triangles.size() == 1);
  }
}

TEST_CASE("the chord bound is validated with the other reconstruction options", "[recon][peel]") {
  recon::ReconstructOptions opt;
  CHECK(opt.validate().empty());  // 110 by default
  opt.peel_apex_deg = 0;          // off
  CHECK(opt.validate().empty());
  for (const double bad : {45.0, 180.0, -1.0, std::nan("")}) {
    opt.peel_apex_deg = bad;
    const auto errors = opt.validate();
    REQUIRE(errors.size() == 1);
    CHECK(errors.front().find("border chord") != std::string::npos);
  }
}
