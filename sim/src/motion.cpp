// Trapezoidal moves, trajectories, and planning of raster / serpentine / rotary / multi-view
// scans over a part's bounding box.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/motion.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <string>

#include "scanmesh/common/error.hpp"

namespace scanmesh::sim {

// ---------------------------------------------------------------------------------------------
// Trapezoid

Trapezoid::Trapezoid(double length, double v_max, double a_max)
    : length_(std::max(0.0, length)), a_(a_max) {
  if (length_ == 0) return;
  if (length_ >= v_max * v_max / a_max) {
    v_ = v_max;
    t_acc_ = v_ / a_;
    t_cruise_ = (length_ - v_ * v_ / a_) / v_;
  } else {
    v_ = std::sqrt(length_ * a_);
    t_acc_ = v_ / a_;
    t_cruise_ = 0;
  }
}

double Trapezoid::position(double t) const {
  if (length_ == 0 || t <= 0) return 0;
  const double total = duration_s();
  if (t >= total) return length_;
  if (t < t_acc_) return 0.5 * a_ * t * t;
  if (t < t_acc_ + t_cruise_) return 0.5 * a_ * t_acc_ * t_acc_ + v_ * (t - t_acc_);
  const double r = total - t;
  return std::min(length_, length_ - 0.5 * a_ * r * r);
}

double Trapezoid::velocity(double t) const {
  if (length_ == 0 || t <= 0) return 0;
  const double total = duration_s();
  if (t >= total) return 0;
  if (t < t_acc_) return a_ * t;
  if (t < t_acc_ + t_cruise_) return v_;
  return a_ * (total - t);
}

double Trapezoid::time_at(double s) const {
  if (length_ == 0 || s <= 0) return 0;
  if (s >= length_) return duration_s();
  const double s_acc = 0.5 * a_ * t_acc_ * t_acc_;
  if (s < s_acc) return std::sqrt(2 * s / a_);
  if (s <= length_ - s_acc) return t_acc_ + (s - s_acc) / v_;
  return duration_s() - std::sqrt(2 * (length_ - s) / a_);
}

std::vector<std::string> StageLimits::problems() const {
  std::vector<std::string> out;
  auto check = [&](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0))
      out.push_back(std::string("stage ") + name + " must be > 0, got " + std::to_string(v));
  };
  check(linear_velocity_mm_s, "linear_velocity_mm_s");
  check(linear_accel_mm_s2, "linear_accel_mm_s2");
  check(rotary_velocity_rad_s, "rotary_velocity_rad_s");
  check(rotary_accel_rad_s2, "rotary_accel_rad_s2");
  return out;
}

// ---------------------------------------------------------------------------------------------
// Moves and trajectories

namespace {

StagePose lerp(const StagePose& a, const StagePose& b, double s) {
  return {a.x_mm + (b.x_mm - a.x_mm) * s, a.y_mm + (b.y_mm - a.y_mm) * s,
          a.z_mm + (b.z_mm - a.z_mm) * s, a.a_rad + (b.a_rad - a.a_rad) * s};
}

std::int64_t ceil_ns(double seconds) {
  return static_cast<std::int64_t>(std::ceil(seconds * 1e9 - 1e-6));
}

}  // namespace

StagePose Move::at(Timestamp t) const {
  if (t <= start) return from;
  if (t >= end) return end_pose;
  const double s = profile.position(static_cast<double>((t - start).count()) * 1e-9);
  if (s >= 1) return to;
  return lerp(from, to, s);
}

Trajectory::Trajectory(Timestamp start, StagePose home) : start_(start), home_(home) {}

void Trajectory::move_to(const StagePose& to, bool sensing, const StageLimits& limits,
                         double linear_speed_mm_s, double angular_speed_rad_s) {
  const StagePose from = end_pose();
  const std::array<double, 3> d{to.x_mm - from.x_mm, to.y_mm - from.y_mm, to.z_mm - from.z_mm};
  const double da = std::abs(to.a_rad - from.a_rad);
  const double dl = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  if (dl == 0 && da == 0) return;
  // Limits on the path parameter s in [0, 1]: every axis within its own limits.
  double v = 1e300, a = 1e300;
  for (const double di : d) {
    if (di == 0) continue;
    v = std::min(v, limits.linear_velocity_mm_s / std::abs(di));
    a = std::min(a, limits.linear_accel_mm_s2 / std::abs(di));
  }
  if (dl > 0) v = std::min(v, linear_speed_mm_s / dl);
  if (da > 0) {
    v = std::min(v, limits.rotary_velocity_rad_s / da);
    a = std::min(a, limits.rotary_accel_rad_s2 / da);
    v = std::min(v, angular_speed_rad_s / da);
  }
  Move m;
  m.from = from;
  m.to = to;
  m.end_pose = to;
  m.start = end();
  m.profile = Trapezoid(1.0, v, a);
  m.end = m.start + std::chrono::nanoseconds(ceil_ns(m.profile.duration_s()));
  m.sensing = sensing;
  moves_.push_back(m);
}

void Trajectory::dwell(std::chrono::nanoseconds duration, bool sensing) {
  if (duration.count() <= 0) return;
  Move m;
  m.from = m.to = m.end_pose = end_pose();
  m.start = end();
  m.end = m.start + duration;
  m.sensing = sensing;
  moves_.push_back(m);
}

void Trajectory::cut_last(Timestamp t) {
  if (moves_.empty()) return;
  Move& m = moves_.back();
  if (t >= m.end) return;
  if (t < m.start) t = m.start;
  m.end_pose = m.at(t);
  m.end = t;
}

StagePose Trajectory::pose_at(Timestamp t) const {
  if (moves_.empty() || t < start_) return home_;
  const auto it = std::upper_bound(moves_.begin(), moves_.end(), t,
                                   [](Timestamp v, const Move& m) { return v < m.start; });
  if (it == moves_.begin()) return home_;
  return std::prev(it)->at(t);
}

// ---------------------------------------------------------------------------------------------
// Paths

std::string_view to_string(PathKind kind) {
  switch (kind) {
    case PathKind::kRaster:
      return "raster";
    case PathKind::kSerpentine:
      return "serpentine";
    case PathKind::kRotary:
      return "rotary";
    case PathKind::kViews:
      return "views";
  }
  return "?";
}

PathKind path_kind_from_string(std::string_view name) {
  if (name == "raster") return PathKind::kRaster;
  if (name == "serpentine") return PathKind::kSerpentine;
  if (name == "rotary") return PathKind::kRotary;
  if (name == "views") return PathKind::kViews;
  throw ConfigError("unknown path '" + std::string(name) +
                    "' (valid: raster, serpentine, rotary, views)");
}

std::vector<std::string> PathConfig::problems() const {
  std::vector<std::string> out = limits.problems();
  if (!(std::isfinite(spacing_mm) && spacing_mm > 0))
    out.push_back("path spacing_mm must be > 0, got " + std::to_string(spacing_mm));
  if (!(std::isfinite(line_spacing_mm) && line_spacing_mm >= 0))
    out.push_back("path line_spacing_mm must be > 0 (or 0 for the default), got " +
                  std::to_string(line_spacing_mm));
  if (!(std::isfinite(margin_mm) && margin_mm >= 0))
    out.push_back("path margin_mm must be >= 0, got " + std::to_string(margin_mm));
  if (!(views >= 1 && views <= 360))
    out.push_back("path views must be in [1, 360], got " + std::to_string(views));
  if (!(view_tilt_rad >= 0 && view_tilt_rad <= 1.2))
    out.push_back("path view_tilt_rad must be in [0, 1.2], got " + std::to_string(view_tilt_rad));
  if (!(std::isfinite(probe_clearance_mm) && probe_clearance_mm > 0))
    out.push_back("path probe_clearance_mm must be > 0, got " + std::to_string(probe_clearance_mm));
  return out;
}

namespace {

constexpr double kPi = std::numbers::pi;

Eigen::Isometry3d natural_mount(PathKind path, SensorKind sensor, double tilt_rad) {
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  // A profiler's laser line (sensor x) goes across the scan direction (machine y for lines
  // along x): turn it 90 degrees about z.
  const Eigen::Matrix3d across = sensor == SensorKind::kLine
                                     ? Eigen::AngleAxisd(kPi / 2, Vec3::UnitZ()).toRotationMatrix()
                                     : Eigen::Matrix3d::Identity();
  switch (path) {
    case PathKind::kRaster:
    case PathKind::kSerpentine:
      m.linear() = across;
      break;
    case PathKind::kViews:
      m.linear() = Eigen::AngleAxisd(tilt_rad, Vec3::UnitY()).toRotationMatrix() * across;
      break;
    case PathKind::kRotary:
      // Sensor z to machine +x: the beam (sensor -z) looks at the table axis along -x; a
      // profiler's line (sensor x) becomes vertical and its receiver (sensor y) stays on +y.
      m.linear() = Eigen::AngleAxisd(kPi / 2, Vec3::UnitY()).toRotationMatrix();
      break;
  }
  return m;
}

/// Machine-frame bounds of the part's box turned by `a_rad` about the table axis.
void turned_bounds(const Vec3& lo, const Vec3& hi, const Vec3& center, double a_rad, Vec3& out_lo,
                   Vec3& out_hi) {
  const Eigen::Matrix3d r = Eigen::AngleAxisd(a_rad, Vec3::UnitZ()).toRotationMatrix();
  out_lo = Vec3::Constant(1e300);
  out_hi = Vec3::Constant(-1e300);
  for (int k = 0; k < 8; ++k) {
    const Vec3 p((k & 1) ? hi.x() : lo.x(), (k & 2) ? hi.y() : lo.y(), (k & 4) ? hi.z() : lo.z());
    const Vec3 q = r * (p - center) + center;
    out_lo = out_lo.cwiseMin(q);
    out_hi = out_hi.cwiseMax(q);
  }
}

/// Lines (or levels) `step` apart, centred on [lo, hi]. Points (width 0): as many as fit inside
/// [lo, hi]. Swaths `width` wide: enough to cover [lo, hi].
std::vector<double> line_positions(double lo, double hi, double width, double step) {
  const double span = std::max(0.0, hi - lo - width);
  const auto n = static_cast<std::size_t>(width > 0 ? std::ceil(span / step - 1e-9)
                                                    : std::floor(span / step + 1e-9)) +
                 1;
  std::vector<double> out;
  out.reserve(n);
  const double mid = 0.5 * (lo + hi);
  for (std::size_t j = 0; j < n; ++j)
    out.push_back(mid + (static_cast<double>(j) - 0.5 * static_cast<double>(n - 1)) * step);
  return out;
}

/// The near end of the measuring range is placed this fraction of the range outside the part.
constexpr double kRangeClearance = 0.05;

/// Upper bound on planned lines, so a silly spacing fails fast instead of allocating forever.
constexpr std::size_t kMaxLines = 2'000'000;

}  // namespace

ScanPlan plan_scan(const PathConfig& path, const SensorConfig& sensor, const Vec3& part_lo,
                   const Vec3& part_hi) {
  {
    std::vector<std::string> p = path.problems();
    const auto s = sensor.problems();
    p.insert(p.end(), s.begin(), s.end());
    if (!part_lo.allFinite() || !part_hi.allFinite() || !(part_hi.x() >= part_lo.x()))
      p.push_back("the part has no finite bounds (empty mesh?)");
    if (!p.empty()) {
      std::string msg = "invalid scan configuration:";
      for (const auto& m : p) msg += "\n  " + m;
      throw ConfigError(msg);
    }
  }
  const SensorOptics optics(sensor);
  const bool probe = sensor.kind == SensorKind::kProbe;
  if (probe && path.kind != PathKind::kRaster && path.kind != PathKind::kSerpentine)
    throw ConfigError("the touch probe supports the raster and serpentine paths only");

  ScanPlan plan;
  const Vec3 center = 0.5 * (part_lo + part_hi);
  plan.calibration.table_center_mm = Vec3(center.x(), center.y(), 0);
  plan.calibration.mount =
      path.use_mount ? path.mount : natural_mount(path.kind, sensor.kind, path.view_tilt_rad);
  const Eigen::Isometry3d& mount = plan.calibration.mount;
  const Vec3& table_c = plan.calibration.table_center_mm;

  const double mid_range = sensor.standoff_mm + sensor.range_mm / 2;
  const double width =
      sensor.kind == SensorKind::kLine ? 2 * mid_range * std::sin(sensor.fan_angle_rad / 2) : 0.0;
  const double line_spacing = path.line_spacing_mm > 0 ? path.line_spacing_mm
                              : sensor.kind == SensorKind::kLine
                                  ? std::max(0.8 * width, path.spacing_mm)
                                  : 5 * path.spacing_mm;
  const double line_speed = probe ? sensor.probe_speed_mm_s : path.spacing_mm * sensor.rate_hz;
  const StageLimits& lim = path.limits;

  const Vec3 beam_w = mount.linear() * optics.config().beam_dir;
  // Sensor-frame point that is placed at the target: the near end of the measuring range of the
  // central ray, or the probe tip centre.
  const Vec3 anchor_s = probe ? Vec3::Zero() : Vec3(optics.config().beam_dir * sensor.standoff_mm);
  const Vec3 anchor_w = mount * anchor_s;

  if (path.kind == PathKind::kRotary) {
    double r_max = 0;
    for (int k = 0; k < 4; ++k) {
      const Vec3 p((k & 1) ? part_hi.x() : part_lo.x(), (k & 2) ? part_hi.y() : part_lo.y(), 0);
      r_max = std::max(r_max, (p - table_c).head<2>().norm());
    }
    r_max = std::max(r_max, 1.0);
    const double omega = line_speed / r_max;
    if (omega > lim.rotary_velocity_rad_s)
      throw ConfigError("rotary scan: spacing " + std::to_string(path.spacing_mm) + " mm at " +
                        std::to_string(sensor.rate_hz) + " Hz needs " + std::to_string(omega) +
                        " rad/s at radius " + std::to_string(r_max) +
                        " mm, above the table's limit of " +
                        std::to_string(lim.rotary_velocity_rad_s) +
                        " rad/s; use a smaller spacing or a lower rate");
    const double height = part_hi.z() - part_lo.z();
    if (height / line_spacing > static_cast<double>(kMaxLines))
      throw ConfigError("rotary scan: line spacing too small for the part height");
    // Profiler lines are vertical here, so the swath width counts along z.
    const auto levels = line_positions(part_lo.z(), part_hi.z(), width, line_spacing);
    auto pose_for = [&](double z, double a) {
      const Vec3 target(table_c.x() + r_max + kRangeClearance * sensor.range_mm, table_c.y(), z);
      const Vec3 stage = target - anchor_w;
      return StagePose{stage.x(), stage.y(), stage.z(), a};
    };
    plan.trajectory = Trajectory(path.start, pose_for(levels.front(), 0));
    double a = 0;
    for (std::size_t j = 0; j < levels.size(); ++j) {
      if (j > 0) plan.trajectory.move_to(pose_for(levels[j], a), false, lim);
      a += 2 * kPi;
      plan.trajectory.move_to(pose_for(levels[j], a), true, lim, Trajectory::kNoCap, omega);
    }
    plan.lines = levels.size();
    plan.line_speed = omega;
    return plan;
  }

  if (!probe && line_speed > lim.linear_velocity_mm_s)
    throw ConfigError("spacing " + std::to_string(path.spacing_mm) + " mm at " +
                      std::to_string(sensor.rate_hz) + " Hz needs a line speed of " +
                      std::to_string(line_speed) + " mm/s, above the stage's limit of " +
                      std::to_string(lim.linear_velocity_mm_s) +
                      " mm/s; use a smaller spacing or a lower rate");
  if (!(beam_w.z() < -0.2))
    throw ConfigError(
        "raster scans need a sensor looking down (beam z component in the machine frame "
        "below -0.2)");

  // Raster family: one pass per view angle.
  const std::uint32_t views = path.kind == PathKind::kViews ? path.views : 1;
  bool first = true;
  for (std::uint32_t v = 0; v < views; ++v) {
    const double a = 2 * kPi * v / views;
    Vec3 lo, hi;
    turned_bounds(part_lo, part_hi, table_c, a, lo, hi);
    // The near end of the measuring range (or the probe tip) just above the part's top.
    const double top = hi.z() + (probe ? path.probe_clearance_mm + sensor.tip_radius_mm
                                       : kRangeClearance * sensor.range_mm);
    const double z_mid = 0.5 * (lo.z() + hi.z());
    // Where the central ray crosses the part's mid-height, relative to the anchor.
    const double u = (top - z_mid) / -beam_w.z();
    const Vec3 shift = beam_w * u;
    const double slope = beam_w.head<2>().norm() / -beam_w.z();
    const double ext = slope * 0.5 * (hi.z() - lo.z());
    const double x0 = lo.x() - (probe ? 0 : path.margin_mm) - ext;
    const double x1 = hi.x() + (probe ? 0 : path.margin_mm) + ext;
    if ((hi.y() - lo.y() + 2 * ext) / line_spacing > static_cast<double>(kMaxLines) ||
        (probe && (x1 - x0) / path.spacing_mm * (hi.y() - lo.y()) / line_spacing > 1e7))
      throw ConfigError("line spacing (or probe spacing) too small for the part size");
    const auto ys = line_positions(lo.y() - ext, hi.y() + ext, width, line_spacing);
    auto pose_for = [&](double x, double y) {
      const Vec3 stage = Vec3(x, y, z_mid) - shift - anchor_w;
      return StagePose{stage.x(), stage.y(), stage.z(), a};
    };
    for (std::size_t j = 0; j < ys.size(); ++j) {
      const bool reverse = path.kind != PathKind::kRaster && j % 2 == 1;
      const double xa = reverse ? x1 : x0, xb = reverse ? x0 : x1;
      if (probe) {
        const auto xs = line_positions(x0, x1, 0, path.spacing_mm);
        const double travel =
            (hi.z() - lo.z()) + 2 * path.probe_clearance_mm + sensor.tip_radius_mm;
        for (std::size_t i = 0; i < xs.size(); ++i) {
          const double x = reverse ? xs[xs.size() - 1 - i] : xs[i];
          plan.approaches.push_back({pose_for(x, ys[j]), beam_w.normalized(), travel});
        }
        continue;
      }
      const StagePose start = pose_for(xa, ys[j]);
      if (first) {
        plan.trajectory = Trajectory(path.start, start);
        first = false;
      } else {
        plan.trajectory.move_to(start, false, lim);
      }
      plan.trajectory.move_to(pose_for(xb, ys[j]), true, lim, line_speed);
    }
    plan.lines += ys.size();
  }
  if (probe && !plan.approaches.empty())
    plan.trajectory = Trajectory(path.start, plan.approaches.front().start);
  plan.line_speed = line_speed;
  return plan;
}

}  // namespace scanmesh::sim
