// Synthetic point clouds with known surfaces for the geometry tests and benchmarks.
// SPDX-License-Identifier: MIT
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::test {

using recon::Vec3;

/// Unit right tetrahedron, outward oriented; volume 1/6.
inline recon::Mesh tetrahedron(const Vec3& offset = Vec3::Zero()) {
  recon::Mesh m;
  m.vertices = {offset + Vec3(0, 0, 0), offset + Vec3(1, 0, 0), offset + Vec3(0, 1, 0),
                offset + Vec3(0, 0, 1)};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return m;
}

/// Fibonacci sphere: n nearly uniform points on a sphere of radius r at c.
inline std::vector<Vec3> sphere_points(std::size_t n, double r = 10, Vec3 c = Vec3::Zero()) {
  std::vector<Vec3> pts;
  pts.reserve(n);
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (std::size_t i = 0; i < n; ++i) {
    const double z = 1.0 - 2.0 * (static_cast<double>(i) + 0.5) / static_cast<double>(n);
    const double rad = std::sqrt(1.0 - z * z);
    const double th = golden * static_cast<double>(i);
    pts.push_back(c + r * Vec3(rad * std::cos(th), rad * std::sin(th), z));
  }
  return pts;
}

/// Open cylinder (axis z, radius r, height h) sampled as a raster scan: rings every
/// `line_mm` along z, samples every `along_mm` along each ring.
inline std::vector<Vec3> cylinder_raster(double r, double h, double along_mm, double line_mm) {
  std::vector<Vec3> pts;
  const int per_ring = static_cast<int>(std::round(2 * std::numbers::pi * r / along_mm));
  const int rings = static_cast<int>(std::round(h / line_mm)) + 1;
  for (int k = 0; k < rings; ++k)
    for (int i = 0; i < per_ring; ++i) {
      const double a = 2 * std::numbers::pi * i / per_ring;
      pts.emplace_back(r * std::cos(a), r * std::sin(a), k * line_mm);
    }
  return pts;
}

/// Surface of an axis-aligned cube of edge s (corner at origin), grid-sampled every `step`.
inline std::vector<Vec3> cube_points(double s, double step) {
  std::vector<Vec3> pts;
  const int m = static_cast<int>(std::round(s / step));
  for (int i = 0; i <= m; ++i)
    for (int j = 0; j <= m; ++j)
      for (int k = 0; k <= m; ++k) {
        const bool on = i == 0 || i == m || j == 0 || j == m || k == 0 || k == m;
        if (on) pts.emplace_back(i * step, j * step, k * step);
      }
  return pts;
}

/// The faces of the box [0, side]^3 sampled on grids `step` apart with no sample on an edge, as
/// when a scanner's samples fall where they fall: each face's grid starts `near` in along one
/// direction and step - near along the other (half a step in along both by default).
inline std::vector<Vec3> box_face_points(double side, double step, double near = -1) {
  if (near < 0) near = 0.5 * step;
  const double first[2] = {near, step - near};
  std::vector<Vec3> pts;
  const int m = static_cast<int>(std::round(side / step));
  for (int axis = 0; axis < 3; ++axis)
    for (const double at : {0.0, side})
      for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) {
          Vec3 p;
          p[axis] = at;
          p[(axis + 1) % 3] = first[0] + i * step;
          p[(axis + 2) % 3] = first[1] + j * step;
          pts.push_back(p);
        }
  return pts;
}

/// The points kept with probability keep(p) each, seeded: random dropouts, uneven density.
template <class Keep>
std::vector<Vec3> thin_out(const std::vector<Vec3>& pts, std::uint32_t seed, Keep keep) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> out;
  for (const Vec3& p : pts)
    if (unit(rng) < keep(p)) out.push_back(p);
  return out;
}

/// A density falling linearly across x, from every point at the lowest x to the share `last`
/// at the highest (a scan whose sensor moves away, or turns to a grazing angle, across the part).
inline std::vector<Vec3> density_ramp_x(const std::vector<Vec3>& pts, double last,
                                        std::uint32_t seed) {
  double lo = pts.front().x(), hi = lo;
  for (const Vec3& q : pts) {
    lo = std::min(lo, q.x());
    hi = std::max(hi, q.x());
  }
  return thin_out(pts, seed, [&](const Vec3& q) { return 1.0 - (1.0 - last) * (q.x() - lo) / (hi - lo); });
}

/// Adds seeded Gaussian noise of standard deviation sigma to every coordinate.
inline void add_noise(std::vector<Vec3>& pts, double sigma, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> nd(0.0, sigma);
  for (auto& p : pts) p += Vec3(nd(rng), nd(rng), nd(rng));
}

/// A ruled surface z = f(y) scanned along straight lines in x (the y of each line and the step
/// along it vary): the points of one line are exactly collinear, as on the scan lines of a raw
/// range scan (bun000) or of a profiler moved in a straight line.
inline std::vector<Vec3> ruled_scan_lines(double width, double depth, std::uint32_t seed) {
  std::mt19937 gen(seed);
  auto unit = [&gen] { return static_cast<double>(gen() >> 8) * 0x1.0p-24; };  // [0, 1)
  std::vector<Vec3> pts;
  for (double y = 0; y < depth; y += 0.01 + 0.01 * unit()) {
    const double z = 0.4 * std::sin(2.1 * y) + 0.1 * std::sin(5 * y + seed);
    const double step = 0.01 + 0.004 * unit();
    for (double x = 0.01 * unit(); x < width; x += step * (0.7 + 0.6 * unit())) pts.emplace_back(x, y, z);
  }
  return pts;
}

/// A gently curved height field over an n x n grid of unit spacing, each sample jittered by up
/// to +-0.3 in x and y (seeded), as the benchmark's large synthetic scan.
inline std::vector<Vec3> jittered_height_field(int n, std::uint32_t seed) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  std::vector<Vec3> pts;
  pts.reserve(static_cast<std::size_t>(n) * static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double x = i + jitter(gen), y = j + jitter(gen);
      pts.emplace_back(x, y, 4 * std::sin(x / 20) + 3 * std::sin(y / 15));
    }
  return pts;
}

}  // namespace scanmesh::test
