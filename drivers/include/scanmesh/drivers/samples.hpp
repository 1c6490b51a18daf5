// The timestamped values displacement sensors and motion stages deliver (the drivers' sample
// types, shared by drivers/, sim/ and acquisition/).
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <compare>
#include <cstdint>
#include <optional>
#include <string_view>

namespace scanmesh::drivers {

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

/// Host monotonic time now (CLOCK_MONOTONIC through std::chrono::steady_clock).
Timestamp monotonic_now();

/// What the sensor itself reports for one measurement.
/// The string forms (to_string) are part of the `device read` JSON and of the sim stream format.
enum class SensorStatus : std::uint8_t {
  kOk,          ///< "ok": value_mm is a distance inside the measuring range
  kNoTarget,    ///< "no_target": no usable return (nothing there, shadowed, grazing, no peak)
  kOverRange,   ///< "over_range": a return outside the measuring range (too near or too far)
  kAlarm,       ///< "alarm": the sensor flags the value as invalid (alarm, dashes, XXXXXXX)
  kDeviceError, ///< "device_error": an error code in place of a value (laser off, rate too high)
};

std::string_view to_string(SensorStatus status);
/// Inverse of to_string; nullopt for an unknown word.
std::optional<SensorStatus> sensor_status_from_string(std::string_view word);

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
  std::uint32_t device_code = 0;  ///< the raw code the device sent with kAlarm/kDeviceError
};

/// Position of the machine axes: three linear axes carrying the sensor and a rotary table
/// carrying the part. The one axis tuple of the project (stage reports, probe latches, sim paths,
/// acquisition's pose interpolation).
struct StagePose {
  double x_mm = 0;
  double y_mm = 0;
  double z_mm = 0;
  double a_rad = 0;  ///< rotary table angle, counter-clockwise about +z seen from above

  friend constexpr bool operator==(const StagePose&, const StagePose&) = default;
};

/// What a stage is doing. The string forms (to_string) are part of `scanmesh stage --json`.
enum class StageStatus : std::uint8_t {
  kIdle,    ///< "idle": standing, ready for commands
  kMoving,  ///< "moving": a move, jog or probing move is running (or held)
  kHoming,  ///< "homing": the homing cycle is running
  kAlarm,   ///< "alarm": the controller refuses motion until its alarm is cleared
  kLost,    ///< "lost": the controller does not answer (the driver reconnects on its own)
};

std::string_view to_string(StageStatus status);
/// Inverse of to_string; nullopt for an unknown word.
std::optional<StageStatus> stage_status_from_string(std::string_view word);

/// One position report of the stage.
struct StageSample {
  std::uint64_t seq = 0;  ///< per stage, +1 per report
  Timestamp t;            ///< host monotonic time of the position (when the report arrived)
  StagePose pose;
  std::optional<Timestamp> t_device;      ///< the controller's own clock, if it reports one
  StageStatus status = StageStatus::kIdle;  ///< what the stage was doing at that report
};

/// A point the controller measured itself, already compensated for the probe tip (a CMM over
/// I++ DME): the surface point and the unit surface normal it compensated along, machine frame.
struct SurfacePoint {
  double x_mm = 0;
  double y_mm = 0;
  double z_mm = 0;
  double i = 0;
  double j = 0;
  double k = 0;
};

/// A touch-probe trigger: the stage position latched at the instant of contact.
struct ProbeTrigger {
  std::uint64_t seq = 0;
  Timestamp t;  ///< host monotonic time of the latch
  StagePose pose;  ///< the latched axes: the probe tip centre at contact (machine frame)
  std::optional<Timestamp> t_device;    ///< the controller's clock at the latch, if it has one
  std::optional<SurfacePoint> surface;  ///< the controller's own compensated point, if it gives one
};

}  // namespace scanmesh::drivers
