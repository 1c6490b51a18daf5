// Advancing-front (boundary extension) triangulation of a reduced, oriented point set.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string_view>
#include <string>
#include <vector>

#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/mesh.hpp"
#include "scanmesh/recon/normals.hpp"

namespace scanmesh::recon {

/// Explicit per-vertex state, exposed for tests (../shared/STYLE.md §7).
enum class VertexState : std::uint8_t {
  kFree,      ///< not yet in the mesh
  kFront,     ///< in the mesh with an open fan (on the advancing front)
  kDone,      ///< interior: its fan is closed
  kBoundary,  ///< in the mesh, on a boundary loop that stays open (hole or scan border)
  kOutlier,   ///< never reachable by the front: reported, not meshed
};

struct FrontOptions {
  double min_angle_deg = 20;  ///< smallest interior angle of a new triangle (reference: 20)
  /// Smallest dihedral angle between a new triangle and the one across its front edge
  /// (reference: 90, no fold-back). 180 is flat.
  double min_dihedral_deg = 90;
  /// Candidate radius as a multiple of the local spacing (mean distance to 6 neighbours) of the
  /// edge's end points and the candidate.
  double radius_factor = 2.0;
  /// Second chance for edges nothing fitted: larger radius, smaller angle bound.
  double relaxed_radius_factor = 2.6;
  double relaxed_min_angle_deg = 8;
  /// Relaxed dihedral bound: right-angle CAD edges sampled only on the feature lines need
  /// triangles meeting at 90 degrees exactly.
  double relaxed_min_dihedral_deg = 60;
  /// Largest angle between a new triangle's normal and the PCA normal of its new vertex.
  double max_normal_deviation_deg = 60;
  int max_valence = 16;  ///< edges per vertex
  /// Real holes stay open. Before each relaxed pass, a front loop that the mesh surrounds (it
  /// winds against its vertices' normals, as the rim of a hole does and a scan's border does
  /// not) with an area of at least `hole_min_area` and a mean width (twice its area over its
  /// perimeter) of at least `hole_min_width` local spacings squared and spacings is a hole:
  /// the relaxed pass may join its edges to free points, and to front points only within the
  /// strict reach. Without it the relaxed pass zips such holes from their narrow ends with
  /// edges of 4-6 spacings whenever noise, dropouts or uneven density leave their rims ragged
  /// (bench_holes). Slits narrower than that, and small loops, are sampling gaps and close.
  bool keep_holes = true;
  double hole_min_area = 20;
  double hole_min_width = 1.8;
  /// Boundary loops with at most this many edges and a perimeter of at most
  /// `fill_perimeter_factor` local spacings (the larger of each edge's ends, averaged over the
  /// edges by length) are sampling gaps, closed at the end.
  std::size_t fill_max_edges = 8;
  double fill_perimeter_factor = 10.0;
  /// The new triangle must not cross or overlap the mesh (rule 3 of the front): each one is
  /// tested exactly against the triangles around its corners, and near turning points (the
  /// surface turns back within reach: thin walls, sharp edges) or where the front-edge tests
  /// cannot see the front near it, against every triangle near it; and a free point a new
  /// triangle covers away from turning points is no candidate afterwards (it would make a
  /// triangle overlapping that one). Off only for comparison.
  bool crossing_guard = true;
  /// Start from the bulk: the flat, well-sampled interior (away from turning points, normals
  /// within a 60-degree cone per patch) is triangulated by planar Delaunay patches that meet
  /// the rules above, and the front grows from their borders into the rest. Off: the front
  /// grows everything from seed triangles.
  bool bulk = true;
  /// A bulk patch stops growing at this many points (one patch's triangulation is live at a
  /// time: this bounds the stage's memory). 16,384 keeps a patch's triangulation and its
  /// points' data in the cache: on the synthetic scan the front took 2.6 s with it against
  /// 2.9 s with 131,072 (4,096: 2.8 s, more seams).
  std::size_t bulk_patch_points = std::size_t{1} << 14;
  /// A bulk patch takes points whose normals lie within this angle (degrees, in (0, 90)) of its
  /// seed cell's mean normal and of its projection axis: wider cones make larger patches and
  /// shorter seams for the front to zip (the bunny: 53 % of the triangles from the bulk at 30,
  /// 62 % at 60).
  double bulk_patch_cone_deg = 60;
  [[nodiscard]] std::vector<std::string> validate() const;
};

struct FrontResult {
  std::vector<Triangle> triangles;      ///< indices into the point array, consistently oriented
  std::vector<VertexState> state;       ///< final state of every point
  std::vector<std::uint32_t> outliers;  ///< points the front never reached
  std::size_t seeds = 0;                ///< seed triangles placed (one per component grown)
  std::size_t relaxed_triangles = 0;    ///< triangles placed by the relaxed second pass
  std::size_t filled_gaps = 0;          ///< small loops closed at the end
  std::size_t removed_fan_triangles = 0;  ///< triangles dropped to keep vertices manifold
  std::size_t flipped_components = 0;
  std::size_t edge_evaluations = 0;  ///< front edges examined (cost counter)
  std::size_t points_scanned = 0;    ///< grid points visited while gathering candidates
  /// Evaluations not run: the edge had found no candidate in that mode before, and none can
  /// have appeared since (cost counter; debug builds run them anyway and check that they find
  /// nothing).
  std::size_t skipped_evaluations = 0;
  std::size_t seed_attempts = 0;
  std::size_t bulk_patches = 0;    ///< planar Delaunay patches the front started from
  std::size_t bulk_triangles = 0;  ///< triangles they gave
  std::size_t turning_points = 0;  ///< points near which the surface turns back (crossing guard)
  /// Small components removed because they crossed another one (their points are outliers).
  std::size_t dropped_components = 0;
  /// Components of one or two triangles beside a large one, removed (their points are
  /// outliers): seeds among a few stray points (spikes) that could not grow.
  std::size_t dropped_specks = 0;
  /// The front's local spacing of a point is frames.spacing capped at this (2.5 x the median),
  /// except on a region sampled sparsely as a whole (a point whose neighbours within three of
  /// its spacings are at least 12, lie on a plane with it and are as sparse: 2.5 x their median
  /// by area): such a region connects, while a point much sparser than its surroundings (a
  /// stray reading) or a scatter of them in the air cannot pull long triangles.
  double spacing_cap = 0;
  /// The capped local spacing of every point, as the front used it (the insertion of the points
  /// it left out and the gap closing use it too).
  std::vector<float> spacing;
};

/// Called with the name of each stage (or step of a stage) as it starts; the core keeps no
/// clock, the caller times what it wants.
using StageObserver = std::function<void(std::string_view stage)>;

/// Triangulates `points` (with `frames` from estimate_frames and `grid` indexing the points
/// with a cell of about 3.6x the median local spacing). Deterministic. `observer`, when given,
/// hears the front's steps as they start: "front/setup", "front/turning" (the crossing guard's
/// turning points), "front/bulk" (the planar Delaunay patches), "front/growth" (the front
/// itself, from the bulk's border and from seeds), "front/repairs" (sampling gaps and fan
/// repairs, with the growth they restart), "front/fan check" (every vertex one fan) and
/// "front/orientation" (components, orientation, final states).
FrontResult advance_front(std::span<const Vec3> points, const LocalFrames& frames,
                          const PointGrid& grid, const FrontOptions& options = {},
                          const StageObserver& observer = {});

namespace detail {

/// An existing mesh among the points that the front continues (the incremental path meshes a
/// region against the published mesh around it). Every new triangle has at least one `active`
/// corner (one flag per point); the existing triangles are never re-oriented, and a component
/// holding one is never dropped (as crossing another or as a speck): the other one goes. The
/// repairs may still remove existing triangles. The existing triangles must be vertex-manifold
/// (every vertex one fan) and consistently oriented; their vertices are not free points.
struct FrontContext {
  std::span<const Triangle> triangles;
  std::span<const std::uint8_t> active;
};

/// advance_front continuing `context` (its triangles come first in the result, as kept).
FrontResult advance_front_from(std::span<const Vec3> points, const LocalFrames& frames,
                               const PointGrid& grid, const FrontOptions& options,
                               const FrontContext& context);

}  // namespace detail

}  // namespace scanmesh::recon
