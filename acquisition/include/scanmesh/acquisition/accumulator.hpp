// The point accumulator: joins sensor samples with the stage pose at their instant (linear
// interpolation, configurable latencies, bounded hold at the ends of the pose history), maps
// device clocks to the host clock, applies the sensor's calibrated mounting, and counts every
// sample it cannot turn into a point by cause. Pure: no I/O, no clock, no threads.
// SPDX-License-Identifier: MIT
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "scanmesh/acquisition/clock_mapper.hpp"
#include "scanmesh/acquisition/sensor_model.hpp"
#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::acq {

using drivers::ProbeTrigger;
using drivers::SensorSample;
using drivers::SensorStatus;
using drivers::StageSample;
using drivers::Timestamp;

struct AccumulatorConfig {
  /// Host receive time minus the true measurement time of the sensor and of the stage, >= 0,
  /// <= 1 s. A sample is joined with the stage pose reported at
  /// t_host - sensor_latency + stage_latency. Default 0 / 0.
  std::chrono::nanoseconds sensor_latency{0};
  std::chrono::nanoseconds stage_latency{0};
  /// Two stage reports farther apart than this do not bracket a sample (the stage stopped
  /// reporting): the sample is counted as `no_pose_gap`. > 0. Default 250 ms.
  std::chrono::nanoseconds max_pose_gap{std::chrono::milliseconds(250)};
  /// A sample at most this far before the first or after the last stage report takes that
  /// report's pose (the stage at rest); farther out it is counted as `no_pose` (never
  /// extrapolated). >= 0, <= 1 s. Default 0: no hold.
  std::chrono::nanoseconds max_hold{0};
  /// Stage reports this far behind the newest are forgotten once no sensor's cursor needs them
  /// (bounds memory over a long scan). 0: keep every report (batch use). Default 2 s.
  std::chrono::nanoseconds history_horizon{std::chrono::seconds(2)};
  /// Map the sensor's own clock (SensorSample::t_device) to host time (ClockMapper) where the
  /// device has one, instead of the host receive time. Default on.
  bool use_device_clock = true;
  ClockMapperConfig clock;

  /// Every bad field, one message each (empty: valid).
  std::vector<std::string> problems() const;
  void validate() const;  ///< throws ConfigError listing every problem
};

/// One 3D point in the part frame with where it was seen from.
struct MeasuredPoint {
  std::uint64_t seq = 0;     ///< the sample's sequence number
  std::uint32_t index = 0;   ///< point within the profile (0 for a point sensor)
  Timestamp t;               ///< the sample's instant on the host clock (device clock mapped)
  Vec3 point_mm{};           ///< part frame
  bool probe = false;        ///< a touch-probe trigger rather than an optical reading
  std::uint16_t device = 0;  ///< sensor index in the accumulator
  Vec3 sensor_mm{};          ///< the emitter (probe: the tip centre) in the part frame
};

/// Why samples did not become points, and what did.
struct AccumulatorStats {
  std::uint64_t samples = 0;       ///< sensor samples received (profile points each count)
  std::uint64_t points = 0;        ///< points produced (probe points included)
  std::uint64_t probe_points = 0;  ///< of which touch-probe triggers
  /// Samples without a value, by SensorStatus (kOk: a value that was not finite or a profile
  /// index out of the sensor's range).
  std::array<std::uint64_t, 5> invalid{};
  std::uint64_t no_pose_before = 0;  ///< earlier than the pose history (beyond max_hold)
  std::uint64_t no_pose_after = 0;   ///< later than the last report, at finish (beyond max_hold)
  std::uint64_t no_pose_gap = 0;     ///< between two reports farther apart than max_pose_gap
  std::uint64_t lost = 0;            ///< measurements missing from a device's sequence numbers
  std::uint64_t stage_samples = 0;
  std::uint64_t stage_out_of_order = 0;  ///< stage reports older than the last one (dropped)
  std::uint64_t pending = 0;             ///< samples waiting for a later stage report

  std::uint64_t invalid_total() const;
  std::uint64_t no_pose() const { return no_pose_before + no_pose_after + no_pose_gap; }
};

/// Joins samples with poses. Points come out in sample order per device, each as soon as a stage
/// report at or after its instant has arrived, so the output depends on the order of the calls
/// only, never on how they were batched: a recorded scan replayed in its recorded order gives
/// the live scan's points exactly. Cost: O(1) per sample (a moving cursor on the pose history;
/// one transform per profile); memory: the pending samples and the stage reports they need.
class Accumulator {
 public:
  explicit Accumulator(AccumulatorConfig config = {});  ///< validates

  /// Registers a sensor; returns its device index (0, 1, ... in call order). Throws
  /// ConfigError for an invalid sensor model.
  std::uint16_t add_sensor(const SensorConfig& sensor, const Calibration& calibration);
  std::size_t sensors() const { return sensors_.size(); }
  const SensorOptics& optics(std::uint16_t device) const;
  const Calibration& calibration(std::uint16_t device) const;

  /// A stage report; appends the points it resolves to `out`.
  void add_stage(const StageSample& sample, std::vector<MeasuredPoint>& out);
  /// Samples of one sensor in arrival order (a profile is a run with one seq); appends the points
  /// that can be resolved already to `out`, keeps the rest pending.
  void add_sensor_samples(std::uint16_t device, std::span<const SensorSample> samples,
                          std::vector<MeasuredPoint>& out);
  /// A touch-probe trigger: the latched pose is part of the trigger, so it maps at once: the
  /// tip centre moved by the tip radius along the approach (measured_probe_point).
  void add_probe(std::uint16_t device, const ProbeTrigger& trigger,
                 std::vector<MeasuredPoint>& out);
  /// The stage will report no more: pending samples within max_hold of the last report take its
  /// pose, the rest count as no_pose_after.
  void finish(std::vector<MeasuredPoint>& out);

  const AccumulatorStats& stats() const { return stats_; }
  /// Stage reports held (memory check).
  std::size_t history_size() const { return history_.size(); }
  const AccumulatorConfig& config() const { return config_; }

 private:
  struct Sensor {
    SensorOptics optics;
    Calibration calibration;
    ClockMapper clock;
    // The mounting applied to each ray once: mount.linear() * ray direction, and the emitter's
    // position on the carriage (mount.translation()).
    std::vector<Vec3> mounted_dirs;
    Vec3 mount_origin{};
    std::optional<std::uint64_t> last_seq;
    std::uint64_t cursor = 0;  // absolute history index: the report at or before its last query
    bool active = false;       // has queried the history
  };
  struct Pending {
    SensorSample sample;
    Timestamp t;      ///< the sample's instant on the host clock
    Timestamp query;  ///< stage time the pose is wanted at
    std::uint16_t device;
  };
  /// Resolves pending samples while the pose history covers them.
  void drain(std::vector<MeasuredPoint>& out, bool final);
  /// Resolves one sample at `query` (the history covers it, or it is final and may not).
  void resolve(const SensorSample& s, Timestamp t, Timestamp query, std::uint16_t device,
               std::vector<MeasuredPoint>& out);
  /// Maps one sample at a known pose.
  void emit(const SensorSample& s, Timestamp t, Timestamp query, std::uint16_t device,
            const StagePose& pose, std::vector<MeasuredPoint>& out);
  void prune_history();

  AccumulatorConfig config_;
  std::vector<Sensor> sensors_;
  // Stage reports in time order; history_[i] has the absolute index history_base_ + i.
  std::vector<StageSample> history_;
  std::uint64_t history_base_ = 0;
  std::vector<Pending> pending_;  // in arrival order, [pending_begin_, end)
  std::size_t pending_begin_ = 0;
  // The transform of the last emitted pose (profiles share one).
  // The last pose's transform (a profile's points share it): the emitter relative to the table
  // axis, and the table's rotation (cos, sin of the angle, recomputed only when it changes).
  std::optional<Timestamp> cached_query_;
  std::uint16_t cached_device_ = 0;
  Vec3 cached_base_{};  // stage + mount origin - table centre (machine frame)
  double cached_a_ = 0, cos_a_ = 1, sin_a_ = 0;
  AccumulatorStats stats_;
};

/// Linear interpolation of a stage pose between two reports (the rotary angle too: reports are
/// dense compared with a table's turn, and angles are not wrapped).
StagePose interpolate(const StageSample& a, const StageSample& b, Timestamp t);

/// Batch convenience over one sensor (device 0): every stage report, then every sensor sample,
/// finish(), then every probe trigger; the points in sample order, triggers after. The history
/// is kept whole (history_horizon 0).
std::vector<MeasuredPoint> points_from_samples(const SensorOptics& optics,
                                               const Calibration& calibration,
                                               std::span<const StageSample> stage,
                                               std::span<const SensorSample> sensor,
                                               std::span<const ProbeTrigger> probe = {},
                                               AccumulatorStats* stats = nullptr,
                                               const AccumulatorConfig& config = {});

}  // namespace scanmesh::acq
