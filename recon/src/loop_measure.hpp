// The measure that tells a sampling gap from a hole: a boundary loop's perimeter against its
// local spacing. Shared by the front's small-loop closing, the check for sampling gaps after the
// insertion, and the final gap closing, so that the three agree on what a gap is; and the test
// of a slit (a loop vertex lying along a loop edge), shared by that check and zip_slits.
// SPDX-License-Identifier: MIT
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <span>

#include "scanmesh/recon/front.hpp"
#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon::detail {

/// Accumulates a closed loop edge by edge. Its spacing is the mean over its edges, weighted by
/// their lengths, of the larger local spacing of each edge's two ends: along a seam between a
/// dense and a coarse sampling, the loop's few long edges lie on the coarse side, and a plain
/// mean over its vertices (most of them dense) took a gap one coarse spacing wide for a hole.
/// On a loop sampled evenly both measures agree.
class LoopMeasure {
 public:
  void add(const Vec3& a, const Vec3& b, double spacing_a, double spacing_b) {
    const double len = (b - a).norm();
    perimeter_ += len;
    weighted_ += len * std::max(spacing_a, spacing_b);
  }
  [[nodiscard]] double spacing() const { return perimeter_ > 0 ? weighted_ / perimeter_ : 0; }
  /// Whether the perimeter is at most `factor` spacings (false for a non-finite coordinate).
  [[nodiscard]] bool within(double factor) const { return perimeter_ <= factor * spacing(); }

 private:
  double perimeter_ = 0, weighted_ = 0;
};

/// Whether x lies within `tol` of the line through u and v; `at`: how far along it from u, in
/// the units of the points (the caller tells whether that is between u and v).
inline bool lies_along(const Vec3& u, const Vec3& v, const Vec3& x, double tol, double& at) {
  const Vec3 e = v - u;
  const double len = e.norm();
  if (!(len > 0)) return false;
  const Vec3 dir = e / len, q = x - u;
  at = q.dot(dir);
  return (q - at * dir).norm() <= tol;
}

/// What the boundary loops left after the front and the insertion need.
struct LoopCheck {
  /// A loop of at most `max_edges` edges whose perimeter is at most `factor` times its spacing
  /// (LoopMeasure): a sampling gap for the "gaps" stage.
  bool gap = false;
  /// A boundary edge with the loop vertex after or before it lying along it (within `band`
  /// times its spacing of the line, between the ends): a slit for zip_slits.
  bool slit = false;
};

/// Only the triangles with two boundary vertices (`state` kBoundary) are looked at, so a mesh
/// without such loops costs one pass over the triangles, not a topology analysis; each loop is
/// walked once (reconstruct.cpp).
LoopCheck check_loops(std::span<const Vec3> points, std::span<const Triangle> triangles,
                      std::span<const VertexState> state, std::span<const float> spacing,
                      std::size_t max_edges, double factor, double band);

}  // namespace scanmesh::recon::detail
