// Uniform grid index over a point array for neighbour queries (27-cell and ring queries).
// Points are referenced by index; `spatial_order` gives a cache-friendly permutation.
// SPDX-License-Identifier: MIT
#pragma once

#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon {

/// Open-addressing map from a packed cell key to a [begin, end) range of point slots.
/// Cell keys pack three 21-bit cell coordinates; the grid origin is the bounding-box minimum,
/// so coordinates are non-negative and at most 2^21 cells per axis (checked by the builder).
class PointGrid {
 public:
  PointGrid() = default;
  /// Indexes `points` with cubic cells of edge `cell` (> 0). The grid keeps a reference-free
  /// copy of the permutation only; `points` must stay alive and unchanged while it is queried.
  void build(std::span<const Vec3> points, double cell);

  [[nodiscard]] double cell() const { return cell_; }
  [[nodiscard]] bool empty() const { return slots_.empty(); }

  /// Calls f(index) for every point in the (2*ring+1)^3 cells around p. ring 1 = 27 cells.
  template <class F>
  void for_each_near(const Vec3& p, int ring, F&& f) const {
    const std::int64_t cx = coord(p.x(), 0), cy = coord(p.y(), 1), cz = coord(p.z(), 2);
    for (std::int64_t dz = -ring; dz <= ring; ++dz)
      for (std::int64_t dy = -ring; dy <= ring; ++dy)
        for (std::int64_t dx = -ring; dx <= ring; ++dx) {
          const std::int64_t x = cx + dx, y = cy + dy, z = cz + dz;
          if (x < 0 || y < 0 || z < 0 || x > kMax || y > kMax || z > kMax) continue;
          const std::uint32_t s = find(pack(x, y, z));
          if (s == kNone) continue;
          for (std::uint32_t i = begin_[s]; i < begin_[s] + count_[s]; ++i) f(order_[i]);
        }
  }

  /// Ring needed so that every point within `radius` of the query is visited.
  [[nodiscard]] int ring_for(double radius) const {
    return std::max(1, static_cast<int>(std::ceil(radius * inv_cell_)));
  }

  /// Point indices sorted by cell (cells in key order): a spatially coherent permutation.
  [[nodiscard]] const std::vector<std::uint32_t>& order() const { return order_; }

 private:
  static constexpr std::int64_t kMax = (1 << 21) - 1;
  static constexpr std::uint32_t kNone = 0xffffffffu;
  [[nodiscard]] std::int64_t coord(double v, int axis) const {
    return static_cast<std::int64_t>(std::floor((v - origin_[axis]) * inv_cell_));
  }
  static std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
    return (static_cast<std::uint64_t>(z) << 42) | (static_cast<std::uint64_t>(y) << 21) |
           static_cast<std::uint64_t>(x);
  }
  [[nodiscard]] std::uint32_t find(std::uint64_t key) const {
    std::size_t h = hash(key);
    while (true) {
      const std::uint32_t s = slots_[h];
      if (s == kNone) return kNone;
      if (keys_[s] == key) return s;
      h = (h + 1) & mask_;
    }
  }
  [[nodiscard]] std::size_t hash(std::uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift_);
  }

  double cell_ = 0, inv_cell_ = 0;
  double origin_[3] = {0, 0, 0};
  std::vector<std::uint64_t> keys_;    // per occupied cell
  std::vector<std::uint32_t> begin_;   // per occupied cell: first slot in order_
  std::vector<std::uint32_t> count_;   // per occupied cell
  std::vector<std::uint32_t> slots_;   // hash table: cell id or kNone
  std::size_t mask_ = 0;
  int shift_ = 63;  // 64 - log2(table size): the hash takes the product's high bits
  std::vector<std::uint32_t> order_;   // point indices grouped by cell
};

}  // namespace scanmesh::recon
