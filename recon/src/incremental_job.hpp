// One meshing job of the incremental path: the kept points of a group of settled blocks are
// meshed by the advancing front continuing the published mesh around them (their neighbours'
// borders), and the difference is published with stable ids. Also the closing passes of
// finish().
// SPDX-License-Identifier: MIT
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "scanmesh/recon/reconstruct.hpp"
#include "chunked.hpp"
#include "incremental_grid.hpp"
#include "incremental_store.hpp"

namespace scanmesh::recon::detail {

struct JobStats {
  std::size_t jobs = 0;
  std::size_t context_triangles = 0;  ///< published triangles the jobs continued (summed)
  std::size_t removed = 0;            ///< published triangles the jobs removed (repairs, re-opening)
  std::size_t gaps_closed = 0;        ///< sampling gaps closed by finish()
  std::size_t flipped = 0;            ///< closed components turned outward by finish()
};

class JobMesher {
 public:
  JobMesher(const ReconstructOptions& options, CubeGrid& grid, PublishedMesh& mesh)
      : opt_(options), grid_(grid), mesh_(mesh) {}

  /// Meshes the blocks `job` (ascending ids; each settled, its neighbours settled or meshed).
  /// Triangles touching a vertex of these blocks (a re-opened block) are removed first.
  void run(std::span<const std::uint32_t> job);
  /// finish(): closes the sampling gaps left between jobs (the batch path's gap closing) and
  /// turns closed components outward.
  void close();
  /// The boundary loops through `touched` vertices (ascending), each once as a vertex cycle in
  /// the direction its triangles run, starting at its smallest id; loops ascending.
  [[nodiscard]] std::vector<std::vector<std::uint32_t>> loops_through(
      std::span<const std::uint32_t> touched) const;
  /// Whether the kept point of cube c is a vertex of a live triangle.
  [[nodiscard]] bool used(std::uint32_t vertex) const;
  [[nodiscard]] const JobStats& stats() const { return stats_; }
  [[nodiscard]] std::size_t heap_bytes() const;

 private:
  std::uint32_t publish_vertex(std::uint32_t cube, const Vec3& p, const Eigen::Vector3f& normal,
                               float spacing);
  std::uint32_t publish_triangle(const Triangle& t);
  /// The sectors (open fans) of v's triangles `fan` (every live triangle with v): more than one
  /// where they do not make one fan.
  [[nodiscard]] int sectors(std::span<const std::uint32_t> fan, std::uint32_t v) const;
  /// The live triangles listed under block b (the list is compacted on the way).
  const std::vector<std::uint32_t>& live_triangles(std::uint32_t b);
  /// Recomputes the boundary successor of `vertices` (any order, repeats allowed) from their
  /// fans.
  void update_boundary(std::vector<std::uint32_t> vertices);

  const ReconstructOptions& opt_;
  CubeGrid& grid_;
  PublishedMesh& mesh_;
  // Per published vertex.
  Chunked<std::uint32_t> vertex_cube_;
  Chunked<Eigen::Vector3f> vertex_normal_;
  Chunked<float> vertex_spacing_;
  Chunked<std::uint32_t> vertex_uses_;  // live triangles using it
  /// Scratch per vertex id (run(): 0 not looked at, 1 within the context's band, 2 not;
  /// update_boundary(): 1 a vertex of the block at hand),
  /// all zero between calls (run() lists the entries it set in near_set_).
  std::vector<std::uint8_t> near_;
  std::vector<std::uint32_t> near_set_;
  // Per block: the published triangles with a vertex in it (dead ones dropped lazily).
  std::vector<std::vector<std::uint32_t>> block_tris_;
  /// Per boundary vertex: the next vertex along its loop (kNoId once it is not on one).
  KeyTable boundary_next_;
  double max_edge2_ = 0;  // the longest published edge so far, squared (the context's band)
  JobStats stats_;
};

}  // namespace scanmesh::recon::detail
