// Sharp-edge recovery on request: a scanner samples a part without regard to its edges, so a
// convex or concave edge of a machined part comes out as a bevel, a strip of triangles that cut
// the corner between the last sample on one face and the first on the other (up to about half a
// spacing off the true edge). Following Attene et al.'s EdgeSharpener (SGP 2003), the faces on
// both sides are extended and each bevel triangle gets a new vertex where they meet: on the
// intersection line of two face planes (an edge) or at the point of three (a corner), taken
// over the bevel as seen along the faces' mean normal (a bevel cut off-centre is nearly parallel
// to one face); edges between two such vertices are flipped so that the recovered edge runs
// through them, and the slivers a new vertex near a face makes are flipped away within it.
// A rounded edge (a fillet sampled across: bevel corners that belong to neither face and lie
// off both planes) is left round.
// Pure: no I/O, no globals.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon {

struct SharpenOptions {
  /// Two triangles sharing an edge belong to the same face when their normals are at most this
  /// far apart (degrees): above the sampling noise's own normal scatter (a few degrees on a
  /// scan), below half the sharpest feature to recover.
  double smooth_deg = 10;
  /// The faces on the two sides of a bevel must be at least this far apart (degrees between
  /// their normals) for an edge to be recovered there; a gentler crease stays as it is.
  double feature_deg = 50;
  /// Give back to the bevels the face triangles with a corner on another face that lies off
  /// their face's plane (bevels within the face angle of a face).
  bool peel = true;
  /// Passes over the mesh, each on the one before's output: a second recovers more of the edges
  /// (the bevels beside a recovered stretch then see both faces) at the price of more thin
  /// triangles (bench_edges: about twice as many). At most kMaxPasses.
  int passes = 1;
  static constexpr int kMaxPasses = 8;
  [[nodiscard]] std::vector<std::string> validate() const;
};

struct SharpenStats {
  std::size_t bevel_triangles = 0;  ///< triangles of no face: between faces, near features
  std::size_t edge_vertices = 0;    ///< new vertices on the line where two faces meet
  std::size_t corner_vertices = 0;  ///< new vertices at the point where three faces meet
  std::size_t flipped = 0;          ///< edges flipped to run between two new vertices
  /// Slivers next to a face (a new vertex close to its bevel's side) flipped with the face's
  /// triangle to the diagonal through the new vertex.
  std::size_t tidied = 0;
  /// Bevel triangles left as they are because their new vertex would have made a triangle
  /// cross the mesh or fold onto a neighbour (in the last pass; bevel_triangles counts the
  /// first's, the other fields are summed over the passes).
  std::size_t refused = 0;
  /// Bevel triangles left as they are because one of their corners lies on a rounded blend
  /// between the faces (a fillet sampled across: it belongs to neither face and lies off both
  /// planes), summed over the passes.
  std::size_t rounded = 0;
};

/// Recovers the sharp edges and corners that `mesh` bevels (see above). Each new vertex is
/// appended to mesh.vertices and splits its bevel triangle in three; existing vertices never
/// move, so the measured samples stay where they were measured. The result stays manifold,
/// consistently oriented and free of self-intersections when the input is (a split or flip that
/// would cross or fold is refused); the topology (loops, components, genus) does not change.
/// Meshes with non-manifold edges are left unchanged. Cost: linear in the triangles (one
/// self-intersection check over the new triangles, repeated only where one is refused).
SharpenStats sharpen_edges(Mesh& mesh, const SharpenOptions& options = {});

}  // namespace scanmesh::recon
