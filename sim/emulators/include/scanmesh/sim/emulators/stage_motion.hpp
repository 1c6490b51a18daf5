// The motion model of the stage emulators (GRBL, Modbus drives, I++ DME CMM): a planner queue of
// straight moves executed in real time with velocity and acceleration limits, homing, feed hold,
// abort, a touch probe that triggers on a reference mesh, and an external trajectory the axes can
// follow instead (the simulated scanner's planned scan path).
// SPDX-License-Identifier: MIT
//
// Time is the host monotonic clock (drivers::monotonic_now()): the emulators run in real time
// against real drivers. Every call takes `now` so tests and emulators agree on one instant.
// Simplifications (documented, deliberate): each move starts and ends at rest (no junction
// blending); a feed hold and an abort stop the axes at once (no deceleration ramp); a probing move
// stops exactly at the trigger (no overtravel); the latched position carries the probe noise.
// Thread-safe: one mutex; an emulator thread commands it while tests and trajectories query it.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>

#include "scanmesh/sim/motion.hpp"
#include "scanmesh/sim/simulator.hpp"

namespace scanmesh::sim {

/// The touch probe on the carriage: its tip is a sphere at the mount's origin (Calibration::mount
/// = carriage -> tip centre); the part sits on the table (Calibration::table_center_mm).
struct TouchProbeModel {
  std::shared_ptr<const Scene> scene;  ///< reference mesh, part frame; null: nothing to touch
  Calibration calibration;
  double tip_radius_mm = 1.0;  ///< > 0
  double noise_mm = 0;         ///< Gaussian sigma on each latched linear axis, >= 0
  std::uint64_t seed = 1;
};

struct StageMotionOptions {
  StageLimits limits;      ///< velocity / acceleration limits of the axes
  StagePose start{};       ///< pose at power-up
  StagePose home{};        ///< where the homing cycle ends
  double homing_speed_mm_s = 100;  ///< > 0
  TouchProbeModel probe;
};

/// How a probing move ended.
struct ProbeOutcome {
  enum class Kind { kPending, kContact, kNoContact, kTriggeredAtStart, kAborted };
  Kind kind = Kind::kPending;
  StagePose latched;  ///< kContact: tip centre at the trigger (with noise); else where it stopped
  Timestamp t;        ///< when it ended (the trigger instant for kContact)
};

class StageMotion {
 public:
  explicit StageMotion(StageMotionOptions options);

  /// Appends a straight move to `to`; speeds cap the linear path speed (mm/s) and the table
  /// (rad/s) below the limits. It starts when the previous move ended (or now, when idle).
  /// linear_accel_mm_s2 > 0 caps the linear acceleration below the limit (a drive's commanded
  /// ramp).
  void queue_move(const StagePose& to, double linear_speed_mm_s, double angular_speed_rad_s,
                  Timestamp now, double linear_accel_mm_s2 = 0);
  /// Appends a probing move to `to` (linear axes; the table stays); returns its id for
  /// probe_outcome().
  std::uint64_t queue_probe(const StagePose& to, double speed_mm_s, Timestamp now);
  /// kPending until the probing move ended (then its outcome, kept).
  ProbeOutcome probe_outcome(std::uint64_t id, Timestamp now);
  /// Aborts everything and drives to options.home at the homing speed.
  void start_homing(Timestamp now);
  bool homing(Timestamp now);
  /// Feed hold: the axes stop where they are now; the rest of the queue waits for resume().
  void hold(Timestamp now);
  void resume(Timestamp now);
  bool held() const;
  /// Stops at once and forgets the queue (reset, alarm, jog cancel).
  void abort(Timestamp now);

  StagePose pose(Timestamp now);
  /// Moves running or waiting (a held queue counts).
  std::size_t planned(Timestamp now);
  /// Whether the axes are moving at `now` (not while held).
  bool moving(Timestamp now);
  /// Current commanded path speed, mm/s (0 when standing).
  double speed_mm_s(Timestamp now);
  /// Whether the probe tip touches (or is inside) the part at the current pose.
  bool probe_touching(Timestamp now);

  /// Follows `path` (pose at a time) until `until`, then stands at path(until). Clears the
  /// queue. The simulated scanner drives the axes this way; drivers read the positions back.
  void follow(std::function<StagePose(Timestamp)> path, Timestamp until);
  /// Fault: probing moves never trigger.
  void set_probe_never_triggers(bool on);

  const StageMotionOptions& options() const { return options_; }

 private:
  struct Segment {
    StagePose to;
    double linear_mm_s = 0;
    double angular_rad_s = 0;
    Timestamp queued;
    std::uint64_t probe_id = 0;  ///< 0: not a probing move
    bool homing = false;
    double linear_accel_mm_s2 = 0;  ///< 0: the limit
  };
  struct Active {
    Move move;
    Segment segment;
  };
  void advance(Timestamp now);
  void begin(const Segment& s, Timestamp start);
  bool touching(const StagePose& p) const;
  StagePose pose_locked(Timestamp now);

  StageMotionOptions options_;
  mutable std::mutex mutex_;
  StagePose rest_;
  Timestamp free_at_{};
  std::optional<Active> active_;
  std::deque<Segment> queue_;
  bool held_ = false;
  bool homing_ = false;
  bool never_triggers_ = false;
  std::function<StagePose(Timestamp)> follow_;
  Timestamp follow_until_{};
  std::uint64_t next_probe_id_ = 1;
  std::map<std::uint64_t, ProbeOutcome> probes_;
  std::mt19937_64 rng_;
};

}  // namespace scanmesh::sim
