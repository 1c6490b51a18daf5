// MotionStage: the family interface of motion stages, turntables and CMM axes, including their
// touch-trigger probe (../shared/STYLE.md §5.1). Every stage driver implements it (grbl,
// modbus-stage, ippdme); acquisition joins its StageSamples with the sensor samples.
// SPDX-License-Identifier: MIT
//
// Units: inside the project a pose is StagePose (X/Y/Z in mm, the rotary table A in radians,
// samples.hpp). On the wire the A axis is in degrees; drivers convert. Positions are machine
// coordinates (GRBL MPos, drive counts scaled by the profile, the CMM's machine system).
//
// Commands (move_to ... probe_move) may be called from any thread once start() ran; they are
// executed in order on the driver's worker, which owns the transport. A motion command returns
// when the controller accepted it (not when the motion ended: wait_idle() waits for that); it
// throws DeviceError naming the device, the command and the controller's own words when the
// controller refuses it (kProtocol), does not answer in time (kTimeout) or is lost
// (kDisconnected). Position reports (StageSample) and probe triggers arrive through the
// callbacks, on the worker thread, in order; none after stop() returned.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::drivers {

/// The named axes of a stage. Linear axes in mm; A is the rotary table (degrees on the wire,
/// radians in StagePose).
enum class StageAxis : std::uint8_t { kX, kY, kZ, kA };
std::string_view to_string(StageAxis axis);  ///< "x", "y", "z", "a"

struct StageAxisInfo {
  StageAxis axis = StageAxis::kX;
  std::string unit;  ///< "mm" or "deg": the unit the controller and `scanmesh stage` use
  /// Travel limits in that unit (min == max: unknown).
  double min = 0;
  double max = 0;
};

/// Static facts of a stage driver/model (from its profile or read from the controller).
struct StageCapabilities {
  std::vector<StageAxisInfo> axes;  ///< the axes present, in X, Y, Z, A order
  double max_feed_mm_min = 0;       ///< fastest feed the driver allows (0 = unknown)
  double report_rate_hz = 0;        ///< position reports per second as configured
  bool homing = false;              ///< home() is supported
  bool probing = false;             ///< probe_move() is supported
  bool jog = false;                 ///< jog() is supported (otherwise it is a relative move)
  bool device_clock = false;        ///< StageSample::t_device is set
  /// The controller compensates the probe tip itself (ProbeTrigger::surface is set).
  bool compensates_probe = false;
};

/// Where a move goes: the axes to move (an absent axis stays where it is).
struct StageTarget {
  std::optional<double> x_mm, y_mm, z_mm, a_rad;
  bool empty() const { return !x_mm && !y_mm && !z_mm && !a_rad; }
};

/// The stage's latest known state.
struct StageStatusReport {
  StageStatus status = StageStatus::kLost;
  StagePose pose;         ///< last reported position
  Timestamp t;            ///< host time of that report (0: none yet)
  std::uint64_t seq = 0;  ///< seq of the StageSample it came from (reports so far)
  bool has_report = false;
  int alarm_code = 0;      ///< the controller's own alarm / error number (0: none)
  std::string alarm_text;  ///< its meaning ("Hard limit triggered", "AL009 excessive deviation")
};

/// One touch-probing move from where the stage stands: along the unit vector `direction` for at
/// most `travel_mm`, at `feed_mm_min`; the controller latches the axes at the trigger and stops.
struct ProbeMove {
  double i = 0, j = 0, k = -1;  ///< approach direction, machine frame (normalised by the driver)
  double travel_mm = 10;        ///< > 0
  double feed_mm_min = 100;     ///< > 0
};

struct ProbeMoveResult {
  enum class Outcome {
    kContact,           ///< the probe triggered within the travel: `trigger` holds the latch
    kNoContact,         ///< the whole travel without contact (GRBL [PRB:...:0], I++ 1006)
    kTriggeredAtStart,  ///< the probe was deflected before the move began (GRBL ALARM:4)
  };
  Outcome outcome = Outcome::kNoContact;
  ProbeTrigger trigger;  ///< kContact only
  int device_code = 0;   ///< the controller's code for a non-contact outcome (alarm / error no.)
  std::string detail;    ///< the controller's words for it
};

struct StageCallbacks {
  /// Every position report, in order (worker thread; must not block for long nor throw).
  std::function<void(const StageSample&)> on_sample;
  /// Every probe trigger with its latched axes (worker thread).
  std::function<void(const ProbeTrigger&)> on_probe;
  /// Lifecycle state changes with a reason naming the device. Optional.
  std::function<void(DeviceState, const std::string& reason)> on_state;
};

/// Common options of every stage driver.
struct StageOptions {
  std::string name = "stage";  ///< device name in every message
  /// Position report (status poll) period. Default 50 ms (20 Hz); valid 1 ms .. 10 s.
  std::chrono::microseconds poll_interval{50000};
  /// Reply timeout of one request or command acknowledgement. Default 500 ms; 1 ms .. 60 s.
  std::chrono::milliseconds timeout{500};
  /// Consecutive unanswered status requests after which the stage counts as lost. Default 3.
  int timeouts_until_lost = 3;
  /// Reconnect backoff: first delay, doubled up to the maximum.
  std::chrono::milliseconds backoff_initial{100};
  std::chrono::milliseconds backoff_max{5000};
  /// Longest homing cycle before it counts as failed. Default 120 s.
  std::chrono::milliseconds homing_timeout{120000};
};

class MotionStage {
 public:
  virtual ~MotionStage() = default;

  virtual const std::string& name() const = 0;
  /// Opens the transport and identifies the controller. Throws DeviceError (names the device).
  virtual void open() = 0;
  /// Stops the worker and releases the transport. Never throws.
  virtual void close() noexcept = 0;
  /// Starts position reporting and command execution on the driver's worker. Requires open().
  virtual void start(StageCallbacks callbacks) = 0;
  /// Stops the worker and joins it. Never throws; no callback runs after it returns. Does not
  /// stop the axes (halt() does).
  virtual void stop() noexcept = 0;

  virtual DeviceIdentity identify() const = 0;
  virtual StageCapabilities capabilities() const = 0;
  virtual DeviceState state() const = 0;
  virtual DeviceStats stats() const = 0;

  /// Latest status and position (kLost while the controller does not answer).
  virtual StageStatusReport status() const = 0;
  /// Absolute move of the given axes at feed_mm_min (the table's feed in deg/min).
  virtual void move_to(const StageTarget& target, double feed_mm_min) = 0;
  /// Relative move.
  virtual void move_by(const StageTarget& delta, double feed_mm_min) = 0;
  /// Jog (a relative move the controller lets halt() cancel at once, GRBL $J=).
  virtual void jog(const StageTarget& delta, double feed_mm_min) = 0;
  /// Starts the homing cycle; wait_idle() waits for its end.
  virtual void home() = 0;
  /// Stops all motion as fast as the controller allows and discards queued moves.
  virtual void halt() = 0;
  /// Clears an alarm so the controller accepts motion again (GRBL $X, I++ ClearAllErrors()).
  virtual void clear_alarm() = 0;
  /// Runs one probing move (blocking until it ended) and reports the latch; a kContact result
  /// is also delivered to on_probe.
  virtual ProbeMoveResult probe_move(const ProbeMove& move) = 0;
  /// Waits for a report taken after this call that says the stage stands (idle, alarm, lost)
  /// and returns it; on timeout returns the latest report (status kMoving or kHoming).
  virtual StageStatusReport wait_idle(std::chrono::milliseconds timeout) = 0;
};

}  // namespace scanmesh::drivers
