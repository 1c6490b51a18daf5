// Sensor model configuration, ray geometry and the pose + reading -> point mapping.
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/sensor_model.hpp"

#include <cmath>
#include <numbers>
#include <string>

#include "scanmesh/common/error.hpp"

namespace scanmesh::acq {

std::string_view to_string(SensorKind kind) {
  switch (kind) {
    case SensorKind::kPoint:
      return "point";
    case SensorKind::kLine:
      return "line";
    case SensorKind::kProbe:
      return "probe";
  }
  return "?";
}

SensorKind sensor_kind_from_string(std::string_view name) {
  if (name == "point") return SensorKind::kPoint;
  if (name == "line") return SensorKind::kLine;
  if (name == "probe") return SensorKind::kProbe;
  throw ConfigError("unknown sensor '" + std::string(name) + "' (valid: point, line, probe)");
}

namespace {

bool finite_positive(double v) { return std::isfinite(v) && v > 0; }

std::string num(double v) {
  std::string s = std::to_string(v);
  return s;
}

}  // namespace

std::vector<std::string> SensorConfig::problems() const {
  std::vector<std::string> out;
  if (!finite_positive(standoff_mm))
    out.push_back("sensor standoff_mm must be > 0, got " + num(standoff_mm));
  if (!finite_positive(range_mm))
    out.push_back("sensor range_mm must be > 0, got " + num(range_mm));
  const bool beam_ok = beam_dir.allFinite() && beam_dir.norm() > 1e-12;
  if (!beam_ok) out.push_back("sensor beam_dir must be a finite non-zero vector");
  if (!(rate_hz > 0 && rate_hz <= 1e8))
    out.push_back("sensor rate_hz must be in (0, 1e8], got " + num(rate_hz));
  if (kind != SensorKind::kProbe) {
    if (!(receiver_angle_rad > 0 && receiver_angle_rad <= 1.4))
      out.push_back("sensor receiver_angle_rad must be in (0, 1.4], got " +
                    num(receiver_angle_rad));
    if (!(max_incidence_rad > 0 && max_incidence_rad <= std::numbers::pi / 2 + 1e-12))
      out.push_back("sensor max_incidence_rad must be in (0, pi/2], got " + num(max_incidence_rad));
    if (beam_ok) {
      const Vec3 b = beam_dir.normalized();
      const Vec3 base =
          baseline_dir.allFinite() ? Vec3(baseline_dir - b * baseline_dir.dot(b)) : Vec3::Zero();
      if (!(base.norm() > 1e-6 * std::max(1.0, baseline_dir.norm())))
        out.push_back("sensor baseline_dir must not be parallel to the beam");
      if (kind == SensorKind::kLine) {
        const Vec3 fan = fan_dir.allFinite() ? Vec3(fan_dir - b * fan_dir.dot(b)) : Vec3::Zero();
        if (!(fan.norm() > 1e-6 * std::max(1.0, fan_dir.norm()))) {
          out.push_back("sensor fan_dir must not be parallel to the beam");
        } else if (base.norm() > 0) {
          const Vec3 plane_normal = b.cross(fan.normalized());
          if (std::abs(base.normalized().dot(plane_normal)) < 0.1)
            out.push_back(
                "sensor baseline_dir lies (nearly) in the laser plane: the receiver must look "
                "at the plane from outside it");
        }
      }
    }
  }
  if (kind == SensorKind::kLine) {
    if (!(profile_points >= 1 && profile_points <= 65536))
      out.push_back("sensor profile_points must be in [1, 65536], got " +
                    std::to_string(profile_points));
    if (!(fan_angle_rad >= 0 && fan_angle_rad <= 2.5))
      out.push_back("sensor fan_angle_rad must be in [0, 2.5], got " + num(fan_angle_rad));
  }
  if (kind == SensorKind::kProbe) {
    if (!(std::isfinite(tip_radius_mm) && tip_radius_mm >= 0))
      out.push_back("sensor tip_radius_mm must be >= 0, got " + num(tip_radius_mm));
    if (!finite_positive(probe_speed_mm_s))
      out.push_back("sensor probe_speed_mm_s must be > 0, got " + num(probe_speed_mm_s));
  }
  return out;
}

void SensorConfig::validate() const {
  const auto p = problems();
  if (p.empty()) return;
  std::string msg = "invalid sensor configuration:";
  for (const auto& s : p) msg += "\n  " + s;
  throw ConfigError(msg);
}

SensorConfig default_sensor(SensorKind kind) {
  SensorConfig c;
  c.kind = kind;
  if (kind == SensorKind::kLine) {
    c.fan_dir = Vec3(1, 0, 0);
    c.baseline_dir = Vec3(0, 1, 0);
    c.rate_hz = 500;
  }
  if (kind == SensorKind::kPoint) c.profile_points = 1;
  return c;
}

SensorOptics::SensorOptics(const SensorConfig& config) : config_(config) {
  config_.validate();
  const Vec3 beam = config_.beam_dir.normalized();
  config_.beam_dir = beam;
  if (config_.kind == SensorKind::kLine) {
    const Vec3 fan = (config_.fan_dir - beam * config_.fan_dir.dot(beam)).normalized();
    const std::uint32_t n = config_.profile_points;
    dirs_.reserve(n);
    for (std::uint32_t i = 0; i < n; ++i) {
      const double theta =
          n == 1 ? 0.0 : config_.fan_angle_rad * (static_cast<double>(i) / (n - 1) - 0.5);
      dirs_.push_back((beam * std::cos(theta) + fan * std::sin(theta)).normalized());
    }
  } else {
    dirs_.push_back(beam);
  }
  if (config_.kind != SensorKind::kProbe) {
    const Vec3 base = (config_.baseline_dir - beam * config_.baseline_dir.dot(beam)).normalized();
    receiver_ = base * ((config_.standoff_mm + config_.range_mm / 2) *
                        std::tan(config_.receiver_angle_rad));
  }
}

Eigen::Isometry3d part_from_sensor(const Calibration& calibration, const StagePose& pose) {
  // machine <- sensor: translate(stage) * mount; part <- machine: rotate by -a about the axis.
  const Eigen::Isometry3d machine_from_sensor =
      Eigen::Translation3d(pose.x_mm, pose.y_mm, pose.z_mm) * calibration.mount;
  const Vec3& c = calibration.table_center_mm;
  const Eigen::Isometry3d part_from_machine = Eigen::Translation3d(c) *
                                              Eigen::AngleAxisd(-pose.a_rad, Vec3::UnitZ()) *
                                              Eigen::Translation3d(-c);
  return part_from_machine * machine_from_sensor;
}

Vec3 measured_point(const SensorOptics& optics, const Calibration& calibration,
                    const StagePose& pose, std::uint32_t index, double value_mm) {
  return part_from_sensor(calibration, pose) * optics.point_in_sensor(index, value_mm);
}

Vec3 measured_probe_point(const SensorOptics& optics, const Calibration& calibration,
                          const StagePose& pose) {
  return part_from_sensor(calibration, pose) *
         Vec3(optics.ray_dir(0) * optics.config().tip_radius_mm);
}

}  // namespace scanmesh::acq
