// Planar Delaunay triangulation by radial sweep, with exact predicates: the bulk's triangulator.
// SPDX-License-Identifier: MIT
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace scanmesh::recon::detail {

/// Delaunay triangulation of points in the plane, built by a radial sweep: the points are taken
/// in order of distance from the circumcentre of a small seed triangle, each is joined to the
/// part of the convex hull it sees, and Lawson flips restore the empty-circle property after
/// every join. The orientation and in-circle tests are CGAL's filtered exact predicates, so the
/// result is exactly Delaunay (among the possible ones where four points are cocircular).
///
/// Storage is flat and reused between calls: triangle t has corners corner[3t..3t+2],
/// counter-clockwise; half-edge 3t+k goes from corner k to corner k+1 (it is opposite corner
/// k+2), and twin[h] is the same edge in the neighbouring triangle, or kNone on the hull.
///
/// A point whose position repeats one already in, and the rare point that rounding in the
/// sweep order puts inside the hull already built, is left out (inserted() is false). Fewer than
/// three points, or all of them on one line, give no triangle.
class Delaunay2 {
 public:
  static constexpr std::uint32_t kNone = 0xffffffffu;

  void triangulate(std::span<const std::array<double, 2>> points);

  [[nodiscard]] std::size_t triangle_count() const { return corner_.size() / 3; }
  [[nodiscard]] std::span<const std::uint32_t> corners() const { return corner_; }
  [[nodiscard]] std::span<const std::uint32_t> twins() const { return twin_; }
  [[nodiscard]] bool inserted(std::uint32_t v) const { return out_[v] != kNone; }
  /// A half-edge leaving v; for a vertex on the hull, the hull edge leaving it, so that the
  /// walk h -> twin(prev(h)) visits all of v's triangles before it reaches the hull.
  [[nodiscard]] std::uint32_t out_edge(std::uint32_t v) const { return out_[v]; }
  [[nodiscard]] bool on_hull(std::uint32_t v) const { return out_[v] != kNone && twin_[out_[v]] == kNone; }

  static std::uint32_t next(std::uint32_t h) { return h % 3 == 2 ? h - 2 : h + 1; }
  static std::uint32_t prev(std::uint32_t h) { return h % 3 == 0 ? h + 2 : h - 1; }

 private:
  std::uint32_t add_triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t ab,
                             std::uint32_t bc, std::uint32_t ca);
  void link(std::uint32_t h, std::uint32_t t);
  void legalize(std::uint32_t h);
  [[nodiscard]] std::uint32_t hash_key(const std::array<double, 2>& p) const;

  std::span<const std::array<double, 2>> p_;
  std::vector<std::uint32_t> corner_, twin_, out_;
  std::vector<std::uint32_t> hull_next_, hull_prev_, hull_edge_, hash_, stack_;
  std::vector<std::uint32_t> order_, sorted_, key_, key_sorted_;  // the sweep order
  std::vector<double> dist_;  // per point: squared distance from the centre
  std::vector<std::uint32_t> perm_;  // sweep position -> point
  std::vector<std::array<double, 2>> swept_;  // the points in sweep order
  std::array<double, 2> centre_{};
};

}  // namespace scanmesh::recon::detail
