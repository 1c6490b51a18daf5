// Cube reduction (reference method): keep, in every occupied cube, the point nearest its centre.
// SPDX-License-Identifier: MIT
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/reduce.hpp"

namespace scanmesh::recon {

std::vector<std::uint32_t> cube_reduce(std::span<const Vec3> points, double cube) {
  if (!(cube > 0) || !std::isfinite(cube)) throw GeometryError("cube size must be positive");
  const std::size_t n = points.size();
  if (n == 0) return {};
  Vec3 lo = points[0], hi = points[0];
  for (const Vec3& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double inv = 1.0 / cube;
  if ((hi - lo).maxCoeff() * inv > 2.0e6) {
    throw GeometryError("cube size " + std::to_string(cube) +
                        " is too small for the extent of the cloud (over 2 million cubes per "
                        "axis)");
  }
  // Open-addressing table: cube key -> slot holding (best index, best squared distance).
  const std::size_t cap = std::bit_ceil(std::max<std::size_t>(16, n * 2));
  const std::size_t mask = cap - 1;
  const int shift = 64 - std::countr_zero(cap);
  constexpr std::uint32_t kEmpty = 0xffffffffu;
  std::vector<std::uint64_t> keys(cap);
  std::vector<std::uint32_t> best(cap, kEmpty);
  std::vector<double> best_d2(cap);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 g = (points[i] - lo) * inv;
    const auto ix = static_cast<std::uint64_t>(g.x()), iy = static_cast<std::uint64_t>(g.y()),
               iz = static_cast<std::uint64_t>(g.z());
    const std::uint64_t key = (iz << 42) | (iy << 21) | ix;
    const Vec3 centre = lo + (Vec3(static_cast<double>(ix), static_cast<double>(iy),
                                   static_cast<double>(iz)) +
                              Vec3::Constant(0.5)) *
                                 cube;
    const double d2 = (points[i] - centre).squaredNorm();
    std::size_t h = static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift);
    while (best[h] != kEmpty && keys[h] != key) h = (h + 1) & mask;
    if (best[h] == kEmpty) {
      keys[h] = key;
      best[h] = static_cast<std::uint32_t>(i);
      best_d2[h] = d2;
    } else if (d2 < best_d2[h]) {  // strict: the lower index wins ties
      best[h] = static_cast<std::uint32_t>(i);
      best_d2[h] = d2;
    }
  }
  std::vector<std::uint32_t> kept;
  for (std::size_t h = 0; h < cap; ++h)
    if (best[h] != kEmpty) kept.push_back(best[h]);
  std::sort(kept.begin(), kept.end());
  return kept;
}

std::vector<std::uint32_t> thin_min_distance(std::span<const Vec3> points,
                                             std::span<const std::uint32_t> priority,
                                             double min_distance) {
  std::vector<Vec3> sub(priority.size());
  for (std::size_t i = 0; i < priority.size(); ++i) sub[i] = points[priority[i]];
  PointGrid grid;
  grid.build(sub, min_distance);
  std::vector<std::uint8_t> kept(sub.size(), 0);
  const double r2 = min_distance * min_distance;
  std::vector<std::uint32_t> out;
  out.reserve(sub.size());
  for (std::uint32_t i = 0; i < sub.size(); ++i) {
    bool clash = false;
    grid.for_each_near(sub[i], 1, [&](std::uint32_t j) {
      if (kept[j] && (sub[j] - sub[i]).squaredNorm() < r2) clash = true;
    });
    if (clash) continue;
    kept[i] = 1;
    out.push_back(priority[i]);
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<Vec3> project_to_local_planes(std::span<const Vec3> input,
                                          std::span<const std::uint32_t> representatives,
                                          double radius, double max_move) {
  PointGrid grid;
  grid.build(input, radius);
  const double r2 = radius * radius;
  std::vector<Vec3> out(representatives.size());
  for (std::size_t i = 0; i < representatives.size(); ++i) {
    const Vec3& p = input[representatives[i]];
    Vec3 sum = Vec3::Zero();
    Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
    std::size_t n = 0;
    grid.for_each_near(p, 1, [&](std::uint32_t j) {
      const Vec3 d = input[j] - p;  // relative to p: well conditioned
      if (d.squaredNorm() > r2) return;
      sum += d;
      outer += d * d.transpose();
      ++n;
    });
    out[i] = p;
    if (n < 6) continue;
    const Vec3 mean = sum / static_cast<double>(n);
    const Eigen::Matrix3d cov = outer / static_cast<double>(n) - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    const Vec3 normal = es.eigenvectors().col(0);
    double move = -mean.dot(normal);  // signed distance from p to the plane, along -normal
    move = std::clamp(move, -max_move, max_move);
    out[i] = p - move * normal;
  }
  return out;
}

std::vector<std::uint32_t> cube_reduce_thin(std::span<const Vec3> points, double cube) {
  std::vector<std::uint32_t> kept = cube_reduce(points, cube);
  if (kept.empty()) return kept;
  // Priority: distance to the own cube centre, most central first (index breaks ties).
  Vec3 lo = points[0];
  for (const Vec3& p : points) lo = lo.cwiseMin(p);
  std::vector<std::pair<double, std::uint32_t>> order(kept.size());
  for (std::size_t i = 0; i < kept.size(); ++i) {
    const Vec3 g = (points[kept[i]] - lo) / cube;
    const Vec3 c = (g.array().floor() + 0.5).matrix();
    order[i] = {(g - c).squaredNorm(), kept[i]};
  }
  std::sort(order.begin(), order.end());
  std::vector<std::uint32_t> prio(order.size());
  for (std::size_t i = 0; i < order.size(); ++i) prio[i] = order[i].second;
  return thin_min_distance(points, prio, 0.65 * cube);
}

}  // namespace scanmesh::recon
