// Reconstruction quality on simulated scans of parts whose truth is known: every built-in part,
// scanned in every scanning mode of the simulator (point sensor on a serpentine raster and on a
// rotary table, line profiler on a raster and from table angles) with noise and dropouts, over
// several seeds. For each scan it prints the mesh's validity, topology against the part's own
// (a genus above the part's is a false handle), the points used, the distance to the part both
// ways (reference -> mesh measures coverage: what the views never saw) and the time; then a
// summary. It prints figures; it asserts nothing (the CLI test of the same modes does).
// SPDX-License-Identifier: MIT
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "exact_points.hpp"
#include "sim_scan.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/simulator.hpp"
#include "scanmesh/sim/stream.hpp"

#ifndef SCANMESH_BENCH_BUILD_TYPE
#define SCANMESH_BENCH_BUILD_TYPE "unknown"
#endif

namespace {

using scanmesh::recon::Vec3;
using scanmesh::bench::Imperfections;
using scanmesh::bench::Mode;
using scanmesh::bench::scan;
namespace recon = scanmesh::recon;
namespace sim = scanmesh::sim;


void usage(const char* argv0) {
  std::printf(
      "usage: %s [--seeds N] [--first S] [--part NAME]... [--noise MM] [--dropout P] [--spike P] [--denoise] [--save DIR]\n"
      "  --seeds N    seeds 1..N per part and mode (default 3)\n"
      "  --first S    start at seed S instead of 1 (seeds S..N)\n"
      "  --part NAME  only this built-in part (repeatable; default: all)\n"
      "  --noise MM   range noise of every scan, sigma in mm (default 0.02)\n"
      "  --dropout P  probability that a reading drops out (default 0.05)\n"
      "  --spike P    probability that a reading is a random spike (default 0)\n"
      "  --denoise    remove the noise from each mesh (reconstruct's denoise stage, defaults)\n"
      "  --save DIR   write the points of every flagged scan to DIR/PART-MODE-SEED.xyz, every\n"
      "               digit kept (17), so `scanmesh reconstruct` meets exactly the same input\n",
      argv0);
}

}  // namespace

int main(int argc, char** argv) {
  int seeds = 3, first = 1;
  Imperfections imp;
  std::vector<std::string> parts;
  recon::ReconstructOptions options;
  std::string save_dir;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seeds" && i + 1 < argc) {
      seeds = std::atoi(argv[++i]);
    } else if (a == "--part" && i + 1 < argc) {
      parts.emplace_back(argv[++i]);
    } else if (a == "--first" && i + 1 < argc) {
      first = std::atoi(argv[++i]);
    } else if (a == "--noise" && i + 1 < argc) {
      imp.noise_mm = std::atof(argv[++i]);
    } else if (a == "--dropout" && i + 1 < argc) {
      imp.dropout = std::atof(argv[++i]);
    } else if (a == "--spike" && i + 1 < argc) {
      imp.spike = std::atof(argv[++i]);
    } else if (a == "--denoise") {
      options.denoise = true;
    } else if (a == "--save" && i + 1 < argc) {
      save_dir = argv[++i];
    } else {
      usage(argv[0]);
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  if (seeds < 1 || first < 1 || first > seeds || !(imp.noise_mm >= 0) || !(imp.dropout >= 0) ||
      !(imp.dropout < 1) || !(imp.spike >= 0) || !(imp.spike <= 1)) {
    usage(argv[0]);
    return 2;
  }
  if (parts.empty()) parts = sim::part_names();
  const Mode modes[] = {
      {"point serpentine 0.5", sim::SensorKind::kPoint, "serpentine", 0.5, 0, 0},
      {"point rotary 0.5", sim::SensorKind::kPoint, "rotary", 0.5, 0, 0},
      {"line raster 0.6", sim::SensorKind::kLine, "raster", 0.6, 80, 0},
      {"line 4 views 0.8", sim::SensorKind::kLine, "views", 0.8, 60, 4},
      {"line 6 views 0.4", sim::SensorKind::kLine, "views", 0.4, 120, 6},
  };
  std::printf("bench_quality: build type %s; noise %.2f mm, dropout %.2f, spikes %.3f; seeds %d..%d%s\n",
              SCANMESH_BENCH_BUILD_TYPE, imp.noise_mm, imp.dropout, imp.spike, first, seeds,
              options.denoise ? "; the noise removed from each mesh" : "");
  std::printf(
      "genus: the mesh's / the part's; used: reduced points in the mesh; m->r: mesh to part "
      "(mean, p95, max), r->m p95: part to mesh (coverage), mm\n\n");
  std::printf("%-10s %-22s %4s %8s %8s %5s %7s %4s %8s %5s %8s %8s %8s %8s %8s\n", "part",
              "mode", "seed", "points", "reduced", "loops", "genus", "comp", "used %", "cross",
              "m->r", "m->r p95", "m->r max", "r->m p95", "ms");
  int runs = 0, invalid = 0, false_handles = 0, low_use = 0, failed = 0;
  double sum_mean = 0, sum_p95 = 0;  // of the mesh -> part figures, over the scans meshed
  for (const std::string& part : parts) {
    const recon::Mesh reference = sim::make_part(part);
    const long part_genus = recon::analyze(reference).genus;
    const sim::Scene scene{recon::Mesh(reference)};
    for (const Mode& m : modes) {
      for (int seed = first; seed <= seeds; ++seed) {
        ++runs;
        try {
          const std::vector<Vec3> points = scan(scene, m, imp, static_cast<std::uint64_t>(seed));
          const auto t0 = std::chrono::steady_clock::now();
          const recon::ReconstructResult r = recon::reconstruct(points, options);
          const double ms =
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                  .count();
          const recon::MeshReport rep = recon::analyze(r.mesh);
          const std::size_t crossing = recon::find_self_intersections(r.mesh).pairs;
          const recon::DeviationReport dev = recon::deviation(r.mesh, reference);
          const double used = 100.0 * static_cast<double>(r.mesh.vertices.size()) /
                              static_cast<double>(r.reduced_points);
          const bool valid = rep.non_manifold_edges == 0 && rep.non_manifold_vertices == 0 &&
                             rep.orientation_consistent && crossing == 0;
          invalid += valid ? 0 : 1;
          false_handles += rep.genus > part_genus ? 1 : 0;
          low_use += used < 99.0 ? 1 : 0;
          sum_mean += dev.mesh_to_ref.mean;
          sum_p95 += dev.mesh_to_ref.p95;
          std::printf("%-10s %-22s %4d %8zu %8zu %5zu %4ld/%-2ld %4zu %8.2f %5zu %8.4f %8.4f %8.4f %8.3f %8.1f%s\n",
                      part.c_str(), m.name, seed, points.size(), r.reduced_points,
                      rep.boundary_loops, rep.genus, part_genus, rep.components, used, crossing,
                      dev.mesh_to_ref.mean, dev.mesh_to_ref.p95, dev.mesh_to_ref.max,
                      dev.ref_to_mesh.p95, ms,
                      valid ? (rep.genus > part_genus ? "  FALSE HANDLE" : "") : "  INVALID");
          if (!save_dir.empty() && (!valid || rep.genus > part_genus || used < 99.0))
            scanmesh::bench::save_points_exact(points, save_dir,
                                               part + "-" + m.name + "-" + std::to_string(seed));
        } catch (const std::exception& e) {
          ++failed;
          std::printf("%-10s %-22s %4d  failed: %s\n", part.c_str(), m.name, seed, e.what());
        }
        std::fflush(stdout);
      }
    }
  }
  std::printf(
      "\n%d scans: %d invalid (non-manifold, inconsistently oriented or crossing), %d with a "
      "genus above the part's, %d using under 99 %% of their points, %d failed\n",
      runs, invalid, false_handles, low_use, failed);
  if (runs > failed)
    std::printf("mesh -> part over the scans meshed: mean of the means %.4f mm, of the p95s %.4f mm\n",
                sum_mean / (runs - failed), sum_p95 / (runs - failed));
  return 0;
}
