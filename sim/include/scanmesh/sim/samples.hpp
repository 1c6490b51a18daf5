// The timestamped values a displacement/profile sensor and a motion stage deliver, as the drivers
// will deliver them (drivers/ does not exist yet: these move to scanmesh_drivers_api unchanged),
// plus the simulator's ground truth for each sensor sample.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <compare>
#include <cstdint>
#include <optional>
#include <string_view>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::sim {

/// A point in time: nanoseconds on the host's monotonic clock (or on a device's own clock where
/// a field says so). Never a bare double.
struct Timestamp {
  std::int64_t ns = 0;

  friend constexpr auto operator<=>(const Timestamp&, const Timestamp&) = default;
  constexpr Timestamp operator+(std::chrono::nanoseconds d) const { return {ns + d.count()}; }
  constexpr Timestamp operator-(std::chrono::nanoseconds d) const { return {ns - d.count()}; }
  constexpr std::chrono::nanoseconds operator-(Timestamp o) const {
    return std::chrono::nanoseconds(ns - o.ns);
  }
};

/// What the sensor itself reports for one measurement (a real sensor cannot tell a dropout or a
/// spike from a real reading: those causes live only in SampleTruth).
enum class SensorStatus : std::uint8_t {
  kOk,         ///< value_mm is a distance inside the measuring range
  kNoTarget,   ///< no usable return (nothing there, shadowed, grazing, dropout)
  kOverRange,  ///< a return outside the measuring range (too near or too far)
};

std::string_view to_string(SensorStatus status);

/// One measurement of a point sensor, or one point of a line profile (a profile is the run of
/// samples sharing one seq, with index 0..n-1 across the laser line).
struct SensorSample {
  std::uint64_t seq = 0;              ///< per sensor, +1 per measurement; gaps = lost samples
  std::optional<Timestamp> t_device;  ///< the sensor's own clock, if it has one
  Timestamp t_host;                   ///< host monotonic time the sample was received
  std::uint32_t index = 0;            ///< point within the profile (0 for a point sensor)
  double value_mm = 0;                ///< distance from the start of the measuring range
                                      ///< along the ray, mm; NaN unless status is kOk
  SensorStatus status = SensorStatus::kNoTarget;
};

/// One position report of the stage: three linear axes and a rotary table.
struct StageSample {
  std::uint64_t seq = 0;  ///< per stage, +1 per report
  Timestamp t;            ///< host monotonic time of the position
  double x_mm = 0;
  double y_mm = 0;
  double z_mm = 0;
  double a_rad = 0;  ///< rotary table angle, counter-clockwise about +z seen from above
};

/// A touch-probe trigger: the stage position latched at the instant of contact.
struct ProbeTrigger {
  std::uint64_t seq = 0;
  Timestamp t;
  double x_mm = 0;
  double y_mm = 0;
  double z_mm = 0;
  double a_rad = 0;
};

/// Why a sensor sample has the value it has. Simulation only.
enum class SampleCause : std::uint8_t {
  kOk,          ///< a genuine reading of the surface (plus range noise)
  kNoHit,       ///< the ray met nothing
  kOutOfRange,  ///< the surface was nearer or farther than the measuring range
  kGrazing,     ///< incidence angle beyond the sensor's limit
  kShadowed,    ///< the receiver could not see the lit spot (triangulation shadow)
  kDropout,     ///< a random dropout of a valid reading
  kSpike,       ///< a random outlier value reported as kOk
};

std::string_view to_string(SampleCause cause);

/// Ground truth of one sensor sample.
struct SampleTruth {
  Timestamp t_true;  ///< instant the measurement was really taken (host clock)
  SampleCause cause = SampleCause::kNoHit;
  recon::Vec3 surface_point_mm{};  ///< the lit surface point in the part frame; NaN if none
  double true_value_mm = 0;        ///< noise-free reading; NaN if no surface point
};

}  // namespace scanmesh::sim
