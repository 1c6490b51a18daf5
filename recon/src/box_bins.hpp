// Internal to recon: boxes binned on a coarse hashed grid, for the crossing searches' lists of
// long triangles (the front's and the insertion pass's).
// SPDX-License-Identifier: MIT
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon::detail {

/// Keys (triangle ids or list positions) with an axis-aligned box each, binned on a grid of
/// cubic cells hashed by their coordinates. visit() calls back every key whose box may overlap
/// a query box: each key binned in a cell the query box touches, and every key whose box spans
/// more than kMaxCells cells (kept apart); all keys while there are at most kFew. A key may be called back more than once, and keys
/// whose box misses the query's may be too (hash collisions, coordinates wrapped at 2^21 cells,
/// boxes since replaced): callers test the box they hold and deduplicate. Nothing is ever
/// removed; clear() and insert again where the keys change meaning.
///
/// Built for the lists of long triangles that the crossing searches test besides the triangles
/// they find by their corners: on a multi-view line scan (anisotropic, grazing fringes) such a
/// list holds thousands of triangles, and a linear pass over it for every new triangle was a
/// third of the whole reconstruction.
class BoxBins {
 public:
  static constexpr std::int64_t kMaxCells = 64;
  static constexpr std::size_t kFew = 16;  // up to this many keys, visit() calls back all

  /// Empties the bins and sets the cell edge (the long-edge limit of the list suits: its
  /// triangles then span a few cells each, and a new triangle's box one to eight). An edge
  /// that is not positive and finite puts everything in one cell.
  void reset(double cell) {
    inv_ = cell > 0 && std::isfinite(1.0 / cell) ? 1.0 / cell : 0.0;
    clear();
  }
  void clear() {
    keys_.clear();
    heads_.clear();
    nodes_.clear();
    wide_.clear();
    all_.clear();
    used_ = 0;
  }
  [[nodiscard]] bool empty() const { return all_.empty(); }

  void insert(std::uint32_t key, const Vec3& lo, const Vec3& hi) {
    all_.push_back(key);
    const Range r = range(lo, hi);
    if (r.cells() > kMaxCells) {
      wide_.push_back(key);
      return;
    }
    for (std::int64_t z = r.lo[2]; z <= r.hi[2]; ++z)
      for (std::int64_t y = r.lo[1]; y <= r.hi[1]; ++y)
        for (std::int64_t x = r.lo[0]; x <= r.hi[0]; ++x) {
          std::uint32_t& head = heads_[slot_for_insert(pack(x, y, z))];
          nodes_.push_back({key, head});
          head = static_cast<std::uint32_t>(nodes_.size() - 1);
        }
  }

  /// Calls f(key) for every key whose box may hold point p (visit(p, p, f), one cell).
  template <class F>
  void visit_point(const Vec3& p, F&& f) const {
    if (all_.size() <= kFew) {
      for (std::uint32_t k : all_) f(k);
      return;
    }
    for (std::uint32_t k : wide_) f(k);
    if (keys_.empty()) return;
    const std::uint32_t s = find(pack(coord(p.x()), coord(p.y()), coord(p.z())));
    if (s == kNone) return;
    for (std::uint32_t n = heads_[s]; n != kNone; n = nodes_[n].next) f(nodes_[n].key);
  }

  /// Calls f(key) for every key whose box may overlap [lo, hi] (see the class comment).
  template <class F>
  void visit(const Vec3& lo, const Vec3& hi, F&& f) const {
    if (all_.size() <= kFew) {  // cheaper than the hashing (the bunny's points list one)
      for (std::uint32_t k : all_) f(k);
      return;
    }
    const Range r = range(lo, hi);
    if (r.cells() > kMaxCells) {
      for (std::uint32_t k : all_) f(k);
      return;
    }
    for (std::uint32_t k : wide_) f(k);
    if (keys_.empty()) return;
    for (std::int64_t z = r.lo[2]; z <= r.hi[2]; ++z)
      for (std::int64_t y = r.lo[1]; y <= r.hi[1]; ++y)
        for (std::int64_t x = r.lo[0]; x <= r.hi[0]; ++x) {
          const std::uint32_t s = find(pack(x, y, z));
          if (s == kNone) continue;
          for (std::uint32_t n = heads_[s]; n != kNone; n = nodes_[n].next) f(nodes_[n].key);
        }
  }

 private:
  static constexpr std::uint32_t kNone = 0xffffffffu;
  static constexpr std::uint64_t kEmpty = ~std::uint64_t{0};
  struct Node {
    std::uint32_t key, next;
  };
  struct Range {
    std::array<std::int64_t, 3> lo, hi;
    [[nodiscard]] std::int64_t cells() const {
      std::int64_t n = 1;
      for (int k = 0; k < 3; ++k) {
        n *= hi[k] - lo[k] + 1;
        if (n > kMaxCells) return n;
      }
      return n;
    }
  };

  [[nodiscard]] std::int64_t coord(double v) const {
    // Clamped so that far coordinates (the core accepts up to 1e100) cannot overflow; boxes
    // beyond the clamp share its cells, which only costs tests.
    constexpr double kLimit = 0x1.0p40;
    return static_cast<std::int64_t>(std::floor(std::clamp(v * inv_, -kLimit, kLimit)));
  }
  [[nodiscard]] Range range(const Vec3& lo, const Vec3& hi) const {
    Range r{};
    for (int k = 0; k < 3; ++k) {
      r.lo[k] = coord(lo[k]);
      r.hi[k] = coord(hi[k]);
    }
    return r;
  }
  static std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
    constexpr std::uint64_t m = (std::uint64_t{1} << 21) - 1;
    return (static_cast<std::uint64_t>(x) & m) | ((static_cast<std::uint64_t>(y) & m) << 21) |
           ((static_cast<std::uint64_t>(z) & m) << 42);
  }
  static std::uint64_t mix(std::uint64_t k) {
    k ^= k >> 31;
    k *= 0x7fb5d329728ea185ULL;
    k ^= k >> 27;
    k *= 0x81dadef4bc2dd44dULL;
    return k ^ (k >> 33);
  }
  [[nodiscard]] std::uint32_t find(std::uint64_t key) const {
    const std::size_t mask = keys_.size() - 1;
    for (std::size_t s = mix(key) & mask;; s = (s + 1) & mask) {
      if (keys_[s] == key) return static_cast<std::uint32_t>(s);
      if (keys_[s] == kEmpty) return kNone;
    }
  }
  std::size_t slot_for_insert(std::uint64_t key) {
    if (2 * (used_ + 1) > keys_.size()) grow();
    const std::size_t mask = keys_.size() - 1;
    for (std::size_t s = mix(key) & mask;; s = (s + 1) & mask) {
      if (keys_[s] == key) return s;
      if (keys_[s] == kEmpty) {
        keys_[s] = key;
        heads_[s] = kNone;
        ++used_;
        return s;
      }
    }
  }
  void grow() {
    std::vector<std::uint64_t> keys(std::max<std::size_t>(64, 2 * keys_.size()), kEmpty);
    std::vector<std::uint32_t> heads(keys.size(), kNone);
    const std::size_t mask = keys.size() - 1;
    for (std::size_t s = 0; s < keys_.size(); ++s) {
      if (keys_[s] == kEmpty) continue;
      std::size_t t = mix(keys_[s]) & mask;
      while (keys[t] != kEmpty) t = (t + 1) & mask;
      keys[t] = keys_[s];
      heads[t] = heads_[s];
    }
    keys_.swap(keys);
    heads_.swap(heads);
  }

  double inv_ = 1;
  std::vector<std::uint64_t> keys_;   // open addressing, load at most 1/2; kEmpty when free
  std::vector<std::uint32_t> heads_;  // per slot: its cell's first node
  std::vector<Node> nodes_;           // per (key, cell): the key and the cell's next node
  std::vector<std::uint32_t> wide_;   // keys of boxes over kMaxCells cells, always visited
  std::vector<std::uint32_t> all_;    // every key inserted, for query boxes over kMaxCells
  std::size_t used_ = 0;
};

}  // namespace scanmesh::recon::detail
