// Calibration helpers: a sphere of known diameter fitted to a scan of a calibration sphere (its
// residual and the mounting offset it implies), a plane fitted to a scan of a flat reference (its
// flatness), and the age rule a scan checks before it starts. Pure.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <optional>
#include <span>
#include <string>

#include "scanmesh/acquisition/sensor_model.hpp"

namespace scanmesh::acq {

struct SphereFit {
  Vec3 centre_mm{};
  double radius_mm = 0;
  double rms_mm = 0;       ///< RMS of |p - centre| - radius
  double max_abs_mm = 0;   ///< largest |residual|
  std::size_t points = 0;  ///< points used (after rejecting outliers)
  std::size_t rejected = 0;
  int iterations = 0;
};

/// Least-squares sphere through `points` (algebraic fit, then Gauss-Newton on the geometric
/// distance). With `known_radius_mm` only the centre is fitted. Points farther than
/// `reject_sigma` RMS residuals from the sphere are dropped and the fit redone (once).
/// Throws GeometryError for fewer than 4 points (3 with a known radius) or a degenerate set.
SphereFit fit_sphere(std::span<const Vec3> points,
                     std::optional<double> known_radius_mm = std::nullopt,
                     double reject_sigma = 4.0);

/// What a scan of a calibration sphere at a known position says about the sensor's mounting:
/// the translation to apply to the mount (in the carriage frame, valid for a scan at table angle
/// 0) so that the measured centre lands on the known one, with the fit's quality.
struct MountCheck {
  SphereFit fit;
  Vec3 mount_correction_mm{};  ///< known centre - fitted centre
  Calibration corrected;       ///< the calibration with the correction applied
};
MountCheck check_mount(std::span<const Vec3> points, double sphere_diameter_mm,
                       const Vec3& known_centre_mm, const Calibration& used);

struct PlaneFit {
  Vec3 normal{0, 0, 1};    ///< unit
  Vec3 point_mm{};         ///< centroid of the points used
  double rms_mm = 0;       ///< RMS distance to the plane
  double flatness_mm = 0;  ///< max - min signed distance of the points used
  std::size_t points = 0;
  std::size_t rejected = 0;
};

/// Total least squares plane (PCA); points farther than `reject_sigma` RMS from it are dropped
/// and the fit redone (once). Throws GeometryError for fewer than 3 points or collinear ones.
PlaneFit fit_plane(std::span<const Vec3> points, double reject_sigma = 4.0);

/// Why a scan must not start with this calibration ("missing", "made 40 days ago, limit 30"),
/// or nullopt when it may. `made`: when the calibration was made (nullopt: none); `max_age` 0:
/// no limit.
std::optional<std::string> calibration_problem(
    std::optional<std::chrono::system_clock::time_point> made,
    std::chrono::system_clock::time_point now, std::chrono::hours max_age);

}  // namespace scanmesh::acq
