// LineProfiler: the family interface of line profilers (a camera and a line laser, or any device
// that measures a whole profile of 3D points per frame). std only, like displacement_sensor.hpp.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::drivers {

/// One point of a profile, in the sensor frame, mm. The sensor frame of a camera profiler is the
/// camera's (OpenCV's convention: x right, y down, z along the optical axis, origin at the
/// centre of projection). Coordinates are NaN unless status is kOk: the invalid marker.
struct ProfilePoint {
  double x_mm = std::numeric_limits<double>::quiet_NaN();
  double y_mm = std::numeric_limits<double>::quiet_NaN();
  double z_mm = std::numeric_limits<double>::quiet_NaN();
  SensorStatus status = SensorStatus::kNoTarget;  ///< kOk, kNoTarget (no line) or kOverRange
  bool valid() const { return status == SensorStatus::kOk; }
};

/// One frame's profile: a batch of samples sharing one seq, one time and therefore one stage
/// pose. points[i] belongs to image column i (or row i, for a profiler extracting per row).
struct Profile {
  std::uint64_t seq = 0;              ///< per profiler, +1 per profile; gaps = lost frames
  std::optional<Timestamp> t_device;  ///< the camera's own frame time, if it reports one
  Timestamp t_host;                   ///< host monotonic time the frame was received
  std::optional<double> exposure_us;  ///< the frame's exposure, when the camera reports it
  std::optional<double> gain;         ///< the frame's gain (camera units), when reported
  std::vector<ProfilePoint> points;   ///< one per column (or row); invalid markers included

  std::size_t valid_count() const {
    std::size_t n = 0;
    for (const auto& p : points) n += p.valid() ? 1 : 0;
    return n;
  }
};

/// Static facts of a profiler (known after open()).
struct ProfilerCapabilities {
  std::uint32_t width_px = 0;            ///< frame size
  std::uint32_t height_px = 0;
  std::uint32_t points_per_profile = 0;  ///< width (per-column extraction) or height (per row)
  double max_rate_hz = 0;                ///< frames per second the source announces (0: unknown)
  bool exposure_control = false;         ///< the requested exposure was accepted
  bool gain_control = false;             ///< the requested gain was accepted
  bool live = false;                     ///< a camera (false: a file or image sequence)
  bool device_clock = false;             ///< profiles carry t_device
};

struct ProfilerCallbacks {
  /// Called on the profiler's worker thread for every profile, in order. The profile (and its
  /// points) is valid during the call only: copy what must outlive it. Must not block for long
  /// and must not throw.
  std::function<void(const Profile&)> on_profile;
  /// State changes with a reason ("cam0 (/dev/video0): lost: no frame within 1000 ms").
  std::function<void(DeviceState, const std::string& reason)> on_state;
};

/// Common options of every line profiler.
struct ProfilerOptions {
  std::string name = "profiler";  ///< device name in every message
  /// Longest wait for one frame. Default 1000 ms; valid 1 ms .. 60 s.
  std::chrono::milliseconds timeout{1000};
  /// Frames missed in a row after which a live source counts as lost. Default 3.
  int timeouts_until_lost = 3;
  /// Reconnect backoff: first delay, doubled up to the maximum.
  std::chrono::milliseconds backoff_initial{100};
  std::chrono::milliseconds backoff_max{5000};
};

/// The lifecycle, states, statistics and errors are those of DisplacementSensor
/// (drivers/README.md "How a device behaves"): open() throws DeviceError naming the device;
/// start() runs a worker thread; a live source that stops delivering frames becomes kLost and is
/// reopened with bounded backoff; a finite source (files) that ends becomes kLost with the reason
/// "end of ..." and is not reopened; stop() joins the worker and no callback runs after it.
/// stats().samples counts profiles delivered, malformed frames of the wrong size or type,
/// timeouts frames that did not come in time.
class LineProfiler {
 public:
  virtual ~LineProfiler() = default;

  virtual const std::string& name() const = 0;
  /// Opens the source and reads one frame. Throws DeviceError (names the device).
  virtual void open() = 0;
  /// Stops acquisition and releases the source. Never throws.
  virtual void close() noexcept = 0;
  /// Starts acquisition on the profiler's own worker thread. Requires open().
  virtual void start(ProfilerCallbacks callbacks) = 0;
  /// Stops acquisition and joins the worker. Never throws; no callback runs after it returns.
  virtual void stop() noexcept = 0;

  virtual DeviceIdentity identify() const = 0;
  virtual ProfilerCapabilities capabilities() const = 0;
  virtual DeviceState state() const = 0;
  virtual DeviceStats stats() const = 0;
};

}  // namespace scanmesh::drivers
