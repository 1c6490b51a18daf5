// Renders camera frames of laser sheets on a mesh and of chessboards, with their truth (see
// laser_frames.hpp). Ray casting through the sim BVH; OpenCV only for the blur and the 8-bit
// conversion.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/laser_frames.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "scanmesh/common/error.hpp"
#include "scanmesh/sim/rng.hpp"

namespace scanmesh::sim {

using recon::Vec3;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
/// The laser is drawn up to this many sigmas from its sheet.
constexpr double kLaserReach = 6;
/// Two neighbouring rays meet one continuous surface when their depths differ by less than this
/// fraction (about 80 degrees of grazing at the test cameras' pixel footprints).
constexpr double kContinuity = 0.01;

void check_camera(const CameraModel& c) {
  if (c.width < 2 || c.height < 2 || !(c.fx > 0) || !(c.fy > 0))
    throw ConfigError("camera model: width and height >= 2 and fx, fy > 0 required");
}

/// A ray cast through the scene in camera coordinates.
struct SurfaceHit {
  bool hit = false;
  double depth = 0;  ///< z of the point, camera frame (the ray is (x, y, 1) * depth)
  Vec3 point{};      ///< camera frame
  Vec3 normal{};     ///< camera frame, unit
  Vec3 ray{};        ///< (x, y, 1)
};

class Scene {
 public:
  Scene(const Bvh& bvh, const Eigen::Isometry3d& scene_from_camera, const CameraModel& camera,
        const std::vector<LaserSheet>& sheets, const FrameLook& look)
      : bvh_(bvh), pose_(scene_from_camera), camera_(camera), sheets_(sheets), look_(look) {
    for (auto& s : sheets_) s.normal.normalize();
  }

  SurfaceHit cast(double u, double v) const {
    SurfaceHit h;
    h.ray = camera_.ray(u, v);
    Bvh::Hit hit;
    if (!bvh_.intersect(pose_.translation(), pose_.linear() * h.ray, 1e-9, 1e12, hit)) return h;
    h.hit = true;
    h.depth = hit.t;
    h.point = h.ray * hit.t;
    h.normal = pose_.linear().transpose() * bvh_.normal(hit.triangle);
    return h;
  }

  /// Signed distance of the hit from sheet k's centre plane, mm.
  double distance(const SurfaceHit& h, std::size_t k) const {
    return sheets_[k].normal.dot(h.point - sheets_[k].origin);
  }

  /// Whether sheet k's emitter sees the point.
  bool lit(const SurfaceHit& h, std::size_t k) const {
    const Vec3 from = pose_ * sheets_[k].origin;
    const Vec3 to = pose_ * h.point;
    return !bvh_.occluded(from, to - from, 1e-9, 1.0 - 1e-6);
  }

  /// Ambient and laser light of a hit, grey levels.
  void shade(const SurfaceHit& h, double u, double& ambient, double& laser) const {
    if (!h.hit) {
      ambient = look_.background;
      laser = 0;
      return;
    }
    const double cos_view = std::abs(h.normal.dot(h.ray.normalized()));
    const double level =
        look_.ambient * (1 + look_.ambient_gradient * (u / (camera_.width - 1) - 0.5));
    ambient = look_.albedo * level * (0.4 + 0.6 * cos_view);
    laser = 0;
    for (std::size_t k = 0; k < sheets_.size(); ++k) {
      const double d = distance(h, k) / sheets_[k].sigma_mm;
      if (std::abs(d) > kLaserReach || !lit(h, k)) continue;
      const double cos_in = std::abs(h.normal.dot((h.point - sheets_[k].origin).normalized()));
      laser += sheets_[k].power * look_.albedo * cos_in * std::exp(-0.5 * d * d);
    }
  }

  std::size_t sheet_count() const { return sheets_.size(); }
  double sigma(std::size_t k) const { return sheets_[k].sigma_mm; }

 private:
  const Bvh& bvh_;
  Eigen::Isometry3d pose_;
  const CameraModel& camera_;
  std::vector<LaserSheet> sheets_;
  const FrameLook& look_;
};

bool continuous(const SurfaceHit& a, const SurfaceHit& b) {
  return a.hit && b.hit && std::abs(a.depth - b.depth) < kContinuity * std::min(a.depth, b.depth);
}

/// The truth of sheet k in column u (see LaserFrame): the crossing, and whether it is clean.
std::pair<double, bool> true_centre(const Scene& scene, const std::vector<SurfaceHit>& column,
                                    double u, std::size_t k) {
  const int h = static_cast<int>(column.size());
  double found = kNaN;
  bool found_clean = false;
  int crossings = 0;
  for (int v = 0; v + 1 < h; ++v) {
    const SurfaceHit& a = column[static_cast<std::size_t>(v)];
    const SurfaceHit& b = column[static_cast<std::size_t>(v + 1)];
    if (!continuous(a, b)) continue;
    const double da = scene.distance(a, k);
    const double db = scene.distance(b, k);
    if ((da < 0) == (db < 0)) continue;
    ++crossings;
    double lo = v, hi = v + 1, dlo = da;
    bool bisected = true;
    for (int it = 0; it < 48 && bisected; ++it) {
      const double mid = 0.5 * (lo + hi);
      const SurfaceHit m = scene.cast(u, mid);
      if (!m.hit || !continuous(m, a)) {
        bisected = false;  // an edge of the surface between the two rows
        break;
      }
      const double dm = scene.distance(m, k);
      if ((dm < 0) == (dlo < 0)) {
        lo = mid;
        dlo = dm;
      } else {
        hi = mid;
      }
    }
    const double centre = 0.5 * (lo + hi);
    const SurfaceHit c = scene.cast(u, centre);
    if (!bisected || !c.hit || !scene.lit(c, k)) {
      found = kNaN;
      continue;
    }
    bool clean = true;
    for (int r = v - 3; clean && r <= v + 4; ++r) {
      if (r < 0 || r + 1 >= h) {
        clean = false;
        break;
      }
      const SurfaceHit& s = column[static_cast<std::size_t>(r)];
      clean = continuous(s, column[static_cast<std::size_t>(r + 1)]) && scene.lit(s, k);
    }
    found = centre;
    found_clean = clean;
  }
  if (crossings != 1) return {kNaN, false};
  return {found, found_clean};
}

/// Speckle, blur, read noise, 8-bit conversion (rounded, clipped).
cv::Mat finish(const cv::Mat& ambient, const cv::Mat& laser, const FrameLook& look) {
  cv::Mat img(ambient.size(), CV_64F);
  Rng speckle(substream_seed(look.seed, 1));
  for (int r = 0; r < img.rows; ++r) {
    for (int c = 0; c < img.cols; ++c) {
      const double l = laser.at<double>(r, c);
      const double f = l > 0 && look.speckle > 0 ? std::max(0.0, 1 + look.speckle * speckle.gaussian())
                                                 : 1.0;
      img.at<double>(r, c) = ambient.at<double>(r, c) + l * f;
    }
  }
  if (look.blur_px > 0) cv::GaussianBlur(img, img, cv::Size(0, 0), look.blur_px);
  if (look.read_noise > 0) {
    Rng noise(substream_seed(look.seed, 2));
    for (int r = 0; r < img.rows; ++r)
      for (int c = 0; c < img.cols; ++c) img.at<double>(r, c) += look.read_noise * noise.gaussian();
  }
  cv::Mat out;
  img.convertTo(out, CV_8U);  // saturate_cast: rounded and clipped to 0..255
  return out;
}

}  // namespace

Eigen::Vector2d CameraModel::project(const Vec3& p) const {
  const double x = p.x() / p.z();
  const double y = p.y() / p.z();
  const double r2 = x * x + y * y;
  const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
  const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  return {fx * xd + cx, fy * yd + cy};
}

Vec3 CameraModel::ray(double u, double v) const {
  const double xd = (u - cx) / fx;
  const double yd = (v - cy) / fy;
  double x = xd, y = yd;
  for (int it = 0; it < 100; ++it) {
    const double r2 = x * x + y * y;
    const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
    const double dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
    const double nx = (xd - dx) / radial;
    const double ny = (yd - dy) / radial;
    const bool done = std::abs(nx - x) < 1e-13 && std::abs(ny - y) < 1e-13;
    x = nx;
    y = ny;
    if (done) break;
  }
  return {x, y, 1};
}

LaserFrame render_laser_frame(const Bvh& bvh, const Eigen::Isometry3d& scene_from_camera,
                              const CameraModel& camera, const std::vector<LaserSheet>& sheets,
                              const FrameLook& look) {
  check_camera(camera);
  for (const auto& s : sheets)
    if (!(s.sigma_mm > 0) || s.normal.norm() == 0)
      throw ConfigError("laser sheet: sigma_mm > 0 and a non-zero normal required");
  const Scene scene(bvh, scene_from_camera, camera, sheets, look);
  const int w = camera.width;
  const int h = camera.height;
  // One ray per pixel centre first; kept per column for the truth.
  std::vector<std::vector<SurfaceHit>> columns(static_cast<std::size_t>(w),
                                               std::vector<SurfaceHit>(static_cast<std::size_t>(h)));
  for (int u = 0; u < w; ++u)
    for (int v = 0; v < h; ++v) columns[static_cast<std::size_t>(u)][static_cast<std::size_t>(v)] = scene.cast(u, v);
  const auto at = [&](int u, int v) -> const SurfaceHit& {
    return columns[static_cast<std::size_t>(u)][static_cast<std::size_t>(v)];
  };

  // Pixels where the light changes fast (near a sheet, or at an edge of the surface) are
  // supersampled; the others take their centre's light.
  cv::Mat ambient(h, w, CV_64F), laser(h, w, CV_64F);
  const int s = std::max(1, look.supersample);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const SurfaceHit& c = at(u, v);
      bool fast = false;
      for (int dv = -1; dv <= 1 && !fast; ++dv) {
        for (int du = -1; du <= 1 && !fast; ++du) {
          const int uu = std::clamp(u + du, 0, w - 1);
          const int vv = std::clamp(v + dv, 0, h - 1);
          const SurfaceHit& n = at(uu, vv);
          if (n.hit != c.hit || (c.hit && !continuous(n, c))) {
            fast = true;
            break;
          }
          if (!c.hit) continue;
          for (std::size_t k = 0; k < scene.sheet_count(); ++k) {
            const double dn = scene.distance(n, k);
            const double dc = scene.distance(c, k);
            if (std::abs(dn) < kLaserReach * scene.sigma(k) || (dn < 0) != (dc < 0)) fast = true;
          }
        }
      }
      double a = 0, l = 0;
      if (!fast || s == 1) {
        scene.shade(c, u, a, l);
      } else {
        for (int i = 0; i < s; ++i) {
          for (int j = 0; j < s; ++j) {
            const double su = u - 0.5 + (i + 0.5) / s;
            const double sv = v - 0.5 + (j + 0.5) / s;
            double sa = 0, sl = 0;
            scene.shade(scene.cast(su, sv), su, sa, sl);
            a += sa;
            l += sl;
          }
        }
        a /= s * s;
        l /= s * s;
      }
      ambient.at<double>(v, u) = a;
      laser.at<double>(v, u) = l;
    }
  }

  LaserFrame frame;
  frame.image = finish(ambient, laser, look);
  if (look.blur_px > 0) cv::GaussianBlur(laser, laser, cv::Size(0, 0), look.blur_px);
  laser.convertTo(frame.laser, CV_32F);
  frame.truth.assign(sheets.size(), std::vector<double>(static_cast<std::size_t>(w), kNaN));
  frame.crossing = frame.truth;
  for (std::size_t k = 0; k < sheets.size(); ++k) {
    for (int u = 0; u < w; ++u) {
      const auto uu = static_cast<std::size_t>(u);
      const auto [centre, clean] = true_centre(scene, columns[uu], u, k);
      frame.crossing[k][uu] = centre;
      if (clean) frame.truth[k][uu] = centre;
    }
  }
  return frame;
}

cv::Mat render_chessboard(const CameraModel& camera, const Eigen::Isometry3d& camera_from_board,
                          const ChessboardTarget& board, const FrameLook& look,
                          const LaserSheet* laser) {
  check_camera(camera);
  if (board.cols < 2 || board.rows < 2 || !(board.square_mm > 0) || board.margin_mm < 0)
    throw ConfigError("chessboard: at least 2 x 2 inner corners and square_mm > 0 required");
  const int w = camera.width, h = camera.height;
  const Vec3 origin = camera_from_board.translation();
  const Vec3 normal = camera_from_board.linear().col(2);
  const Eigen::Matrix3d board_from_camera = camera_from_board.linear().transpose();
  const double sq = board.square_mm;
  Vec3 laser_normal{0, 0, 0};
  if (laser) laser_normal = laser->normal.normalized();

  // Board coordinates (x, y) of every pixel centre's ray, NaN where it misses the board plane.
  cv::Mat q(h, w, CV_64FC2);
  cv::Mat points(h, w, CV_64FC3);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const Vec3 ray = camera.ray(u, v);
      const double den = normal.dot(ray);
      const double t = std::abs(den) > 1e-12 ? normal.dot(origin) / den : -1;
      if (!(t > 0)) {
        q.at<cv::Vec2d>(v, u) = cv::Vec2d(kNaN, kNaN);
        continue;
      }
      const Vec3 p = ray * t;
      const Vec3 b = board_from_camera * (p - origin);
      q.at<cv::Vec2d>(v, u) = cv::Vec2d(b.x(), b.y());
      points.at<cv::Vec3d>(v, u) = cv::Vec3d(p.x(), p.y(), p.z());
    }
  }
  // Anti-aliasing without sampling: each edge covers the pixel by the fraction its distance in
  // pixels gives (a one-pixel box across the edge), from the local derivatives of the board
  // coordinates; the checker is the XOR of the two axes' smoothed parities. Unbiased corners.
  const auto coverage = [](double d_px) { return std::clamp(0.5 + d_px, 0.0, 1.0); };
  // Smoothed indicator of [lo, hi] along one board axis; g: mm per pixel across it.
  const auto inside = [&](double x, double lo, double hi, double g) {
    return coverage((x - lo) / g) * coverage((hi - x) / g);
  };
  // Smoothed parity of floor(x / sq): 1 on odd cells.
  const auto parity = [&](double x, double g) {
    const double k = std::round(x / sq);  // the nearest edge, between cells k-1 and k
    const double c = coverage((x - k * sq) / g);
    const double before = std::fmod(std::abs(k - 1), 2.0);
    const double after = std::fmod(std::abs(k), 2.0);
    return before * (1 - c) + after * c;
  };
  cv::Mat ambient(h, w, CV_64F), light(h, w, CV_64F, cv::Scalar(0));
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const cv::Vec2d& c = q.at<cv::Vec2d>(v, u);
      const cv::Vec2d& cu = q.at<cv::Vec2d>(v, std::min(u + 1, w - 1));
      const cv::Vec2d& cu0 = q.at<cv::Vec2d>(v, std::max(u - 1, 0));
      const cv::Vec2d& cv1 = q.at<cv::Vec2d>(std::min(v + 1, h - 1), u);
      const cv::Vec2d& cv0 = q.at<cv::Vec2d>(std::max(v - 1, 0), u);
      const double level = look.ambient * (1 + look.ambient_gradient * (double(u) / (w - 1) - 0.5));
      if (std::isnan(c[0]) || std::isnan(cu[0]) || std::isnan(cu0[0]) || std::isnan(cv1[0]) ||
          std::isnan(cv0[0])) {
        ambient.at<double>(v, u) = look.background;
        continue;
      }
      const double su = (u + 1 < w ? 1 : 0) + (u > 0 ? 1 : 0);
      const double sv = (v + 1 < h ? 1 : 0) + (v > 0 ? 1 : 0);
      const cv::Vec2d du = (cu - cu0) / su, dv = (cv1 - cv0) / sv;  // board mm per pixel
      const double gx = std::max(1e-9, std::hypot(du[0], dv[0]));
      const double gy = std::max(1e-9, std::hypot(du[1], dv[1]));
      const double on_board = inside(c[0], -sq - board.margin_mm, board.cols * sq + board.margin_mm, gx) *
                              inside(c[1], -sq - board.margin_mm, board.rows * sq + board.margin_mm, gy);
      const double on_squares = inside(c[0], -sq, board.cols * sq, gx) *
                                inside(c[1], -sq, board.rows * sq, gy);
      const double px = parity(c[0], gx), py = parity(c[1], gy);
      const double black = on_squares * (px * py + (1 - px) * (1 - py));  // (ix + iy) even
      const double albedo = board.white - (board.white - board.black) * black;
      ambient.at<double>(v, u) = on_board * albedo * level + (1 - on_board) * look.background;
      if (laser) {
        const cv::Vec3d& pc = points.at<cv::Vec3d>(v, u);
        const Vec3 p(pc[0], pc[1], pc[2]);
        const double d = laser_normal.dot(p - laser->origin) / laser->sigma_mm;
        if (std::abs(d) <= kLaserReach) {
          const double cos_in = std::abs(normal.dot((p - laser->origin).normalized()));
          light.at<double>(v, u) =
              on_board * laser->power * albedo * cos_in * std::exp(-0.5 * d * d);
        }
      }
    }
  }
  return finish(ambient, light, look);
}

}  // namespace scanmesh::sim
