// The pipeline over the scan journal: JournalRecorder records a live scan into an MCAP journal
// (the pipeline's Recorder), ReplayBackend plays recorded journals back into the pipeline (a
// ScanBackend), in their recorded order, so a replay meshes exactly what the live scan meshed.
// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "scanmesh/acquisition/backend.hpp"
#include "scanmesh/acquisition/journal.hpp"
#include "scanmesh/acquisition/pipeline.hpp"
#include "scanmesh/drivers/device_support.hpp"

namespace scanmesh::acq {

/// Records into a new journal file: one sensor channel per sensor of the model (a probe also
/// gets a probe channel), one stage channel. Parameters and events are JSON objects (a
/// parameters object without "kind" gets "kind": "scan"). acknowledged_samples() counts every
/// record the journal acknowledged: sensor samples, stage samples and probe triggers.
class JournalRecorder final : public Recorder {
 public:
  /// Creates the file (refused if it exists: JournalWriteError / ConfigError).
  JournalRecorder(const std::filesystem::path& path, const ScannerModel& model,
                  JournalOptions options = {});
  void write_parameters(std::string_view json) override;
  void write_sensor(std::uint16_t device, std::span<const SensorSample> samples) override;
  void write_stage(const StageSample& sample) override;
  void write_probe(std::uint16_t device, const ProbeTrigger& trigger) override;
  void write_event(std::string_view json) override;
  /// Writes a chunk that has waited its time and syncs on the policy's schedule. While no
  /// samples come (a pause), the journal's clock advances with the host clock.
  void flush() override;
  void close() override;
  std::uint64_t acknowledged_samples() const override { return writer_.acknowledged_samples(); }
  std::uint64_t bytes() const override { return writer_.stats().bytes; }
  const std::filesystem::path& path() const { return writer_.path(); }

 private:
  void saw(Timestamp t);
  Timestamp now() const;
  JournalWriter writer_;
  std::vector<SensorChannel> sensors_;
  std::map<std::uint16_t, ProbeChannel> probes_;
  StageChannel stage_;
  Timestamp last_{};
  std::chrono::steady_clock::time_point last_wall_ = std::chrono::steady_clock::now();
};

struct ReplayOptions {
  /// Playback speed relative to the recording (1: as recorded), 0: as fast as possible.
  double speed = 0;
  /// Skip damaged chunks and stop at a torn tail (a journal not recovered after a crash).
  bool tolerate_damage = true;
};

/// Plays journal segments (one scan: the segments in order) into the pipeline. The scanner model
/// and the meshing parameters come from the first segment's "scan" parameters record.
class ReplayBackend final : public ScanBackend {
 public:
  /// Reads the parameters (InputError naming the file when they are missing or malformed).
  explicit ReplayBackend(std::vector<std::filesystem::path> segments, ReplayOptions options = {});
  ~ReplayBackend() override;

  std::string_view kind() const override { return "replay"; }
  ScannerModel model() const override { return model_; }
  std::vector<DeviceStatus> devices() const override;
  void start(SampleInput& input) override;
  void pause() override;
  void resume() override;
  void stop() noexcept override;

  /// The whole "scan" parameters object as recorded (scanner, meshing, ...).
  const nlohmann::json& parameters() const { return parameters_; }
  /// What reading found, per segment (after the replay ended).
  std::vector<JournalReport> reports() const;

 private:
  class Visitor;
  void run(drivers::Worker& worker, SampleInput& input);

  std::vector<std::filesystem::path> segments_;
  ReplayOptions options_;
  ScannerModel model_;
  nlohmann::json parameters_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  bool paused_ = false;
  bool stopping_ = false;
  drivers::DeviceState state_ = drivers::DeviceState::kClosed;
  std::uint64_t delivered_ = 0;
  std::vector<JournalReport> reports_;
  drivers::Worker worker_;
};

}  // namespace scanmesh::acq
