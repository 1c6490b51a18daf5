// Uniform grid index: counting sort of points into rows of cells (dense row index) or, for
// sparse extents, a hash table of cells sorted by key; plus the row look-up structure (per-cell
// first slots when the box is small enough, else the rows' cell lists).
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/grid.hpp"

#include <algorithm>
#include <bit>
#include <limits>
#include <numeric>

#include "scanmesh/common/error.hpp"

namespace scanmesh::recon {
namespace {

std::size_t hash_slot(std::uint64_t key, int shift) {
  return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift);
}

}  // namespace

void PointGrid::build(std::span<const Vec3> points, double cell) {
  if (!(cell > 0) || !std::isfinite(cell)) throw GeometryError("grid cell size must be positive");
  cell_ = cell;
  inv_cell_ = 1.0 / cell;
  const Eigen::AlignedBox3d box = bounding_box(points);
  const Vec3 lo = box.min(), hi = box.max();
  // Leave one empty cell of margin below the minimum so ring queries never underflow.
  for (int a = 0; a < 3; ++a) origin_[a] = points.empty() ? 0.0 : lo[a] - cell;
  if (!points.empty() && ((hi - lo).maxCoeff() * inv_cell_ + 3 > static_cast<double>(kMax))) {
    throw GeometryError(
        "point cloud too large for the grid resolution (over 2 million cells "
        "per axis); use a larger cube size");
  }
  const std::size_t n = points.size();
  if (n >= kNone) throw GeometryError("too many points for the grid (at most 2^32 - 1)");
  order_.resize(n);
  cells_.clear();
  row_key_.clear();
  row_first_cell_.clear();
  dense_.clear();
  table_.clear();
  ny_ = nz_ = nx_ = 0;
  cell_start_.clear();
  if (n == 0) {
    cells_.push_back({0, 0});
    row_first_cell_.push_back(0);
    return;
  }
  // Cell coordinates are in [0, hi * inv + 2]; a point's row is (y, z).
  ny_ = coord(hi.y(), 1) + 1;
  nz_ = coord(hi.z(), 2) + 1;
  const bool dense = static_cast<double>(ny_) * static_cast<double>(nz_) <=
                     static_cast<double>(std::max<std::size_t>(4096, 2 * n));

  // Point indices grouped by cell, cells in key order (z, y, x), points of a cell by index.
  if (dense) {
    // Counting sort by row (rows in key order) of packed (x << 32 | index) keys, then a sort of
    // each row's keys (already in index order, and rows are short).
    const auto rows = static_cast<std::size_t>(ny_ * nz_);
    std::vector<std::uint32_t> start(rows + 1, 0);
    auto row_of = [&](const Vec3& p) {
      return static_cast<std::size_t>(coord(p.z(), 2) * ny_ + coord(p.y(), 1));
    };
    for (const Vec3& p : points) ++start[row_of(p) + 1];
    std::partial_sum(start.begin(), start.end(), start.begin());
    std::vector<std::uint64_t> packed(n);
    {
      std::vector<std::uint32_t> next(start.begin(), start.end() - 1);
      for (std::size_t i = 0; i < n; ++i) {
        const Vec3& p = points[i];
        packed[next[row_of(p)]++] = (static_cast<std::uint64_t>(coord(p.x(), 0)) << 32) | i;
      }
    }
    dense_.assign(rows, RowSpan{0, 0});
    std::vector<std::uint32_t> count;
    std::vector<std::uint64_t> scratch;
    for (std::size_t r = 0; r < rows; ++r) {
      const std::uint32_t b = start[r], e = start[r + 1];
      if (b == e) continue;
      std::uint64_t* seg = packed.data() + b;
      const std::uint32_t len = e - b;
      if (len <= 32) {
        for (std::uint32_t a = 1; a < len; ++a) {
          const std::uint64_t v = seg[a];
          std::uint32_t c = a;
          while (c > 0 && seg[c - 1] > v) {
            seg[c] = seg[c - 1];
            --c;
          }
          seg[c] = v;
        }
      } else {  // counting sort by x when the row's x range is compact (stable: index order)
        std::uint32_t min_x = kNone, max_x = 0;
        for (std::uint32_t a = 0; a < len; ++a) {
          const auto x = static_cast<std::uint32_t>(seg[a] >> 32);
          min_x = std::min(min_x, x);
          max_x = std::max(max_x, x);
        }
        const std::size_t range = std::size_t{max_x} - min_x + 1;
        if (range <= 4 * std::size_t{len}) {
          count.assign(range + 1, 0);
          for (std::uint32_t a = 0; a < len; ++a) ++count[(seg[a] >> 32) - min_x + 1];
          std::partial_sum(count.begin(), count.end(), count.begin());
          scratch.resize(len);
          for (std::uint32_t a = 0; a < len; ++a) scratch[count[(seg[a] >> 32) - min_x]++] = seg[a];
          std::copy(scratch.begin(), scratch.begin() + len, seg);
        } else {
          std::sort(seg, seg + len);
        }
      }
      const auto first_cell = static_cast<std::uint32_t>(cells_.size());
      for (std::uint32_t a = 0; a < len; ++a) {
        order_[b + a] = static_cast<std::uint32_t>(seg[a]);
        const auto x = static_cast<std::uint32_t>(seg[a] >> 32);
        if (a == 0 || x != static_cast<std::uint32_t>(seg[a - 1] >> 32))
          cells_.push_back({x, b + a});
      }
      dense_[r] = {first_cell, static_cast<std::uint32_t>(cells_.size())};
      row_key_.push_back((static_cast<std::uint64_t>(r / static_cast<std::size_t>(ny_)) << 21) |
                         (r % static_cast<std::size_t>(ny_)));
      row_first_cell_.push_back(first_cell);
    }
  } else {
    // Sparse extent: cells through a growing hash table, then sorted by key.
    std::vector<std::uint32_t> cell_of(n);
    std::vector<std::uint32_t> xcell(n);                        // per point: x cell coordinate
    std::vector<std::pair<std::uint64_t, std::uint32_t>> keys;  // (key, count) per cell id
    std::size_t cap = std::bit_ceil(std::max<std::size_t>(64, n / 8));
    int shift = 64 - std::countr_zero(cap);
    std::vector<std::uint32_t> table(cap, kNone);
    std::uint64_t last_key = ~std::uint64_t{0};
    std::uint32_t last_id = kNone;
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3& p = points[i];
      xcell[i] = static_cast<std::uint32_t>(coord(p.x(), 0));
      const std::uint64_t key = (static_cast<std::uint64_t>(coord(p.z(), 2)) << 42) |
                                (static_cast<std::uint64_t>(coord(p.y(), 1)) << 21) | xcell[i];
      if (key != last_key) {  // consecutive points often share a cell
        std::size_t h = hash_slot(key, shift);
        while (table[h] != kNone && keys[table[h]].first != key) h = (h + 1) & (cap - 1);
        if (table[h] != kNone) {
          last_id = table[h];
        } else {
          last_id = static_cast<std::uint32_t>(keys.size());
          table[h] = last_id;
          keys.emplace_back(key, 0);
          if (keys.size() * 2 > cap) {  // keep the load under one half
            cap *= 2;
            shift = 64 - std::countr_zero(cap);
            table.assign(cap, kNone);
            for (std::uint32_t c = 0; c < keys.size(); ++c) {
              std::size_t g = hash_slot(keys[c].first, shift);
              while (table[g] != kNone) g = (g + 1) & (cap - 1);
              table[g] = c;
            }
          }
        }
        last_key = key;
      }
      cell_of[i] = last_id;
      ++keys[last_id].second;
    }
    std::vector<std::uint32_t>().swap(table);
    const std::size_t m = keys.size();
    // Sort (key, id) pairs; ids replace the counts, which move to a separate array.
    std::vector<std::uint32_t> count(m);
    for (std::uint32_t c = 0; c < m; ++c) {
      count[c] = keys[c].second;
      keys[c].second = c;
    }
    std::sort(keys.begin(), keys.end());
    std::vector<std::uint32_t> cursor(m);
    std::uint32_t slot = 0;
    for (std::uint32_t c = 0; c < m; ++c) {
      const auto [key, id] = keys[c];
      cursor[id] = slot;
      cells_.push_back({static_cast<std::uint32_t>(key & kMax), slot});
      slot += count[id];
      if (row_key_.empty() || row_key_.back() != (key >> 21)) {
        row_key_.push_back(key >> 21);
        row_first_cell_.push_back(c);
      }
    }
    for (std::size_t i = 0; i < n; ++i)
      order_[cursor[cell_of[i]]++] = static_cast<std::uint32_t>(i);
  }
  cells_.push_back({0, static_cast<std::uint32_t>(n)});
  row_first_cell_.push_back(static_cast<std::uint32_t>(cells_.size() - 1));
  build_cell_starts(coord(hi.x(), 0) + 1);
  if (!cell_start_.empty()) std::vector<RowSpan>().swap(dense_);  // not needed for look-ups
  if (dense) return;

  const std::size_t rows = row_key_.size();
  const std::size_t rcap = std::bit_ceil(std::max<std::size_t>(16, rows * 2));
  mask_ = rcap - 1;
  shift_ = 64 - std::countr_zero(rcap);
  table_.assign(rcap, RowEntry{kEmptyRow, {0, 0}});
  for (std::uint32_t r = 0; r < rows; ++r) {
    std::size_t h = hash_slot(row_key_[r], shift_);
    while (table_[h].key != kEmptyRow) h = (h + 1) & mask_;
    table_[h] = {row_key_[r], {row_first_cell_[r], row_first_cell_[r + 1]}};
  }
}

void PointGrid::build_cell_starts(std::int64_t nx) {
  cell_start_.clear();
  nx_ = 0;
  const double total =
      static_cast<double>(nx) * static_cast<double>(ny_) * static_cast<double>(nz_);
  if (total > static_cast<double>(2 * order_.size() + 4096)) return;  // ~8 bytes a point at most
  nx_ = nx;
  const auto cells = static_cast<std::size_t>(total);
  cell_start_.resize(cells + 1);
  std::size_t at = 0;
  for (std::size_t r = 0; r + 1 < row_first_cell_.size(); ++r) {
    const auto y = static_cast<std::size_t>(row_key_[r] & kMax);
    const auto z = static_cast<std::size_t>(row_key_[r] >> 21);
    const std::size_t base =
        (z * static_cast<std::size_t>(ny_) + y) * static_cast<std::size_t>(nx_);
    for (std::uint32_t c = row_first_cell_[r]; c < row_first_cell_[r + 1]; ++c) {
      const std::size_t lin = base + cells_[c].x;
      while (at <= lin) cell_start_[at++] = cells_[c].first;
    }
  }
  while (at <= cells) cell_start_[at++] = static_cast<std::uint32_t>(order_.size());
}

}  // namespace scanmesh::recon
