// The profiler's geometry: camera intrinsics with OpenCV's distortion model, the laser plane,
// and the triangulation of a line's pixel positions into 3D points in the camera frame.
// SPDX-License-Identifier: MIT
#pragma once

#include <limits>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "scanmesh/drivers/line_profiler.hpp"
#include "scanmesh/drivers/profiler/extraction.hpp"

namespace scanmesh::drivers::profiler {

/// Camera intrinsics: frame size, matrix [fx 0 cx; 0 fy cy; 0 0 1] (pixels, pixel centres at
/// integers) and distortion coefficients in OpenCV's order (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3
/// s4 [tx ty]]]]: 0, 4, 5, 8, 12 or 14 values).
struct CameraIntrinsics {
  cv::Size size;
  cv::Matx33d matrix = cv::Matx33d::eye();
  std::vector<double> distortion;
};

/// The laser plane in the camera frame: the points X (mm) with normal . X = distance_mm, the
/// normal a unit vector, distance_mm > 0 (the camera's centre lies on its negative side).
struct LaserPlane {
  cv::Vec3d normal{0, 0, 1};
  double distance_mm = 0;
};

/// Everything a profiler needs to turn frames into profiles, and what the calibration measured.
struct ProfilerCalibration {
  CameraIntrinsics camera;
  LaserPlane plane;
  std::string source;  ///< the file it was read from ("" when made in memory): named in errors
  double reprojection_error_px = std::numeric_limits<double>::quiet_NaN();
  double plane_rms_mm = std::numeric_limits<double>::quiet_NaN();
};

/// The undistorted ray (x, y, 1) through pixel (u, v), exact (OpenCV's iterative undistortion
/// run to convergence). For a few points; Triangulator keeps a table for whole frames.
cv::Vec3d undistorted_ray(const CameraIntrinsics& camera, cv::Point2d pixel);

/// Pixel positions of a line -> points in the camera frame. Precomputes the undistorted ray of
/// every pixel centre (8 bytes per pixel; for up to five coefficients about 0.1 s for
/// 1280 x 1024 at construction, seconds for the longer models) and then interpolates between
/// the two pixel centres around each sub-pixel position: a few ns per point, no allocation
/// after the first profile.
class Triangulator {
 public:
  /// Points nearer than min_z_mm or farther than max_z_mm (along the optical axis) are
  /// kOverRange. Throws ConfigError for a bad camera or plane.
  Triangulator(const CameraIntrinsics& camera, const LaserPlane& plane, LineAxis axis,
               double min_z_mm = 0,
               double max_z_mm = std::numeric_limits<double>::infinity());

  /// positions: one per column (kColumns) or row (kRows) as LineExtractor gives them, NaN for
  /// none. `points` is resized to match; none -> an invalid marker (kNoTarget).
  void triangulate(const std::vector<float>& positions, std::vector<ProfilePoint>& points) const;

  const CameraIntrinsics& camera() const { return camera_; }
  const LaserPlane& plane() const { return plane_; }

 private:
  CameraIntrinsics camera_;
  LaserPlane plane_;
  LineAxis axis_;
  double min_z_mm_;
  double max_z_mm_;
  cv::Mat rays_;  ///< CV_32FC2: undistorted (x, y) of every pixel centre
};

/// Every problem of a camera model (size, focal lengths, principal point, coefficients), one
/// message each; empty when usable.
std::vector<std::string> camera_problems(const CameraIntrinsics& camera);
/// The same for a plane (unit normal, positive distance, finite).
std::vector<std::string> plane_problems(const LaserPlane& plane);

}  // namespace scanmesh::drivers::profiler
