// Reconstruction of the real scans under $SCANMESH_DATA with default options, against the known
// truth: topology where it is known, manifoldness, coverage, no gap bridging, distance to the
// reference surface. Skipped when SCANMESH_DATA is unset; fails when it is set but empty.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <catch2/catch.hpp>
#include <optional>
#include <string>
#include <vector>

#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/normals.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "scanmesh/recon/reduce.hpp"
#include "scanmesh/recon/sharpen.hpp"
#include "support/data.hpp"
#include "support/holes.hpp"
#include "support/shapes.hpp"
#include "support/shared_mesh.hpp"

namespace {

using namespace scanmesh;
using recon::Vec3;

struct Case {
  std::string name;
  std::vector<std::string> inputs;  // relative to SCANMESH_DATA
  std::string conf;                 // registration file (empty: none)
  std::string reference;            // reference surface
  std::optional<std::size_t> loops;
  std::optional<long> genus;
  std::optional<std::size_t> components;
  bool covers_reference;  // the input sees the whole reference (then check ref -> mesh too)
  bool check_usage = true;  // at least min_usage of the reduced points become vertices
  double min_usage = 0.998;  // the fraction checked when check_usage
  std::optional<long> max_genus = std::nullopt;  // upper bound, where the exact genus is not reached yet
  /// Upper bound on the boundary loops, where the exact count is not reached yet.
  std::optional<std::size_t> max_loops = std::nullopt;
  /// Mesh -> reference mean and 95th percentile, in spacings, at most.
  double max_mean = 0.2, max_p95 = 0.5;
};

/// Longest edge of each triangle over the spacing around its vertices (distance to the 6th
/// nearest other vertex, the larger of the three): how far a triangle reaches across a gap,
/// measured independently of the reconstruction's own radius.
double worst_bridge_ratio(const recon::Mesh& m) {
  double mean_edge = 0;
  for (const auto& t : m.triangles) mean_edge += (m.vertices[t[0]] - m.vertices[t[1]]).norm();
  mean_edge /= static_cast<double>(m.triangles.size());
  recon::PointGrid grid;
  grid.build(m.vertices, 2.0 * mean_edge);
  std::vector<double> local(m.vertices.size());
  std::vector<double> d;
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    d.clear();
    grid.for_each_near(m.vertices[i], 2, [&](std::uint32_t j) {
      if (j != i) d.push_back((m.vertices[j] - m.vertices[i]).norm());
    });
    const std::size_t k = std::min<std::size_t>(6, d.size());
    std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(k - 1), d.end());
    local[i] = d[k - 1];
  }
  double worst = 0;
  for (const auto& t : m.triangles) {
    double longest = 0, sp = 0;
    for (int e = 0; e < 3; ++e) {
      longest = std::max(longest, (m.vertices[t[e]] - m.vertices[t[(e + 1) % 3]]).norm());
      sp = std::max(sp, local[t[e]]);
    }
    worst = std::max(worst, longest / sp);
  }
  return worst;
}

/// The points of `inputs` (relative to SCANMESH_DATA), each scan moved by its entry in `conf`
/// when one is given; nothing (with a warning naming `what`) when SCANMESH_DATA is not set.
/// With a conf and `towards_sensor`, each point's scan's +z axis in world coordinates goes
/// there, as `scanmesh reconstruct --conf` gives it (the scans look along their -z).
std::optional<std::vector<Vec3>> load_points(const std::vector<std::string>& inputs,
                                             const std::string& conf, const std::string& what,
                                             std::vector<Vec3>* towards_sensor = nullptr) {
  std::vector<std::filesystem::path> files;
  for (const auto& in : inputs) {
    const auto f = test::shared_file(in);
    if (!f) {
      WARN("SCANMESH_DATA is not set: skipping " << what);
      return std::nullopt;
    }
    files.push_back(*f);
  }
  std::vector<Vec3> points;
  if (!conf.empty()) {
    const auto conf_file = test::shared_file(conf);
    REQUIRE(conf_file);
    const auto entries = meshio::read_conf(*conf_file);
    for (const auto& f : files) {
      const auto it = std::find_if(entries.begin(), entries.end(), [&](const auto& e) {
        return e.file.filename() == f.filename();
      });
      REQUIRE(it != entries.end());
      const Vec3 sensor = it->to_world(Vec3::UnitZ()) - it->to_world(Vec3::Zero());
      for (const Vec3& p : meshio::read_points(f).points) {
        points.push_back(it->to_world(p));
        if (towards_sensor) towards_sensor->push_back(sensor);
      }
    }
  } else {
    for (const auto& f : files) {
      const auto cloud = meshio::read_points(f);
      points.insert(points.end(), cloud.points.begin(), cloud.points.end());
    }
  }
  return points;
}

const std::vector<std::string> kMergedBunnyScans{
    "bunny/data/bun000.ply", "bunny/data/bun045.ply", "bunny/data/bun090.ply",
    "bunny/data/bun180.ply", "bunny/data/bun270.ply", "bunny/data/bun315.ply",
    "bunny/data/chin.ply",   "bunny/data/ear_back.ply", "bunny/data/top2.ply",
    "bunny/data/top3.ply"};

/// What closing loops with patches keeps: the genus and the components, and a manifold,
/// consistently oriented mesh without duplicate triangles.
void check_patches_keep_topology(const recon::MeshReport& before, const recon::MeshReport& after) {
  CHECK(after.genus == before.genus);
  CHECK(after.components == before.components);
  CHECK(after.non_manifold_edges == 0);
  CHECK(after.non_manifold_vertices == 0);
  CHECK(after.orientation_consistent);
  CHECK(after.duplicate_triangles == 0);
}

/// A valid mesh of one closed-up piece without handles: no non-manifold edge or vertex,
/// consistently oriented, genus 0, one component.
void check_valid_one_piece_genus0(const recon::MeshReport& rep) {
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.non_manifold_vertices == 0);
  CHECK(rep.orientation_consistent);
  CHECK(rep.genus == 0);
  CHECK(rep.components == 1);
}

void run_case(const Case& c) {
  const auto loaded = load_points(c.inputs, c.conf, c.name);
  if (!loaded) return;
  const std::vector<Vec3>& points = *loaded;
  const auto ref_file = test::shared_file(c.reference);
  REQUIRE(ref_file);
  const recon::ReconstructResult r = recon::reconstruct(points);
  const recon::MeshReport rep = recon::analyze(r.mesh);
  const double spacing = r.cube_mm;  // spacing of the reduced cloud the mesh is made of
  INFO(c.name << ": " << points.size() << " points, cube " << spacing << ", reduced "
              << r.reduced_points << ", vertices " << r.mesh.vertices.size() << ", loops "
              << rep.boundary_loops << ", components " << rep.components << ", genus "
              << rep.genus << ", corners under 10 deg " << rep.frac_min_angle_below_10);
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.non_manifold_vertices == 0);
  CHECK(rep.orientation_consistent);
  CHECK(rep.degenerate_triangles == 0);
  CHECK(rep.duplicate_triangles == 0);
  if (c.check_usage)
    CHECK(static_cast<double>(r.mesh.vertices.size()) >=
          c.min_usage * static_cast<double>(r.reduced_points));
  if (c.loops) CHECK(rep.boundary_loops == *c.loops);
  if (c.max_loops) CHECK(rep.boundary_loops <= *c.max_loops);
  if (c.genus) CHECK(rep.genus == *c.genus);
  if (c.max_genus) CHECK(rep.genus <= *c.max_genus);
  if (c.components) CHECK(rep.components == *c.components);
  CHECK(worst_bridge_ratio(r.mesh) < 6.0);
  const recon::SelfIntersections crossing = recon::find_self_intersections(r.mesh);
  INFO("crossing triangle pairs: " << crossing.pairs);
  CHECK(crossing.pairs == 0);
  // Slivers: after the flips, at most 0.25 % of the triangles have a corner under 10 degrees
  // (0.1-0.33 % before them).
  CHECK(rep.frac_min_angle_below_10 < 0.0025);

  const recon::Mesh ref = meshio::read_mesh(*ref_file);
  const recon::DeviationReport dev = recon::deviation(r.mesh, ref);
  INFO("mesh->ref mean " << dev.mesh_to_ref.mean / spacing << " p95 "
                         << dev.mesh_to_ref.p95 / spacing << " max " << dev.mesh_to_ref.max / spacing
                         << " spacings; ref->mesh p95 " << dev.ref_to_mesh.p95 / spacing);
  CHECK(dev.mesh_to_ref.mean < c.max_mean * spacing);
  CHECK(dev.mesh_to_ref.p95 < c.max_p95 * spacing);
  CHECK(dev.mesh_to_ref.max < 4.0 * spacing);
  if (c.covers_reference) CHECK(dev.ref_to_mesh.p95 < 0.5 * spacing);
}

/// The largest angle (degrees) between the normals of two triangles sharing an edge, over the
/// edges of triangles [first, end) of the mesh (the patches the filling appended).
double sharpest_patch_crease(const recon::Mesh& m, std::size_t first) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<std::size_t>> on_edge;
  std::vector<char> patch_vertex(m.vertices.size(), 0);
  for (std::size_t t = first; t < m.triangles.size(); ++t)
    for (std::uint32_t v : m.triangles[t]) patch_vertex[v] = 1;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const recon::Triangle& tri = m.triangles[t];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t u = tri[k], v = tri[(k + 1) % 3];
      if (patch_vertex[u] && patch_vertex[v]) on_edge[{std::min(u, v), std::max(u, v)}].push_back(t);
    }
  }
  auto normal = [&](std::size_t t) {
    const recon::Triangle& tri = m.triangles[t];
    return Vec3((m.vertices[tri[1]] - m.vertices[tri[0]]).cross(m.vertices[tri[2]] - m.vertices[tri[0]]));
  };
  double worst = 0;
  for (const auto& [edge, tris] : on_edge) {
    if (tris.size() != 2 || std::max(tris[0], tris[1]) < first) continue;
    const Vec3 a = normal(tris[0]), b = normal(tris[1]);
    worst = std::max(worst, std::atan2(a.cross(b).norm(), a.dot(b)) * 180 / 3.141592653589793);
  }
  return worst;
}

}  // namespace

TEST_CASE("real scan: bunny points (bun_zipper) keep exactly the 5 holes of the base",
          "[recon][real][slow]") {
  run_case({"bunny", {"bunny/reconstruction/bun_zipper_vertices.xyz"}, "",
            "bunny/reconstruction/bun_zipper.ply", 5, 0, 1, true});
}

// The holes' rims go through the samples the reference's rims go through (the reference mesh
// has these very points as its vertices): precision, the share of the mesh's boundary vertices
// that are rim vertices of the reference; recall, the share of the reference's rim vertices that
// the mesh has (the reduction keeps 210 of 223) and leaves on its boundary. Measured with the
// border chords peeled at 110 degrees (the default): 191 of 194 and 191 of 210; at 120 degrees
// 172 of 174 and 172 of 210 (recall 0.82); at 100 degrees 204 of 227 (precision 0.90).
TEST_CASE("real scan: the bunny's hole rims run through the reference's rim points",
          "[recon][real][slow]") {
  const auto loaded = test::shared_mesh("bunny/reconstruction/bun_zipper.ply",
                                        "the bunny's hole rims against the reference's");
  if (!loaded) return;
  const recon::Mesh& ref = *loaded;
  const recon::MeshReport ref_rep = recon::analyze(ref, true);
  REQUIRE(ref_rep.boundary_loops == 5);
  std::vector<char> ref_rim(ref.vertices.size(), 0);
  for (const auto& loop : ref_rep.loops)
    for (const std::uint32_t v : loop.vertices) ref_rim[v] = 1;
  const recon::ReconstructResult res = recon::reconstruct(ref.vertices);
  const recon::MeshReport rep = recon::analyze(res.mesh, true);
  REQUIRE(rep.boundary_loops == 5);
  // Each mesh vertex's reference vertex: the nearest, within a tenth of the cube (the
  // projection onto local planes moves a point by far less on this scan).
  recon::PointGrid grid;
  grid.build(ref.vertices, res.cube_mm);
  const double within2 = 0.01 * res.cube_mm * res.cube_mm;
  auto reference_of = [&](const Vec3& p) {
    std::uint32_t best = UINT32_MAX;
    double best2 = within2;
    grid.for_each_near(p, 1, [&](std::uint32_t j) {
      const double d2 = (ref.vertices[j] - p).squaredNorm();
      if (d2 < best2) {
        best2 = d2;
        best = j;
      }
    });
    return best;
  };
  std::vector<char> on_boundary(res.mesh.vertices.size(), 0);
  for (const auto& loop : rep.loops)
    for (const std::uint32_t v : loop.vertices) on_boundary[v] = 1;
  std::size_t boundary = 0, boundary_on_rim = 0, rim_kept = 0, rim_on_boundary = 0;
  for (std::size_t v = 0; v < res.mesh.vertices.size(); ++v) {
    const std::uint32_t j = reference_of(res.mesh.vertices[v]);
    const bool rim = j != UINT32_MAX && ref_rim[j] != 0;
    boundary += on_boundary[v];
    boundary_on_rim += on_boundary[v] && rim;
    rim_kept += rim;
    rim_on_boundary += rim && on_boundary[v];
  }
  INFO("boundary vertices " << boundary << ", on the reference's rims " << boundary_on_rim
                            << "; reference rim vertices kept " << rim_kept << " of "
                            << std::count(ref_rim.begin(), ref_rim.end(), 1)
                            << ", on the boundary " << rim_on_boundary);
  REQUIRE(boundary > 0);
  REQUIRE(rim_kept > 0);
  CHECK(static_cast<double>(boundary_on_rim) >= 0.97 * static_cast<double>(boundary));
  CHECK(static_cast<double>(rim_on_boundary) >= 0.88 * static_cast<double>(rim_kept));
}

// Self-intersections: with the front's crossing guard and the insertion's, none on any real scan
// (bun000 had 32 without the guards, and 3 more where its exactly collinear scan-line points
// touched a new triangle's edge; recon/README, "Crossing guard").
TEST_CASE("real scan: raw range scan bun000", "[recon][real][slow]") {
  Case c{"bun000", {"bunny/data/bun000.ply"}, "", "bunny/reconstruction/bun_zipper.ply",
         std::nullopt, std::nullopt, std::nullopt, false};
  run_case(c);
}

TEST_CASE("real scan: raw range scan bun045 (registered)", "[recon][real][slow]") {
  Case c{"bun045", {"bunny/data/bun045.ply"}, "bunny/data/bun.conf",
         "bunny/reconstruction/bun_zipper.ply", std::nullopt, std::nullopt, std::nullopt, false};
  run_case(c);
}

// No view of the ten sees the bunny's base, so the truth of this data is the reference mesh's
// (bun_zipper) five holes there and nothing else. Asserted: genus 0, one component, and no more
// than today's 6 loops (8 before the bulk's patches took normals up to 60 degrees off their
// axis and were projected along their mean normal: three 5-edge gaps the gap closing could not
// take). In this order of the scans the sixth is a 15-edge loop at the base's rim, too long
// for a sampling gap; in the registration file's order, as the CLI reads them, exactly the base's
// 5 stay (below: "the merged scans as the CLI reads them").
TEST_CASE("real scan: ten raw bunny scans merged with bun.conf make one component",
          "[recon][real][slow]") {
  Case c{"bunny-merged", kMergedBunnyScans, "bunny/data/bun.conf",
         "bunny/reconstruction/bun_zipper.ply", std::nullopt, 0, 1, true};
  c.max_loops = 6;
  run_case(c);
}

TEST_CASE("real scan: igea closes (genus 0, no boundary)", "[recon][real][slow]") {
  run_case({"igea", {"igea/igea_vertices.xyz"}, "", "igea/igea.ply", 0, 0, 1, true});
}

// The front's result depends on the order in which it meets hard places, and the bulk's patch
// cone changes that order. At 67 degrees igea used to come out with a handle and a 10-edge loop
// at a sparsely sampled fold (a 6-edge and a 5-edge loop of one piece of mesh merged there);
// the front now refuses to merge a small loop with another loop of its own piece.
TEST_CASE("real scan: igea stays closed with another bulk patch cone (no false handle at its fold)",
          "[recon][real][slow]") {
  const auto points = load_points({"igea/igea_vertices.xyz"}, "", "igea with a 67-degree cone");
  if (!points) return;
  recon::ReconstructOptions opt;
  opt.front.bulk_patch_cone_deg = 67;
  const recon::ReconstructResult r = recon::reconstruct(*points, opt);
  const recon::MeshReport rep = recon::analyze(r.mesh);
  INFO("loops " << rep.boundary_loops << ", genus " << rep.genus << ", components "
                << rep.components << ", bulk triangles " << r.bulk_triangles);
  CHECK(r.bulk_triangles > r.mesh.triangles.size() / 2);
  CHECK(rep.boundary_loops == 0);
  check_valid_one_piece_genus0(rep);
  CHECK(recon::find_self_intersections(r.mesh).pairs == 0);
}

TEST_CASE("real scan: fandisk closes with its sharp edges", "[recon][real][slow]") {
  // Its points are the part's CAD vertices, on its surface: the mesh keeps them at its sharp
  // edges and corners, where the projection rounds the part off (mean 0.044 and p95 0.23
  // spacings when the output kept the projections; now 0.003 and 0.0005).
  Case c{"fandisk", {"fandisk/fandisk_vertices.xyz"}, "", "fandisk/fandisk.obj", 0, 0, 1, true};
  c.max_mean = 0.01;
  c.max_p95 = 0.01;
  run_case(c);
}

TEST_CASE("real scan: sharpening fandisk brings its surface closer to the part",
          "[recon][real][slow][sharpen]") {
  // The mesh through the part's CAD vertices bevels every sharp edge whose two sides no vertex
  // joins; sharpening puts a vertex where the faces meet. Measured (stop 48): reference -> mesh
  // mean 5.75e-4 -> 1.20e-4, p95 3.3e-4 -> 1.54e-4 (spacing 0.093), mesh -> reference mean
  // 3.0e-4 -> 0.92e-4; 138 new vertices.
  const auto points = load_points({"fandisk/fandisk_vertices.xyz"}, "", "fandisk sharpened");
  if (!points) return;
  const auto ref = test::shared_mesh("fandisk/fandisk.obj", "fandisk sharpened");
  REQUIRE(ref);
  const recon::Mesh before = recon::reconstruct(*points).mesh;
  recon::Mesh after = before;
  const recon::SharpenStats st = recon::sharpen_edges(after);
  const recon::DeviationReport d0 = recon::deviation(before, *ref);
  const recon::DeviationReport d1 = recon::deviation(after, *ref);
  INFO("new vertices " << st.edge_vertices << " + " << st.corner_vertices << ", refused "
                       << st.refused << "; ref -> mesh mean " << d0.ref_to_mesh.mean << " -> "
                       << d1.ref_to_mesh.mean << ", p95 " << d0.ref_to_mesh.p95 << " -> "
                       << d1.ref_to_mesh.p95 << "; mesh -> ref mean " << d0.mesh_to_ref.mean
                       << " -> " << d1.mesh_to_ref.mean);
  CHECK(st.edge_vertices > 100);
  // Each new vertex on the part: a face seen two rings away across a narrow face once put
  // some a spacing (0.104) off it, and its rounded blends 0.031 off (stop 47).
  const recon::SurfaceDistance part(*ref);
  double worst = 0;
  for (std::size_t v = before.vertices.size(); v < after.vertices.size(); ++v)
    worst = std::max(worst, part.distance(after.vertices[v]));
  INFO("farthest new vertex " << worst);
  CHECK(worst < 0.02);  // 0.0065 now, a fourteenth of a spacing
  CHECK(d1.ref_to_mesh.mean < 0.4 * d0.ref_to_mesh.mean);
  CHECK(d1.ref_to_mesh.p95 < d0.ref_to_mesh.p95);
  CHECK(d1.mesh_to_ref.mean < d0.mesh_to_ref.mean);
  const recon::MeshReport r0 = recon::analyze(before), r1 = recon::analyze(after);
  CHECK(r1.non_manifold_edges == 0);
  CHECK(r1.non_manifold_vertices == 0);
  CHECK(r1.orientation_consistent);
  CHECK(r1.boundary_loops == r0.boundary_loops);
  CHECK(r1.genus == r0.genus);
  CHECK(recon::find_self_intersections(after).pairs == 0);
}

// The casting's walls are 0.045-0.07 units thick (measured by ray casting the reference)
// while its points are 0.028-0.045 apart: both faces of a wall lie within one or two point
// spacings, below the sampling density at which points alone tell the two sides apart. The
// normals are oriented right (ray-parity repair, test below). The front leaves about 6% of the
// reduced points out, mostly the feature rows of sharp edges it bevelled; the insertion pass
// puts them back (splitting the bevel, then flipping edges along the feature), so the mesh
// covers the part and 99% of the points are used. The front still makes extra handles (genus
// 15-21 for 9 before the crossing guard, 14 with it, 10 since it refuses to merge a small loop
// with another loop of the same piece of mesh: it moves by several with any change in the
// order in which the front meets the thin features, measured over several orderings of the
// queue; with the reference's own normals it does no better). Asserted: a valid mesh on and
// covering the part, one component, no crossing triangles, and no genus above 10 nor more than
// today's 4 boundary loops (5 before the untangling took a fold's flap and a lone triangle
// with a gap's crossed triangles, 6 before a spike through a gap was untangled, test below; 16
// before the front's edge tests counted a vertex within a few float roundings of an edge as
// touching it: the CAD part's exactly collinear points; 11 before the
// sampling gaps left after the insertion were closed, test below; 9, with genus 10, before a
// vertex within those roundings of a triangle's base edge counted as inside it; genus 8 since,
// one below the part's).
TEST_CASE("real scan: casting (thin walls) gives a valid mesh on the surface",
          "[recon][real][slow]") {
  Case c{"casting", {"casting/casting_vertices.xyz"}, "", "casting/casting.obj", std::nullopt,
         std::nullopt, 1, true};
  c.min_usage = 0.99;
  c.max_genus = 10;
  c.max_loops = 4;
  run_case(c);
}

// Small loops (at most 8 edges, a perimeter of at most 10 local spacings: the front's own
// definition of a sampling gap) that the front's ear clipping could not close, or that its fan
// repairs opened again, are closed at the end by the minimum-weight patch of their own vertices
// where that patch crosses nothing. Measured: two of the merged scans' small loops (8 -> 6
// loops; 10 -> 8 before the bulk's patches widened to 60 degrees, and before the bulk's own
// triangulation one 4-edge loop at the base rim, 10 input points inside it), the casting's two
// 5-edge loops (11 -> 9). Every larger loop stays open.
TEST_CASE("real scan: sampling gaps left after the front are closed with their own vertices",
          "[recon][real][slow]") {
  struct Gaps {
    std::vector<std::string> inputs;
    std::string conf;
  };
  for (const Gaps& c : {Gaps{{"casting/casting_vertices.xyz"}, ""},
                        Gaps{kMergedBunnyScans, "bunny/data/bun.conf"}}) {
    const auto loaded = load_points(c.inputs, c.conf, "the sampling gaps of " + c.inputs.front());
    if (!loaded) return;
    const std::vector<Vec3>& points = *loaded;
    recon::ReconstructOptions opt;
    opt.untangle_gaps = false;  // the next test
    opt.zip_band = 0;           // slits are zipped before: their own tests (test_fill, test_front)
    opt.peel_apex_deg = 0;      // border chords are peeled after: their own tests (test_peel)
    const recon::ReconstructResult closed = recon::reconstruct(points, opt);
    opt.close_gaps = false;
    const recon::ReconstructResult open = recon::reconstruct(points, opt);
    const recon::MeshReport before = recon::analyze(open.mesh), after = recon::analyze(closed.mesh);
    INFO(c.inputs.front() << ": loops " << before.boundary_loops << " -> " << after.boundary_loops
                          << ", genus " << before.genus << " -> " << after.genus);
    CHECK(open.gaps.filled == 0);
    CHECK(closed.gaps.filled >= 1);
    CHECK(after.boundary_loops + closed.gaps.filled == before.boundary_loops);
    check_patches_keep_topology(before, after);
    // The same vertices (measured points only) and the same triangles, plus the patches.
    CHECK(closed.gaps.vertices == 0);
    REQUIRE(closed.mesh.vertices == open.mesh.vertices);
    REQUIRE(closed.mesh.triangles.size() == open.mesh.triangles.size() + closed.gaps.triangles);
    CHECK(std::equal(open.mesh.triangles.begin(), open.mesh.triangles.end(),
                     closed.mesh.triangles.begin()));
    CHECK(recon::find_self_intersections(closed.mesh, 0, open.mesh.triangles.size()).pairs == 0);
    // Only short loops were closed: the loops left are the ones before minus closed short ones.
    std::vector<std::size_t> lb = before.boundary_loop_lengths, la = after.boundary_loop_lengths;
    for (std::size_t len : la) {
      const auto it = std::find(lb.begin(), lb.end(), len);
      REQUIRE(it != lb.end());
      lb.erase(it);
    }
    for (std::size_t len : lb) CHECK(len <= opt.front.fill_max_edges);
  }
}

// A gap whose patch would cross the mesh: on the casting, a point of one face of a wall that the
// front meshed with the other face, a spike of three triangles from that face through the gap
// the point left in its own (a 3-edge loop). Untangled: the spike removed, both faces closed, the
// point back in its face. Its 5-edge gap's removal would leave a vertex of two fans and a lone
// triangle: widened to both, it closes too, and the 4 vertices of the flap that lie on no patch
// become outliers. Measured: the casting 6 -> 4 loops (5 before the widening); the other real
// scans but the merged ones (their own test) come out byte-identical.
TEST_CASE("real scan: the casting's gap that a spike reaches through is untangled",
          "[recon][real][slow]") {
  const auto loaded = load_points({"casting/casting_vertices.xyz"}, "", "the casting's spike");
  if (!loaded) return;
  recon::ReconstructOptions opt;
  opt.untangle_gaps = false;
  const recon::ReconstructResult tangled = recon::reconstruct(*loaded, opt);
  const recon::ReconstructResult untangled = recon::reconstruct(*loaded);
  const recon::MeshReport before = recon::analyze(tangled.mesh),
                          after = recon::analyze(untangled.mesh);
  INFO("loops " << before.boundary_loops << " -> " << after.boundary_loops << ", genus "
                << before.genus << " -> " << after.genus);
  CHECK(tangled.untangle.closed == 0);
  CHECK(untangled.untangle.closed >= 1);
  CHECK(untangled.untangle.removed >= 3);
  CHECK(after.boundary_loops + untangled.untangle.closed == before.boundary_loops);
  CHECK(after.non_manifold_edges == 0);
  CHECK(after.non_manifold_vertices == 0);
  CHECK(after.orientation_consistent);
  CHECK(after.components == before.components);
  CHECK(after.genus == before.genus);
  CHECK(untangled.untangle.widened >= 1);
  // No point lost: the same vertices, every one used, but the few dropped, which are outliers.
  const std::size_t dropped = untangled.untangle.dropped.size();
  CHECK(dropped <= recon::kUntangleMaxDropped * untangled.untangle.widened);
  REQUIRE(untangled.mesh.vertices.size() + dropped == tangled.mesh.vertices.size());
  if (dropped == 0) {
    CHECK(untangled.mesh.vertices == tangled.mesh.vertices);
  } else {
    REQUIRE(untangled.untangle.renumber.size() == tangled.mesh.vertices.size());
    std::size_t kept_same = 0;
    for (std::size_t v = 0; v < tangled.mesh.vertices.size(); ++v) {
      const std::uint32_t to = untangled.untangle.renumber[v];
      if (to == recon::kNoVertex) continue;
      kept_same += untangled.mesh.vertices[to] == tangled.mesh.vertices[v] ? 1 : 0;
    }
    CHECK(kept_same == untangled.mesh.vertices.size());
  }
  CHECK(after.referenced_vertices == untangled.mesh.vertices.size());
  CHECK(untangled.outliers.size() == tangled.outliers.size() + dropped);
  CHECK(recon::find_self_intersections(untangled.mesh).pairs == 0);
}

// Read as `scanmesh reconstruct --conf` reads them (in the registration file's order, each
// scan's normals towards its sensor), the ten merged scans leave a 5-edge gap at an ear's tip,
// where the misregistered views make a sheet a few layers thick: its patch crosses a flap of the
// ear's other side, and removing the crossed triangles alone would leave a vertex two fans. The
// removal takes in the flap; two of its vertices lie on no patch and become outliers. Then only
// the base's five loops stay (6 before; recon/README.md, Pipeline 8). The front's result
// depends on the points' order: in kMergedBunnyScans' order (the test above) no gap crosses, but
// a 15-edge loop at the base's rim stays, too long for a sampling gap.
TEST_CASE("real scan: the merged scans as the CLI reads them keep only the base's loops",
          "[recon][real][slow]") {
  // In the registration file's order, as the CLI reads them.
  const std::vector<std::string> in_conf_order{
      "bunny/data/bun000.ply", "bunny/data/bun045.ply", "bunny/data/bun090.ply",
      "bunny/data/bun180.ply", "bunny/data/bun270.ply", "bunny/data/top2.ply",
      "bunny/data/top3.ply",   "bunny/data/bun315.ply", "bunny/data/chin.ply",
      "bunny/data/ear_back.ply"};
  std::vector<Vec3> towards;
  const auto loaded =
      load_points(in_conf_order, "bunny/data/bun.conf", "the merged scans' flap", &towards);
  if (!loaded) return;
  REQUIRE(towards.size() == loaded->size());
  recon::ReconstructOptions opt;
  opt.untangle_gaps = false;
  const recon::ReconstructResult tangled = recon::reconstruct(*loaded, opt, {}, towards);
  const recon::ReconstructResult r = recon::reconstruct(*loaded, {}, {}, towards);
  const recon::MeshReport before = recon::analyze(tangled.mesh), rep = recon::analyze(r.mesh);
  INFO("loops " << before.boundary_loops << " -> " << rep.boundary_loops << ", widened "
                << r.untangle.widened << ", dropped " << r.untangle.dropped.size());
  check_valid_one_piece_genus0(rep);
  CHECK(rep.boundary_loops == 5);
  CHECK(before.boundary_loops == 6);
  CHECK(r.untangle.widened >= 1);
  CHECK(r.untangle.closed == 1);
  CHECK(r.untangle.dropped.size() <= recon::kUntangleMaxDropped * r.untangle.widened);
  CHECK(rep.referenced_vertices == r.mesh.vertices.size());
  CHECK(recon::find_self_intersections(r.mesh).pairs == 0);
  // Nothing lost: every point the mesh left out is an outlier.
  CHECK(r.mesh.vertices.size() + r.outliers.size() ==
        tangled.mesh.vertices.size() + tangled.outliers.size());
  for (const Vec3& p : r.untangle.dropped)
    CHECK(std::find(r.outliers.begin(), r.outliers.end(), p) != r.outliers.end());
  CHECK(r.far_points == tangled.far_points);
  CHECK(std::equal(tangled.outliers.end() - static_cast<std::ptrdiff_t>(tangled.far_points),
                   tangled.outliers.end(),
                   r.outliers.end() - static_cast<std::ptrdiff_t>(r.far_points)));
}

// The casting's walls are one or two spacings thick, so a triangle the front grows on one side
// can pierce the other (whose front faces away, so the front-edge tests ignore it), and across
// its sharp edges a triangle can fold over the face beyond. Without the crossing guard its
// output has about two hundred crossing pairs; with it, none, and the points still go in.
TEST_CASE("real scan: the crossing guard keeps the casting's triangles from piercing its walls",
          "[recon][real][slow]") {
  const auto points =
      load_points({"casting/casting_vertices.xyz"}, "", "the casting's crossing guard");
  if (!points) return;
  recon::ReconstructOptions opt;
  opt.front.crossing_guard = false;
  const recon::ReconstructResult unguarded = recon::reconstruct(*points, opt);
  const recon::ReconstructResult guarded = recon::reconstruct(*points);
  const std::size_t before = recon::find_self_intersections(unguarded.mesh).pairs;
  const std::size_t after = recon::find_self_intersections(guarded.mesh).pairs;
  INFO("crossing pairs: unguarded " << before << ", guarded " << after << "; turning points "
                                    << guarded.turning_points << " of " << guarded.reduced_points);
  CHECK(before > 50);
  CHECK(after == 0);
  CHECK(guarded.turning_points > 0);
  CHECK(static_cast<double>(guarded.mesh.vertices.size()) >= 0.99 * static_cast<double>(guarded.reduced_points));
  const recon::MeshReport rep = recon::analyze(guarded.mesh);
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.non_manifold_vertices == 0);
  CHECK(rep.orientation_consistent);
}

// A scan whose density falls across the part: the bunny's points, thinned from all of them at
// the lowest x to 15 % at the highest. The front once ran a front edge 15 um beside one of its
// own vertices (1.3 % of the spacing), which left the open sector at the edge's end within a
// degree of a full turn; the next ear there, over a flat stretch where the fan test is skipped,
// lay over two bulk triangles (2 crossing pairs). Near-closed and near-full sectors now take the
// fan test.
TEST_CASE("real scan: the bunny's points thinned across x mesh without a crossing pair",
          "[recon][real][slow]") {
  const auto points = load_points({"bunny/reconstruction/bun_zipper.ply"}, "",
                                  "the thinned bunny points");
  if (!points) return;
  const std::vector<Vec3> thinned = test::density_ramp_x(*points, 0.15, 1);
  const recon::ReconstructResult res = recon::reconstruct(thinned);
  const recon::MeshReport rep = recon::analyze(res.mesh);
  INFO(thinned.size() << " points, " << rep.boundary_loops << " loops, genus " << rep.genus);
  CHECK(recon::find_self_intersections(res.mesh).pairs == 0);
  check_valid_one_piece_genus0(rep);
}

// The bunny's four large holes (176-304 spacings^2; the fifth, 47, is two to three spacings
// wide once the points are thinned) under noise and dropouts. Their rims come out ragged, and
// the relaxed pass used to zip them from their narrow ends with edges of 4-6 spacings: a loop
// the mesh surrounds, of at least 20 spacings^2 and 1.8 spacings' mean width, is now a hole,
// whose rim the relaxed pass joins to front points only within the strict reach. Measured with
// bench_holes, seeds 1-5: the mean open share of the largest hole 40 -> 72 % with noise of 0.1
// spacing, 49 -> 66 % with 40 % dropouts; of the 176-spacings^2 one 46 -> 73 %, 33 -> 60 %.
TEST_CASE("real scan: the bunny's large holes stay open under noise and dropouts",
          "[recon][real][slow]") {
  const auto loaded = test::shared_mesh("bunny/reconstruction/bun_zipper.ply",
                                        "the bunny's holes under noise and dropouts");
  if (!loaded) return;
  const recon::Mesh& ref = *loaded;
  const double spacing = recon::estimate_spacing(ref.vertices).nearest_mm;
  const std::vector<test::Hole> holes = test::reference_holes(ref, 0.2 * spacing);
  REQUIRE(holes.size() == 5);
  struct Run {
    const char* what;
    std::vector<Vec3> points;
  };
  std::vector<Run> runs;
  runs.push_back({"noise 0.1 spacing, seed 1", ref.vertices});
  test::add_noise(runs.back().points, 0.1 * spacing, 1);
  runs.push_back({"40 % dropouts, seed 2",
                  test::thin_out(ref.vertices, 2, [](const Vec3&) { return 0.6; })});
  for (const Run& run : runs) {
    // The smallest open share of the four large holes, with and without the hole rule.
    auto least_open = [&](bool keep_holes, recon::MeshReport& rep) {
      recon::ReconstructOptions opt;
      opt.front.keep_holes = keep_holes;
      const recon::ReconstructResult res = recon::reconstruct(run.points, opt);
      rep = recon::analyze(res.mesh);
      CHECK(recon::find_self_intersections(res.mesh).pairs == 0);
      const recon::SurfaceDistance surface(res.mesh);
      double least = 100;
      for (std::size_t h = 0; h < 4; ++h)
        least = std::min(least, test::open_percent(holes[h], surface, 0.25 * res.cube_mm));
      return least;
    };
    recon::MeshReport kept, zipped;
    const double with_rule = least_open(true, kept), without = least_open(false, zipped);
    INFO(run.what << ": least open share of the four large holes " << without << " % -> "
                  << with_rule << " %; loops " << zipped.boundary_loops << " -> "
                  << kept.boundary_loops);
    CHECK(without < 60);
    CHECK(with_rule >= 60);
    check_valid_one_piece_genus0(kept);
  }
}

// The casting's points are a CAD mesh's vertices, crowded along its features: every neighbourhood
// spans structure, and its shell measures 0.42 cross spacings thick, as a noisy scan's could. But
// structure shrinks with the neighbourhood (a 12-point fit leaves 0.40 of a 20-point fit's
// residual; noise 0.85), so the cube stays the sampling's: 14 times that shell would be 8 times
// the spacing and erase the part.
TEST_CASE("real scan: the casting's thick shell is structure and leaves the cube to the sampling",
          "[recon][real]") {
  const auto points = load_points({"casting/casting_vertices.xyz"}, "", "the casting's spacing");
  if (!points) return;
  const recon::SpacingEstimate s = recon::estimate_spacing(*points);
  INFO("nearest " << s.nearest_mm << " cross " << s.cross_mm << " thickness " << s.thickness_mm
                  << " few " << s.thickness_few_mm << " shape " << s.thickness_shape);
  REQUIRE(s.thickness_mm > 0.3 * s.cross_mm);
  CHECK(s.thickness_few_mm < 0.6 * s.thickness_mm);
  CHECK(recon::auto_cube_size(s) == std::max(s.nearest_mm, 0.75 * s.cross_mm));
}

// Orientation across thin walls: the point across the wall has a parallel PCA normal, and the
// plain most-parallel-first propagation oriented 38% of the casting's normals inward. Against
// the reference's vertex normals, among the normals PCA resolves (|cos| >= 0.7).
TEST_CASE("real scan: casting normals are oriented outward across thin walls",
          "[recon][real][slow]") {
  const auto loaded = test::shared_mesh("casting/casting.obj", "the casting normals");
  if (!loaded) return;
  const recon::Mesh& m = *loaded;
  std::vector<Vec3> vn(m.vertices.size(), Vec3::Zero());
  for (const auto& t : m.triangles) {
    const Vec3 n = (m.vertices[t[1]] - m.vertices[t[0]]).cross(m.vertices[t[2]] - m.vertices[t[0]]);
    for (const auto v : t) vn[v] += n;
  }
  const recon::SpacingEstimate sp = recon::estimate_spacing(m.vertices);
  recon::PointGrid grid;
  grid.build(m.vertices, 2.5 * sp.nearest_mm);
  const recon::LocalFrames f = recon::estimate_frames(m.vertices, grid);
  std::size_t resolved = 0, inward = 0;
  for (std::size_t i = 0; i < m.vertices.size(); ++i) {
    const double d = f.normal[i].cast<double>().dot(vn[i].normalized());
    if (std::abs(d) < 0.7) continue;
    ++resolved;
    if (d < 0) ++inward;
  }
  INFO(inward << " of " << resolved << " resolved normals point inward");
  CHECK(resolved > m.vertices.size() * 8 / 10);
  CHECK(inward * 100 < resolved);  // measured: 6 of 4447
}

// On request (`--fill-holes`), the loops are closed where a patch closes them without crossing
// the mesh: the bunny's five base holes all are, so that a CAD tool gets a closed mesh. The
// casting's loops lie at thin walls and sharp edges, where patches would cut through the part,
// and those stay open (4 of its 9 loops were filled before the front refused triangles whose
// base edge runs through a front vertex; its 6 loops since are all of that kind). The
// topology is otherwise kept (filling adds no handle), the patches face outward like the rest,
// and the refinement gives them edges of the mesh's length without moving a vertex of the mesh.
TEST_CASE("real scan: on request the bunny's base holes and the casting's loops are filled",
          "[recon][real][slow]") {
  struct Filled {
    std::string input;
    std::size_t max_edges;
  };
  // The bunny's largest base hole has a rim of 66 edges (45 before its border chords were peeled).
  for (const Filled& c : {Filled{"bunny/reconstruction/bun_zipper_vertices.xyz", 96},
                          Filled{"casting/casting_vertices.xyz", 64}}) {
    const auto points = load_points({c.input}, "", "the hole filling on " + c.input);
    if (!points) return;
    recon::ReconstructOptions opt;
    const recon::ReconstructResult open = recon::reconstruct(*points, opt);
    opt.fill.max_edges = c.max_edges;
    const recon::ReconstructResult closed = recon::reconstruct(*points, opt);
    const recon::MeshReport before = recon::analyze(open.mesh), after = recon::analyze(closed.mesh);
    INFO(c.input << ": loops " << before.boundary_loops << " -> " << after.boundary_loops
                 << ", genus " << before.genus << " -> " << after.genus);
    const bool bunny = c.input.starts_with("bunny");
    CHECK(before.boundary_loops > 0);
    CHECK(closed.fill.filled + closed.fill.kept == before.boundary_loops);
    CHECK(after.boundary_loops == closed.fill.kept);
    // every loop kept is within max_edges: kept because each of its patches would cross
    CHECK(closed.fill.crossing == closed.fill.kept);
    if (bunny) {
      CHECK(closed.fill.filled == before.boundary_loops);
      CHECK(after.signed_volume > 0);  // closed and outward
    }
    const std::size_t mesh_triangles = open.mesh.triangles.size();
    INFO("crossing pairs in the output: " << recon::find_self_intersections(closed.mesh).pairs);
    CHECK(recon::find_self_intersections(closed.mesh, 0, mesh_triangles).pairs == 0);
    check_patches_keep_topology(before, after);
    CHECK(closed.mesh.vertices.size() == open.mesh.vertices.size() + closed.fill.vertices);
    if (closed.fill.filled == 0) continue;  // the casting today: nothing to measure a patch by
    CHECK(closed.fill.vertices > 0);
    for (std::size_t v = 0; v < open.mesh.vertices.size(); ++v)
      REQUIRE(closed.mesh.vertices[v] == open.mesh.vertices[v]);
    auto mean_edge = [&](std::size_t first, std::size_t last) {
      double sum = 0;
      for (std::size_t t = first; t < last; ++t)
        for (int k = 0; k < 3; ++k)
          sum += (closed.mesh.vertices[closed.mesh.triangles[t][(k + 1) % 3]] -
                  closed.mesh.vertices[closed.mesh.triangles[t][k]])
                     .norm();
      return sum / static_cast<double>(3 * (last - first));
    };
    const double patch = mean_edge(mesh_triangles, closed.mesh.triangles.size());
    const double mesh = mean_edge(0, mesh_triangles);
    INFO("mean edge: patches " << patch << ", mesh " << mesh);
    CHECK(patch < 2.0 * mesh);  // measured: bunny 1.4x, casting 1.8x (its patches stay flat)
    // Refinement and fairing never fold a patch: its sharpest crease stays within 10 degrees of
    // the minimum-weight (flat) patch's. The casting's loops span sharp edges of the part.
    opt.fill.refine = false;
    const recon::ReconstructResult flat = recon::reconstruct(*points, opt);
    const double flat_crease = sharpest_patch_crease(flat.mesh, mesh_triangles);
    const double crease = sharpest_patch_crease(closed.mesh, mesh_triangles);
    INFO("sharpest crease: flat patches " << flat_crease << " deg, refined " << crease << " deg; filled "
         << flat.fill.filled << " flat, " << closed.fill.filled << " refined");
    // Compared over the same loops only: a loop whose flat patch crosses the mesh is filled
    // refined alone, and its crease has no flat counterpart (the casting once: 4 loops refined,
    // 3 flat).
    if (flat.fill.filled == closed.fill.filled) CHECK(crease <= flat_crease + 10);
  }
}
