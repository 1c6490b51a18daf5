// Feature-preserving noise removal on request: a scanner's noise (a few hundredths of a mm on a
// laser line) leaves a meshed flat face rough and bends every plane fitted to it. Following
// Zheng et al., "Bilateral Normal Filtering for Mesh Denoising" (IEEE TVCG 2011), the triangles'
// normals are first averaged with those of the triangles around them, weighted by area, by
// distance and by how far apart the normals are (a Gaussian in each), so that a face's normals
// agree while two faces meeting at an edge keep theirs; then the vertices are moved so that
// each triangle lies in the plane its filtered normal gives (Sun et al.'s vertex update, the
// least-squares fit of the vertices to those planes). Pure: no I/O, no globals.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon {

struct DenoiseOptions {
  /// The normals' range: two triangles whose normals are this far apart (degrees) weigh
  /// exp(-1/2) of a parallel one in each other's average, twice as far exp(-2). Above the
  /// noise's own normal scatter, below the features to keep. 0 (the default): kAutoFactor times
  /// the median angle between the normals of two triangles sharing an edge (the noise's
  /// scatter, which a scan's sharp edges are too few to move), at most kAutoMaxDeg.
  double feature_deg = 0;
  static constexpr double kAutoFactor = 2, kAutoMaxDeg = 15;
  /// A range under this (degrees) is no noise: the mesh is left exactly as it is.
  static constexpr double kNoNoiseDeg = 0.01;
  /// Rounds of the normal filter: each averages over the triangles sharing a corner, so n
  /// rounds reach about n rings.
  int normal_iterations = 4;
  /// Rounds of the vertex update: each moves a vertex towards the planes of its triangles.
  int vertex_iterations = 10;
  /// A vertex moves at most this share of the mean length of its edges (the noise is a small
  /// share of the spacing; a larger move would be a feature flattened, not noise removed).
  double max_move = 0.5;
  /// The scan's noise (standard deviation, mesh units); 0 (the default): measured on the
  /// vertices, as the shell's thickness about quadric fits through their 20 nearest neighbours
  /// (curvature absorbed; reduce.hpp, estimate_spacing). Where it cannot be measured (0), nothing
  /// moves.
  double noise_mm = 0;
  /// A vertex moves at most this many times the noise: removing noise moves a sample by about
  /// the noise; a larger move flattens what the scan measured (a coarsely sampled curve).
  double noise_moves = 3;
  static constexpr int kMaxIterations = 100;
  [[nodiscard]] std::vector<std::string> validate() const;
};

struct DenoiseStats {
  std::size_t moved = 0;    ///< vertices moved
  /// Vertices left where they were because their move would have tilted one of their triangles
  /// by more than 60 degrees, made an angle under 1 degree, or a crossing.
  std::size_t refused = 0;
  std::size_t clamped = 0;  ///< vertices whose move was cut to max_move
  double mean_move = 0;     ///< over the moved vertices, in mesh units
  double max_move = 0;
  /// The median angle between the normals of two triangles sharing an edge, before (degrees).
  double noise_deg = 0;
  double feature_deg = 0;  ///< the normals' range used (degrees)
  double noise_mm = 0;     ///< the noise used (mesh units; see DenoiseOptions::noise_mm)
};

/// Removes the noise of `mesh` (see above) in place. Only vertex positions change: the
/// triangles, and so the topology (loops, components, genus) and the orientation, stay as they
/// are, and no move is made that would make two triangles cross (each is checked against the
/// mesh around it, as the reconstruction's restored features are). A boundary vertex moves
/// like any other, towards the planes of its triangles. Cost: linear in the triangles.
/// Throws std::invalid_argument for bad options or a triangle naming a missing vertex, and
/// GeometryError (scanmesh/common/error.hpp) for a vertex of a triangle whose coordinates are
/// not finite or beyond +-1e100.
DenoiseStats denoise_mesh(Mesh& mesh, const DenoiseOptions& options = {});

}  // namespace scanmesh::recon
