// Topology and quality report of a triangle mesh (what `scanmesh inspect` prints and what the
// tests assert on). Pure: no I/O.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon {

/// A boundary loop's vertices, in the direction its triangles run along it (for a consistently
/// oriented mesh); `closed` is false only for a chain that dead-ends at non-manifold edges.
struct BoundaryLoop {
  std::vector<std::uint32_t> vertices;
  bool closed = true;
};

struct MeshReport {
  std::size_t vertices = 0;            ///< vertices in the vertex array
  std::size_t referenced_vertices = 0; ///< vertices used by at least one triangle
  std::size_t triangles = 0;
  std::size_t degenerate_triangles = 0;  ///< repeated index or zero area
  std::size_t duplicate_triangles = 0;   ///< same vertex set as an earlier triangle
  std::size_t edges = 0;
  std::size_t boundary_edges = 0;        ///< edges in exactly one triangle
  std::size_t non_manifold_edges = 0;    ///< edges in three or more triangles
  std::size_t non_manifold_vertices = 0; ///< vertices whose triangles form more than one fan
  std::size_t inconsistent_edges = 0;    ///< manifold edges used twice in the same direction
  bool orientation_consistent = true;    ///< inconsistent_edges == 0
  std::size_t boundary_loops = 0;
  std::vector<std::size_t> boundary_loop_lengths;  ///< edges per loop, descending
  /// Length of each loop (sum of its edges' lengths, in mesh units), same order as the edges.
  std::vector<double> boundary_loop_perimeters;
  std::size_t components = 0;            ///< edge-connected components of triangles
  long euler_characteristic = 0;         ///< V - E + F over referenced vertices
  /// Genus from chi = 2c - 2g - b (c components, b boundary loops); exact for manifold meshes.
  long genus = 0;
  double min_angle_deg = 0, max_angle_deg = 0, mean_angle_deg = 0;
  /// Fraction of triangles whose smallest interior angle is below 10 and 20 degrees.
  double frac_min_angle_below_10 = 0, frac_min_angle_below_20 = 0;
  double mean_edge_length = 0, max_edge_length = 0;
  double signed_volume = 0;              ///< > 0 when closed and outward oriented
  std::vector<BoundaryLoop> loops;       ///< the loops themselves, with analyze(mesh, true)
};

/// With keep_loops the report also lists every boundary loop's vertices.
MeshReport analyze(const Mesh& mesh, bool keep_loops = false);

/// The order in which a report lists loops (boundary_loop_lengths and the arrays beside it):
/// positions into `loops`, most edges first, ties in the order given (a stable order).
std::vector<std::size_t> loop_report_order(const std::vector<BoundaryLoop>& loops);

/// A loop's width: the largest distance between two of its vertices (a round hole's diameter),
/// in mesh units; O(n^2). The search stops as soon as a pair is farther apart than `stop_above`
/// and returns that pair's distance. A non-finite coordinate gives infinity.
double loop_width(const Mesh& mesh, std::span<const std::uint32_t> loop,
                  double stop_above = std::numeric_limits<double>::infinity());

/// Whether a mesh's vertices sample its surface as a scan does, so that a reconstruction can
/// take them as its points: at least 5,000 of them, no edge longer than 6 mean edges, and
/// at most 10 % of the triangles with an angle under 20 degrees. A CAD export fails it: few
/// vertices, long edges across flat faces, slivers; its flat faces would have no points, so
/// its surface is to be sampled instead. Measured share of
/// such thin triangles: the Stanford scans' meshes 0.6-4.3 % (bunny at full and half
/// resolution, igea), the casting's CAD mesh 17 % (from its vertices genus 8 with 5 loops, from
/// 100k points on its surface exactly genus 9 and closed), fandisk 0 %. Longest over mean edge:
/// 2.0-4.0 on those scans' meshes (igea 4.0), the casting 2.2, fandisk 2.6.
bool scan_like_vertices(const MeshReport& r);

}  // namespace scanmesh::recon
