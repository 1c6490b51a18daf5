// Sharp-edge recovery on simulated scans of the built-in parts: how far the part's sharp edges
// (reference edges whose faces' normals differ by 35 degrees or more) lie from the mesh, before
// and after `sharpen_edges`, over the edge points the scan saw (the mesh before has both faces
// beside them, two spacings in from the edge, within 0.1 mm), with the mesh's validity, topology and distance to the part after. It prints
// figures; it asserts nothing (tests/recon/test_sharpen.cpp does).
// SPDX-License-Identifier: MIT
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "scanmesh/recon/sharpen.hpp"
#include "scanmesh/recon/denoise.hpp"
#include "scanmesh/sim/parts.hpp"
#include "sim_scan.hpp"

#ifndef SCANMESH_BENCH_BUILD_TYPE
#define SCANMESH_BENCH_BUILD_TYPE "unknown"
#endif

namespace {

using scanmesh::bench::Imperfections;
using scanmesh::bench::Mode;
using scanmesh::recon::Vec3;
namespace recon = scanmesh::recon;
namespace sim = scanmesh::sim;

/// A point on a sharp edge of the part and, for each of its two faces, a point of that face
/// `inset` in from the edge.
struct EdgePoint {
  Vec3 p, face[2];
};

/// Points every `step` along the edges of `ref` whose two triangles' normals differ by at least
/// `deg` degrees.
std::vector<EdgePoint> sharp_edge_points(const recon::Mesh& ref, double deg, double step,
                                         double inset) {
  struct Seen {
    Vec3 normal, inward;
  };
  std::map<std::pair<std::uint32_t, std::uint32_t>, Seen> first;  // edge -> its first side
  std::vector<EdgePoint> out;
  const double c = std::cos(deg * 3.14159265358979323846 / 180.0);
  for (const auto& t : ref.triangles) {
    const auto& v = ref.vertices;
    const Vec3 n = (v[t[1]] - v[t[0]]).cross(v[t[2]] - v[t[0]]).normalized();
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k], b = t[(k + 1) % 3];
      const Vec3 inward = n.cross(v[b] - v[a]).normalized();  // towards the third corner
      const auto key = std::minmax(a, b);
      const auto it = first.find(key);
      if (it == first.end()) {
        first.emplace(key, Seen{n, inward});
        continue;
      }
      if (it->second.normal.dot(n) > c) continue;
      const Vec3 &p = v[a], &q = v[b];
      const int m = std::max(1, static_cast<int>(std::ceil((q - p).norm() / step)));
      for (int i = 0; i <= m; ++i) {
        const Vec3 x = p + (q - p) * (static_cast<double>(i) / m);
        out.push_back({x, {x + inset * inward, x + inset * it->second.inward}});
      }
    }
  }
  return out;
}

/// Triangles whose smallest interior angle is under 10 degrees.
std::size_t below_10(const recon::MeshReport& r) {
  return static_cast<std::size_t>(std::lround(r.frac_min_angle_below_10 *
                                              static_cast<double>(r.triangles)));
}

}  // namespace

int main(int argc, char** argv) {
  int seeds = 2;
  recon::SharpenOptions options;
  bool denoise = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seeds" && i + 1 < argc) {
      seeds = std::atoi(argv[++i]);
    } else if (a == "--face-angle" && i + 1 < argc) {
      options.smooth_deg = std::atof(argv[++i]);
    } else if (a == "--feature-angle" && i + 1 < argc) {
      options.feature_deg = std::atof(argv[++i]);
    } else if (a == "--passes" && i + 1 < argc) {
      options.passes = std::atoi(argv[++i]);
    } else if (a == "--denoise") {
      denoise = true;
    } else if (a == "--no-peel") {
      options.peel = false;
    } else {
      std::fprintf(stderr,
                   "usage: %s [--seeds N] [--face-angle DEG] [--feature-angle DEG] [--passes N]\n"
                   "          [--no-peel] [--denoise]\n"
                   "  seeds 1..N per part and mode (default 2); the angles as scanmesh sharpen's;\n"
                   "  --denoise: the noise removed first (denoise_mesh, defaults)\n",
                   argv[0]);
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  const Imperfections imp;
  const Mode modes[] = {
      {"point serpentine 0.5", sim::SensorKind::kPoint, "serpentine", 0.5, 0, 0},
      {"line raster 0.6", sim::SensorKind::kLine, "raster", 0.6, 80, 0},
      {"line 4 views 0.8", sim::SensorKind::kLine, "views", 0.8, 60, 4},
      {"line 6 views 0.4", sim::SensorKind::kLine, "views", 0.4, 120, 6},
  };
  if (const auto errors = options.validate(); !errors.empty()) {
    std::fprintf(stderr, "%s\n", errors.front().c_str());
    return 2;
  }
  std::printf(
      "bench_edges: build type %s; noise %.2f mm, dropout %.2f; seeds 1..%d; face angle %g, "
      "feature angle %g degrees, %d pass(es), peeling %s%s\n",
      SCANMESH_BENCH_BUILD_TYPE, imp.noise_mm, imp.dropout, seeds, options.smooth_deg,
      options.feature_deg, options.passes, options.peel ? "on" : "off",
      denoise ? "; the noise removed first" : "");
  std::printf(
      "edge: distance from the part's sharp edges (the points seen) to the mesh, before -> "
      "after sharpening (mean, p95, max); m->r: mesh to part after (mean, max); new: edge + "
      "corner vertices (refused); tri. <10 deg: triangles with an angle under 10 degrees, "
      "before -> after; mm\n\n");
  std::printf("%-10s %-22s %4s %6s %17s %17s %17s %17s %13s %13s %11s %6s\n", "part", "mode",
              "seed", "points", "edge mean", "edge p95", "edge max", "m->r mean", "new (ref.)",
              "tri. <10 deg", "loops genus", "ms");
  int runs = 0, invalid = 0, changed = 0;
  for (const std::string part : {"container", "steps", "cylinder"}) {
    const recon::Mesh reference = sim::make_part(part);
    const sim::Scene scene{recon::Mesh(reference)};
    for (const Mode& m : modes) {
      // Face points two spacings in from the edge: the edge was seen when both are meshed.
      const std::vector<EdgePoint> edge = sharp_edge_points(reference, 35, 0.1, 2 * m.spacing_mm);
      for (int seed = 1; seed <= seeds; ++seed) {
        ++runs;
        try {
          const auto points = scanmesh::bench::scan(scene, m, imp, static_cast<std::uint64_t>(seed));
          const recon::ReconstructResult r = recon::reconstruct(points, recon::ReconstructOptions{});
          recon::Mesh sharp = r.mesh;
          const auto t0 = std::chrono::steady_clock::now();
          if (denoise) recon::denoise_mesh(sharp);
          const recon::SharpenStats st = recon::sharpen_edges(sharp, options);
          const double ms =
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                  .count();
          const recon::SurfaceDistance before(r.mesh), after(sharp);
          std::vector<double> db, da;
          for (const EdgePoint& e : edge) {
            // Not seen: a face beside it is not meshed there (a scan's border, a hole).
            if (before.distance(e.face[0]) > 0.1 || before.distance(e.face[1]) > 0.1) continue;
            db.push_back(before.distance(e.p));
            da.push_back(after.distance(e.p));
          }
          const recon::DistanceStats sb = recon::stats_of(db), sa = recon::stats_of(da);
          const recon::DeviationReport dev0 = recon::deviation(r.mesh, reference);
          const recon::DeviationReport dev1 = recon::deviation(sharp, reference);
          const recon::MeshReport rep0 = recon::analyze(r.mesh), rep = recon::analyze(sharp);
          const std::size_t crossing = recon::find_self_intersections(sharp).pairs;
          const bool valid = rep.non_manifold_edges == 0 && rep.non_manifold_vertices == 0 &&
                             rep.orientation_consistent && crossing == 0;
          const bool same = rep.boundary_loops == rep0.boundary_loops &&
                            rep.genus == rep0.genus && rep.components == rep0.components;
          invalid += valid ? 0 : 1;
          changed += same ? 0 : 1;
          std::printf(
              "%-10s %-22s %4d %6zu %7.4f > %7.4f %7.4f > %7.4f %7.4f > %7.4f %7.4f > %7.4f "
              "%5zu+%zu (%zu) %5zu > %5zu %5zu %5ld %6.1f%s%s\n",
              part.c_str(), m.name, seed, sb.count, sb.mean, sa.mean, sb.p95, sa.p95, sb.max,
              sa.max, dev0.mesh_to_ref.mean, dev1.mesh_to_ref.mean, st.edge_vertices,
              st.corner_vertices, st.refused, below_10(rep0), below_10(rep), rep.boundary_loops,
              rep.genus, ms,
              valid ? "" : "  INVALID", same ? "" : "  TOPOLOGY CHANGED");
        } catch (const std::exception& e) {
          ++invalid;
          std::printf("%-10s %-22s %4d  failed: %s\n", part.c_str(), m.name, seed, e.what());
        }
        std::fflush(stdout);
      }
    }
  }
  std::printf("\n%d scans: %d invalid or failed after sharpening, %d with their topology changed\n",
              runs, invalid, changed);
  return 0;
}
