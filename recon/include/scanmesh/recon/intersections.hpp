// Self-intersection check: pairs of triangles that meet other than along the edge or at the
// vertex they share. CAD import, offsetting and 3D printing reject such meshes even when they are
// manifold and consistently oriented, so `scanmesh inspect` reports them. Pure: no I/O.
// SPDX-License-Identifier: MIT
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon {

struct SelfIntersections {
  std::size_t pairs = 0;      ///< intersecting triangle pairs
  std::size_t triangles = 0;  ///< triangles in at least one such pair
  /// The first pairs found (lower triangle index first), in a deterministic order.
  std::vector<std::array<std::uint32_t, 2>> examples;
};

/// Finds every pair of triangles whose intersection is more than their shared vertices: crossing
/// triangles, a triangle touching another's face, coplanar overlaps (a fold onto a neighbour
/// across their shared edge) and repeated triangles. Degenerate triangles (zero area, a repeated
/// index) are skipped: analyze() counts them. Coplanarity and touching are decided with a
/// tolerance of 1e-9 times the pair's longest edge. Cost: a uniform grid of cells two mean
/// edges wide, then an exact test for the pairs whose bounding boxes overlap; about linear in
/// the number of triangles.
/// With `from`, only pairs with at least one triangle of index >= from are tested (what was
/// added to a mesh: hole-filling patches). max_examples = kAllPairs keeps every pair found.
SelfIntersections find_self_intersections(const Mesh& mesh, std::size_t max_examples = 16,
                                          std::size_t from = 0);
/// The same over a vertex array and a triangle list (no Mesh to build).
SelfIntersections find_self_intersections(std::span<const Vec3> vertices,
                                          std::span<const Triangle> triangles,
                                          std::size_t max_examples = 16, std::size_t from = 0);

/// The pair test itself: do triangles s and t (indices into `vertices`, neither degenerate)
/// intersect other than along the vertices they share? Same tolerance as above; `on_plane`, when
/// larger, is the distance within which a corner counts as lying on the other triangle's plane
/// (the advancing front passes a few float roundings of the coordinates: two triangles of one
/// flat face that overlap a little apart in height are a fold once written as float).
bool triangles_intersect(std::span<const Vec3> vertices, const Triangle& s, const Triangle& t,
                         double on_plane = 0);

/// Whether triangles s and t come within `clearance` of each other other than at the vertex they
/// share: a corner (not shared) that near the other triangle, or two edges without a common end
/// point that near each other. Triangles sharing an edge are left to triangles_intersect. Used
/// with a few float roundings of the coordinates as the clearance: a pair this close may cross
/// once written as float (STL, PLY).
bool triangles_touch(std::span<const Vec3> vertices, const Triangle& s, const Triangle& t,
                     double clearance);

inline constexpr std::size_t kAllPairs = static_cast<std::size_t>(-1);

/// Removes every component (triangles joined through shared vertices) that crosses another
/// component, the smaller of the two (by triangles; ties: the later one). The order of the kept
/// triangles is unchanged. Returns the number of components removed. Costs nothing with a
/// single component; otherwise a check of the smaller components against everything.
/// `keep` (one flag per triangle, optional): a component holding a flagged triangle is never
/// the one removed.
std::size_t remove_crossing_components(std::span<const Vec3> vertices,
                                       std::vector<Triangle>& triangles,
                                       std::span<const std::uint8_t> keep = {});

}  // namespace scanmesh::recon
