// Uniform grid index: counting sort of points into cells plus an open-addressing cell table.
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/grid.hpp"

#include <algorithm>
#include <bit>
#include <limits>

#include "scanmesh/common/error.hpp"

namespace scanmesh::recon {

void PointGrid::build(std::span<const Vec3> points, double cell) {
  if (!(cell > 0) || !std::isfinite(cell)) throw GeometryError("grid cell size must be positive");
  cell_ = cell;
  inv_cell_ = 1.0 / cell;
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = -lo;
  for (const Vec3& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // Leave one empty cell of margin below the minimum so ring queries never underflow.
  for (int a = 0; a < 3; ++a) origin_[a] = points.empty() ? 0.0 : lo[a] - cell;
  if (!points.empty() && ((hi - lo).maxCoeff() * inv_cell_ + 3 > static_cast<double>(kMax))) {
    throw GeometryError("point cloud too large for the grid resolution (over 2 million cells "
                        "per axis); use a larger cube size");
  }
  const std::size_t n = points.size();
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3& p = points[i];
    keyed[i] = {pack(coord(p.x(), 0), coord(p.y(), 1), coord(p.z(), 2)),
                static_cast<std::uint32_t>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  order_.resize(n);
  keys_.clear();
  begin_.clear();
  count_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    order_[i] = keyed[i].second;
    if (i == 0 || keyed[i].first != keyed[i - 1].first) {
      keys_.push_back(keyed[i].first);
      begin_.push_back(static_cast<std::uint32_t>(i));
      count_.push_back(0);
    }
    ++count_.back();
  }
  const std::size_t cap = std::bit_ceil(std::max<std::size_t>(16, keys_.size() * 2));
  mask_ = cap - 1;
  shift_ = 64 - std::countr_zero(cap);
  slots_.assign(cap, kNone);
  for (std::uint32_t s = 0; s < keys_.size(); ++s) {
    std::size_t h = hash(keys_[s]);
    while (slots_[h] != kNone) h = (h + 1) & mask_;
    slots_[h] = s;
  }
}

}  // namespace scanmesh::recon
