// The scan pipeline: backend devices -> ingest (journal, then the accumulator) -> meshing, on two
// threads of its own. Samples are never dropped: the journal records them first, and when
// meshing falls behind it lags (visible in the stats) and catches up. Live and replayed scans
// run through the same code; a replay feeds the recorded order, so it gives the live points.
// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <variant>
#include <vector>

#include "scanmesh/acquisition/accumulator.hpp"
#include "scanmesh/acquisition/backend.hpp"
#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::acq {

/// The journal stage, called on the ingest thread only. Implementations write each record
/// before the accumulator sees it; acknowledged_samples() counts those durably in the file.
/// Errors (a full disk) throw scanmesh::Error naming the file; the pipeline then stops the scan.
class Recorder {
 public:
  virtual ~Recorder() = default;
  virtual void write_parameters(std::string_view json) = 0;
  virtual void write_sensor(std::uint16_t device, std::span<const SensorSample> samples) = 0;
  virtual void write_stage(const StageSample& sample) = 0;
  virtual void write_probe(std::uint16_t device, const ProbeTrigger& trigger) = 0;
  virtual void write_event(std::string_view json) = 0;
  /// Called after each ingest cycle: the recorder applies its chunk and fsync policy.
  virtual void flush() = 0;
  /// Writes what is pending and closes the file (summary, footer).
  virtual void close() = 0;
  virtual std::uint64_t acknowledged_samples() const = 0;
  virtual std::uint64_t bytes() const = 0;
};

/// What the meshing stage reports.
struct MeshProgress {
  std::uint64_t points_in = 0;     ///< points given to add()
  std::uint64_t kept_points = 0;   ///< after cube reduction
  std::uint64_t vertices = 0;
  std::uint64_t triangles = 0;
  std::uint64_t pending_points = 0;  ///< inside the mesher, not meshed yet
  std::uint64_t deltas = 0;          ///< mesh updates published
  std::uint64_t reopened_blocks = 0;
};

/// The meshing stage, called on the meshing thread only.
class Mesher {
 public:
  virtual ~Mesher() = default;
  virtual void add(std::span<const MeasuredPoint> points) = 0;
  virtual MeshProgress progress() const = 0;
  /// The current mesh, valid (manifold, oriented) at any moment.
  virtual recon::Mesh snapshot() = 0;
  /// Meshes everything left; the final mesh.
  virtual recon::Mesh finish() = 0;
};

enum class PipelineState : std::uint8_t {
  kIdle,       ///< not started
  kRunning,
  kPaused,     ///< by request, or because a device was lost (see PipelineStats::reason)
  kStopping,   ///< finishing the journal and the mesh
  kCompleted,  ///< the scan motion ended and everything was meshed
  kStopped,    ///< stopped on request before the end
  kFailed,     ///< a device or the journal failed; what was recorded is kept
};
std::string_view to_string(PipelineState state);

struct PipelineStats {
  PipelineState state = PipelineState::kIdle;
  std::string reason;                   ///< why paused / failed / stopped
  std::uint64_t samples_received = 0;   ///< sensor samples that entered the pipeline
  std::uint64_t samples_recorded = 0;   ///< acknowledged by the journal
  std::uint64_t stage_samples = 0;
  std::uint64_t points = 0;             ///< 3D points made by the accumulator
  std::uint64_t invalid = 0;            ///< samples with no value
  std::uint64_t no_pose = 0;            ///< samples without a stage pose
  std::uint64_t lost = 0;               ///< samples missing from the devices' sequences
  std::uint64_t journal_bytes = 0;
  std::uint64_t meshing_lag = 0;        ///< points made but not yet meshed (queue + mesher)
  MeshProgress mesh;
  std::chrono::nanoseconds elapsed{0};  ///< since start, pauses included
};

/// Progress and state changes, delivered on the pipeline's threads (a daemon posts them to its
/// own loop). Kinds: "state", "progress", "device", "failure".
struct PipelineEvent {
  std::string kind;
  std::string device;  ///< for "device"
  std::string message;
  PipelineStats stats;
};
using PipelineEventCallback = std::function<void(const PipelineEvent&)>;

struct PipelineConfig {
  /// Ingest cycle: the ingest thread wakes at least this often to write the journal and map
  /// samples. 1 .. 1000 ms. Default 10 ms.
  std::chrono::milliseconds cycle{10};
  /// "progress" events at most this often. Default 250 ms.
  std::chrono::milliseconds progress_interval{250};
  /// Pause the scan when a device is lost, and resume when it is back. Default on.
  bool pause_on_device_loss = true;
  /// Parameters recorded in the journal at the start (scanner model, meshing options), JSON.
  std::string parameters_json = "{}";
};

class Pipeline {
 public:
  /// `recorder` may be null (no journal: a replay). Events go to `on_event` (may be empty).
  Pipeline(ScanBackend& backend, std::unique_ptr<Recorder> recorder, std::unique_ptr<Mesher> mesher,
           PipelineConfig config = {}, PipelineEventCallback on_event = {});
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// Starts the threads and the backend. Throws (and stays idle) when the backend cannot start.
  void start();
  void pause();
  void resume();
  /// Asks the scan to stop before its end; returns at once (wait() for the result).
  void stop();
  /// Blocks until the scan is over (completed, stopped or failed) and its mesh is final.
  PipelineState wait();
  /// Waits at most `timeout`; true when over.
  bool wait_for(std::chrono::milliseconds timeout);

  PipelineStats stats() const;
  /// The current mesh, made on the meshing thread between two batches.
  recon::Mesh snapshot();
  /// The final mesh (after wait()).
  const recon::Mesh& result() const { return result_; }

 private:
  struct DeviceChange {
    std::string name;
    drivers::DeviceState state;
    std::string reason;
  };
  struct Record {
    std::variant<SensorSample, StageSample, ProbeTrigger, DeviceChange> value;
    std::uint16_t device = 0;
  };
  class Input;
  void ingest_loop();
  void mesh_loop();
  void process(std::vector<Record>& records);
  void device_changed(const DeviceChange& change);
  /// Runs a journal write; false (and the scan stopping) when the journal failed.
  template <class F>
  bool record(F&& write) {
    if (!recorder_) return true;
    if (recorder_failed_) return false;
    try {
      write();
      return true;
    } catch (const std::exception& e) {
      recorder_error(e.what());
      return false;
    }
  }
  void recorder_error(const std::string& what);
  std::string final_reason() const;
  void publish_ingest_stats();
  void set_state(PipelineState state, std::string reason);
  void emit(std::string kind, std::string device, std::string message);
  void fail(std::string message);

  ScanBackend* backend_;
  std::unique_ptr<Recorder> recorder_;
  std::unique_ptr<Mesher> mesher_;
  PipelineConfig config_;
  PipelineEventCallback on_event_;
  std::unique_ptr<Input> input_;
  Accumulator accumulator_;
  std::vector<SensorSample> run_;        // ingest thread: one device's consecutive samples
  std::vector<MeasuredPoint> points_;    // ingest thread: points of one cycle

  // Ingest queue (device threads -> ingest thread).
  std::mutex in_mutex_;
  std::condition_variable in_cv_;
  std::vector<Record> incoming_;
  bool end_ = false;              // the backend said the motion ended
  bool stop_requested_ = false;   // stop() was called
  std::string failure_;           // the backend or journal failed

  // Points (ingest thread -> meshing thread).
  std::mutex mesh_mutex_;
  std::condition_variable mesh_cv_;
  std::vector<MeasuredPoint> to_mesh_;
  bool ingest_done_ = false;
  std::vector<std::promise<recon::Mesh>> snapshot_requests_;

  // State and counters (any thread).
  mutable std::mutex state_mutex_;
  std::condition_variable state_cv_;
  PipelineStats stats_;
  bool over_ = false;
  PipelineState final_state_ = PipelineState::kCompleted;  // what the scan ends as
  std::string final_reason_;
  bool recorder_failed_ = false;  // ingest thread
  bool auto_paused_ = false;
  std::chrono::steady_clock::time_point started_;
  std::chrono::steady_clock::time_point ended_;
  std::chrono::steady_clock::time_point last_progress_;

  recon::Mesh result_;
  std::jthread ingest_thread_;
  std::jthread mesh_thread_;
};

}  // namespace scanmesh::acq
