// Hole filling on request: boundary loops up to a size are closed by a minimum-weight
// triangulation of the loop (Liepa 2003: smallest largest dihedral angle, then smallest area),
// then, by default, refined to the density around the hole and faired (Liepa's refinement and
// a thin-plate, bilaplacian fairing) so that the patch continues the surface's shape.
// Pure: no I/O, no globals.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon {

struct FillOptions {
  /// Loops with at most this many edges are closed; 0 closes none (every hole is kept).
  std::size_t max_edges = 0;
  /// Upper bound of max_edges: the triangulation costs O(n^3) time and O(n^2) memory per loop.
  static constexpr std::size_t kLimit = 1000;
  /// Refine the patch to the edge lengths around the hole (new vertices inside it, Delaunay edge
  /// swaps) and fair it (bilaplacian with the loop and the ring of mesh vertices around it
  /// held), so that it continues the curvature of the surface. False: the patch is the loop's
  /// own vertices only (flat triangles, no new vertex).
  bool refine = true;
  /// When positive, a loop is closed only if its perimeter is at most this many times its
  /// spacing (fill_holes' `vertex_spacing`: the larger of each edge's two ends, averaged over
  /// the edges weighted by their lengths): a sampling gap rather than a hole of the part or a
  /// scan's border. 0: loops are chosen by their edge count alone.
  double max_perimeter_spacings = 0;
  /// When positive, a loop is closed only if it is at most this wide, in the mesh's units: the
  /// largest distance between two of its vertices (a round hole's diameter). Lets a user say
  /// "close the holes under 3 mm" whatever the sampling, where an edge count depends on how
  /// densely the rim is sampled. 0: no width limit. Checked together with max_edges.
  double max_width = 0;
  [[nodiscard]] std::vector<std::string> validate() const;
};

struct FillStats {
  std::size_t filled = 0;     ///< loops closed
  std::size_t kept = 0;       ///< loops left open (too many edges, too long, or not fillable)
  std::size_t crossing = 0;   ///< of those, loops whose every patch would cross the mesh
  std::size_t triangles = 0;  ///< triangles added
  std::size_t vertices = 0;   ///< vertices added (inside the patches, by the refinement)
  std::size_t faired = 0;     ///< patches faired (the others keep their refined, flat shape)
  /// For each loop kept open as `crossing`: the mesh triangles (indices into the triangles as
  /// they were before the call, ascending) that its flattest patch would cross.
  std::vector<std::vector<std::uint32_t>> crossed;
};

/// Closes the boundary loops of `mesh` with at most `options.max_edges` edges. The patch is
/// oriented like the triangles around it and never adds an edge the mesh already has, so a
/// manifold, consistently oriented mesh stays so (and the genus is unchanged). No patch crosses
/// the mesh, itself or another patch: such a loop is filled flatter (unfaired, then without new
/// vertices) or, failing that, left open and counted as kept. New vertices (of
/// the refinement) are appended to mesh.vertices; existing vertices never move. A mesh with non-manifold edges or vertices is left as it is (every loop kept).
/// `vertex_spacing` (the sampling spacing around each vertex, one per vertex) is read only when
/// options.max_perimeter_spacings > 0, and must then cover every vertex (std::invalid_argument).
FillStats fill_holes(Mesh& mesh, const FillOptions& options,
                     std::span<const float> vertex_spacing = {});

struct UntangleStats {
  std::size_t removed = 0;     ///< mesh triangles removed
  std::size_t closed = 0;      ///< boundary loops fewer than before
  std::size_t reinserted = 0;  ///< vertices the removal stranded, put back into a patch
  std::size_t skipped = 0;     ///< gaps not tried: beyond kMaxUntangledGaps
  /// Gaps left as they are without a trial: removing the triangles their patch crosses would
  /// leave a vertex with two fans, which no fill mends, and taking in the smaller fans would
  /// take more than kUntangleRounds rounds or kUntangleMaxTriangles triangles.
  std::size_t split_fans = 0;
  /// Gaps tried with a removal widened to the smaller fans of a corner it split
  /// (kUntangleRounds), kept or not (not counting `unfillable` ones).
  std::size_t widened = 0;
  /// Widened gaps not tried: a loop the removal would leave is one no fill closes (too many
  /// edges or too long for its spacing).
  std::size_t unfillable = 0;
  /// Vertices of the removed triangles that no patch could take back (at most
  /// kUntangleMaxDropped per widened gap): no longer in the mesh, reported as outliers.
  std::vector<Vec3> dropped;
  /// When `dropped` is not empty: each vertex's new index (kNoVertex for a dropped one), as the
  /// mesh's vertices were closed up; empty otherwise (no index changed).
  std::vector<std::uint32_t> renumber;
};

inline constexpr std::uint32_t kNoVertex = 0xffffffffu;
/// A removal that splits a corner's fan takes in the corner's smaller fans, at most this many
/// rounds and kUntangleMaxTriangles triangles in all.
inline constexpr int kUntangleRounds = 3;
inline constexpr std::size_t kUntangleMaxTriangles = 16;
/// Of a widened removal's vertices, at most this many may be left out.
inline constexpr std::size_t kUntangleMaxDropped = 4;
/// A piece of at most this many triangles that a removal cuts loose goes with it (as the
/// front's specks).
inline constexpr std::size_t kUntangleSpeck = 2;

/// untangle_gaps tries at most this many gaps. Each trial checks the whole mesh again (its loops,
/// components and crossings), so a scan with hundreds of such gaps took minutes (a volume of
/// random points: 156 gaps, 9.4 s of 100k points); the real scans have at most 3. A gap whose
/// removal would split a vertex's fan (`split_fans`) is refused from its corners' own triangles,
/// without a trial.
inline constexpr std::size_t kMaxUntangledGaps = 16;

/// A sampling gap that stays open because its patch would cross the mesh is often a gap that a
/// few wrong triangles reach through: across a wall thinner than about two spacings, the front
/// meshed a point of one face, lying in the gap, with the other face (a spike through the gap).
/// untangle_gaps removes the mesh triangles that a gap's flattest patch crosses (`first.crossed`,
/// from the fill_holes call that left it open, with the same options and spacing), closes the
/// loops that leaves with fill_holes, and puts each vertex the removal stranded back where it
/// lies (within a quarter of its spacing of the plane): into a patch triangle, split in three,
/// or into one of its edges, split with the triangles on both sides. A removal that would leave
/// a corner with two fans takes in that corner's smaller fans, and a piece of at most
/// kUntangleSpeck triangles it would cut loose (a flap of a wrongly meshed fold; at most
/// kUntangleRounds rounds and kUntangleMaxTriangles triangles, or the gap is counted in
/// `split_fans` and left); it is tried only when every loop it leaves is one the fill may
/// close (or counted in `unfillable`). Gap by gap, the result is kept only when it is manifold and
/// consistently oriented, has fewer boundary loops and as many components, nothing new crosses
/// the mesh, and it uses every vertex the mesh used, except, for a widened removal, at most
/// kUntangleMaxDropped that lie on no patch: those leave the mesh (`dropped`, `renumber`);
/// otherwise that gap stays as it is. A gap whose patch crosses more than 2 * options.max_edges
/// triangles is left alone, and so is every gap after the first kMaxUntangledGaps tried
/// (counted in `skipped`). The genus can change (a spike across a wall is a handle).
UntangleStats untangle_gaps(Mesh& mesh, const FillOptions& options,
                            std::span<const float> vertex_spacing, const FillStats& first);

struct ZipStats {
  std::size_t zipped = 0;        ///< boundary edges split (their triangle replaced by a fan)
  std::size_t split_points = 0;  ///< loop vertices those splits took in
  std::size_t refused = 0;       ///< zips taken back: their fan crossed the mesh
};

/// Zippering of slits (Turk and Levoy's zipper): where the boundary vertices that follow or
/// precede a boundary edge u -> v on its loop lie along it (within `band` times their
/// `vertex_spacing` of the line, in order along it, strictly between u and v), the triangle on
/// the edge, (u, v, w), is replaced by the fan from w over u, those vertices, v. The loop edges
/// between them close; what is left of the loop (nothing, for a slit) stays a loop. Such a slit
/// is what the front leaves where a coarse row meets a dense one: a long edge of the coarse side
/// with the dense row's points lying along it, each triangle of the fan too thin for the front's
/// angle rules. A fan is made only when it adds no edge the mesh has, no angle under 1 degree,
/// no fold (60 degrees from the old triangle, 90 from those across the edges it closes), and
/// crosses nothing (else that edge is left as it was). Rounds repeat on the new loops (at most
/// 8). Vertices never move or appear; a manifold, consistently oriented mesh stays so.
/// `maybe_boundary` (one flag per vertex, optional): the vertices that may lie on a boundary
/// (the others are known inner ones); the work is then only around those.
ZipStats zip_slits(Mesh& mesh, std::span<const float> vertex_spacing, double band = 0.5,
                   std::span<const std::uint8_t> maybe_boundary = {});

}  // namespace scanmesh::recon
