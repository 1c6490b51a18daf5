// Internal to recon: the points of a cell's (2*ring+1)^3 block copied into flat coordinate
// arrays, so per-point loops over a shared neighbourhood run branch-free over contiguous data.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "scanmesh/recon/grid.hpp"

namespace scanmesh::recon::detail {

/// Reusable scratch: after gather(), index[t], x[t], y[t], z[t] for t < size() are the block's
/// points in the order for_each_near visits them. Capacity only grows.
class BlockPoints {
 public:
  std::size_t gather(const PointGrid& grid, std::int64_t cx, std::int64_t cy, std::int64_t cz,
                     int ring, std::span<const Vec3> points) {
    ranges_.clear();
    std::size_t cnt = 0;
    grid.for_each_block_range(cx, cy, cz, ring, [&](std::uint32_t b, std::uint32_t e) {
      ranges_.emplace_back(b, e);
      cnt += e - b;
    });
    if (index.size() < cnt) {
      index.resize(cnt);
      x.resize(cnt);
      y.resize(cnt);
      z.resize(cnt);
    }
    const std::vector<std::uint32_t>& order = grid.order();
    std::size_t t = 0;
    for (const auto& [b, e] : ranges_) {
      for (std::uint32_t s = b; s < e; ++s, ++t) {
        const std::uint32_t j = order[s];
        const Vec3& q = points[j];
        index[t] = j;
        x[t] = q.x();
        y[t] = q.y();
        z[t] = q.z();
      }
    }
    size_ = cnt;
    return cnt;
  }
  [[nodiscard]] std::size_t size() const { return size_; }

  std::vector<std::uint32_t> index;
  std::vector<double> x, y, z;

 private:
  std::vector<std::pair<std::uint32_t, std::uint32_t>> ranges_;
  std::size_t size_ = 0;
};

}  // namespace scanmesh::recon::detail
