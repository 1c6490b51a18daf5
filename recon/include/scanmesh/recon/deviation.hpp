// Distances between a mesh (or points) and a reference surface, as inspection software reports
// them. Pure: no I/O.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon {

struct DistanceStats {
  std::size_t count = 0;
  double mean = 0, rms = 0, p95 = 0, max = 0;
};

/// Point-to-triangle distance queries against a fixed mesh (BVH or grid inside).
class SurfaceDistance {
 public:
  explicit SurfaceDistance(const Mesh& surface);
  ~SurfaceDistance();
  SurfaceDistance(SurfaceDistance&&) noexcept;
  SurfaceDistance& operator=(SurfaceDistance&&) noexcept;
  /// Unsigned distance from p to the nearest point of the surface.
  [[nodiscard]] double distance(const Vec3& p) const;
  /// Signed: positive on the side the nearest triangle's normal points to.
  [[nodiscard]] double signed_distance(const Vec3& p) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

DistanceStats stats_of(std::vector<double> values);

struct DeviationReport {
  DistanceStats mesh_to_ref;   ///< sampled over the mesh (vertices and triangle samples)
  DistanceStats ref_to_mesh;   ///< sampled over the reference
  DistanceStats hausdorff() const;  ///< max of both (only max is meaningful)
  std::vector<double> vertex_signed_distance;  ///< per mesh vertex, signed, to the reference
};

/// Symmetric deviation. Each side is sampled at its vertices plus the centroids of its triangles.
DeviationReport deviation(const Mesh& mesh, const Mesh& reference);

}  // namespace scanmesh::recon
