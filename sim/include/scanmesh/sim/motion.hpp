// Stage motion: velocity- and acceleration-limited (trapezoidal) moves of the X/Y/Z axes and the
// rotary table, the trajectory they form, and the scan paths (raster, serpentine, rotary,
// several views) planned over a part's bounds.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/sim/samples.hpp"
#include "scanmesh/sim/sensor.hpp"

namespace scanmesh::sim {

/// Rest-to-rest motion over `length` (any unit u) with a velocity limit (u/s) and an
/// acceleration limit (u/s^2): accelerate, cruise, decelerate; a triangle when the cruise speed
/// cannot be reached. Times in seconds from the start of the move.
class Trapezoid {
 public:
  Trapezoid() = default;
  Trapezoid(double length, double v_max, double a_max);  ///< length >= 0, limits > 0

  double length() const { return length_; }
  double duration_s() const { return 2 * t_acc_ + t_cruise_; }
  double peak_velocity() const { return v_; }
  double accel_time_s() const { return t_acc_; }
  double position(double t_s) const;  ///< clamped to [0, length]
  double velocity(double t_s) const;
  double time_at(double s) const;  ///< inverse of position, s in [0, length]

 private:
  double length_ = 0;
  double v_ = 0;
  double a_ = 1;
  double t_acc_ = 0;
  double t_cruise_ = 0;
};

/// Velocity and acceleration limits of the axes. Defaults are a small desktop gantry.
struct StageLimits {
  double linear_velocity_mm_s = 200;      ///< per linear axis, > 0
  double linear_accel_mm_s2 = 1000;       ///< per linear axis, > 0
  double rotary_velocity_rad_s = 3.1416;  ///< > 0
  double rotary_accel_rad_s2 = 6.2832;    ///< > 0
  std::vector<std::string> problems() const;
};

/// One straight move in axis space from `from` to `to`, all axes starting and stopping
/// together on one trapezoidal profile of the path parameter s in [0, 1].
struct Move {
  StagePose from;
  StagePose to;        ///< where the profile leads (s = 1)
  StagePose end_pose;  ///< where the move really ends: `to`, or the pose at the cut-off time
  Timestamp start;
  Timestamp end;         ///< start + duration rounded up to a nanosecond (or the cut-off time)
  Trapezoid profile;     ///< over s in [0, 1]
  bool sensing = false;  ///< the sensor measures during this move (gated to scan lines)

  StagePose at(Timestamp t) const;  ///< exact `from` / `end_pose` at and beyond the ends
};

/// A sequence of back-to-back moves (and dwells) starting at a given time.
class Trajectory {
 public:
  explicit Trajectory(Timestamp start = Timestamp{1'000'000'000}, StagePose home = {});

  /// Appends a move from the current end pose to `to` under `limits`, optionally slower:
  /// linear_speed_mm_s caps the speed along the X/Y/Z path and angular_speed_rad_s the table
  /// (infinity: no extra cap). A zero-length move is a no-op.
  void move_to(const StagePose& to, bool sensing, const StageLimits& limits,
               double linear_speed_mm_s = kNoCap, double angular_speed_rad_s = kNoCap);
  /// Stays at the current pose for `duration`.
  void dwell(std::chrono::nanoseconds duration, bool sensing = false);
  /// Stops the last move at time t (a probe trigger): it ends there at its pose at t.
  void cut_last(Timestamp t);

  StagePose pose_at(Timestamp t) const;  ///< before start: home; after end: the final pose
  const std::vector<Move>& moves() const { return moves_; }
  Timestamp start() const { return start_; }
  Timestamp end() const { return moves_.empty() ? start_ : moves_.back().end; }
  const StagePose& end_pose() const { return moves_.empty() ? home_ : moves_.back().end_pose; }

  static constexpr double kNoCap = 1e300;

 private:
  Timestamp start_;
  StagePose home_;
  std::vector<Move> moves_;
};

enum class PathKind : std::uint8_t {
  kRaster,      ///< parallel lines along +x, flyback between them
  kSerpentine,  ///< parallel lines along x, alternating direction
  kRotary,      ///< one table revolution per level of the Z axis, sensor looking at the axis
  kViews,       ///< several table angles, a serpentine raster with a tilted sensor at each
};

std::string_view to_string(PathKind kind);
PathKind path_kind_from_string(std::string_view name);  ///< throws ConfigError

struct PathConfig {
  PathKind kind = PathKind::kSerpentine;
  /// Along-line sample spacing at cruise speed, mm, > 0 (the line speed is spacing * sensor
  /// rate; rotary: at the part's outer radius). Probe: spacing of touch points along a line.
  double spacing_mm = 0.2;
  /// Distance between scan lines (rotary: between Z levels), mm, > 0. 0: one profile width
  /// times 0.8 for a profiler, else 5 * spacing_mm.
  double line_spacing_mm = 0;
  /// Run-in and run-out beyond the part's bounds on each line, mm, >= 0. Default 5.
  double margin_mm = 5;
  /// kViews: number of table angles (2 pi k / views), 1 .. 360. Default 4.
  std::uint32_t views = 4;
  /// kViews: tilt of the sensor from vertical, rad, in [0, 1.2]. Default 0.5.
  double view_tilt_rad = 0.5;
  /// Probe: clearance above the part before each approach, mm, > 0. Default 3.
  double probe_clearance_mm = 3;
  StageLimits limits;
  Timestamp start{1'000'000'000};  ///< time of the first move
  /// Sensor mount (sensor -> carriage), used when use_mount is set; otherwise the path's
  /// natural mount (looking down; sideways for kRotary; tilted for kViews; a profiler's laser
  /// line across the scan direction).
  bool use_mount = false;
  Eigen::Isometry3d mount = Eigen::Isometry3d::Identity();

  std::vector<std::string> problems() const;
};

/// A touch-probe approach: start pose, unit approach direction in the machine frame, travel.
struct ProbeApproach {
  StagePose start;
  Vec3 direction{0, 0, -1};
  double travel_mm = 0;
};

/// A planned scan: the trajectory (without probe approaches), the calibration it implies and,
/// for a probe, the approaches to make in order.
struct ScanPlan {
  Trajectory trajectory;
  Calibration calibration;
  std::vector<ProbeApproach> approaches;
  std::size_t lines = 0;  ///< scan lines (or probe rows)
  double line_speed = 0;  ///< cruise speed along the lines, mm/s (rotary: rad/s)
};

/// Plans `path` for `sensor` over the part bounds (part frame, mm). Throws ConfigError for bad
/// settings, and when the requested line speed exceeds the stage's velocity limit.
ScanPlan plan_scan(const PathConfig& path, const SensorConfig& sensor, const Vec3& part_lo,
                   const Vec3& part_hi);

}  // namespace scanmesh::sim
