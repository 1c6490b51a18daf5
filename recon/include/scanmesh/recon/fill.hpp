// Hole filling on request: boundary loops up to a size are closed by a minimum-weight
// triangulation of the loop (Liepa 2003: smallest largest dihedral angle, then smallest area),
// then, by default, refined to the density around the hole and faired (Liepa's refinement and
// a thin-plate, bilaplacian fairing) so that the patch continues the surface's shape.
// Pure: no I/O, no globals.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
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
  /// When positive, a loop is closed only if its perimeter is at most this many times the mean
  /// spacing of its vertices (fill_holes' `vertex_spacing`): a sampling gap rather than a hole
  /// of the part or a scan's border. 0: loops are chosen by their edge count alone.
  double max_perimeter_spacings = 0;
  [[nodiscard]] std::vector<std::string> validate() const;
};

struct FillStats {
  std::size_t filled = 0;     ///< loops closed
  std::size_t kept = 0;       ///< loops left open (too many edges, too long, or not fillable)
  std::size_t crossing = 0;   ///< of those, loops whose every patch would cross the mesh
  std::size_t triangles = 0;  ///< triangles added
  std::size_t vertices = 0;   ///< vertices added (inside the patches, by the refinement)
  std::size_t faired = 0;     ///< patches faired (the others keep their refined, flat shape)
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

}  // namespace scanmesh::recon
