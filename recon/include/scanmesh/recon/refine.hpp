// Inserting the points the advancing front left out into the finished mesh.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "scanmesh/recon/front.hpp"
#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/normals.hpp"

namespace scanmesh::recon {

struct RefineOptions {
  bool enabled = true;
  /// Triangles are looked for around used vertices within this many local spacings of the point.
  double search_factor = 2.5;
  /// Largest distance from the point to the plane of the triangle it goes into, in local
  /// spacings of the point: a bevel across a sharp edge leaves its feature row about half a
  /// spacing above it.
  double max_height_factor = 1.0;
  /// Largest angle between the triangle's normal and the point's (signed) normal.
  double max_normal_deviation_deg = 75;
  /// Passes over the points still left out (an insertion can bring a neighbour within reach).
  int rounds = 2;
  /// Flip edges around the inserted points (bending / Delaunay criterion).
  bool flip = true;
  /// Triangles with a corner under this many degrees (slivers, mostly from closing gaps and
  /// fan repairs) get the same flips; 0 = off.
  double sliver_deg = 10;
  [[nodiscard]] std::vector<std::string> validate() const;
};

struct RefineStats {
  std::size_t inserted = 0;     ///< points put into the mesh
  std::size_t edge_splits = 0;  ///< of them, by splitting an edge (the others split a triangle)
  std::size_t flips = 0;        ///< edges flipped afterwards (all)
  std::size_t sliver_flips = 0; ///< of them, to mend slivers
  std::size_t slivers = 0;      ///< triangles found with a corner under sliver_deg
};

/// Puts points the front never reached (`front.outliers`) into the mesh when they lie just
/// off it: above a triangle that cuts a sharp edge (the feature row the front bridged), or
/// inside a flat stretch the front covered with larger triangles. Each such point splits the
/// nearest triangle whose plane it lies close to, with its normal agreeing (or the edge it is
/// near, with the triangle across it), so the mesh stays manifold and keeps its orientation and
/// topology. Then the edges around the new vertices are flipped where that lowers the total
/// bending (the sum over edges of length x angle between the normals of the two triangles,
/// Dyn-Levin-Rippa's data-dependent criterion, which turns edges along a sharp feature); on flat
/// stretches the Delaunay criterion decides. `front.triangles`, `front.state` and
/// `front.outliers` are updated. `grid` indexes `points`. The local spacing is the front's
/// capped one (`front.spacing`) where given, else `frames.spacing`. Deterministic.
RefineStats insert_unused_points(std::span<const Vec3> points, const LocalFrames& frames,
                                 const PointGrid& grid, FrontResult& front,
                                 const RefineOptions& options = {});

}  // namespace scanmesh::recon
