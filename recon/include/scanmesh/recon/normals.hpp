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
/// `towards_sensor`, when it has one entry per point, is a vector from each point towards the
/// sensor that measured it (a direction, or the sensor position minus the point). The
/// propagation still makes the normals consistent (it is more reliable than a per-point sign at
/// grazing angles); then each part it oriented as one piece is turned to face its sensors: by
/// the sum of n . unit(towards_sensor) over its points. Without it, a part that is not closed
/// faces +z where it is highest. options.view_point, when set, orients every normal towards it
/// instead (no propagation, `towards_sensor` unused).
LocalFrames estimate_frames(std::span<const Vec3> points, const PointGrid& grid,
                            const NormalOptions& options = {},
                            std::span<const Vec3> towards_sensor = {});

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
