// Internal to recon: the shape of a triangle, shared by the front and the insertion pass.
// SPDX-License-Identifier: MIT
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon::detail {

/// Cosine of the smallest interior angle of triangle (a, b, c) (1 when degenerate).
inline double min_angle_cos(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3* q[3] = {&a, &b, &c};
  double worst = -1;
  for (int k = 0; k < 3; ++k) {
    const Vec3 u = *q[(k + 1) % 3] - *q[k], w = *q[(k + 2) % 3] - *q[k];
    const double den = u.norm() * w.norm();
    if (den == 0) return 1.0;
    worst = std::max(worst, u.dot(w) / den);
  }
  return worst;
}

/// A triangle too long for a crossing search that finds triangles by their corners near the
/// new one (each point of a triangle lies within longest edge / sqrt(3) of a corner), with its
/// box: the front's and the insertion's lists of such triangles.
struct LongTriangle {
  Vec3 lo, hi;
  std::uint32_t id;
};

/// Whether triangle id = (a, b, c) has an edge longer than sqrt(limit2); then `q` is its entry.
inline bool long_entry(const Vec3& a, const Vec3& b, const Vec3& c, std::uint32_t id, double limit2,
                       LongTriangle& q) {
  if (!(std::max({(a - b).squaredNorm(), (b - c).squaredNorm(), (c - a).squaredNorm()}) > limit2))
    return false;
  q = {a.cwiseMin(b).cwiseMin(c), a.cwiseMax(b).cwiseMax(c), id};
  return true;
}

/// Bounding sphere (centroid, distance to the farthest corner) and box of a triangle: the broad
/// phase of the crossing tests in the front and the insertion pass.
struct TriangleBounds {
  Vec3 centre, lo, hi;
  double reach;
  TriangleBounds(const Vec3& a, const Vec3& b, const Vec3& c)
      : centre((a + b + c) / 3.0), lo(a.cwiseMin(b).cwiseMin(c)), hi(a.cwiseMax(b).cwiseMax(c)),
        reach(std::sqrt(std::max({(a - centre).squaredNorm(), (b - centre).squaredNorm(),
                                  (c - centre).squaredNorm()}))) {}
  /// Whether the box of triangle (a, b, c) misses this one's (then the two cannot meet).
  /// Axis by axis, stopping at the first that separates (most triangles of a crossing search
  /// are out on the first axis; the vectorised form computed all six bounds first).
  [[nodiscard]] bool box_misses(const Vec3& a, const Vec3& b, const Vec3& c) const {
    for (int k = 0; k < 3; ++k) {
      if (std::min({a[k], b[k], c[k]}) > hi[k]) return true;
      if (std::max({a[k], b[k], c[k]}) < lo[k]) return true;
    }
    return false;
  }
  /// Whether the box [lo, hi] misses this one's.
  [[nodiscard]] bool box_misses(const Vec3& l, const Vec3& h) const {
    for (int k = 0; k < 3; ++k)
      if (l[k] > hi[k] || h[k] < lo[k]) return true;
    return false;
  }
};

/// Per-triangle marks of the current crossing search, 2 bytes a triangle: start() begins a
/// search (and clears every mark when the 16-bit counter wraps), take(t) marks t and says
/// whether it was unmarked, so that a search sees each triangle once however many of its
/// corners or list entries lead to it.
class SearchStamps {
 public:
  /// A new search over triangle ids below `triangles`.
  void start(std::size_t triangles) {
    if (stamp_.size() < triangles) stamp_.resize(triangles + triangles / 4, 0);
    if (++now_ == 0) {  // wrapped: clear every mark, start again
      std::fill(stamp_.begin(), stamp_.end(), std::uint16_t{0});
      now_ = 1;
    }
  }
  [[nodiscard]] bool seen(std::uint32_t t) const { return stamp_[t] == now_; }
  bool take(std::uint32_t t) {
    if (stamp_[t] == now_) return false;
    stamp_[t] = now_;
    return true;
  }

 private:
  std::vector<std::uint16_t> stamp_;
  std::uint16_t now_ = 0;
};

}  // namespace scanmesh::recon::detail
