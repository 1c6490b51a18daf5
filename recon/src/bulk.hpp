// Bulk meshing of the flat, well-sampled interior: planar Delaunay triangulation of patches
// over which the surface is a height field, for the advancing front to start from.
// SPDX-License-Identifier: MIT
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/mesh.hpp"
#include "scanmesh/recon/normals.hpp"

namespace scanmesh::recon::detail {

struct BulkOptions {
  /// The front's rules, which every bulk triangle meets: edges at most radius_factor times the
  /// larger (capped) local spacing of their end points, no angle under the minimum, no fold
  /// between neighbours (normals' dot product above cos_dihedral), and every corner's normal
  /// within the bent-triangle angle of the triangle's.
  double radius_factor = 2.0;
  double cos_min_angle = 0.9396926207859084;  // cos 20 degrees
  double cos_dihedral = 0.0;                  // cos (180 - 90) degrees
  double cos_corner = 0.8660254037844387;     // cos 30 degrees
  std::span<const float> spacing;             // the front's capped local spacing, per point
  int max_valence = 16;
  /// Every point of a patch has its normal within this angle of the seed cell's direction and
  /// of the projection axis (the patch's mean normal, or else the seed's), so the patch is a
  /// height field over the plane normal to that axis (locally). 60: the bunny's patches hold 62
  /// % of its triangles instead of 53 % at 30 (recon/README, Bulk).
  double patch_cone_deg = 60;
  /// Patches stop growing at this many points: the triangulation of one patch is live at a
  /// time, so this bounds the stage's memory.
  std::size_t max_patch_points = std::size_t{1} << 17;
  /// Kept faces with an edge longer than this (squared) are named in BulkMesh::long_triangles
  /// (the front's crossing guard lists them; the bulk has their edges at hand).
  double long_edge2 = std::numeric_limits<double>::infinity();
};

/// The bulk's triangles and their border: the front's starting point.
struct BulkMesh {
  std::vector<Triangle> triangles;  ///< oriented with the normals (counter-clockwise seen from them)
  /// Border edges as the front takes them: {a, b, opp}, directed a -> b as in their triangle
  /// (a, b, opp), so the mesh lies on their left.
  std::vector<std::array<std::uint32_t, 3>> border;
  /// Edges of two triangles whose end points are both on the border (the front must know
  /// them; the other interior edges it never meets).
  std::vector<std::array<std::uint32_t, 2>> border_chords;
  /// Positions in `triangles` of the faces with an edge longer than BulkOptions::long_edge2
  /// allows, ascending.
  std::vector<std::uint32_t> long_triangles;
};

struct BulkStats {
  std::size_t patches = 0;        ///< patches triangulated
  std::size_t patch_points = 0;   ///< points in them
  std::size_t triangles = 0;      ///< triangles kept
};

/// Triangles over the patches: grid cells grown breadth-first while the mean normal of their
/// eligible points (not `excluded`: turning points and points near them) stays within the cone
/// around the first cell's; each patch's eligible points with normals in the cone are projected
/// on the plane normal to their mean normal (the seed's direction where some normal would be
/// outside the cone around the mean) and triangulated (Delaunay, exact predicates). A triangle is
/// kept when it meets the front's rules (above) and no point outside its patch lies in its
/// circumsphere (tested where the triangle comes near the patch's border); then every vertex
/// is left with a single fan of at most max_valence edges. The triangles are oriented with the
/// normals, vertex-manifold, and cross nothing. `out.triangles` is appended to (so the caller
/// can hand over storage it has reserved); the other lists are replaced. Deterministic.
void bulk_triangles(std::span<const Vec3> points, const LocalFrames& frames, const PointGrid& grid,
                    std::span<const std::uint8_t> excluded, const BulkOptions& options,
                    BulkMesh& out, BulkStats& stats);

}  // namespace scanmesh::recon::detail
