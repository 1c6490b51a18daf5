// Uniform grid index over a point array for neighbour queries (27-cell, ring and radius queries).
// Points are referenced by index; `order()` gives a cache-friendly permutation.
// SPDX-License-Identifier: MIT
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon {

/// Points grouped by cubic cell. Occupied cells are kept in key order (z, then y, then x), and
/// a row of cells (same y and z) is found through a dense (y, z) array, or an open-addressing
/// table when that array would be large; when the grid's box has at most about two cells a
/// point, every cell's first slot is stored instead, so a row's range needs no search within the
/// row. The cells of a row are contiguous and sorted by x, and
/// so are their points in `order()`: a block of cells x0..x1 of one row is one contiguous slot
/// range. A ring query therefore costs one look-up per row instead of one per cell, and
/// for_each_range_within skips the rows and cells out of reach.
/// Cell coordinates are 21-bit; the grid origin is the bounding-box minimum minus one cell, so
/// coordinates are non-negative and at most 2^21 cells per axis (checked by the builder).
class PointGrid {
 public:
  PointGrid() = default;
  /// Indexes `points` with cubic cells of edge `cell` (> 0). The grid keeps no reference to
  /// `points`, only the permutation; queries read positions from the caller's array, which must
  /// stay alive and unchanged while the grid is queried.
  void build(std::span<const Vec3> points, double cell);

  /// After the caller has permuted its points into `order()` (new point s = old order()[s]):
  /// the grid of the permuted points, as build() with the same cell would make it (its order
  /// is then the identity: cells in key order, points of a cell by index), without rebuilding.
  void renumber_in_order() {
    for (std::size_t s = 0; s < order_.size(); ++s) order_[s] = static_cast<std::uint32_t>(s);
  }

  [[nodiscard]] double cell() const { return cell_; }
  [[nodiscard]] bool empty() const { return order_.empty(); }

  /// Calls f(index) for every point in the (2*ring+1)^3 cells around p. ring 1 = 27 cells.
  /// Visiting order: cells by z, then y, then x (ascending), points of a cell by index.
  template <class F>
  void for_each_near(const Vec3& p, int ring, F&& f) const {
    for_each_block_range(coord(p.x(), 0), coord(p.y(), 1), coord(p.z(), 2), ring,
                         [&](std::uint32_t first, std::uint32_t last) {
                           for (std::uint32_t s = first; s < last; ++s) f(order_[s]);
                         });
  }

  /// Calls f(first, last) with the slot ranges [first, last) of `order()` that hold the points
  /// of the (2*ring+1)^3 cells around cell (cx, cy, cz): one range per non-empty row, in the
  /// order for_each_near visits them.
  template <class F>
  void for_each_block_range(std::int64_t cx, std::int64_t cy, std::int64_t cz, int ring,
                            F&& f) const {
    for (std::int64_t z = cz - ring; z <= cz + ring; ++z) {
      if (z < 0 || z > kMax) continue;
      for (std::int64_t y = cy - ring; y <= cy + ring; ++y) {
        if (y < 0 || y > kMax) continue;
        std::uint32_t first = 0, last = 0;
        if (row_range(y, z, cx - ring, cx + ring, first, last)) f(first, last);
      }
    }
  }

  /// Calls f(first, last) with slot ranges of `order()` that together hold every point within
  /// `radius` of p (and some farther ones): only cells whose box comes within `radius` of p are
  /// scanned. Ranges come row by row, z then y ascending.
  template <class F>
  void for_each_range_within(const Vec3& p, double radius, F&& f) const {
    if (order_.empty()) return;
    const double ux = (p.x() - origin_[0]) * inv_cell_, uy = (p.y() - origin_[1]) * inv_cell_,
                 uz = (p.z() - origin_[2]) * inv_cell_;
    // Slack against rounding in the cell coordinates: never miss a point at the boundary.
    const double rr = radius * inv_cell_ * (1.0 + 1e-12) + 1e-6;
    const double rr2 = rr * rr;
    const auto fz = static_cast<double>(floor_int(uz)), fy = static_cast<double>(floor_int(uy));
    const std::int64_t z0 = std::max<std::int64_t>(0, floor_int(uz - rr)),
                       z1 = std::min(kMax, floor_int(uz + rr));
    for (std::int64_t z = z0; z <= z1; ++z) {
      const double zd = static_cast<double>(z);
      const double gz = zd > fz ? zd - uz : (zd < fz ? uz - (zd + 1) : 0.0);
      const double rem_z = rr2 - gz * gz;
      if (rem_z < 0) continue;
      const double ry = std::sqrt(rem_z);
      const std::int64_t y0 = std::max<std::int64_t>(0, floor_int(uy - ry)),
                         y1 = std::min(kMax, floor_int(uy + ry));
      for (std::int64_t y = y0; y <= y1; ++y) {
        const double yd = static_cast<double>(y);
        const double gy = yd > fy ? yd - uy : (yd < fy ? uy - (yd + 1) : 0.0);
        const double rem = rem_z - gy * gy;
        if (rem < 0) continue;
        const double rx = std::sqrt(rem);
        std::uint32_t first = 0, last = 0;
        if (row_range(y, z, floor_int(ux - rx), floor_int(ux + rx), first, last)) f(first, last);
      }
    }
  }

  /// Calls f(cx, cy, cz, first, last) for every occupied cell in key order; [first, last) are
  /// the slots of its points in `order()`.
  template <class F>
  void for_each_cell(F&& f) const {
    for (std::uint32_t r = 0; r + 1 < row_first_cell_.size(); ++r) {
      const auto y = static_cast<std::int64_t>(row_key_[r] & kMax);
      const auto z = static_cast<std::int64_t>(row_key_[r] >> 21);
      for (std::uint32_t c = row_first_cell_[r]; c < row_first_cell_[r + 1]; ++c)
        f(static_cast<std::int64_t>(cells_[c].x), y, z, cells_[c].first, cells_[c + 1].first);
    }
  }

  /// Cell coordinate of v along axis (0 = x, 1 = y, 2 = z).
  [[nodiscard]] std::int64_t coord(double v, int axis) const {
    return floor_int((v - origin_[axis]) * inv_cell_);
  }

  /// Ring needed so that every point within `radius` of the query is visited.
  [[nodiscard]] int ring_for(double radius) const {
    return std::max(1, static_cast<int>(std::ceil(radius * inv_cell_)));
  }

  /// Point indices sorted by cell (cells in key order, points of a cell by index): a spatially
  /// coherent permutation.
  [[nodiscard]] const std::vector<std::uint32_t>& order() const { return order_; }

 private:
  static constexpr std::int64_t kMax = (1 << 21) - 1;
  static constexpr std::uint32_t kNone = 0xffffffffu;
  /// floor(v) as an integer, clamped far outside the coordinate range (std::floor is a library
  /// call without SSE4.1, and this is on every query's path).
  static std::int64_t floor_int(double v) {
    constexpr double kLim = 4.0 * static_cast<double>(kMax);
    v = v > -kLim ? (v < kLim ? v : kLim) : -kLim;  // NaN goes low
    const auto t = static_cast<std::int64_t>(v);
    return t - static_cast<std::int64_t>(static_cast<double>(t) > v);
  }
  /// Slots of the cells of row (y, z) with x in [x0, x1]; false when there are none.
  bool row_range(std::int64_t y, std::int64_t z, std::int64_t x0, std::int64_t x1,
                 std::uint32_t& first, std::uint32_t& last) const {
    if (cell_start_.empty()) return row_range_search(y, z, x0, x1, first, last);
    // Direct index over (x, y, z): two loads, no search (small enough to inline).
    if (y < 0 || z < 0 || x1 < 0 || y >= ny_ || z >= nz_ || x0 >= nx_) return false;
    const std::size_t base = static_cast<std::size_t>((z * ny_ + y) * nx_);
    first = cell_start_[base + static_cast<std::size_t>(std::max<std::int64_t>(x0, 0))];
    last = cell_start_[base + static_cast<std::size_t>(std::min(x1, nx_ - 1)) + 1];
    return first < last;
  }
  /// row_range through the row tables, when there is no per-cell index.
  bool row_range_search(std::int64_t y, std::int64_t z, std::int64_t x0, std::int64_t x1,
                        std::uint32_t& first, std::uint32_t& last) const {
    if (y < 0 || z < 0 || x1 < 0) return false;
    std::uint32_t a = 0, e = 0;
    if (!dense_.empty()) {  // direct index over (y, z)
      if (y >= ny_ || z >= nz_) return false;
      const RowSpan& r = dense_[static_cast<std::size_t>(z * ny_ + y)];
      a = r.first_cell;
      e = r.end_cell;
      if (a == e) return false;
    } else {
      if (y > kMax || z > kMax || table_.empty()) return false;
      const std::uint64_t key =
          (static_cast<std::uint64_t>(z) << 21) | static_cast<std::uint64_t>(y);
      std::size_t h = static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift_);
      while (table_[h].key != key) {
        if (table_[h].key == kEmptyRow) return false;
        h = (h + 1) & mask_;
      }
      a = table_[h].span.first_cell;
      e = table_[h].span.end_cell;
    }
    const Cell* c = cells_.data();
    const auto lo = static_cast<std::uint32_t>(std::max<std::int64_t>(x0, 0));
    const auto hi = static_cast<std::uint32_t>(std::min<std::int64_t>(x1, kMax));
    if (e - a > 8) {
      a = static_cast<std::uint32_t>(
          std::lower_bound(c + a, c + e, lo,
                           [](const Cell& q, std::uint32_t v) { return q.x < v; }) -
          c);
    } else {
      while (a < e && c[a].x < lo) ++a;
    }
    std::uint32_t b = a;
    while (b < e && c[b].x <= hi) ++b;
    if (a == b) return false;
    first = c[a].first;
    last = c[b].first;
    return true;
  }

  struct Cell {
    std::uint32_t x;      // cell coordinate along x
    std::uint32_t first;  // first slot in order_ (the next cell's first ends it)
  };
  struct RowSpan {
    std::uint32_t first_cell, end_cell;  // the row's cells [first_cell, end_cell)
  };
  struct RowEntry {
    std::uint64_t key;  // z << 21 | y, or kEmptyRow
    RowSpan span;
  };
  static constexpr std::uint64_t kEmptyRow = ~std::uint64_t{0};

  double cell_ = 0, inv_cell_ = 0;
  double origin_[3] = {0, 0, 0};
  std::vector<std::uint32_t> order_;           // point indices grouped by cell
  std::vector<Cell> cells_;                    // occupied cells in key order, plus a sentinel
  std::vector<std::uint64_t> row_key_;         // per row: z << 21 | y
  std::vector<std::uint32_t> row_first_cell_;  // per row + 1: first cell of the row
  // Rows are found through a dense (y, z) array when it is small (a few entries per point at
  // most), otherwise through an open-addressing table.
  std::vector<RowSpan> dense_;  // index z * ny_ + y
  std::int64_t ny_ = 0, nz_ = 0;
  std::vector<RowEntry> table_;
  // When the grid's box has at most about two cells a point: the first slot of every cell
  // (index (z * ny_ + y) * nx_ + x, one past the end closing the last), so that a row's slot
  // range is two loads. Empty otherwise.
  std::vector<std::uint32_t> cell_start_;
  std::int64_t nx_ = 0;
  void build_cell_starts(std::int64_t nx);
  std::size_t mask_ = 0;
  int shift_ = 63;  // 64 - log2(table size): the hash takes the product's high bits
};

}  // namespace scanmesh::recon
