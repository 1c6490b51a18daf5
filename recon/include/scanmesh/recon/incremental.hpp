// Incremental reconstruction: points arrive in batches while the scan runs; regions the scan has
// left are meshed and published as deltas with stable ids. Pure, deterministic, single-threaded.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "scanmesh/recon/mesh.hpp"
#include "scanmesh/recon/reconstruct.hpp"

namespace scanmesh::recon {

namespace detail {
class PublishedMesh;
}  // namespace detail

struct IncrementalOptions {
  /// The batch path's options, with the same meaning: cube mode and size, projection, front,
  /// normals, insertion, gap closing. The on-request passes (fill, denoise, sharpen) are not
  /// run by the incremental path (validate() refuses them).
  ReconstructOptions reconstruct;
  /// With an automatic cube, its edge is derived (auto_cube_size) from the spacing of the first
  /// `spacing_points` points of the sequence (all of them when fewer arrive before finish());
  /// those points wait in a buffer until then. [100, 10,000,000], default 4,096.
  std::size_t spacing_points = 4096;
  /// Edge of a block, in cubes: the unit of settling, meshing and re-opening. [8, 64], default
  /// 16 (a block must be wider than twice the front's reach).
  int block_cubes = 16;
  /// Settling and meshing are decided after every this many points of the sequence (never at
  /// the batch cuts): [1, 1,000,000], default 1,024.
  std::size_t settle_interval_points = 1024;
  /// Without a footprint, a block settles once no point has landed in it for this many points
  /// of the sequence. [0, 1e9], default 8,192.
  std::size_t settle_delay_points = 8192;
  /// With a footprint, a block settles once the footprint is farther than its radius plus this
  /// many cubes from the block. [0, 1000], default 6.
  double settle_margin_cubes = 6.0;
  /// At most this many blocks are meshed at one decision point (the rest wait for the next),
  /// which bounds the work done inside one add(). [1, 1,000,000], default 8.
  std::size_t max_blocks_per_step = 8;
  /// Reports every bad field at once (empty when valid).
  [[nodiscard]] std::vector<std::string> validate() const;
};

/// Where the sensor is measuring now: a point and a radius (input units).
struct Footprint {
  Vec3 centre = Vec3::Zero();
  double radius_mm = 0;
};

/// What the per-point sensor vectors given to add() are.
enum class SensorData : std::uint8_t {
  kPosition,   ///< the sensor's position when it measured the point
  kDirection,  ///< a vector from the point towards the sensor
};

/// What changed in the published mesh since the previous take_delta(). Ids are stable: a vertex
/// id always names the same position, a triangle id the same three vertex ids; a removed
/// triangle's id is never reused. Applying deltas in order (add the vertices, then the added
/// triangles, then drop the removed ids) rebuilds the published mesh exactly.
struct MeshDelta {
  std::uint32_t first_vertex = 0;  ///< id of vertices.front(); new ids are consecutive
  std::vector<Vec3> vertices;
  std::vector<std::uint32_t> added_ids;  ///< ascending
  std::vector<Triangle> added;           ///< vertex ids, counter-clockwise seen from outside
  /// Triangles published by an earlier delta and removed since (ascending). A triangle added
  /// and removed between two calls appears in neither list.
  std::vector<std::uint32_t> removed;
  /// The boundary loops of the published mesh that pass through a vertex of an added or
  /// removed triangle, as vertex-id cycles in the direction their triangles run.
  std::vector<std::vector<std::uint32_t>> boundary_loops;
  [[nodiscard]] bool empty() const {
    return vertices.empty() && added.empty() && removed.empty();
  }
};

/// The published mesh at one moment, sharing its storage (fixed-size chunks) with the
/// reconstructor and other snapshots: taking one copies a pointer per chunk, not the mesh; the
/// reconstructor copies a chunk before it changes one a snapshot still holds. Immutable, and
/// safe to read from another thread while the reconstructor goes on.
class MeshSnapshot {
 public:
  static constexpr std::size_t kChunk = 4096;
  static constexpr std::uint32_t kRemoved = 0xffffffffu;  ///< the vertex ids of a removed slot

  [[nodiscard]] std::size_t vertex_count() const { return vertex_count_; }  ///< ids [0, n)
  [[nodiscard]] const Vec3& vertex(std::uint32_t id) const {
    return (*vertices_[id / kChunk])[id % kChunk];
  }
  [[nodiscard]] std::size_t triangle_slots() const { return triangle_slots_; }  ///< ids [0, n)
  /// A removed triangle's slot holds {kRemoved, kRemoved, kRemoved}.
  [[nodiscard]] const Triangle& triangle(std::uint32_t id) const {
    return (*triangles_[id / kChunk])[id % kChunk];
  }
  [[nodiscard]] bool alive(std::uint32_t id) const { return triangle(id)[0] != kRemoved; }
  [[nodiscard]] std::size_t triangle_count() const { return triangle_count_; }  ///< alive ones
  /// A compact copy: the vertices used by live triangles in id order, the live triangles in id
  /// order; `vertex_ids`, when given, receives each vertex's id. O(mesh).
  [[nodiscard]] Mesh to_mesh(std::vector<std::uint32_t>* vertex_ids = nullptr) const;

 private:
  friend class detail::PublishedMesh;
  using VertexChunk = std::vector<Vec3>;
  using TriangleChunk = std::vector<Triangle>;
  std::vector<std::shared_ptr<const VertexChunk>> vertices_;
  std::vector<std::shared_ptr<const TriangleChunk>> triangles_;
  std::size_t vertex_count_ = 0, triangle_slots_ = 0, triangle_count_ = 0;
};

/// Counters of the reconstructor's state and work. Seconds are filled only when the caller
/// gave a clock (the core reads none).
struct IncrementalStats {
  std::size_t points_in = 0;       ///< points given to add()
  std::size_t pending_points = 0;  ///< waiting for the cube size (the first spacing_points)
  std::size_t far_points = 0;      ///< out of the grid's reach (stray readings): outliers
  double cube_mm = 0;              ///< 0 until decided
  std::size_t cubes_kept = 0;      ///< occupied cubes (one kept point each)
  std::size_t blocks_open = 0, blocks_settled = 0, blocks_meshed = 0;
  /// Points in cubes of blocks not meshed yet: the lag between measuring and meshing.
  std::size_t unmeshed_cubes = 0;
  std::size_t vertices = 0;        ///< published vertex ids
  std::size_t triangles = 0;       ///< live published triangles
  std::size_t meshing_steps = 0;   ///< times meshing ran
  std::size_t meshed_blocks_total = 0;  ///< blocks meshed, counting every re-meshing
  std::size_t reopened_blocks = 0;  ///< meshed blocks re-opened by points in empty cubes
  std::size_t deltas = 0;           ///< take_delta() calls that returned a non-empty delta
  /// Seconds per stage ("reduce", "settle", "mesh", "finish", ...), in first-use order.
  std::vector<std::pair<std::string, double>> seconds;
  /// Seconds from a block's settling to its triangles being published: the largest, and the
  /// 99th percentile over every block meshed so far.
  double settle_to_mesh_max_seconds = 0, settle_to_mesh_p99_seconds = 0;
};

struct IncrementalResult {
  Mesh mesh;  ///< only vertices used by triangles, in id order; triangles in id order
  std::vector<std::uint32_t> vertex_ids;  ///< the published id of each mesh vertex
  /// Kept points that are no vertex of the final mesh, then the far points.
  std::vector<Vec3> outliers;
  std::size_t far_points = 0;
  IncrementalStats stats;
};

/// Meshes a scan while it runs. add() takes the points in arrival order; a region is meshed
/// once it has settled (the footprint, or without one the point sequence, has left it) and
/// published through take_delta() and snapshot(); finish() meshes what is left.
///
/// Guarantees: the same points in the same order give the same deltas and the same final mesh
/// whatever the batch cuts (when footprints are given, they are part of the input). Vertex and
/// triangle ids never change meaning. snapshot() is manifold and consistently oriented at any
/// moment. finish() gives the batch path's guarantees: manifold, consistently oriented, no
/// crossing triangles, every kept point a vertex or an outlier.
///
/// How (recon/NOTEBOOK.md has the measurements): cube reduction is incremental (sparse hashed
/// cubes in blocks of block_cubes^3, keep-nearest-to-centre as the batch path, per-cube moments
/// for the projection, no raw point kept once the cube size is known); settling and re-opening
/// are per block; a job meshes the kept points of ready blocks with the advancing front
/// continuing the published triangles around them (their neighbours' borders), so blocks join
/// without seams, and publishes the difference. finish() meshes the rest, closes the sampling
/// gaps between jobs (the batch path's gap closing, over the whole mesh) and turns closed
/// components outward. Not done incrementally: the batch path's insertion of left-out points,
/// slit zipping, untangling, feature restoring and border peeling.
///
/// Not thread-safe: one thread calls it (snapshots may be read from any thread).
class IncrementalReconstructor {
 public:
  /// A monotonic clock in seconds, for stats().seconds only (optional).
  using SecondsClock = std::function<double()>;
  /// Throws ConfigError listing every bad option.
  explicit IncrementalReconstructor(const IncrementalOptions& options = {},
                                    SecondsClock clock = {});
  ~IncrementalReconstructor();
  IncrementalReconstructor(IncrementalReconstructor&&) noexcept;
  IncrementalReconstructor& operator=(IncrementalReconstructor&&) noexcept;
  IncrementalReconstructor(const IncrementalReconstructor&) = delete;
  IncrementalReconstructor& operator=(const IncrementalReconstructor&) = delete;

  /// A batch of points in arrival order. A batch with a non-finite coordinate is refused whole
  /// (GeometryError naming its index in the batch), nothing of it taken. Cost: O(batch) plus
  /// the meshing of the blocks that settle.
  void add(std::span<const Vec3> points, const std::optional<Footprint>& footprint = std::nullopt);
  /// The same, with one sensor vector per point (orients the surface towards its sensors).
  void add(std::span<const Vec3> points, std::span<const Vec3> sensor, SensorData kind,
           const std::optional<Footprint>& footprint = std::nullopt);
  /// The caller says the whole scan, or the region in `box`, is complete: those blocks settle
  /// now and are meshed (until points arrive in them again).
  void settle_all();
  void settle(const Eigen::AlignedBox3d& box);
  /// What changed since the previous call. O(delta).
  MeshDelta take_delta();
  /// The published mesh now, without copying it (see MeshSnapshot).
  [[nodiscard]] MeshSnapshot snapshot() const;
  /// Settles and meshes everything left and returns the final mesh (also published as a
  /// delta). Further add() calls are refused (ConfigError).
  IncrementalResult finish();
  [[nodiscard]] IncrementalStats stats() const;

 private:
  struct State;
  std::unique_ptr<State> s_;
};

}  // namespace scanmesh::recon
