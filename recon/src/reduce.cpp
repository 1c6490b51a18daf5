// Cube reduction (reference method): keep, in every occupied cube, the point nearest its centre.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include "scanmesh/common/error.hpp"
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

}  // namespace scanmesh::recon
