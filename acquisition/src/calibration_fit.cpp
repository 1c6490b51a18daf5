// Sphere and plane fits for calibration, and the calibration age rule.
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/calibration_fit.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "scanmesh/common/error.hpp"

namespace scanmesh::acq {

namespace {

/// Algebraic sphere: |p|^2 = 2 c.p + (r^2 - |c|^2), linear in (c, k).
bool algebraic_sphere(std::span<const Vec3> pts, Vec3& c, double& r) {
  Eigen::MatrixXd a(pts.size(), 4);
  Eigen::VectorXd b(pts.size());
  Vec3 mean = Vec3::Zero();
  for (const auto& p : pts) mean += p;
  mean /= static_cast<double>(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Vec3 q = pts[i] - mean;  // centred for conditioning
    a.row(static_cast<Eigen::Index>(i)) << 2 * q.x(), 2 * q.y(), 2 * q.z(), 1.0;
    b[static_cast<Eigen::Index>(i)] = q.squaredNorm();
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  if (qr.rank() < 4) return false;
  const Eigen::Vector4d x = qr.solve(b);
  c = mean + x.head<3>();
  const double r2 = x[3] + x.head<3>().squaredNorm();
  if (!(r2 > 0)) return false;
  r = std::sqrt(r2);
  return true;
}

/// Gauss-Newton on sum (|p - c| - r)^2; r fixed when `fixed_r`.
int refine_sphere(std::span<const Vec3> pts, Vec3& c, double& r, bool fixed_r) {
  int it = 0;
  for (; it < 50; ++it) {
    Eigen::Matrix4d jtj = Eigen::Matrix4d::Zero();
    Eigen::Vector4d jtr = Eigen::Vector4d::Zero();
    for (const auto& p : pts) {
      const Vec3 d = p - c;
      const double n = d.norm();
      if (n < 1e-12) continue;
      const double res = n - r;
      Eigen::Vector4d j;
      j.head<3>() = -d / n;
      j[3] = -1;
      jtj += j * j.transpose();
      jtr += j * res;
    }
    Eigen::Vector4d step;
    if (fixed_r) {
      const Eigen::Matrix3d m = jtj.topLeftCorner<3, 3>();
      Eigen::Vector3d s3 = m.ldlt().solve(-jtr.head<3>());
      step << s3, 0;
    } else {
      step = jtj.ldlt().solve(-jtr);
    }
    if (!step.allFinite()) break;
    c += step.head<3>();
    r += step[3];
    if (step.norm() < 1e-12 * std::max(1.0, r)) break;
  }
  return it;
}

void sphere_residuals(std::span<const Vec3> pts, const Vec3& c, double r, SphereFit& f) {
  double s = 0, m = 0;
  for (const auto& p : pts) {
    const double e = (p - c).norm() - r;
    s += e * e;
    m = std::max(m, std::abs(e));
  }
  f.rms_mm = std::sqrt(s / static_cast<double>(pts.size()));
  f.max_abs_mm = m;
}

}  // namespace

SphereFit fit_sphere(std::span<const Vec3> points, std::optional<double> known_radius_mm,
                     double reject_sigma) {
  const std::size_t need = known_radius_mm ? 3 : 4;
  if (points.size() < need)
    throw GeometryError("sphere fit: " + std::to_string(points.size()) + " points (need " +
                        std::to_string(need) + ")");
  for (const auto& p : points)
    if (!p.allFinite()) throw GeometryError("sphere fit: a point is not finite");
  if (known_radius_mm && !(*known_radius_mm > 0))
    throw GeometryError("sphere fit: the known radius must be > 0");
  std::vector<Vec3> pts(points.begin(), points.end());
  SphereFit f;
  Vec3 c;
  double r = 0;
  if (!algebraic_sphere(pts, c, r)) {
    if (!known_radius_mm) throw GeometryError("sphere fit: the points do not span a sphere");
    c = Vec3::Zero();
    for (const auto& p : pts) c += p;
    c /= static_cast<double>(pts.size());
  }
  if (known_radius_mm) r = *known_radius_mm;
  for (int pass = 0; pass < 2; ++pass) {
    f.iterations += refine_sphere(pts, c, r, known_radius_mm.has_value());
    sphere_residuals(pts, c, r, f);
    if (pass == 1 || reject_sigma <= 0) break;
    std::vector<Vec3> kept;
    for (const auto& p : pts)
      if (std::abs((p - c).norm() - r) <= reject_sigma * f.rms_mm + 1e-12) kept.push_back(p);
    if (kept.size() == pts.size() || kept.size() < need) break;
    f.rejected += pts.size() - kept.size();
    pts.swap(kept);
  }
  if (!c.allFinite() || !std::isfinite(r))
    throw GeometryError("sphere fit: did not converge (degenerate points)");
  f.centre_mm = c;
  f.radius_mm = r;
  f.points = pts.size();
  return f;
}

MountCheck check_mount(std::span<const Vec3> points, double sphere_diameter_mm,
                       const Vec3& known_centre_mm, const Calibration& used) {
  MountCheck m;
  m.fit = fit_sphere(points, sphere_diameter_mm / 2);
  m.mount_correction_mm = known_centre_mm - m.fit.centre_mm;
  m.corrected = used;
  // At table angle 0 the part frame is the machine frame: a translation of the mount in the
  // carriage frame moves every point by the same vector.
  m.corrected.mount.pretranslate(m.mount_correction_mm);
  return m;
}

PlaneFit fit_plane(std::span<const Vec3> points, double reject_sigma) {
  if (points.size() < 3)
    throw GeometryError("plane fit: " + std::to_string(points.size()) + " points (need 3)");
  std::vector<Vec3> pts(points.begin(), points.end());
  PlaneFit f;
  for (int pass = 0; pass < 2; ++pass) {
    Vec3 mean = Vec3::Zero();
    for (const auto& p : pts) mean += p;
    mean /= static_cast<double>(pts.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : pts) cov += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    if (es.eigenvalues()[1] <= 1e-12 * es.eigenvalues()[2])
      throw GeometryError("plane fit: the points are collinear");
    f.normal = es.eigenvectors().col(0).normalized();
    if (f.normal.z() < 0 || (f.normal.z() == 0 && f.normal.y() < 0)) f.normal = -f.normal;
    f.point_mm = mean;
    double s = 0, lo = 0, hi = 0;
    bool first = true;
    for (const auto& p : pts) {
      const double d = (p - mean).dot(f.normal);
      s += d * d;
      lo = first ? d : std::min(lo, d);
      hi = first ? d : std::max(hi, d);
      first = false;
    }
    f.rms_mm = std::sqrt(s / static_cast<double>(pts.size()));
    f.flatness_mm = hi - lo;
    f.points = pts.size();
    if (pass == 1 || reject_sigma <= 0) break;
    std::vector<Vec3> kept;
    for (const auto& p : pts)
      if (std::abs((p - mean).dot(f.normal)) <= reject_sigma * f.rms_mm + 1e-12) kept.push_back(p);
    if (kept.size() == pts.size() || kept.size() < 3) break;
    f.rejected += pts.size() - kept.size();
    pts.swap(kept);
  }
  return f;
}

std::optional<std::string> calibration_problem(
    std::optional<std::chrono::system_clock::time_point> made,
    std::chrono::system_clock::time_point now, std::chrono::hours max_age) {
  if (!made) return "no calibration: calibrate the sensor mounting first";
  if (*made > now + std::chrono::minutes(5))
    return "the calibration is dated in the future (check the clock)";
  if (max_age.count() > 0 && now - *made > max_age) {
    const auto days = std::chrono::duration_cast<std::chrono::hours>(now - *made).count() / 24;
    return "the calibration is " + std::to_string(days) + " days old, older than the limit of " +
           std::to_string(max_age.count() / 24) + " days";
  }
  return std::nullopt;
}

}  // namespace scanmesh::acq
