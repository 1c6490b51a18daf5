// Local surface frames of a point set: PCA normals (Eigen), consistently oriented, plus the
// local spacing and flatness the advancing front uses for its adaptive radius and seeds.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon {

struct LocalFrames {
  std::vector<Eigen::Vector3f> normal;  ///< unit normals, consistently oriented per component
  std::vector<float> spacing;           ///< mean distance to the 6 nearest neighbours
  std::vector<float> flatness;          ///< lambda0 / (lambda0 + lambda1 + lambda2), 0 = planar
};

struct NormalOptions {
  int neighbours = 12;  ///< k of the PCA neighbourhood (>= 6)
  /// Sensor position: when given, every normal points towards it (single-view scans).
  std::optional<Vec3> view_point;
};

/// `grid` must index `points` with a cell of at least ~2x the typical spacing. The neighbours
/// of a point are the `neighbours` nearest among the points of the 27 grid cells around it
/// (ties broken by the lower index); 125 and then 343 cells when 27 hold too few.
LocalFrames estimate_frames(std::span<const Vec3> points, const PointGrid& grid,
                            const NormalOptions& options = {});

namespace detail {

/// Principal axes of a 3x3 covariance matrix.
struct PlaneFit {
  Vec3 normal;       ///< unit eigenvector of the smallest eigenvalue (sign arbitrary)
  Vec3 eigenvalues;  ///< ascending
};

/// Closed-form eigen-decomposition (Eigen's computeDirect); falls back to the iterative solver
/// when the two smallest eigenvalues are too close for the closed form to resolve the normal.
PlaneFit plane_normal(const Eigen::Matrix3d& cov);

}  // namespace detail

}  // namespace scanmesh::recon
