// The sensor model acquisition maps through: intrinsic optics of a point sensor, a line
// profiler or a touch probe, the extrinsic calibration (sensor mount, rotary table axis), and the
// pure function from a stage pose plus a reading to a 3D point in the part frame.
// SPDX-License-Identifier: MIT
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/drivers/samples.hpp"
#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::acq {

using drivers::StagePose;
using recon::Vec3;

enum class SensorKind : std::uint8_t {
  kPoint,  ///< laser triangulation point sensor: one ray per sample
  kLine,   ///< laser line profiler: a fan of rays in the laser plane per sample (a profile)
  kProbe,  ///< touch-trigger probe: contact points along approach vectors
};

std::string_view to_string(SensorKind kind);
/// "point", "line" or "probe"; throws ConfigError otherwise.
SensorKind sensor_kind_from_string(std::string_view name);

/// Intrinsic sensor parameters, in the sensor frame (origin at the laser emitter, or at the
/// probe tip centre). Angles in radians, lengths in millimetres.
struct SensorConfig {
  SensorKind kind = SensorKind::kPoint;
  /// Emitter to the near end of the measuring range along each ray, mm. > 0. Default 80.
  double standoff_mm = 80;
  /// Length of the measuring range along each ray, mm. > 0. Default 60. A reading value_mm is
  /// the distance beyond the standoff: 0 .. range_mm.
  double range_mm = 60;
  /// Laser beam direction (point sensor; the central ray of a profiler; the probe's approach
  /// direction). Any non-zero vector, normalised. Default -z.
  Vec3 beam_dir{0, 0, -1};
  /// Direction from the emitter towards the receiver (its component along the beam is
  /// ignored). For a profiler it must leave the laser plane. Default +x (point) / +y (line).
  Vec3 baseline_dir{1, 0, 0};
  /// Triangulation angle between the beam and the line from the middle of the measuring range
  /// to the receiver, rad, in (0, 1.4]. Sets the receiver position: baseline distance
  /// (standoff + range / 2) tan(angle). Default 0.436 (25 degrees).
  double receiver_angle_rad = 0.436;
  /// Largest angle between a ray and the surface normal that still returns light, rad, in
  /// (0, pi/2]. Default 1.309 (75 degrees).
  double max_incidence_rad = 1.309;
  /// Measurement (profile) rate, Hz. > 0, at most 1e8. Default 1000.
  double rate_hz = 1000;
  /// Line profiler: direction across the laser line, perpendicular to the beam. Default +x.
  Vec3 fan_dir{1, 0, 0};
  /// Line profiler: points per profile, 1 .. 65536. Ignored (1) for the point sensor.
  std::uint32_t profile_points = 200;
  /// Line profiler: full fan angle, rad, in [0, 2.5]. Default 0.35 (about 39 mm wide at 110 mm).
  double fan_angle_rad = 0.35;
  /// Touch probe: tip ball radius, mm, >= 0. Default 1.
  double tip_radius_mm = 1;
  /// Touch probe: approach speed, mm/s, > 0. Default 5.
  double probe_speed_mm_s = 5;

  /// Every problem with the fields, one message each (empty: valid).
  std::vector<std::string> problems() const;
  /// Throws ConfigError listing every problem at once.
  void validate() const;
};

/// The default configuration of each kind (the profiler's receiver sits out of its laser plane).
SensorConfig default_sensor(SensorKind kind);

/// Precomputed optics of a validated SensorConfig: unit ray directions and receiver position in
/// the sensor frame.
class SensorOptics {
 public:
  explicit SensorOptics(const SensorConfig& config);  ///< validates

  const SensorConfig& config() const { return config_; }
  std::uint32_t ray_count() const { return static_cast<std::uint32_t>(dirs_.size()); }
  /// Unit direction of ray `index` (0 .. ray_count-1). Profile rays are evenly spaced in angle
  /// from -fan/2 (towards -fan_dir) to +fan/2.
  const Vec3& ray_dir(std::uint32_t index) const { return dirs_[index]; }
  /// Receiver (camera) centre in the sensor frame.
  const Vec3& receiver() const { return receiver_; }
  /// Point of ray `index` at reading value_mm, sensor frame: dir * (standoff + value).
  Vec3 point_in_sensor(std::uint32_t index, double value_mm) const {
    return dirs_[index] * (config_.standoff_mm + value_mm);
  }

 private:
  SensorConfig config_;
  std::vector<Vec3> dirs_;
  Vec3 receiver_{};
};


/// Extrinsic calibration. Frames: the machine frame is fixed; the stage's X/Y/Z axes carry the
/// sensor (sensor frame = translate(x, y, z) * mount in the machine frame); the part sits on the
/// rotary table, whose axis is +z through table_center_mm. The part frame equals the machine
/// frame at a = 0 and turns with the table. Reference meshes and all output points are in the
/// part frame.
struct Calibration {
  Eigen::Isometry3d mount = Eigen::Isometry3d::Identity();  ///< sensor -> carriage
  Vec3 table_center_mm{0, 0, 0};                            ///< a point on the table axis
};

/// Sensor frame -> part frame at stage pose `pose`.
Eigen::Isometry3d part_from_sensor(const Calibration& calibration, const StagePose& pose);

/// The pure mapping acquisition applies: stage pose at the sample's time + optical reading of
/// ray `index` -> 3D point in the part frame, mm.
Vec3 measured_point(const SensorOptics& optics, const Calibration& calibration,
                    const StagePose& pose, std::uint32_t index, double value_mm);

/// The same for a touch-probe trigger: the tip centre at the latched pose, moved by the tip
/// radius along the approach direction (exact where the surface faces the approach).
Vec3 measured_probe_point(const SensorOptics& optics, const Calibration& calibration,
                          const StagePose& pose);

}  // namespace scanmesh::acq
