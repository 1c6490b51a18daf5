// The simulated scanner: a sensor on a stage following a planned path over a reference mesh,
// producing the timestamped sensor and stage streams the drivers deliver (with seeded
// imperfections) and the ground truth of every sample.
// SPDX-License-Identifier: MIT
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "scanmesh/recon/mesh.hpp"
#include "scanmesh/sim/bvh.hpp"
#include "scanmesh/sim/motion.hpp"
#include "scanmesh/sim/samples.hpp"
#include "scanmesh/sim/sensor.hpp"

namespace scanmesh::sim {

/// Receives the sample streams, in the order they are produced (drivers deliver the same).
class SampleSink {
 public:
  virtual ~SampleSink() = default;
  /// One measurement: a single sample (point sensor) or a whole profile (same seq, index 0..n-1).
  virtual void on_sensor(std::span<const SensorSample> samples) = 0;
  virtual void on_stage(const StageSample& sample) = 0;
  virtual void on_probe(const ProbeTrigger& trigger) { (void)trigger; }
};

/// Receives the ground truth of the measurement just passed to on_sensor / on_probe.
class TruthSink {
 public:
  virtual ~TruthSink() = default;
  virtual void on_truth(std::span<const SampleTruth> truth) = 0;
};

/// Imperfections. Each draws from its own seeded stream, once per sample whether or not it
/// fires, so changing one setting never moves another's random numbers.
struct ImperfectionConfig {
  std::uint64_t seed = 1;
  double range_noise_mm = 0;       ///< Gaussian sigma on each reading, mm, >= 0
  double dropout_probability = 0;  ///< a valid reading reported as no target, [0, 1]
  double spike_probability = 0;    ///< a valid reading replaced by a uniform random value, [0, 1]
  double missing_probability = 0;  ///< a whole measurement never arrives (a seq gap), [0, 1)
  double stage_noise_mm = 0;       ///< Gaussian sigma on each reported linear axis, mm, >= 0
  double stage_noise_rad = 0;      ///< Gaussian sigma on the reported table angle, rad, >= 0
  /// Host receive time minus true measurement time, sensor and stage. Unequal values shift the
  /// pose acquisition assigns to a sample. Each >= 0, <= 1 s.
  std::chrono::nanoseconds sensor_latency{0};
  std::chrono::nanoseconds stage_latency{0};
  /// The sensor's own clock: true time + offset; nullopt: samples carry no device time.
  std::optional<std::chrono::nanoseconds> device_clock_offset;

  std::vector<std::string> problems() const;
};

struct SimConfig {
  SensorConfig sensor;
  PathConfig path;
  ImperfectionConfig imperfections;
  /// Stage position reports per second, > 0; 0: the sensor rate, on the same clock ticks
  /// (synchronous, so pose interpolation at an unshifted sample time is exact).
  double stage_rate_hz = 0;
  /// Threads casting rays, 0: one per hardware thread. The output does not depend on it.
  std::uint32_t threads = 0;

  void validate() const;  ///< throws ConfigError listing every problem
};

/// A reference mesh with its BVH (part frame, mm).
class Scene {
 public:
  explicit Scene(recon::Mesh mesh);  ///< throws ConfigError for bad indices or no triangles
  const recon::Mesh& mesh() const { return mesh_; }
  const Bvh& bvh() const { return bvh_; }
  Vec3 lo() const { return bvh_.bounds_lo(); }
  Vec3 hi() const { return bvh_.bounds_hi(); }

 private:
  recon::Mesh mesh_;
  Bvh bvh_;
};

/// The geometric outcome of one sensor ray (before any random imperfection).
struct RayHit {
  SampleCause cause = SampleCause::kNoHit;  ///< kOk: a valid return
  bool shadow_ray = false;                  ///< a shadow ray was cast (statistics)
  double t = 0;                             ///< distance along the ray from the emitter, mm
  Vec3 point{};                             ///< lit surface point, part frame (if any)
};

/// Casts one triangulation sensor's rays at a scene: the hit, the incidence limit, the measuring
/// range and the receiver's line of sight (shadowing). Shared by the Simulator and the device
/// emulators, so both see the same surface the same way. Immutable; any thread.
class RayTracer {
 public:
  RayTracer(const Scene& scene, const SensorConfig& sensor);  ///< the scene must outlive it
  /// `emitter`, `receiver` and the unit `dir` in the part frame.
  void trace(const Vec3& emitter, const Vec3& receiver, const Vec3& dir, RayHit& out) const;
  /// Ray `index` of `optics` mounted by `calibration` at stage pose `pose`.
  RayHit trace_at(const SensorOptics& optics, const Calibration& calibration,
                  const StagePose& pose, std::uint32_t index) const;

 private:
  const Scene* scene_;
  double standoff_mm_ = 0;
  double range_mm_ = 0;
  double shadow_offset_mm_ = 0;
  double cos_max_incidence_ = 0;
};

struct SimStats {
  std::uint64_t measurements = 0;  ///< delivered sensor measurements (profiles) and triggers
  std::uint64_t samples = 0;       ///< delivered sensor samples (profile points)
  std::uint64_t missing = 0;       ///< measurements lost (seq gaps)
  std::uint64_t stage_samples = 0;
  std::uint64_t rays = 0;                 ///< primary plus shadow rays cast
  std::array<std::uint64_t, 7> causes{};  ///< delivered samples by SampleCause
  Timestamp start;
  Timestamp end;
  std::uint64_t cause(SampleCause c) const { return causes[static_cast<std::size_t>(c)]; }
};

/// Runs scans of one scene (which must outlive it). Immutable: run() may be called any number of
/// times and gives the same output every time (all randomness is seeded per run).
///
/// run() works in batches of sensor ticks: the calling thread emits one batch (stage reports,
/// imperfections in sample order, sinks) while `threads - 1` workers trace the rays of the next;
/// then it helps finish that batch. Sinks are only ever called from the calling thread.
class Simulator {
 public:
  Simulator(const Scene& scene, SimConfig config);  ///< validates and plans; throws ConfigError

  const SimConfig& config() const { return config_; }
  const SensorOptics& optics() const { return optics_; }
  const Calibration& calibration() const { return plan_.calibration; }
  const ScanPlan& plan() const { return plan_; }
  double stage_rate_hz() const;

  SimStats run(SampleSink& out, TruthSink* truth = nullptr) const;

 private:
  struct Tick;
  struct Batch;
  void trace_chunks(Batch& batch) const;

  const Scene* scene_;
  SimConfig config_;
  SensorOptics optics_;
  ScanPlan plan_;
  struct Contact {
    Timestamp t;     ///< trigger instant (true time)
    Vec3 contact{};  ///< touched surface point, part frame
  };
  std::vector<Contact> probe_triggers_;  ///< touch probe: contacts in time order
  RayTracer tracer_;
};

/// A whole simulated scan in memory.
struct SimulatedScan {
  std::vector<SensorSample> sensor;
  std::vector<SampleTruth> truth;  ///< parallel to `sensor`
  std::vector<StageSample> stage;
  std::vector<ProbeTrigger> probe;
  std::vector<SampleTruth> probe_truth;  ///< parallel to `probe`
  SimStats stats;
};

/// Collects a run into a SimulatedScan.
class ScanRecorder : public SampleSink, public TruthSink {
 public:
  void on_sensor(std::span<const SensorSample> samples) override;
  void on_stage(const StageSample& sample) override;
  void on_probe(const ProbeTrigger& trigger) override;
  void on_truth(std::span<const SampleTruth> truth) override;
  SimulatedScan& scan() { return scan_; }

 private:
  SimulatedScan scan_;
  bool last_was_probe_ = false;
};

/// Convenience: runs the simulator into a ScanRecorder.
SimulatedScan simulate(const Simulator& simulator);

}  // namespace scanmesh::sim
