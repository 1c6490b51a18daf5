// Simulated scans meshed in process, with every digit of the simulated points: some of the
// front's failures depend on the last bits of the input, and `scanmesh simulate` writes 9
// significant digits (enough for a sensor), so a CLI round trip can miss them. bench_quality
// (--save) finds such scans; the ones traced to a cause are pinned here.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/sampling.hpp"
#include "scanmesh/sim/simulator.hpp"
#include "scanmesh/sim/stream.hpp"
#include "support/shared_mesh.hpp"

namespace {

using namespace scanmesh;
using recon::Vec3;

/// A `sensor` (line profiler: `profile_points` a profile) scanning `part` along `path` ("views": from `views` table angles; 0 for the
/// other paths) at 20 mm/s, with range noise (sigma) and dropouts (bench_quality's defaults:
/// 0.02 mm, 5 %).
std::vector<Vec3> scan(sim::SensorKind sensor, const std::string& part, const std::string& path,
                       std::uint32_t views, double spacing_mm, std::uint32_t profile_points,
                       std::uint64_t seed, double noise_mm, double dropout) {
  const sim::Scene scene{sim::make_part(part)};
  sim::SimConfig cfg;
  cfg.sensor = sim::default_sensor(sensor);
  if (sensor == sim::SensorKind::kLine) cfg.sensor.profile_points = profile_points;
  cfg.sensor.rate_hz = 20.0 / spacing_mm;
  cfg.path.kind = sim::path_kind_from_string(path);
  cfg.path.spacing_mm = spacing_mm;
  if (views > 0) cfg.path.views = views;
  cfg.imperfections.seed = seed;
  cfg.imperfections.range_noise_mm = noise_mm;
  cfg.imperfections.dropout_probability = dropout;
  const sim::Simulator simulator(scene, cfg);
  sim::ScanRecorder rec;
  simulator.run(rec, &rec);
  const sim::SimulatedScan& s = rec.scan();
  std::vector<Vec3> points;
  for (const auto& p : sim::points_from_samples(simulator.optics(), simulator.calibration(),
                                                s.stage, s.sensor, s.probe))
    points.push_back(p.point_mm);
  return points;
}

std::vector<Vec3> line_scan(const std::string& part, const std::string& path, std::uint32_t views,
                            double spacing_mm, std::uint32_t profile_points, std::uint64_t seed,
                            double noise_mm = 0.02, double dropout = 0.05) {
  return scan(sim::SensorKind::kLine, part, path, views, spacing_mm, profile_points, seed,
              noise_mm, dropout);
}

/// The output guarantees every scan here must keep: manifold, one orientation, no crossing
/// triangles, at least 99 % of the reduced points used. Returns the mesh's report.
recon::MeshReport check_valid(const recon::ReconstructResult& r) {
  const recon::MeshReport rep = recon::analyze(r.mesh);
  INFO(rep.boundary_loops << " loops, genus " << rep.genus << ", " << rep.components
                          << " components");
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.non_manifold_vertices == 0);
  CHECK(rep.orientation_consistent);
  CHECK(recon::find_self_intersections(r.mesh).pairs == 0);
  CHECK(r.mesh.vertices.size() >= 0.99 * static_cast<double>(r.reduced_points));
  return rep;
}

}  // namespace

// Along the cylinder's top rim the front cut the right-angled edge with a bevel (its corners'
// normals 55 degrees off its own) and later meshed the rim's points flat above it, 0.89 local
// spacings up: a flap, whose joining triangle closed a tunnel between the two layers (genus 1).
// The stacking rule refused flaps only up to 0.8 spacings; over a bevel across a sharp edge it
// now refuses them up to 1.2. (bench_quality, seeds 1-30: the only false handle in 600 scans.)
TEST_CASE("a six-view line scan of the cylinder meshes without a flap over the rim's bevel",
          "[sim][recon]") {
  const std::vector<Vec3> points = line_scan("cylinder", "views", 6, 0.4, 120, 14);
  REQUIRE(points.size() > 60000);
  const recon::ReconstructResult r = recon::reconstruct(points);
  CHECK(check_valid(r).genus == 0);
}

// A sensor whose noise (0.1 mm) is most of its point spacing (0.13 mm along a profile): the
// sampled shell measures a third of the cross spacing thick, where the auto cube used to take it
// for structure and keep the sampling's cube. The front then meshed the noise: genus 12-29,
// 300-400 loops, 97 % of the points used, 2 s. The shell looks like noise (the same at both
// neighbourhood sizes, not two layers), so the cube now swallows it, as for thinner noise.
TEST_CASE("a noisy six-view line scan of the steps is meshed over its noise and not through it",
          "[sim][recon]") {
  const std::vector<Vec3> points = line_scan("steps", "views", 6, 0.4, 120, 1, 0.1, 0.3);
  const recon::ReconstructResult r = recon::reconstruct(points);
  INFO("cube " << r.cube_mm << ", thickness " << r.spacing.thickness_mm << " of cross "
               << r.spacing.cross_mm);
  CHECK(r.spacing.thickness_mm > 0.3 * r.spacing.cross_mm);  // the case is a thick shell
  CHECK(r.cube_mm == Approx(14 * r.spacing.thickness_mm));
  const recon::MeshReport rep = check_valid(r);
  INFO(rep.boundary_loops << " loops, genus " << rep.genus);
  CHECK(rep.genus == 0);
  CHECK(rep.components == 1);
  CHECK(rep.boundary_loops <= 6);  // the views' shadows (5 today)
  // Over the noise: the mesh lies within a quarter of the noise of the part, on average.
  const recon::Mesh part = sim::make_part("steps");
  const recon::DeviationReport dev = recon::deviation(r.mesh, part);
  CHECK(dev.mesh_to_ref.mean < 0.025);
}

// A raster's profiles put points exactly on lines (x = 5.0 here), and with 40 % dropouts the
// bulk and the front left a loop of four front vertices on the cylinder's cap, one of them
// (x = 5.0, y = -1.287) 4e-5 mm from the segment between two others on its line. The triangle
// on that segment, as the loop's base edge, counted the vertex as outside (by 2e-6, under the
// clearance the new edges get) and overlapped the vertex's two triangles: 2 crossing pairs.
// A vertex within the clearance of the base edge now counts as on it, as for the new edges.
TEST_CASE("a raster scan with many dropouts meshes without a triangle over a front vertex",
          "[sim][recon]") {
  const std::vector<Vec3> points = line_scan("cylinder", "raster", 0, 0.6, 80, 4, 0.02, 0.4);
  check_valid(recon::reconstruct(points));
}

// The casting's own points are the vertices of its CAD mesh: rings of 16 around each bolt hole,
// none inside its flat faces. Meshed from them it comes out with genus 8 and 6 loops, 3 of its
// 8 bolt holes closed (recon/README, "Thin walls"). Its surface sampled evenly, as a scanner
// samples a part, meshes with the defaults into exactly its genus 9 (8 bolt holes and the bore)
// without a hole, and no triangle strays from the surface by more than about a cube (a bolt
// hole capped over would be 4 cubes from it, its radius). Measured: seeds 1-3 at 0.01 and seed 1
// at 0.008 and 0.015 alike; at 0.007 and 0.012 one 4-edge loop whose patch would cross the
// mesh stays open; at 0.02 (flange 3.6 spacings thick) 6 loops.
TEST_CASE("the casting's surface sampled evenly meshes closed with its 8 bolt holes and bore",
          "[recon][real][slow]") {
  const auto loaded = test::shared_mesh("casting/casting.obj", "the evenly sampled casting");
  if (!loaded) return;
  const recon::Mesh& ref = *loaded;
  for (const double spacing : {0.01, 0.015}) {
    const std::vector<Vec3> points = sim::sample_surface(ref, spacing, 1);
    const recon::ReconstructResult r = recon::reconstruct(points);
    INFO("spacing " << spacing << ": " << points.size() << " points, cube " << r.cube_mm);
    const recon::MeshReport rep = check_valid(r);
    CHECK(rep.genus == 9);
    CHECK(rep.boundary_loops == 0);
    CHECK(rep.components == 1);
    const recon::DeviationReport dev = recon::deviation(r.mesh, ref);
    INFO("mesh -> ref max " << dev.mesh_to_ref.max / r.cube_mm << ", ref -> mesh max "
                            << dev.ref_to_mesh.max / r.cube_mm << " cubes");
    CHECK(dev.mesh_to_ref.max < 2 * r.cube_mm);
    CHECK(dev.ref_to_mesh.max < 2 * r.cube_mm);
  }
}

// A point sensor's serpentine raster ends the surface with its first and last scan lines, and on
// a curved part such a line is a curve: where it ends the surface, its samples bulge into the
// mesh. The front's relaxed pass joined the line's samples by chords with an angle of 138-162
// degrees at the skipped sample, and the sampling-gap closing filled the loops under them: fans
// in the line's plane, up to 0.78 mm inside the sphere (noise 0.02 mm) and 0.83 mm over the
// container's rims. Border triangles with an angle over 120 degrees at an inner vertex are now
// peeled off (ReconstructOptions::peel_apex_deg), and the border passes through the samples.
TEST_CASE("the border of a curved point-sensor raster passes through its samples, not chords",
          "[sim][recon]") {
  for (const std::string part : {"sphere", "container"}) {
    const recon::Mesh ref = sim::make_part(part);
    for (std::uint64_t seed = 1; seed <= 4; ++seed) {
      const std::vector<Vec3> points =
          scan(sim::SensorKind::kPoint, part, "serpentine", 0, 0.5, 0, seed, 0.02, 0.05);
      recon::ReconstructOptions opt;
      const recon::ReconstructResult r = recon::reconstruct(points, opt);
      opt.peel_apex_deg = 0;
      const recon::ReconstructResult chords = recon::reconstruct(points, opt);
      const recon::MeshReport rep = check_valid(r), with_chords = recon::analyze(chords.mesh);
      const double max = recon::deviation(r.mesh, ref).mesh_to_ref.max;
      const double max_chords = recon::deviation(chords.mesh, ref).mesh_to_ref.max;
      INFO(part << " seed " << seed << ": " << r.peeled_chords << " peeled, mesh -> part max "
                << max_chords << " -> " << max << " mm, cube " << r.cube_mm);
      CHECK(r.peeled_chords > 0);
      CHECK(max_chords > 0.4);  // the fins (0.44-0.83 mm measured)
      // What stays is the chords across the scan's own line spacing (2.5 mm) on the sphere:
      // 0.17-0.19 mm measured; on the container's flat faces 0.02-0.03.
      CHECK(max < (part == "sphere" ? 0.25 : 0.05));
      // Peeling changes no loop, piece or handle and keeps every point.
      CHECK(rep.boundary_loops == with_chords.boundary_loops);
      CHECK(rep.components == with_chords.components);
      CHECK(rep.genus == with_chords.genus);
      CHECK(r.mesh.vertices.size() == chords.mesh.vertices.size());
      CHECK(r.mesh.triangles.size() + r.peeled_chords == chords.mesh.triangles.size());
    }
  }
}
