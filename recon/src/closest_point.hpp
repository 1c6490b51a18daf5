// Internal to recon: the exact closest point on a triangle, shared by the deviation queries and
// the crossing guard's clearance test.
// SPDX-License-Identifier: MIT
#pragma once

#include <cmath>
#include <cstdint>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon::detail {

/// Which feature of a triangle the closest point lies on. Edge k runs from corner k to k+1.
enum class Feature : std::uint8_t { kFace, kEdge0, kEdge1, kEdge2, kVertex0, kVertex1, kVertex2 };

struct ClosestPoint {
  Vec3 point;
  double dist_sq;
  Feature feature;
};

/// Closest point on segment [a, b] to p (handles a == b).
inline ClosestPoint closest_on_segment(const Vec3& p, const Vec3& a, const Vec3& b, Feature edge,
                                Feature at_a, Feature at_b) {
  const Vec3 ab = b - a;
  const double len_sq = ab.squaredNorm();
  double s = len_sq > 0 ? (p - a).dot(ab) / len_sq : 0.0;
  Feature f = edge;
  if (!(s > 0)) {
    s = 0;
    f = at_a;
  } else if (s >= 1) {
    s = 1;
    f = at_b;
  }
  const Vec3 q = a + s * ab;
  return ClosestPoint{q, (p - q).squaredNorm(), f};
}

/// Degenerate (zero-area) triangle: the closest of its three edges.
inline ClosestPoint closest_on_degenerate(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  ClosestPoint best =
      closest_on_segment(p, a, b, Feature::kEdge0, Feature::kVertex0, Feature::kVertex1);
  ClosestPoint e1 =
      closest_on_segment(p, b, c, Feature::kEdge1, Feature::kVertex1, Feature::kVertex2);
  if (e1.dist_sq < best.dist_sq) best = e1;
  ClosestPoint e2 =
      closest_on_segment(p, c, a, Feature::kEdge2, Feature::kVertex2, Feature::kVertex0);
  if (e2.dist_sq < best.dist_sq) best = e2;
  return best;
}

/// In an edge's Voronoi region: the point origin + (num / den) * dir on that edge, or, when the
/// triangle is too thin for the ratio (den not positive), the closest of its three edges.
inline ClosestPoint closest_in_edge_region(const Vec3& p, const Vec3& a, const Vec3& b,
                                           const Vec3& c, const Vec3& origin, const Vec3& dir,
                                           double num, double den, Feature edge) {
  if (!(den > 0)) return closest_on_degenerate(p, a, b, c);
  const Vec3 q = origin + (num / den) * dir;
  return ClosestPoint{q, (p - q).squaredNorm(), edge};
}

/// Closest point on triangle (a, b, c) to p by Voronoi regions (Ericson, Real-Time Collision
/// Detection, 5.1.5), reporting the feature it lies on.
inline ClosestPoint closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return ClosestPoint{a, ap.squaredNorm(), Feature::kVertex0};
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return ClosestPoint{b, bp.squaredNorm(), Feature::kVertex1};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0)
    return closest_in_edge_region(p, a, b, c, a, ab, d1, d1 - d3, Feature::kEdge0);
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return ClosestPoint{c, cp.squaredNorm(), Feature::kVertex2};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0)
    return closest_in_edge_region(p, a, b, c, a, ac, d2, d2 - d6, Feature::kEdge2);
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return closest_in_edge_region(p, a, b, c, b, c - b, d4 - d3, (d4 - d3) + (d5 - d6),
                                  Feature::kEdge1);
  const double sum = va + vb + vc;
  if (!(sum > 0) || !std::isfinite(sum)) return closest_on_degenerate(p, a, b, c);
  const double v = vb / sum, w = vc / sum;
  const Vec3 q = a + v * ab + w * ac;
  return ClosestPoint{q, (p - q).squaredNorm(), Feature::kFace};
}

}  // namespace scanmesh::recon::detail
