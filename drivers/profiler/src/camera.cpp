// Undistortion and triangulation (see camera.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/profiler/camera.hpp"

#include <cmath>
#include <opencv2/calib3d.hpp>

#include "scanmesh/common/error.hpp"

namespace scanmesh::drivers::profiler {

namespace {

const cv::TermCriteria kUndistortExact(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200,
                                       1e-14);

std::string join(const std::vector<std::string>& problems) {
  std::string s;
  for (const auto& p : problems) s += (s.empty() ? "" : "; ") + p;
  return s;
}

}  // namespace

std::vector<std::string> camera_problems(const CameraIntrinsics& c) {
  std::vector<std::string> p;
  if (c.size.width < 2 || c.size.height < 2 || c.size.width > 65535 || c.size.height > 65535)
    p.push_back("image size " + std::to_string(c.size.width) + "x" +
                std::to_string(c.size.height) + " out of 2..65535");
  const double fx = c.matrix(0, 0), fy = c.matrix(1, 1), cx = c.matrix(0, 2), cy = c.matrix(1, 2);
  if (!(std::isfinite(fx) && fx > 0 && std::isfinite(fy) && fy > 0))
    p.push_back("focal lengths must be finite and > 0");
  if (!(std::isfinite(cx) && std::isfinite(cy)))
    p.push_back("principal point must be finite");
  if (c.matrix(0, 1) != 0 || c.matrix(1, 0) != 0 || c.matrix(2, 0) != 0 || c.matrix(2, 1) != 0 ||
      c.matrix(2, 2) != 1)
    p.push_back("camera matrix must be [fx 0 cx; 0 fy cy; 0 0 1]");
  const std::size_t n = c.distortion.size();
  if (n != 0 && n != 4 && n != 5 && n != 8 && n != 12 && n != 14)
    p.push_back("distortion needs 0, 4, 5, 8, 12 or 14 coefficients, got " + std::to_string(n));
  for (double d : c.distortion)
    if (!std::isfinite(d)) {
      p.push_back("distortion coefficients must be finite");
      break;
    }
  return p;
}

std::vector<std::string> plane_problems(const LaserPlane& plane) {
  std::vector<std::string> p;
  const double norm = cv::norm(plane.normal);
  if (!std::isfinite(norm) || std::abs(norm - 1) > 1e-6)
    p.push_back("laser plane normal must be a unit vector");
  if (!(std::isfinite(plane.distance_mm) && plane.distance_mm > 0))
    p.push_back("laser plane distance must be finite and > 0 (the camera off the plane)");
  return p;
}

cv::Vec3d undistorted_ray(const CameraIntrinsics& camera, cv::Point2d pixel) {
  std::vector<cv::Point2d> in{pixel}, out;
  cv::undistortPoints(in, out, camera.matrix, camera.distortion, cv::noArray(), cv::noArray(),
                      kUndistortExact);
  return {out[0].x, out[0].y, 1};
}

namespace {

/// The undistorted rays of every pixel centre for the five-coefficient model (k1 k2 p1 p2 k3):
/// Newton's method on the distortion with its analytic Jacobian, started from the pixel
/// before (two or three steps each: about 50 ms for 1280 x 1024, where cv::undistortPoints run
/// to the same precision takes seconds). False when it does not converge somewhere.
bool newton_rays(const CameraIntrinsics& c, cv::Mat& rays) {
  double k[5] = {0, 0, 0, 0, 0};
  for (std::size_t i = 0; i < c.distortion.size(); ++i) k[i] = c.distortion[i];
  const double k1 = k[0], k2 = k[1], p1 = k[2], p2 = k[3], k3 = k[4];
  const double fx = c.matrix(0, 0), fy = c.matrix(1, 1), cx = c.matrix(0, 2), cy = c.matrix(1, 2);
  const int w = c.size.width, h = c.size.height;
  rays.create(h, w, CV_32FC2);
  for (int v = 0; v < h; ++v) {
    const double yd = (v - cy) / fy;
    double x = (0 - cx) / fx, y = yd;  // start: the distorted point itself
    for (int u = 0; u < w; ++u) {
      const double xd = (u - cx) / fx;
      bool done = false;
      for (int it = 0; it < 30 && !done; ++it) {
        const double r2 = x * x + y * y;
        const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
        const double dr = k1 + r2 * (2 * k2 + 3 * k3 * r2);  // d radial / d r2
        const double fxv = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) - xd;
        const double fyv = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y - yd;
        const double a = radial + 2 * x * x * dr + 2 * p1 * y + 6 * p2 * x;
        const double b = 2 * x * y * dr + 2 * p1 * x + 2 * p2 * y;
        const double d = radial + 2 * y * y * dr + 6 * p1 * y + 2 * p2 * x;
        const double det = a * d - b * b;
        if (!(std::abs(det) > 1e-12)) return false;
        const double dx = (d * fxv - b * fyv) / det;
        const double dy = (a * fyv - b * fxv) / det;
        x -= dx;
        y -= dy;
        done = std::abs(dx) < 1e-13 && std::abs(dy) < 1e-13;
      }
      if (!done || !std::isfinite(x) || !std::isfinite(y)) return false;
      rays.at<cv::Vec2f>(v, u) = cv::Vec2f(static_cast<float>(x), static_cast<float>(y));
    }
  }
  return true;
}

}  // namespace

Triangulator::Triangulator(const CameraIntrinsics& camera, const LaserPlane& plane,
                           LineAxis axis, double min_z_mm, double max_z_mm)
    : camera_(camera), plane_(plane), axis_(axis), min_z_mm_(min_z_mm), max_z_mm_(max_z_mm) {
  auto problems = camera_problems(camera);
  for (auto& p : plane_problems(plane)) problems.push_back(std::move(p));
  if (!(min_z_mm < max_z_mm)) problems.push_back("min_z_mm must be below max_z_mm");
  if (!problems.empty()) throw ConfigError("triangulation: " + join(problems));
  if (camera.distortion.size() <= 5 && newton_rays(camera, rays_)) return;
  // Other models (rational, thin prism, tilted): OpenCV's iteration, slower.
  const int w = camera.size.width, h = camera.size.height;
  cv::Mat pixels(h * w, 1, CV_32FC2);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u)
      pixels.at<cv::Vec2f>(v * w + u) = cv::Vec2f(static_cast<float>(u), static_cast<float>(v));
  cv::Mat rays;
  cv::undistortPoints(pixels, rays, camera.matrix, camera.distortion, cv::noArray(),
                      cv::noArray(), kUndistortExact);
  rays_ = rays.reshape(2, h);
}

void Triangulator::triangulate(const std::vector<float>& positions,
                               std::vector<ProfilePoint>& points) const {
  points.resize(positions.size());
  const int w = camera_.size.width, h = camera_.size.height;
  const bool columns = axis_ == LineAxis::kColumns;
  const int along = columns ? h : w;  // the axis the positions run on
  const double nx = plane_.normal[0], ny = plane_.normal[1], nz = plane_.normal[2];
  for (std::size_t i = 0; i < positions.size(); ++i) {
    ProfilePoint& out = points[i];
    out = ProfilePoint{};
    const float pos = positions[i];
    const int fixed = static_cast<int>(i);
    if (!std::isfinite(pos) || pos < 0 || pos > static_cast<float>(along - 1) ||
        fixed >= (columns ? w : h))
      continue;
    int p0 = static_cast<int>(pos);
    if (p0 >= along - 1) p0 = along - 2;
    const double f = static_cast<double>(pos) - p0;
    const cv::Vec2f& a = columns ? rays_.at<cv::Vec2f>(p0, fixed) : rays_.at<cv::Vec2f>(fixed, p0);
    const cv::Vec2f& b =
        columns ? rays_.at<cv::Vec2f>(p0 + 1, fixed) : rays_.at<cv::Vec2f>(fixed, p0 + 1);
    const double x = a[0] + f * (b[0] - a[0]);
    const double y = a[1] + f * (b[1] - a[1]);
    const double den = nx * x + ny * y + nz;
    if (!(std::abs(den) > 1e-12)) continue;
    const double z = plane_.distance_mm / den;
    if (!(z > 0)) continue;  // the plane behind the camera along this ray
    out.x_mm = x * z;
    out.y_mm = y * z;
    out.z_mm = z;
    out.status = (z < min_z_mm_ || z > max_z_mm_) ? SensorStatus::kOverRange : SensorStatus::kOk;
    if (out.status != SensorStatus::kOk) out.x_mm = out.y_mm = out.z_mm = std::nan("");
  }
}

}  // namespace scanmesh::drivers::profiler
