// Calibration of a camera + line-laser profiler: the camera's intrinsics and distortion from
// chessboard images, then the laser plane from the line seen on the chessboard at several poses;
// with a report of what was used, rejected and why. Calibration files are OpenCV YAML.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <filesystem>
#include <limits>
#include <map>
#include <opencv2/core.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/drivers/profiler/camera.hpp"
#include "scanmesh/drivers/profiler/extraction.hpp"

namespace scanmesh::drivers::profiler {

/// A chessboard: pattern = inner corners (columns x rows, OpenCV's patternSize), square edge in
/// mm.
struct ChessboardSpec {
  cv::Size pattern{9, 6};
  double square_mm = 10;
  /// Throws ConfigError unless at least 3 x 3 corners (one side may be 2) and square_mm > 0.
  void validate() const;
};

/// The board's inner corners, sub-pixel (cv::findChessboardCorners, cv::cornerSubPix), in
/// OpenCV's order; empty when the board is not found. `gray`: CV_8UC1.
std::vector<cv::Point2f> find_chessboard(const cv::Mat& gray, cv::Size pattern);

/// An image with the name it is reported under (its file name).
struct NamedImage {
  std::string name;
  cv::Mat gray;        ///< CV_8UC1
  cv::Mat background;  ///< laser images: the same pose with the laser off (or empty)
};

/// How an image served: used, or rejected and why.
struct ImageUse {
  std::string image;
  bool used = false;
  std::string reason;                                       ///< why it was rejected
  double error_px = std::numeric_limits<double>::quiet_NaN();  ///< camera: its reprojection RMS
  std::size_t points = 0;                                   ///< laser: line points it gave
};

/// A board pose: camera_from_board as OpenCV's rvec (Rodrigues) and tvec (mm).
struct BoardPose {
  cv::Vec3d rvec;
  cv::Vec3d tvec;
};

struct CameraCalibrationResult {
  CameraIntrinsics camera;
  double rms_px = 0;                        ///< reprojection error over the used images
  std::vector<ImageUse> images;             ///< every image, in the order given
  std::map<std::string, BoardPose> poses;   ///< of every used image, by name
};

/// Options of calibrate_camera.
struct CameraCalibrationOptions {
  /// Fit k3 too (cv::calibrateCamera's default); false fixes it at 0 (CALIB_FIX_K3), which
  /// suits ordinary lenses and few images. Default false.
  bool fit_k3 = false;
  /// An image whose reprojection RMS exceeds this many times the median (and 0.5 px) is
  /// rejected and the camera calibrated again without it. Default 3.
  double outlier_ratio = 3;
};

/// Calibrates the camera from the chessboard images (cv::calibrateCamera). `where` names the
/// images' folder in errors. Throws InputError when the board is found in none of the images
/// (naming the folder and the pattern) or in fewer than 3.
CameraCalibrationResult calibrate_camera(const std::vector<NamedImage>& images,
                                         const ChessboardSpec& board, const std::string& where,
                                         const CameraCalibrationOptions& options = {});

struct LaserPlaneResult {
  LaserPlane plane;
  std::size_t points = 0;   ///< line points on the boards
  std::size_t inliers = 0;  ///< kept by the outlier rejection
  double rms_mm = 0;        ///< distance of the inliers from the plane
  double max_mm = 0;
  std::vector<ImageUse> images;
};

/// Fits the laser plane to the line seen on the chessboard: for each laser image the board's
/// pose comes from the chessboard image of the same name (calibrate_camera's poses) or, if
/// there is none, from the board found in its laser-off image or in the laser image itself
/// (cv::solvePnP); the line is extracted (after subtracting the laser-off image when there is
/// one: without it, only columns where the line stands out from the squares give points), kept
/// on the squares (the inner corners' area grown by one square), and each pixel's ray is
/// intersected with the board's plane. The plane is fitted to all points by least squares with iterative rejection
/// of points beyond 3 standard deviations. Throws InputError (naming `where`) when fewer than two
/// images give points or the points do not span a plane (all poses alike).
LaserPlaneResult calibrate_laser_plane(const std::vector<NamedImage>& laser_images,
                                       const CameraCalibrationResult& camera,
                                       const ChessboardSpec& board,
                                       const ExtractionOptions& extraction,
                                       const std::string& where);

/// Least-squares plane through points with iterative rejection beyond 3 standard deviations
/// (at least 0.001 mm). Throws GeometryError when the points do not span a plane.
LaserPlaneResult fit_plane(const std::vector<cv::Vec3d>& points);

/// Writes the calibration as OpenCV YAML (cv::FileStorage): image_width, image_height,
/// camera_matrix, distortion_coefficients, laser_plane_normal, laser_plane_distance_mm and the
/// report's figures. Throws OutputError.
void save_calibration(const std::filesystem::path& file, const ProfilerCalibration& calibration);

/// Reads a calibration file (YAML, or any format cv::FileStorage reads). Throws InputError
/// naming the file and the key (missing, wrong type or size, not finite, out of range) or the
/// parser's words.
ProfilerCalibration load_calibration(const std::filesystem::path& file);
/// The same from the file's text; `source` names it in errors.
ProfilerCalibration parse_calibration(std::string_view text, const std::string& source);

}  // namespace scanmesh::drivers::profiler
