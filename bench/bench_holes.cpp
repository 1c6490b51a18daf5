// Real holes under imperfect sampling. The Stanford bunny's reference mesh has five holes in its
// base (the scanner never saw them): a mesh of its vertices must keep them open. Here the
// vertices are perturbed as real scans are (noise, random dropouts, a density falling off
// across the part, patches of lower density) and meshed with the defaults; for each hole it
// prints the share of its area the mesh leaves open, with the mesh's loops, genus and validity.
// The hole's area is its flat patch in the reference (filled without new vertices), sampled on
// a fine barycentric grid; a sample is covered when the mesh passes within a quarter of the
// cube edge of it. It prints figures; it asserts nothing.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <functional>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "exact_points.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/recon/fill.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "support/holes.hpp"
#include "support/shapes.hpp"

#ifndef SCANMESH_BENCH_BUILD_TYPE
#define SCANMESH_BENCH_BUILD_TYPE "unknown"
#endif

namespace {

namespace recon = scanmesh::recon;
namespace meshio = scanmesh::meshio;
using recon::Vec3;

struct Perturbation {
  std::string name;
  std::function<std::vector<Vec3>(const std::vector<Vec3>&, double spacing, std::uint32_t seed)> make;
};

std::vector<Perturbation> perturbations() {
  std::vector<Perturbation> list;
  list.push_back({"clean", [](const std::vector<Vec3>& p, double, std::uint32_t) { return p; }});
  for (const double s : {0.1, 0.2}) {
    char name[64];
    std::snprintf(name, sizeof name, "noise %.1f spacing", s);
    list.push_back({name, [s](const std::vector<Vec3>& p, double spacing, std::uint32_t seed) {
                      std::vector<Vec3> out = p;
                      scanmesh::test::add_noise(out, s * spacing, seed);
                      return out;
                    }});
  }
  list.push_back({"dropout 40 %", [](const std::vector<Vec3>& p, double, std::uint32_t seed) {
                    return scanmesh::test::thin_out(p, seed, [](const Vec3&) { return 0.6; });
                  }});
  list.push_back({"density 100 to 15 % across x",
                  [](const std::vector<Vec3>& p, double, std::uint32_t seed) {
                    return scanmesh::test::density_ramp_x(p, 0.15, seed);
                  }});
  list.push_back({"patches 100 / 30 % (8 spacings)",
                  [](const std::vector<Vec3>& p, double spacing, std::uint32_t seed) {
                    const double cell = 8 * spacing;
                    return scanmesh::test::thin_out(p, seed, [cell](const Vec3& q) {
                      const auto k = static_cast<long>(std::floor(q.x() / cell)) +
                                     static_cast<long>(std::floor(q.y() / cell)) +
                                     static_cast<long>(std::floor(q.z() / cell));
                      return (k & 1) == 0 ? 1.0 : 0.3;
                    });
                  }});
  return list;
}

int usage(const char* argv0) {
  std::fprintf(stderr,
               "usage: %s [--seeds N] [--save DIR]\n"
               "  --seeds N   run every perturbation with seeds 1..N (default 1)\n"
               "  --save DIR  write the points of every run whose mesh is invalid to DIR (exact)\n"
               "Reads $SCANMESH_DATA/bunny/reconstruction/bun_zipper.ply; without SCANMESH_DATA it "
               "prints that and exits 0.\n",
               argv0);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::uint32_t seeds = 1;
  std::string save_dir;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--seeds") == 0 && i + 1 < argc) {
      seeds = static_cast<std::uint32_t>(std::strtoul(argv[++i], nullptr, 10));
      if (seeds == 0) return usage(argv[0]);
    } else if (std::strcmp(argv[i], "--save") == 0 && i + 1 < argc) {
      save_dir = argv[++i];
    } else {
      return usage(argv[0]);
    }
  }
  const char* data = std::getenv("SCANMESH_DATA");
  if (data == nullptr || *data == 0) {
    std::printf("bench_holes: SCANMESH_DATA is unset: nothing to measure\n");
    return 0;
  }
  const std::filesystem::path file =
      std::filesystem::path(data) / "bunny" / "reconstruction" / "bun_zipper.ply";
  try {
    const recon::Mesh ref = meshio::read_mesh(file);
    const std::vector<Vec3>& points = ref.vertices;
    const double spacing = recon::estimate_spacing(points).nearest_mm;
    const std::vector<scanmesh::test::Hole> holes = scanmesh::test::reference_holes(ref, 0.2 * spacing);
    std::printf("bench_holes: %s (%zu points, spacing %.3g, %zu holes in the reference:",
                file.c_str(), points.size(), spacing, holes.size());
    for (const scanmesh::test::Hole& h : holes) std::printf(" %.0f", h.area / (spacing * spacing));
    std::printf(" spacings^2); build %s; %u seed(s)\n", SCANMESH_BENCH_BUILD_TYPE, seeds);
    std::printf("open: share of each hole's area with no triangle within a quarter cube; a hole "
                "under 25 %% open is counted as closed\n\n");
    std::printf("%-32s %4s %7s %6s %5s %5s %5s  %-29s %6s %7s\n", "perturbation", "seed",
                "points", "cube", "loops", "genus", "valid", "open % (largest hole first)",
                "closed", "seconds");
    std::size_t closed_total = 0, runs = 0;
    for (const Perturbation& pt : perturbations()) {
      for (std::uint32_t seed = 1; seed <= seeds; ++seed) {
        const std::vector<Vec3> input = pt.make(points, spacing, seed);
        const auto t0 = std::chrono::steady_clock::now();
        const recon::ReconstructResult res = recon::reconstruct(input);
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const recon::MeshReport rep = recon::analyze(res.mesh);
        const bool valid = rep.non_manifold_edges == 0 && rep.non_manifold_vertices == 0 &&
                           rep.orientation_consistent &&
                           recon::find_self_intersections(res.mesh).pairs == 0;
        const recon::SurfaceDistance surface(res.mesh);
        const double reach = 0.25 * (res.cube_mm > 0 ? res.cube_mm : spacing);
        std::string open;
        std::size_t closed = 0;
        for (const scanmesh::test::Hole& h : holes) {
          const double share = scanmesh::test::open_percent(h, surface, reach);
          closed += share < 25 ? 1 : 0;
          char cell[16];
          std::snprintf(cell, sizeof cell, "%s%3.0f", open.empty() ? "" : " ", share);
          open += cell;
        }
        closed_total += closed;
        ++runs;
        std::printf("%-32s %4u %7zu %6.3g %5zu %5ld %5s  %-29s %6zu %7.3f\n", pt.name.c_str(),
                    seed, input.size(), res.cube_mm, rep.boundary_loops, rep.genus,
                    valid ? "yes" : "NO", open.c_str(), closed, seconds);
        if (!valid && !save_dir.empty()) {
          scanmesh::bench::save_points_exact(input, save_dir,
                                             "bunny-" + pt.name + "-" + std::to_string(seed));
        }
      }
    }
    std::printf("\n%zu runs: %zu holes closed of %zu\n", runs, closed_total, runs * holes.size());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_holes: %s\n", e.what());
    return 1;
  }
  return 0;
}
