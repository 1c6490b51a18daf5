// Stratified area-uniform surface sampling with seeded, library-independent random numbers.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/sampling.hpp"

#include <cmath>
#include <cstddef>
#include <string>

#include "scanmesh/common/error.hpp"
#include "scanmesh/sim/rng.hpp"

namespace scanmesh::sim {
namespace {

using recon::Vec3;

/// A separate stream for the noise, so a noisy sample is the noise-free sample plus noise.
constexpr std::uint64_t kNoiseStream = 0x9E3779B97F4A7C15ULL;

/// Fraction of a cell (about its centroid) a point may land in.
constexpr double kJitter = 0.5;

/// Corner (s, t) of one cell of the k x k subdivision of the unit triangle, in lattice units.
struct Cell {
  double s0, t0, s1, t1, s2, t2;
};

/// Cell `r` of row `j` (0-based along the row): even r are upward cells, odd r downward, so
/// consecutive cells of a row share an edge.
Cell cell_of(std::size_t row, std::size_t r) {
  const double i = static_cast<double>(r / 2);
  const double j = static_cast<double>(row);
  if (r % 2 == 0) return {i, j, i + 1, j, i, j + 1};
  return {i + 1, j, i + 1, j + 1, i, j + 1};
}

}  // namespace

double surface_area(const recon::Mesh& mesh) {
  double area = 0;
  for (const auto& t : mesh.triangles) {
    const Vec3& a = mesh.vertices[t[0]];
    area += 0.5 * (mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a).norm();
  }
  return area;
}

std::vector<Vec3> sample_surface(const recon::Mesh& mesh, double spacing_mm, std::uint64_t seed,
                                 double noise_mm) {
  if (!(spacing_mm > 0) || !std::isfinite(spacing_mm))
    throw ConfigError("sampling spacing must be a positive number of millimetres, got " +
                      std::to_string(spacing_mm));
  if (!(noise_mm >= 0) || !std::isfinite(noise_mm))
    throw ConfigError("sampling noise must be >= 0 millimetres, got " + std::to_string(noise_mm));
  for (const auto& t : mesh.triangles)
    for (const auto v : t)
      if (v >= mesh.vertices.size())
        throw ConfigError("mesh to sample has a triangle with vertex index " + std::to_string(v) +
                          " out of range (" + std::to_string(mesh.vertices.size()) + " vertices)");
  const double cell_area = spacing_mm * spacing_mm;
  const double expected = surface_area(mesh) / cell_area;
  if (!(expected <= kMaxSamplePoints))
    throw ConfigError("spacing " + std::to_string(spacing_mm) + " mm would give about " +
                      std::to_string(static_cast<long long>(expected)) + " points (at most " +
                      std::to_string(static_cast<long long>(kMaxSamplePoints)) +
                      "); use a larger spacing");

  Rng rng(seed);
  Rng noise_rng(seed ^ kNoiseStream);
  std::vector<Vec3> out;
  out.reserve(static_cast<std::size_t>(expected + std::sqrt(expected) + 16));
  for (const auto& tri : mesh.triangles) {
    const Vec3& a = mesh.vertices[tri[0]];
    const Vec3 ab = mesh.vertices[tri[1]] - a;
    const Vec3 ac = mesh.vertices[tri[2]] - a;
    const Vec3 cross = ab.cross(ac);
    const double area = 0.5 * cross.norm();
    if (!(area > 0) || !std::isfinite(area)) continue;
    const double want = area / cell_area;
    const double whole = std::floor(want);
    // Always draw, so one triangle's count never shifts the random stream of the next.
    const double u = rng.uniform();
    const auto n = static_cast<std::size_t>(whole) + (u < want - whole ? 1 : 0);
    const double offset = rng.uniform();
    if (n == 0) continue;
    const Vec3 normal = cross.normalized();
    // n points spread over the k*k congruent cells of the triangle, taken at even strides along
    // the row-by-row cell order (consecutive cells of a row share an edge).
    const auto k = static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(n))));
    const std::size_t cells = k * k;
    std::size_t row = 0, row_start = 0;  // first cell index of `row`; row j has 2(k-j)-1 cells
    const double inv_k = 1.0 / static_cast<double>(k);
    for (std::size_t i = 0; i < n; ++i) {
      auto idx = static_cast<std::size_t>((static_cast<double>(i) + offset) *
                                          static_cast<double>(cells) / static_cast<double>(n));
      if (idx >= cells) idx = cells - 1;
      while (idx >= row_start + 2 * (k - row) - 1) {
        row_start += 2 * (k - row) - 1;
        ++row;
      }
      const Cell c = cell_of(row, idx - row_start);
      double r1 = rng.uniform();
      double r2 = rng.uniform();
      if (r1 + r2 > 1) {
        r1 = 1 - r1;
        r2 = 1 - r2;
      }
      // Jitter within the middle part of the cell (scaled by kJitter about its centroid), which
      // keeps neighbours from clumping at shared cell edges.
      const double cs = (c.s0 + c.s1 + c.s2) / 3, ct = (c.t0 + c.t1 + c.t2) / 3;
      const double s =
          (cs + kJitter * (c.s0 + r1 * (c.s1 - c.s0) + r2 * (c.s2 - c.s0) - cs)) * inv_k;
      const double t =
          (ct + kJitter * (c.t0 + r1 * (c.t1 - c.t0) + r2 * (c.t2 - c.t0) - ct)) * inv_k;
      Vec3 p = a + s * ab + t * ac;
      if (noise_mm > 0) p += normal * (noise_mm * noise_rng.gaussian());
      out.push_back(p);
    }
  }
  return out;
}

}  // namespace scanmesh::sim
