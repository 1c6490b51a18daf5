// Sampling statistics of a point cloud and the reference method's cube reduction.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon {

/// Measured sampling of a cloud, from the neighbourhoods of an evenly spread subset of points.
struct SpacingEstimate {
  double nearest_mm = 0;  ///< median distance to the nearest neighbour
  /// Median distance to the nearest neighbour lying more than 45 degrees away from the direction
  /// of the nearest one: the spacing across scan lines of a raster scan (equals about
  /// nearest_mm for isotropic sampling, the line spacing for anisotropic raster scans).
  double cross_mm = 0;
  /// Lower quartile of the RMS residual of a quadric height field fitted to the 20 nearest
  /// neighbours (curvature absorbed): the thickness of the sampled shell (noise, registration
  /// error of merged views).
  double thickness_mm = 0;
  /// Only when the shell is thick (thickness_mm above 0.3 cross_mm; 0 otherwise): the same
  /// statistic over the 12 nearest neighbours. Noise gives about 0.85 of thickness_mm (a fit
  /// of fewer points leaves less residual), structure (features, thin walls) much less.
  double thickness_few_mm = 0;
  /// Only when the shell is thick (0 otherwise): the median, over the fits of thickness_mm, of
  /// their mean absolute residual over their RMS: about 0.80 for noise, 1 for two layers.
  double thickness_shape = 0;
  std::size_t sampled = 0;  ///< points the estimate is based on
};

/// Estimates the sampling from about `max_samples` evenly spread points (every
/// (n / max_samples)-th index). Deterministic. Fewer samples are faster (1500 keep the medians and
/// the quartile within about 3 % on real scans), but the cube size follows these statistics and
/// everything downstream follows the cube size.
SpacingEstimate estimate_spacing(std::span<const Vec3> points, std::size_t max_samples = 4000);

/// Cube edge derived from the measured sampling: large enough to make raster scans about
/// isotropic and to collapse a noisy multi-view shell into one layer, close to the spacing on
/// clean evenly sampled clouds.
double auto_cube_size(const SpacingEstimate& s);

/// Cube reduction as in the reference method: space is cut into cubes of edge `cube`; in each
/// occupied cube the point nearest to the cube centre is kept. Returns the kept indices in
/// ascending order. Deterministic (ties broken by the lower index).
std::vector<std::uint32_t> cube_reduce(std::span<const Vec3> points, double cube);

/// Minimum-separation thinning after cube reduction: cube reduction can keep two points a
/// fraction of a cube apart where the sampled shell straddles a cube face (merged views make
/// such a shell). Points are visited in the given priority order (most central in its cube
/// first) and dropped when a kept point lies within `min_distance`. Returns kept indices into
/// `points`, ascending.
std::vector<std::uint32_t> thin_min_distance(std::span<const Vec3> points,
                                             std::span<const std::uint32_t> priority,
                                             double min_distance);

/// Moves each representative onto the least-squares plane of the input points within `radius`
/// of it (first-order MLS projection), so a noisy multi-view shell becomes one thin layer.
/// With `second_order`, onto the least-squares quadric height field over that plane instead,
/// where at least 10 points determine one (second-order MLS: the plane through a curved
/// surface's points lies about radius^2 / (4 R) inside it, which the quadric does not).
/// A point moves at most `max_move`; points with fewer than 6 neighbours stay where they are.
/// `features`, when given, receives the positions in `representatives` (ascending) whose ball
/// is not flat: its points' RMS distance from their plane is above `max_plane_rms` and no
/// quadric explains them. Such a ball straddles a sharp edge, a corner or a step, and its plane
/// cuts across the feature: the point moves off the surface there (recon/README, Pipeline).
std::vector<Vec3> project_to_local_planes(
    std::span<const Vec3> input, std::span<const std::uint32_t> representatives, double radius,
    double max_move, bool second_order = true,
    double max_plane_rms = std::numeric_limits<double>::infinity(),
    std::vector<std::uint32_t>* features = nullptr);

/// cube_reduce followed by thin_min_distance(0.65 * cube) in cube-centre order (squared distance
/// to the own cube centre in cube units, ascending; index breaking ties). Only representatives
/// of neighbouring cubes can clash, so this runs in linear time.
std::vector<std::uint32_t> cube_reduce_thin(std::span<const Vec3> points, double cube);

/// Stray points far outside the body of the cloud: a glitched reading at 1e9, a sensor's
/// out-of-range sentinel. One of them stretches the cloud's extent so far that no grid at the
/// sampling's resolution can hold it (21 bits a cell coordinate), and the whole scan would fail.
/// The body is the box of the 10th to 90th percentile of each coordinate (from an evenly spread
/// sample of at most 4,096 points), widened on every side by its largest width. Only when the
/// whole extent exceeds `max_extent_ratio` times the body's surface-sampling distance
/// (sqrt(face area / points)) are the points outside that box returned; otherwise none. Returns
/// indices, ascending. Clouds that fit, however large, are never split.
std::vector<std::uint32_t> far_points(std::span<const Vec3> points,
                                      double max_extent_ratio = 1e5);

}  // namespace scanmesh::recon
