// The incremental reconstruction (recon/incremental.hpp): the same mesh whatever the batch cuts,
// snapshots and deltas that rebuild it, the batch path's guarantees at finish(), re-opening.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/incremental.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "recon/incremental_support.hpp"

namespace {

using namespace scanmesh;
using recon::Vec3;
using test::raster_scan;

/// Feeds `points` in batches of `batch` (0: all at once) and finishes.
recon::IncrementalResult run_batches(const std::vector<Vec3>& points, std::size_t batch,
                                     const recon::IncrementalOptions& opt = {}) {
  recon::IncrementalReconstructor rec(opt);
  const std::size_t step = batch == 0 ? points.size() : batch;
  for (std::size_t i = 0; i < points.size(); i += step) {
    const std::size_t n = std::min(step, points.size() - i);
    rec.add(std::span<const Vec3>(points.data() + i, n));
  }
  return rec.finish();
}

void require_valid(const recon::Mesh& m) {
  const recon::MeshReport r = recon::analyze(m);
  REQUIRE(r.triangles > 0);
  CHECK(r.non_manifold_edges == 0);
  CHECK(r.non_manifold_vertices == 0);
  CHECK(r.orientation_consistent);
  CHECK(r.degenerate_triangles == 0);
  CHECK(r.duplicate_triangles == 0);
  CHECK(r.referenced_vertices == r.vertices);
}

}  // namespace

TEST_CASE("incremental options report every bad field", "[recon][incremental]") {
  recon::IncrementalOptions opt;
  CHECK(opt.validate().empty());
  opt.block_cubes = 2;
  opt.settle_interval_points = 0;
  opt.reconstruct.sharpen = true;
  const auto errors = opt.validate();
  CHECK(errors.size() == 3);
  CHECK_THROWS_AS(recon::IncrementalReconstructor(opt), ConfigError);
}

TEST_CASE("incremental: a batch with a non-finite point is refused whole", "[recon][incremental]") {
  recon::IncrementalReconstructor rec;
  const std::vector<Vec3> good = raster_scan(40, 30, 0.5, 0.5, 0.0, 1);
  rec.add(std::span<const Vec3>(good.data(), 100));
  std::vector<Vec3> bad(good.begin() + 100, good.begin() + 200);
  bad[17].y() = std::nan("");
  try {
    rec.add(bad);
    FAIL("no error");
  } catch (const GeometryError& e) {
    CHECK(std::string(e.what()).find("#17") != std::string::npos);
  }
  CHECK(rec.stats().points_in == 100);
  rec.add(std::span<const Vec3>(good.data() + 100, good.size() - 100));
  const recon::IncrementalResult r = rec.finish();
  CHECK(r.stats.points_in == good.size());
  require_valid(r.mesh);
  CHECK_THROWS_AS(rec.add(good), ConfigError);
}

TEST_CASE("incremental: the same mesh, byte for byte, whatever the batch size",
          "[recon][incremental]") {
  // A serpentine raster over a bumpy height field with noise: 160 lines of 200 points.
  const std::vector<Vec3> pts = raster_scan(200, 160, 0.1, 0.4, 0.01, 7);
  const recon::IncrementalResult whole = run_batches(pts, 0);
  require_valid(whole.mesh);
  CHECK(whole.stats.meshing_steps > 1);  // regions were meshed while the scan ran
  for (const std::size_t batch : {std::size_t{1}, std::size_t{64}, std::size_t{4096}}) {
    INFO("batch " << batch);
    const recon::IncrementalResult r = run_batches(pts, batch);
    CHECK(r.mesh.vertices == whole.mesh.vertices);
    CHECK(r.mesh.triangles == whole.mesh.triangles);
    CHECK(r.vertex_ids == whole.vertex_ids);
    CHECK(r.outliers == whole.outliers);
  }
}

TEST_CASE("incremental: every snapshot is a valid mesh and the deltas rebuild the final one",
          "[recon][incremental]") {
  const std::vector<Vec3> pts = raster_scan(150, 120, 0.1, 0.4, 0.01, 3);
  recon::IncrementalOptions opt;
  opt.settle_delay_points = 2048;
  recon::IncrementalReconstructor rec(opt);
  test::DeltaReplay replay;
  std::size_t non_empty = 0, loops_named = 0;
  for (std::size_t i = 0; i < pts.size(); i += 150) {  // one scan line a batch
    rec.add(std::span<const Vec3>(pts.data() + i, std::min<std::size_t>(150, pts.size() - i)));
    const recon::MeshDelta d = rec.take_delta();
    if (!d.empty()) ++non_empty;
    REQUIRE(replay.apply(d).empty());
    // Every loop the delta names runs along boundary edges of the mesh, in their direction.
    REQUIRE(replay.loops_are_boundary(d.boundary_loops).empty());
    loops_named += d.boundary_loops.size();
    const recon::MeshSnapshot snap = rec.snapshot();
    REQUIRE(snap.triangle_count() == replay.triangle_count());
    if (snap.triangle_count() > 0) {
      const recon::MeshReport r = recon::analyze(snap.to_mesh());
      REQUIRE(r.non_manifold_edges == 0);
      REQUIRE(r.non_manifold_vertices == 0);
      REQUIRE(r.orientation_consistent);
    }
  }
  CHECK(non_empty > 1);
  CHECK(loops_named > 0);
  const recon::IncrementalResult fin = rec.finish();
  REQUIRE(replay.apply(rec.take_delta()).empty());
  std::vector<std::uint32_t> ids;
  const recon::Mesh rebuilt = replay.mesh(&ids);
  CHECK(rebuilt.vertices == fin.mesh.vertices);
  CHECK(rebuilt.triangles == fin.mesh.triangles);
  CHECK(ids == fin.vertex_ids);
}

TEST_CASE("incremental against batch on a synthetic raster scan", "[recon][incremental]") {
  const std::vector<Vec3> pts = raster_scan(200, 160, 0.1, 0.4, 0.01, 11);
  const recon::IncrementalResult inc = run_batches(pts, 200);
  const recon::ReconstructResult batch = recon::reconstruct(pts);
  require_valid(inc.mesh);
  CHECK(recon::find_self_intersections(inc.mesh, 0).pairs == 0);
  const recon::MeshReport ri = recon::analyze(inc.mesh), rb = recon::analyze(batch.mesh);
  CHECK(ri.components == rb.components);
  const double loops_tol = std::max(2.0, 0.1 * static_cast<double>(rb.boundary_loops));
  CHECK(std::abs(static_cast<double>(ri.boundary_loops) - static_cast<double>(rb.boundary_loops)) <=
        loops_tol);
  // Kept points used: vertices over vertices plus outliers (less the far points).
  const double kept = static_cast<double>(inc.mesh.vertices.size() + inc.outliers.size() - inc.far_points);
  CHECK(static_cast<double>(inc.mesh.vertices.size()) >= 0.99 * kept);
  // Distances to the true surface within 10 % of the batch path's.
  const double di = test::mean_height_error(inc.mesh), db = test::mean_height_error(batch.mesh);
  CHECK(di <= 1.1 * db + 1e-4);
}

TEST_CASE("incremental: a second pass over meshed blocks re-opens them, one surface",
          "[recon][incremental]") {
  // Two passes over the same surface, the second shifted by half a line, with its own noise.
  const std::vector<Vec3> first = raster_scan(200, 100, 0.1, 0.4, 0.01, 21);
  std::vector<Vec3> second = raster_scan(200, 100, 0.1, 0.4, 0.01, 22);
  for (Vec3& p : second) {
    p.y() += 0.2;
    p.z() = test::raster_height(p.x(), p.y()) + (p.z() - test::raster_height(p.x(), p.y() - 0.2));
  }
  recon::IncrementalOptions opt;
  opt.settle_delay_points = 2048;
  recon::IncrementalReconstructor rec(opt);
  for (std::size_t i = 0; i < first.size(); i += 200) rec.add(std::span<const Vec3>(first.data() + i, 200));
  rec.settle_all();
  const std::size_t meshed_after_first = rec.snapshot().triangle_count();
  CHECK(meshed_after_first > 0);
  for (std::size_t i = 0; i < second.size(); i += 200) rec.add(std::span<const Vec3>(second.data() + i, 200));
  const recon::IncrementalResult r = rec.finish();
  require_valid(r.mesh);
  CHECK(r.stats.reopened_blocks > 0);
  CHECK(recon::find_self_intersections(r.mesh, 0).pairs == 0);
  // One layer: no vertex over or under a triangle it is not part of, within half a spacing.
  CHECK(test::layered_vertices(r.mesh, 0.5 * r.stats.cube_mm) == 0);
  // The check sees two layers: the two passes meshed apart, put together.
  recon::Mesh two = recon::reconstruct(first).mesh;
  const recon::Mesh other = recon::reconstruct(second).mesh;
  const auto base = static_cast<std::uint32_t>(two.vertices.size());
  two.vertices.insert(two.vertices.end(), other.vertices.begin(), other.vertices.end());
  for (auto t : other.triangles) two.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  CHECK(test::layered_vertices(two, 0.5 * r.stats.cube_mm) > 1000);
  CHECK(test::mean_height_error(r.mesh) < 0.02);
}
