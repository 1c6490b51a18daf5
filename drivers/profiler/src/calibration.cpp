// Camera and laser-plane calibration from chessboard images (see calibration.hpp).
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/profiler/calibration.hpp"

namespace scanmesh::drivers::profiler {

namespace {

std::string size_text(cv::Size s) { return std::to_string(s.width) + "x" + std::to_string(s.height); }

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

std::vector<cv::Point3f> board_points(const ChessboardSpec& board) {
  std::vector<cv::Point3f> pts;
  for (int r = 0; r < board.pattern.height; ++r)
    for (int c = 0; c < board.pattern.width; ++c)
      pts.emplace_back(static_cast<float>(c * board.square_mm),
                       static_cast<float>(r * board.square_mm), 0.0f);
  return pts;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// Runs cv::calibrateCamera on the views; fills the camera, poses and per-view errors.
double run_calibration(const std::vector<std::vector<cv::Point3f>>& object,
                       const std::vector<std::vector<cv::Point2f>>& image, cv::Size size,
                       int flags, cv::Matx33d& matrix, std::vector<double>& distortion,
                       std::vector<cv::Vec3d>& rvecs, std::vector<cv::Vec3d>& tvecs,
                       std::vector<double>& per_view) {
  cv::Mat k, d, std_in, std_ex, errors;
  std::vector<cv::Mat> rv, tv;
  const double rms = cv::calibrateCamera(
      object, image, size, k, d, rv, tv, std_in, std_ex, errors, flags,
      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200, 1e-12));
  matrix = cv::Matx33d(k);
  d = d.reshape(1, 1);
  distortion.assign(d.ptr<double>(), d.ptr<double>() + d.cols);
  rvecs.clear();
  tvecs.clear();
  for (std::size_t i = 0; i < rv.size(); ++i) {
    rvecs.emplace_back(rv[i].reshape(1, 3));
    tvecs.emplace_back(tv[i].reshape(1, 3));
  }
  per_view.assign(errors.ptr<double>(), errors.ptr<double>() + errors.total());
  return rms;
}

}  // namespace

void ChessboardSpec::validate() const {
  const int lo = std::min(pattern.width, pattern.height);
  const int hi = std::max(pattern.width, pattern.height);
  if (lo < 2 || hi < 3)
    throw ConfigError("chessboard pattern " + size_text(pattern) +
                      ": at least 3 x 2 inner corners (corners where four squares meet)");
  if (!(std::isfinite(square_mm) && square_mm > 0))
    throw ConfigError("chessboard square must be more than 0 mm");
}

std::vector<cv::Point2f> find_chessboard(const cv::Mat& gray, cv::Size pattern) {
  std::vector<cv::Point2f> corners;
  if (gray.empty() || gray.type() != CV_8UC1) return corners;
  const int flags =
      cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK;
  if (!cv::findChessboardCorners(gray, pattern, corners, flags)) return {};
  // The refinement window must stay inside one square: under half the nearest corner spacing.
  double spacing = 1e9;
  for (int r = 0; r < pattern.height; ++r) {
    for (int c = 0; c < pattern.width; ++c) {
      const cv::Point2f& p = corners[static_cast<std::size_t>(r * pattern.width + c)];
      if (c + 1 < pattern.width)
        spacing = std::min(spacing, double(cv::norm(p - corners[static_cast<std::size_t>(r * pattern.width + c + 1)])));
      if (r + 1 < pattern.height)
        spacing = std::min(spacing, double(cv::norm(p - corners[static_cast<std::size_t>((r + 1) * pattern.width + c)])));
    }
  }
  const int half = std::clamp(static_cast<int>(spacing * 0.25), 2, 11);
  cv::cornerSubPix(gray, corners, cv::Size(half, half), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-6));
  return corners;
}

CameraCalibrationResult calibrate_camera(const std::vector<NamedImage>& images,
                                         const ChessboardSpec& board, const std::string& where,
                                         const CameraCalibrationOptions& options) {
  board.validate();
  CameraCalibrationResult result;
  cv::Size size;
  std::vector<std::vector<cv::Point2f>> found;
  std::vector<std::size_t> found_index;  // into result.images
  for (const auto& img : images) {
    ImageUse use;
    use.image = img.name;
    if (img.gray.empty() || img.gray.type() != CV_8UC1) {
      use.reason = "not an 8-bit image";
    } else if (!size.empty() && img.gray.size() != size) {
      use.reason = "its size " + size_text(img.gray.size()) + " differs from the first image's " +
                   size_text(size);
    } else {
      auto corners = find_chessboard(img.gray, board.pattern);
      if (corners.empty()) {
        use.reason = "chessboard of " + size_text(board.pattern) + " inner corners not found";
      } else {
        if (size.empty()) size = img.gray.size();
        found.push_back(std::move(corners));
        found_index.push_back(result.images.size());
        use.used = true;
      }
    }
    result.images.push_back(std::move(use));
  }
  if (found.empty())
    throw InputError(where + ": chessboard of " + size_text(board.pattern) +
                     " inner corners not found in any of the " + std::to_string(images.size()) +
                     " images (--pattern counts the inner corners, where four squares meet)");
  if (found.size() < 3)
    throw InputError(where + ": chessboard found in " + std::to_string(found.size()) + " of " +
                     std::to_string(images.size()) +
                     " images; at least 3 are needed (better 10 or more, tilted in different "
                     "directions)");

  const int flags = options.fit_k3 ? 0 : cv::CALIB_FIX_K3;
  const auto object_all = board_points(board);
  std::vector<cv::Vec3d> rvecs, tvecs;
  std::vector<double> per_view;
  // Calibrate; reject views far worse than the median once, then calibrate again.
  for (int round = 0; round < 2; ++round) {
    std::vector<std::vector<cv::Point3f>> object(found.size(), object_all);
    result.rms_px = run_calibration(object, found, size, flags, result.camera.matrix,
                                    result.camera.distortion, rvecs, tvecs, per_view);
    if (round == 1) break;
    const double limit = std::max(0.5, options.outlier_ratio * median(per_view));
    std::vector<std::vector<cv::Point2f>> kept;
    std::vector<std::size_t> kept_index;
    for (std::size_t i = 0; i < found.size(); ++i) {
      if (per_view[i] <= limit) {
        kept.push_back(found[i]);
        kept_index.push_back(found_index[i]);
        continue;
      }
      ImageUse& use = result.images[found_index[i]];
      use.used = false;
      use.error_px = per_view[i];
      use.reason = "reprojection error " + fixed(per_view[i], 3) + " px, over " +
                   fixed(options.outlier_ratio, 1) +
                   " times the median (a moved board, a blurred or wrongly found pattern)";
    }
    if (kept.size() == found.size() || kept.size() < 3) break;
    found = std::move(kept);
    found_index = std::move(kept_index);
  }
  result.camera.size = size;
  for (std::size_t i = 0; i < found.size(); ++i) {
    ImageUse& use = result.images[found_index[i]];
    use.error_px = per_view[i];
    result.poses[use.image] = BoardPose{rvecs[i], tvecs[i]};
  }
  return result;
}

LaserPlaneResult fit_plane(const std::vector<cv::Vec3d>& points) {
  if (points.size() < 3)
    throw GeometryError("a plane needs at least 3 points, got " + std::to_string(points.size()));
  std::vector<char> keep(points.size(), 1);
  cv::Vec3d normal, centre;
  double sigma = 0;
  cv::Vec3d spread;  // square roots of the eigenvalues, largest first
  for (int it = 0; it < 50; ++it) {
    centre = cv::Vec3d(0, 0, 0);
    std::size_t n = 0;
    for (std::size_t i = 0; i < points.size(); ++i)
      if (keep[i]) {
        centre += points[i];
        ++n;
      }
    if (n < 3) throw GeometryError("the outlier rejection left fewer than 3 points");
    centre *= 1.0 / static_cast<double>(n);
    cv::Matx33d cov = cv::Matx33d::zeros();
    for (std::size_t i = 0; i < points.size(); ++i)
      if (keep[i]) {
        const cv::Vec3d d = points[i] - centre;
        cov += d * d.t();
      }
    cov *= 1.0 / static_cast<double>(n);
    cv::Mat values, vectors;
    cv::eigen(cv::Mat(cov), values, vectors);  // descending
    for (int k = 0; k < 3; ++k) spread[k] = std::sqrt(std::max(0.0, values.at<double>(k)));
    normal = cv::Vec3d(vectors.at<double>(2, 0), vectors.at<double>(2, 1), vectors.at<double>(2, 2));
    double ss = 0;
    for (std::size_t i = 0; i < points.size(); ++i)
      if (keep[i]) ss += std::pow(normal.dot(points[i] - centre), 2);
    sigma = std::sqrt(ss / static_cast<double>(n));
    const double limit = std::max(3 * sigma, 0.001);
    bool changed = false;
    for (std::size_t i = 0; i < points.size(); ++i) {
      const char k = std::abs(normal.dot(points[i] - centre)) <= limit;
      changed |= k != keep[i];
      keep[i] = k;
    }
    if (!changed) break;
  }
  if (spread[1] < 0.02 * spread[0])
    throw GeometryError("the laser points lie along one line (" + fixed(spread[1], 3) +
                        " mm across it, " + fixed(spread[0], 1) +
                        " mm along): take the board at two or more different tilts or distances");
  LaserPlaneResult r;
  double d = normal.dot(centre);
  if (d < 0) {
    normal = -normal;
    d = -d;
  }
  if (!(d > 1e-6)) throw GeometryError("the laser plane passes through the camera's centre");
  r.plane = LaserPlane{normal, d};
  r.points = points.size();
  double ss = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!keep[i]) continue;
    const double e = std::abs(normal.dot(points[i]) - d);
    ss += e * e;
    r.max_mm = std::max(r.max_mm, e);
    ++r.inliers;
  }
  r.rms_mm = std::sqrt(ss / static_cast<double>(r.inliers));
  return r;
}

LaserPlaneResult calibrate_laser_plane(const std::vector<NamedImage>& laser_images,
                                       const CameraCalibrationResult& camera,
                                       const ChessboardSpec& board,
                                       const ExtractionOptions& extraction,
                                       const std::string& where) {
  board.validate();
  LineExtractor extractor(extraction);
  const auto object = board_points(board);
  const cv::Matx33d& k = camera.camera.matrix;
  const std::vector<double>& dist = camera.camera.distortion;
  const int cols = board.pattern.width, rows = board.pattern.height;
  // The squares' area: the inner corners grown by one square (the outer squares).
  const auto sq = static_cast<float>(board.square_mm);
  const std::vector<cv::Point3f> quad_board{{-sq, -sq, 0},
                                            {static_cast<float>(cols) * sq, -sq, 0},
                                            {static_cast<float>(cols) * sq, static_cast<float>(rows) * sq, 0},
                                            {-sq, static_cast<float>(rows) * sq, 0}};
  std::vector<cv::Vec3d> all;
  std::vector<ImageUse> uses;
  std::size_t used = 0;
  std::vector<float> positions;
  for (const auto& img : laser_images) {
    ImageUse& u = uses.emplace_back();
    u.image = img.name;
    if (img.gray.empty() || img.gray.type() != CV_8UC1) {
      u.reason = "not an 8-bit image";
      continue;
    }
    if (img.gray.size() != camera.camera.size) {
      u.reason = "its size " + size_text(img.gray.size()) + " differs from the camera's " +
                 size_text(camera.camera.size);
      continue;
    }
    const bool has_off = !img.background.empty();
    if (has_off && (img.background.size() != img.gray.size() || img.background.type() != CV_8UC1)) {
      u.reason = "its laser-off image is not an 8-bit image of the same size";
      continue;
    }
    BoardPose pose;
    if (auto it = camera.poses.find(img.name); it != camera.poses.end()) {
      pose = it->second;
    } else {
      const auto corners = find_chessboard(has_off ? img.background : img.gray, board.pattern);
      if (corners.empty()) {
        u.reason = std::string("no chessboard image of this name was used for the camera, and "
                               "no board found in ") +
                   (has_off ? "its laser-off image" : "it");
        continue;
      }
      cv::solvePnP(object, corners, k, dist, pose.rvec, pose.tvec);
    }
    std::vector<cv::Point2f> quad;
    cv::projectPoints(quad_board, pose.rvec, pose.tvec, k, dist, quad);
    cv::Matx33d rot;
    cv::Rodrigues(pose.rvec, rot);
    const cv::Vec3d n(rot(0, 2), rot(1, 2), rot(2, 2));
    const double nd = n.dot(pose.tvec);

    extractor.extract(img.gray, img.background, positions);
    std::vector<cv::Point2d> pixels;
    for (std::size_t i = 0; i < positions.size(); ++i) {
      if (!std::isfinite(positions[i])) continue;
      const cv::Point2d p = extraction.axis == LineAxis::kColumns
                                ? cv::Point2d(static_cast<double>(i), positions[i])
                                : cv::Point2d(positions[i], static_cast<double>(i));
      if (cv::pointPolygonTest(quad, cv::Point2f(p), false) > 0) pixels.push_back(p);
    }
    if (pixels.size() < 20) {
      u.reason = "only " + std::to_string(pixels.size()) +
                 " line points on the board (is the laser line across the board?)";
      continue;
    }
    std::vector<cv::Point2d> rays;
    cv::undistortPoints(pixels, rays, k, dist, cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200,
                                         1e-14));
    for (const auto& r : rays) {
      const cv::Vec3d ray(r.x, r.y, 1);
      const double den = n.dot(ray);
      if (std::abs(den) < 1e-9) continue;
      all.push_back(ray * (nd / den));
    }
    u.used = true;
    u.points = rays.size();
    ++used;
  }
  if (used < 2)
    throw InputError(where + ": the laser line was found on the board in " +
                     std::to_string(used) + " of " + std::to_string(laser_images.size()) +
                     " images; at least 2 poses of the board (different tilts or distances) "
                     "are needed");
  LaserPlaneResult result;
  try {
    result = fit_plane(all);
  } catch (const GeometryError& e) {
    throw InputError(where + ": " + e.what());
  }
  result.images = std::move(uses);
  return result;
}

}  // namespace scanmesh::drivers::profiler
