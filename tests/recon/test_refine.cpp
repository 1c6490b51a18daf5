// Inserting the points the front left out (refine.hpp): flat patches, bevelled sharp edges,
// points that must stay out.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <cmath>
#include <set>

#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/refine.hpp"

using scanmesh::recon::analyze;
using scanmesh::recon::FrontResult;
using scanmesh::recon::insert_unused_points;
using scanmesh::recon::LocalFrames;
using scanmesh::recon::Mesh;
using scanmesh::recon::PointGrid;
using scanmesh::recon::Triangle;
using scanmesh::recon::Vec3;
using scanmesh::recon::VertexState;

namespace {

/// A mesh as the front leaves it: points, triangles, and the points it did not reach.
struct Scene {
  std::vector<Vec3> points;
  std::vector<Eigen::Vector3f> normals;
  std::vector<Triangle> triangles;
  std::vector<std::uint32_t> left_out;

  std::uint32_t add(const Vec3& p, const Vec3& n) {
    points.push_back(p);
    normals.push_back(n.normalized().cast<float>());
    return static_cast<std::uint32_t>(points.size() - 1);
  }
  /// Adds triangle (a, b, c), wound so that its normal points along `outward`.
  void tri(std::uint32_t a, std::uint32_t b, std::uint32_t c, const Vec3& outward) {
    const Vec3 n = (points[b] - points[a]).cross(points[c] - points[a]);
    if (n.dot(outward) >= 0)
      triangles.push_back({a, b, c});
    else
      triangles.push_back({a, c, b});
  }
  /// Triangles between two rows of points (same length), wound along `outward`.
  void strip(const std::vector<std::uint32_t>& r1, const std::vector<std::uint32_t>& r2,
             const Vec3& outward) {
    for (std::size_t i = 0; i + 1 < r1.size(); ++i) {
      tri(r1[i], r1[i + 1], r2[i], outward);
      tri(r1[i + 1], r2[i + 1], r2[i], outward);
    }
  }

  struct Run {
    FrontResult front;
    scanmesh::recon::RefineStats stats;
    Mesh mesh;
  };
  Run refine() const {
    LocalFrames frames;
    frames.normal = normals;
    frames.spacing.assign(points.size(), 1.0f);
    frames.flatness.assign(points.size(), 0.0f);
    PointGrid grid;
    grid.build(points, 3.6);
    Run r;
    r.front.triangles = triangles;
    r.front.state.assign(points.size(), VertexState::kDone);
    for (std::uint32_t q : left_out) r.front.state[q] = VertexState::kOutlier;
    r.front.outliers = left_out;
    r.stats = insert_unused_points(points, frames, grid, r.front);
    r.mesh.vertices = points;
    r.mesh.triangles = r.front.triangles;
    return r;
  }
};

/// A flat 6 x 6 patch in z = 0 (spacing 1, normals +z), triangulated.
Scene flat_patch() {
  Scene s;
  std::vector<std::vector<std::uint32_t>> rows(6);
  for (int y = 0; y < 6; ++y)
    for (int x = 0; x < 6; ++x) rows[y].push_back(s.add(Vec3(x, y, 0), Vec3::UnitZ()));
  for (int y = 0; y + 1 < 6; ++y) s.strip(rows[y], rows[y + 1], Vec3::UnitZ());
  return s;
}

void require_valid(const Mesh& m) {
  const auto rep = analyze(m);
  REQUIRE(rep.non_manifold_edges == 0);
  REQUIRE(rep.non_manifold_vertices == 0);
  REQUIRE(rep.orientation_consistent);
  REQUIRE(rep.degenerate_triangles == 0);
  REQUIRE(rep.duplicate_triangles == 0);
}

}  // namespace

TEST_CASE("refine: a point left out of a flat patch is inserted, topology unchanged", "[recon][refine]") {
  Scene s = flat_patch();
  const auto before = analyze(Mesh{s.points, s.triangles});
  const std::uint32_t q = s.add(Vec3(2.3, 2.6, 0.05), Vec3::UnitZ());
  s.left_out = {q};
  const auto r = s.refine();
  CHECK(r.stats.inserted == 1);
  CHECK(r.front.outliers.empty());
  CHECK(r.front.state[q] == VertexState::kDone);
  CHECK(r.mesh.triangles.size() == s.triangles.size() + 2);
  require_valid(r.mesh);
  const auto rep = analyze(r.mesh);
  CHECK(rep.referenced_vertices == s.points.size());
  CHECK(rep.boundary_loops == before.boundary_loops);
  CHECK(rep.genus == before.genus);
  CHECK(rep.components == 1);
  // Still facing +z everywhere (no triangle turned over).
  for (const Triangle& t : r.mesh.triangles) {
    const Vec3 n = (s.points[t[1]] - s.points[t[0]]).cross(s.points[t[2]] - s.points[t[0]]);
    CHECK(n.z() > 0);
  }
}

TEST_CASE("refine: a point on the border of the patch splits the border edge", "[recon][refine]") {
  Scene s = flat_patch();
  const std::uint32_t q = s.add(Vec3(2.5, 0.0, 0.0), Vec3::UnitZ());
  s.left_out = {q};
  const auto r = s.refine();
  CHECK(r.stats.inserted == 1);
  CHECK(r.stats.edge_splits == 1);
  CHECK(r.front.state[q] == VertexState::kBoundary);
  require_valid(r.mesh);
  const auto rep = analyze(r.mesh);
  CHECK(rep.boundary_loops == 1);
  CHECK(rep.boundary_loop_lengths.front() == 21);  // 20 border edges, one of them split
}

TEST_CASE("refine: points facing the other way or far off the surface stay out", "[recon][refine]") {
  Scene s = flat_patch();
  // The other side of a thin wall: its normal points away.
  const std::uint32_t back = s.add(Vec3(2.3, 2.6, -0.4), -Vec3::UnitZ());
  // Well above the patch (more than one spacing).
  const std::uint32_t high = s.add(Vec3(3.4, 1.3, 1.6), Vec3::UnitZ());
  // Beyond the patch's border.
  const std::uint32_t beyond = s.add(Vec3(7.5, 2.5, 0.0), Vec3::UnitZ());
  s.left_out = {back, high, beyond};
  const auto r = s.refine();
  CHECK(r.stats.inserted == 0);
  CHECK(r.front.outliers == s.left_out);
  CHECK(r.front.triangles == s.triangles);
  for (std::uint32_t q : s.left_out) CHECK(r.front.state[q] == VertexState::kOutlier);
}

TEST_CASE("refine: a bevelled sharp edge gets its feature row back, with edges along it", "[recon][refine]") {
  // A right-angle convex edge along x: face A is z = 0 (y <= 0, normal +z), face B is y = 0
  // (z <= 0, normal +y). The front bridged the edge with a bevel from row (y = -1, z = 0) to
  // row (y = 0, z = -1) and left the feature row (y = 0, z = 0) out, 0.71 spacings above it.
  Scene s;
  const int n = 9;
  auto row = [&](double y, double z, const Vec3& normal) {
    std::vector<std::uint32_t> r;
    for (int x = 0; x < n; ++x) r.push_back(s.add(Vec3(x, y, z), normal));
    return r;
  };
  const Vec3 nz = Vec3::UnitZ(), ny = Vec3::UnitY(), bevel = Vec3(0, 1, 1).normalized();
  const auto a3 = row(-3, 0, nz), a2 = row(-2, 0, nz), a1 = row(-1, 0, nz);
  const auto b1 = row(0, -1, ny), b2 = row(0, -2, ny), b3 = row(0, -3, ny);
  // The feature row's PCA normal is one-sided (that of face A), as on real scans.
  const auto feature = row(0, 0, nz);
  s.strip(a3, a2, nz);
  s.strip(a2, a1, nz);
  s.strip(a1, b1, bevel);
  s.strip(b1, b2, ny);
  s.strip(b2, b3, ny);
  s.left_out = feature;
  const auto r = s.refine();
  CHECK(r.stats.inserted == feature.size());
  CHECK(r.front.outliers.empty());
  require_valid(r.mesh);
  const auto rep = analyze(r.mesh);
  CHECK(rep.boundary_loops == 1);
  CHECK(rep.genus == 0);
  // The flips turned the edges along the feature line: consecutive feature points are joined.
  std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
  for (const Triangle& t : r.mesh.triangles)
    for (int k = 0; k < 3; ++k)
      edges.emplace(std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3]));
  for (int x = 0; x + 1 < n; ++x) CHECK(edges.count({feature[x], feature[x + 1]}) == 1);
  // And the corner is sharp again: every triangle lies in one of the two faces.
  std::size_t in_a_face = 0;
  for (const Triangle& t : r.mesh.triangles) {
    const Vec3 nn =
        (s.points[t[1]] - s.points[t[0]]).cross(s.points[t[2]] - s.points[t[0]]).normalized();
    if (nn.dot(nz) > 1 - 1e-9 || nn.dot(ny) > 1 - 1e-9) ++in_a_face;
  }
  CHECK(in_a_face == r.mesh.triangles.size());
}

TEST_CASE("refine: a sliver is flipped away, topology kept; sliver_deg 0 leaves it", "[recon][refine]") {
  // A flat quad u, y, v, x whose diagonal u-v passes just below x: triangle (u, v, x) has
  // corners of about 5.7 degrees.
  Scene s;
  const Vec3 nz = Vec3::UnitZ();
  const std::uint32_t u = s.add(Vec3(0, 0, 0), nz), y = s.add(Vec3(1, -1, 0), nz),
                      v = s.add(Vec3(2, 0, 0), nz), x = s.add(Vec3(1, 0.1, 0), nz);
  // A ring of triangles around the quad, so the flip is an interior one.
  const std::uint32_t far_n = s.add(Vec3(1, 1.2, 0), nz), far_s = s.add(Vec3(1, -2, 0), nz);
  s.tri(u, v, x, nz);
  s.tri(v, u, y, nz);
  s.tri(x, v, far_n, nz);
  s.tri(u, x, far_n, nz);
  s.tri(y, v, far_s, nz);
  s.tri(u, y, far_s, nz);
  const auto before = analyze(Mesh{s.points, s.triangles});
  REQUIRE(before.min_angle_deg < 6);
  const auto r = s.refine();
  require_valid(r.mesh);
  const auto rep = analyze(r.mesh);
  CHECK(r.stats.sliver_flips >= 1);
  CHECK(rep.min_angle_deg > 15);  // the ring's own smallest corner is 18.4
  CHECK(rep.triangles == before.triangles);
  CHECK(rep.boundary_loops == before.boundary_loops);
  CHECK(rep.genus == before.genus);
  bool has_xy = false;
  for (const Triangle& t : r.mesh.triangles)
    for (int k = 0; k < 3; ++k)
      has_xy |= (t[k] == x && t[(k + 1) % 3] == y) || (t[k] == y && t[(k + 1) % 3] == x);
  CHECK(has_xy);

  scanmesh::recon::RefineOptions off;
  off.sliver_deg = 0;
  LocalFrames frames;
  frames.normal = s.normals;
  frames.spacing.assign(s.points.size(), 1.0f);
  frames.flatness.assign(s.points.size(), 0.0f);
  PointGrid grid;
  grid.build(s.points, 3.6);
  FrontResult front;
  front.triangles = s.triangles;
  front.state.assign(s.points.size(), VertexState::kDone);
  const auto stats = insert_unused_points(s.points, frames, grid, front, off);
  CHECK(stats.flips == 0);
  CHECK(front.triangles == s.triangles);
}

TEST_CASE("refine: an insertion does not cross a long triangle whose corners are far away",
          "[recon][refine]") {
  // A left-out point 0.3 above the flat patch: putting it in makes a low tent. A large triangle
  // (corners 20-30 spacings away, far beyond every list the insertion keeps) lies flat at
  // z = 0.15 over the patch, facing down (the underside of a part seen from below): the tent
  // would pierce it.
  Scene s = flat_patch();
  const Vec3 down = -Vec3::UnitZ();
  const std::uint32_t a = s.add(Vec3(-20, -20, 0.15), down), b = s.add(Vec3(30, -20, 0.15), down),
                      c = s.add(Vec3(2.5, 30, 0.15), down);
  s.tri(a, b, c, down);
  REQUIRE(scanmesh::recon::find_self_intersections(s.points, s.triangles).pairs == 0);
  const std::uint32_t q = s.add(Vec3(2.3, 2.6, 0.3), Vec3::UnitZ());
  s.left_out = {q};
  const auto r = s.refine();
  require_valid(r.mesh);
  CHECK(scanmesh::recon::find_self_intersections(r.mesh).pairs == 0);
  // Nowhere to put it without crossing: it stays left out, and nothing else changed.
  CHECK(r.stats.inserted == 0);
  CHECK(r.front.outliers == s.left_out);
  CHECK(r.front.triangles == s.triangles);
}
