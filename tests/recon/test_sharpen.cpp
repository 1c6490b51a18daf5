// Sharp-edge recovery: a box scanned with no sample on its edges comes out bevelled, and
// sharpen_edges puts its edges and corners back (new vertices where the faces meet) while the
// mesh stays manifold, consistently oriented, free of self-intersections and of the same
// topology, the measured vertices unmoved; smooth surfaces and bad input are left alone.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <cstddef>
#include <stdexcept>
#include <vector>

#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "scanmesh/recon/sharpen.hpp"
#include "support/shapes.hpp"

namespace {

using scanmesh::recon::analyze;
using scanmesh::recon::find_self_intersections;
using scanmesh::recon::Mesh;
using scanmesh::recon::SharpenOptions;
using scanmesh::recon::SharpenStats;
using scanmesh::recon::sharpen_edges;
using scanmesh::recon::SurfaceDistance;
using scanmesh::recon::Vec3;

constexpr double kSide = 10, kStep = 0.5;

/// The box [0, kSide]^3's faces, no sample on an edge (support/shapes.hpp: box_face_points).
std::vector<Vec3> box_points(double near = 0.5 * kStep) {
  return scanmesh::test::box_face_points(kSide, kStep, near);
}

/// Points every 0.05 along the box's 12 edges, corners included.
std::vector<Vec3> box_edge_points() {
  std::vector<Vec3> out;
  const int m = static_cast<int>(kSide / 0.05);
  for (int axis = 0; axis < 3; ++axis)
    for (const double a : {0.0, kSide})
      for (const double b : {0.0, kSide})
        for (int i = 0; i <= m; ++i) {
          Vec3 p;
          p[axis] = i * 0.05;
          p[(axis + 1) % 3] = a;
          p[(axis + 2) % 3] = b;
          out.push_back(p);
        }
  return out;
}

/// The prism [0, kSide]^3 whose four vertical edges are rounded to radius `r` (fillets, quarter
/// cylinders) and whose top and bottom rims are sharp, sampled every kStep with no sample on a
/// rim: the top and bottom on the grid half a step in, the sides every kStep along the
/// perimeter (round the fillets too) and up.
std::vector<Vec3> filleted_prism_points(double r) {
  std::vector<Vec3> pts;
  const int m = static_cast<int>(kSide / kStep);
  auto inside = [&](double x, double y) {  // in the rounded square
    const double dx = std::max({r - x, x - (kSide - r), 0.0});
    const double dy = std::max({r - y, y - (kSide - r), 0.0});
    return dx * dx + dy * dy <= r * r;
  };
  for (const double z : {0.0, kSide})
    for (int i = 0; i < m; ++i)
      for (int j = 0; j < m; ++j) {
        const double x = (i + 0.5) * kStep, y = (j + 0.5) * kStep;
        if (inside(x, y)) pts.emplace_back(x, y, z);
      }
  // The perimeter: four straight sides and four quarter circles, counter-clockwise.
  const double flat = kSide - 2 * r, arc = 0.5 * std::numbers::pi * r;
  const double perimeter = 4 * (flat + arc);
  const auto n = static_cast<int>(std::round(perimeter / kStep));
  const Vec3 centre[4] = {{kSide - r, r, 0}, {kSide - r, kSide - r, 0}, {r, kSide - r, 0}, {r, r, 0}};
  for (int k = 0; k < n; ++k) {
    double u = (k + 0.5) * perimeter / n;
    const int side = static_cast<int>(u / (flat + arc));
    u -= side * (flat + arc);
    // Side `side` runs along the bottom edge rotated by side * 90 degrees, then turns round
    // centre[side].
    const double start = side * 0.5 * std::numbers::pi;  // outward normal's angle - 90 degrees
    const Vec3 along(std::cos(start), std::sin(start), 0);
    const Vec3 out(std::sin(start), -std::cos(start), 0);
    Vec3 q;
    if (u < flat) {
      q = centre[(side + 3) % 4] + r * out + u * along;
    } else {
      const double a = (u - flat) / r;
      q = centre[side] + r * (std::cos(a) * out + std::sin(a) * along);
    }
    for (int h = 0; h < m; ++h) pts.emplace_back(q.x(), q.y(), (h + 0.5) * kStep);
  }
  return pts;
}

/// Distance from p to the filleted prism's surface.
double filleted_prism_distance(const Vec3& p, double r) {
  const Vec3 c = Vec3::Constant(0.5 * kSide);
  const Vec3 q = (p - c).cwiseAbs() - Vec3(0.5 * kSide - r, 0.5 * kSide - r, 0.5 * kSide);
  const double side = std::hypot(std::max(q.x(), 0.0), std::max(q.y(), 0.0)) +
                      std::min(std::max(q.x(), q.y()), 0.0) - r;
  const double d = std::max(side, q.z());
  if (d <= 0) return -d;
  return side > 0 && q.z() > 0 ? std::hypot(side, q.z()) : d;
}

struct EdgeDistance {
  double mean = 0, max = 0;
};

EdgeDistance edge_distance(const Mesh& mesh, const std::vector<Vec3>& edge) {
  const SurfaceDistance d(mesh);
  EdgeDistance e;
  for (const Vec3& p : edge) {
    const double x = d.distance(p);
    e.mean += x;
    e.max = std::max(e.max, x);
  }
  e.mean /= static_cast<double>(edge.size());
  return e;
}

void check_valid(const Mesh& m) {
  const auto r = analyze(m);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.non_manifold_vertices == 0);
  CHECK(r.orientation_consistent);
  CHECK(r.degenerate_triangles == 0);
  CHECK(find_self_intersections(m).pairs == 0);
}

}  // namespace

TEST_CASE("sharpen: a bevelled box gets its edges and corners back", "[sharpen]") {
  const auto points = box_points();
  const Mesh before = scanmesh::recon::reconstruct(points).mesh;
  const auto edge = box_edge_points();
  const EdgeDistance d0 = edge_distance(before, edge);
  // The reconstruction cuts every edge: the bevel's middle is half a step * sqrt(2) / 2 in.
  REQUIRE(d0.mean > 0.15);

  Mesh after = before;
  const SharpenStats st = sharpen_edges(after);
  INFO("bevels " << st.bevel_triangles << ", edge vertices " << st.edge_vertices << ", corners "
                 << st.corner_vertices << ", flipped " << st.flipped << ", refused "
                 << st.refused);
  const EdgeDistance d1 = edge_distance(after, edge);
  INFO("edge distance mean " << d0.mean << " -> " << d1.mean << ", max " << d0.max << " -> "
                             << d1.max);
  CHECK(d1.mean < 0.01 * d0.mean);
  CHECK(d1.max < 0.01);  // every edge and corner exactly back (4 of 8 corners before stop 47)
  CHECK(st.corner_vertices == 8);
  CHECK(st.edge_vertices >= 12 * static_cast<std::size_t>(kSide / kStep));
  CHECK(st.flipped > 0);
  check_valid(after);
  const auto r0 = analyze(before), r1 = analyze(after);
  CHECK(r1.boundary_loops == r0.boundary_loops);
  CHECK(r1.genus == r0.genus);
  CHECK(r1.components == r0.components);
  CHECK(r1.signed_volume > r0.signed_volume);  // the corners cut off are back
  // The measured samples stay where they were; the new vertices come after them, each on the
  // box's surface (on an edge: two of its coordinates at 0 or kSide).
  REQUIRE(after.vertices.size() == before.vertices.size() + st.edge_vertices + st.corner_vertices);
  for (std::size_t v = 0; v < before.vertices.size(); ++v)
    REQUIRE(after.vertices[v] == before.vertices[v]);
  for (std::size_t v = before.vertices.size(); v < after.vertices.size(); ++v) {
    int on = 0;
    for (int k = 0; k < 3; ++k) {
      const double c = after.vertices[v][k];
      on += (std::abs(c) < 1e-6 || std::abs(c - kSide) < 1e-6) ? 1 : 0;
    }
    REQUIRE(on >= 2);
  }
}

TEST_CASE("sharpen: edges cut off-centre are recovered too", "[sharpen]") {
  // A bevel 0.1 deep on one face and 0.4 on the other lies 14 degrees off the second face: the
  // edge projects along the bevel's own normal onto its rim, so the new vertex is placed by
  // projecting along the faces' mean normal instead.
  // Every point meshed: the cube reduction would drop the rows 0.4 from an edge where the other
  // face's row 0.1 from it shares their cubes, and the bevel left (0.1 against 0.9) lies within
  // the face angle of a face.
  scanmesh::recon::ReconstructOptions ro;
  ro.cube_mode = scanmesh::recon::ReconstructOptions::CubeMode::kNone;
  const Mesh before = scanmesh::recon::reconstruct(box_points(0.1), ro).mesh;
  Mesh after = before;
  const SharpenStats st = sharpen_edges(after);
  const auto edge = box_edge_points();
  const EdgeDistance d0 = edge_distance(before, edge), d1 = edge_distance(after, edge);
  INFO("edge distance mean " << d0.mean << " -> " << d1.mean << ", max " << d0.max << " -> "
                             << d1.max << "; bevels " << st.bevel_triangles << ", edge vertices "
                             << st.edge_vertices << ", corners " << st.corner_vertices
                             << ", flipped " << st.flipped << ", tidied " << st.tidied
                             << ", refused " << st.refused);
  CHECK(d0.mean > 0.1);
  // Projected along the bevel's normal, the new vertices of the edges cut 0.1 / 0.4 were
  // refused or clamped half-way (mean 0.03, those edges 0.046-0.048 off).
  CHECK(d1.mean < 0.05 * d0.mean);
  CHECK(d1.max < 0.05);
  CHECK(st.tidied > 0);
  check_valid(after);
  const auto r0 = analyze(before), r1 = analyze(after);
  CHECK(r1.genus == r0.genus);
  CHECK(r1.boundary_loops == r0.boundary_loops);
  CHECK(r1.signed_volume > r0.signed_volume);
  // No more thin triangles than the splits must make: the slivers beside the faces are flipped.
  CHECK(r1.frac_min_angle_below_10 * static_cast<double>(r1.triangles) <=
        r0.frac_min_angle_below_10 * static_cast<double>(r0.triangles) +
            0.25 * static_cast<double>(st.edge_vertices + st.corner_vertices));
}

TEST_CASE("sharpen: bevels within the face angle of a face are found by their corners",
          "[sharpen]") {
  // Cut 0.05 from the edge on one face and 0.45 on the other, the bevel lies 6 degrees off the
  // second face and joins it; its corner on the first face lies 0.05 off the second's plane,
  // far beyond that plane's scatter (none here), so it is given back to the bevels.
  scanmesh::recon::ReconstructOptions ro;
  ro.cube_mode = scanmesh::recon::ReconstructOptions::CubeMode::kNone;
  const Mesh before = scanmesh::recon::reconstruct(box_points(0.05), ro).mesh;
  const auto edge = box_edge_points();
  const EdgeDistance d0 = edge_distance(before, edge);
  Mesh unpeeled = before, after = before;
  SharpenOptions no_peel;
  no_peel.peel = false;
  sharpen_edges(unpeeled, no_peel);
  const SharpenStats st = sharpen_edges(after);
  const EdgeDistance d1 = edge_distance(unpeeled, edge), d2 = edge_distance(after, edge);
  INFO("edge distance mean " << d0.mean << " -> " << d1.mean << " without peeling, " << d2.mean
                             << " with it; max " << d0.max << " -> " << d1.max << ", "
                             << d2.max << "; edge vertices " << st.edge_vertices
                             << ", corners " << st.corner_vertices << ", refused "
                             << st.refused);
  CHECK(d0.mean > 0.04);
  // Without: the six edges cut 0.05 / 0.45 stay 0.050 off on average; with: 0.004-0.013.
  CHECK(d2.mean < 0.5 * d1.mean);
  CHECK(d2.mean < 0.15 * d0.mean);
  check_valid(after);
  CHECK(analyze(after).genus == analyze(before).genus);

  // A second pass, on the first's output: the bevels beside the recovered stretches see both
  // faces now.
  SharpenOptions twice;
  twice.passes = 2;
  Mesh again = before;
  const SharpenStats st2 = sharpen_edges(again, twice);
  const EdgeDistance d3 = edge_distance(again, edge);
  INFO("two passes: mean " << d3.mean << ", max " << d3.max << ", edge vertices "
                           << st2.edge_vertices);
  CHECK(st2.edge_vertices > st.edge_vertices);
  CHECK(d3.mean < d2.mean);
  check_valid(again);
  for (std::size_t v = 0; v < before.vertices.size(); ++v)
    REQUIRE(again.vertices[v] == before.vertices[v]);
}

TEST_CASE("sharpen: fillets are left round, the sharp rims beside them recovered", "[sharpen]") {
  // A rounded edge sampled across (radius 1.5 to 4 spacings) meshes into rows of triangles
  // that belong to no face, like a bevel, and the faces' planes meet 0.41 radius off the
  // fillet: before the fillet rule 68 new vertices 0.27 off these fillets at radius 0.75, 34
  // at 0.9 0.37 off (a box's fillets of radius 0.75: 408, 0.31 off). The fillet's samples
  // belong to neither face and lie off both planes, so nothing is added there.
  scanmesh::recon::ReconstructOptions ro;
  ro.cube_mode = scanmesh::recon::ReconstructOptions::CubeMode::kNone;
  for (const double r : {0.75, 0.9, 1.0, 1.5, 2.0}) {
    CAPTURE(r);
    const Mesh before = scanmesh::recon::reconstruct(filleted_prism_points(r), ro).mesh;
    Mesh after = before;
    const SharpenStats st = sharpen_edges(after);
    double worst = 0;
    std::size_t on_fillets = 0;
    for (std::size_t v = before.vertices.size(); v < after.vertices.size(); ++v) {
      const Vec3& p = after.vertices[v];
      worst = std::max(worst, filleted_prism_distance(p, r));
      on_fillets += p.z() > kStep && p.z() < kSide - kStep ? 1 : 0;
    }
    INFO("edge vertices " << st.edge_vertices << ", corners " << st.corner_vertices
                          << ", refused " << st.refused << ", left round " << st.rounded
                          << "; on the fillets " << on_fillets
                          << ", farthest new vertex " << worst);
    CHECK(on_fillets == 0);
    CHECK(st.rounded > 0);
    CHECK(worst < 0.1 * kStep);
    // The rims: two rounded squares, about 4 * 8 straight steps each, are recovered.
    CHECK(st.edge_vertices > 2 * 4 * static_cast<std::size_t>((kSide - 2 * r) / kStep));
    check_valid(after);
    CHECK(analyze(after).genus == analyze(before).genus);
  }
}

TEST_CASE("sharpen: noise on the faces moves the recovered edges by about the noise",
          "[sharpen]") {
  auto points = box_points();
  scanmesh::test::add_noise(points, 0.01, 7);
  // Every point meshed: a cube of about the grid's own step would pick irregular representatives
  // and bevel the edges unevenly (bench_edges measures the default on simulated scans).
  scanmesh::recon::ReconstructOptions ro;
  ro.cube_mode = scanmesh::recon::ReconstructOptions::CubeMode::kNone;
  const Mesh before = scanmesh::recon::reconstruct(points, ro).mesh;
  Mesh after = before;
  const SharpenStats st = sharpen_edges(after);
  const auto edge = box_edge_points();
  const EdgeDistance d0 = edge_distance(before, edge), d1 = edge_distance(after, edge);
  INFO("edge distance mean " << d0.mean << " -> " << d1.mean << "; bevels " << st.bevel_triangles << ", edge vertices " << st.edge_vertices << ", corners " << st.corner_vertices << ", refused " << st.refused);
  CHECK(d0.mean > 0.15);
  CHECK(d1.mean < 0.02);  // twice the noise
  check_valid(after);
  CHECK(analyze(after).genus == analyze(before).genus);
}

TEST_CASE("sharpen: a smooth closed surface gets no new vertex", "[sharpen]") {
  const Mesh sphere = scanmesh::recon::reconstruct(scanmesh::test::sphere_points(4000)).mesh;
  Mesh m = sphere;
  const SharpenStats st = sharpen_edges(m);
  CHECK(st.edge_vertices + st.corner_vertices == 0);
  CHECK(m.vertices == sphere.vertices);
  CHECK(m.triangles.size() == sphere.triangles.size());
}

TEST_CASE("sharpen: bad angles are refused, a non-manifold mesh is left as it is",
          "[sharpen]") {
  Mesh m = scanmesh::test::tetrahedron();
  SharpenOptions o;
  o.smooth_deg = 0;
  CHECK_THROWS_AS(sharpen_edges(m, o), std::invalid_argument);
  o = {};
  o.feature_deg = o.smooth_deg;
  CHECK_THROWS_AS(sharpen_edges(m, o), std::invalid_argument);
  o = {};
  o.passes = 0;
  CHECK_THROWS_AS(sharpen_edges(m, o), std::invalid_argument);
  o.passes = SharpenOptions::kMaxPasses + 1;
  CHECK_THROWS_AS(sharpen_edges(m, o), std::invalid_argument);
  CHECK(SharpenOptions{}.validate().empty());

  // Three triangles on one edge: nothing is done.
  Mesh fan;
  fan.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1)};
  fan.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  const Mesh copy = fan;
  const SharpenStats st = sharpen_edges(fan);
  CHECK(st.bevel_triangles == 0);
  CHECK(fan.triangles == copy.triangles);
  Mesh empty;
  CHECK(sharpen_edges(empty).bevel_triangles == 0);
}
