// The scan journal: one MCAP file per scan segment with typed channels (sensor samples per
// sensor, stage samples per stage, probe triggers, scan events, parameters), acknowledgement of
// recorded samples, a durability policy, and reading, checking and recovery of journals.
// Layout, guarantees and defaults: acquisition/JOURNAL.md.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/acquisition/mcap.hpp"
#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::acq {

/// Chunking and durability of a journal (defaults in JOURNAL.md). Times are sample time (host
/// monotonic ns).
struct JournalOptions {
  std::size_t chunk_bytes = 64 * 1024;
  std::chrono::nanoseconds chunk_duration = std::chrono::milliseconds(100);
  std::chrono::nanoseconds fsync_interval = std::chrono::seconds(1);
  std::uint64_t fsync_bytes = std::uint64_t{64} << 20;
  /// Written as the file's "scanmesh.journal" metadata record (e.g. scan_id, segment, name).
  std::map<std::string, std::string> metadata;

  [[nodiscard]] std::vector<std::string> validate() const;
};

struct SensorChannel {
  std::uint16_t id = 0;
};
struct StageChannel {
  std::uint16_t id = 0;
};
struct ProbeChannel {
  std::uint16_t id = 0;
};

enum class ChannelKind { kSensor, kStage, kProbe, kEvents, kParameters, kOther };

/// A channel as read back: its kind from the schema, the device it belongs to.
struct ChannelInfo {
  std::uint16_t id = 0;
  ChannelKind kind = ChannelKind::kOther;
  std::string topic;   ///< "/sensors/<device>", "/stages/<device>", "/probes/<device>", ...
  std::string device;  ///< the device name (empty for events and parameters)
  std::map<std::string, std::string> metadata;
};

std::string_view to_string(ChannelKind kind);

/// Writes one journal file. Samples are appended in the order given; a chunk goes to the file
/// (one write) when it reaches chunk_bytes or spans chunk_duration of sample time, and its
/// samples are then acknowledged. fdatasync follows fsync_interval and fsync_bytes. Every write
/// error throws JournalWriteError naming the file; the file then ends on its last whole chunk
/// and every later call throws. Does no work on other threads and starts none; only
/// acknowledged_samples() and durable_samples() may be called from another thread.
class JournalWriter {
 public:
  /// Creates `path` (refused if it exists). Throws ConfigError or JournalWriteError.
  explicit JournalWriter(std::filesystem::path path, JournalOptions options = {});
  ~JournalWriter();  ///< closes (writes the summary) unless failed; never throws
  JournalWriter(const JournalWriter&) = delete;
  JournalWriter& operator=(const JournalWriter&) = delete;

  /// Channels for a device (a name unique per kind); metadata goes into the channel record.
  SensorChannel add_sensor(std::string_view device,
                           std::map<std::string, std::string> metadata = {});
  StageChannel add_stage(std::string_view device, std::map<std::string, std::string> metadata = {});
  ProbeChannel add_probe(std::string_view device, std::map<std::string, std::string> metadata = {});

  /// A batch of consecutive samples of one sensor (any size: split across messages and chunks
  /// as needed). Cost: about 25-33 bytes and a few ns per sample.
  void write_sensor(SensorChannel channel, std::span<const drivers::SensorSample> samples);
  void write_stage(StageChannel channel, const drivers::StageSample& sample);
  void write_probe(ProbeChannel channel, const drivers::ProbeTrigger& trigger);
  /// A scan event at time t: a JSON object with a string "event" (ConfigError otherwise).
  void write_event(drivers::Timestamp t, const nlohmann::json& event);
  /// Parameters in force from time t: a JSON object with a string "kind" ("sensor_config",
  /// "calibration", "reduction", "meshing", ...; ConfigError otherwise).
  void write_parameters(drivers::Timestamp t, const nlohmann::json& parameters);

  /// For idle moments: writes the open chunk once it is chunk_duration old at `now`, and syncs
  /// once fsync_interval has passed, so no sample waits longer than that.
  void tick(drivers::Timestamp now);
  /// Writes the open chunk: everything written so far is acknowledged.
  void flush();
  /// flush() and fdatasync: everything written so far is durable.
  void sync();
  /// Writes the summary and footer and closes the file.
  void close();

  /// Samples (sensor samples, stage samples, probe triggers) in chunks written to the file.
  [[nodiscard]] std::uint64_t acknowledged_samples() const noexcept;
  /// Samples in chunks fdatasync'ed.
  [[nodiscard]] std::uint64_t durable_samples() const noexcept;
  /// Samples given to write_* so far (acknowledged or still in the open chunk).
  [[nodiscard]] std::uint64_t written_samples() const noexcept;
  [[nodiscard]] mcap::WriterStats stats() const noexcept;
  [[nodiscard]] const std::filesystem::path& path() const noexcept;
  [[nodiscard]] bool failed() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Receives a journal's records in log-time order (a journal is written in log-time order, so
/// this is file order too: the order the scan saw them). Spans are valid during the call only.
class JournalVisitor {
 public:
  virtual ~JournalVisitor() = default;
  virtual void on_channel(const ChannelInfo&) {}
  virtual void on_sensor(const ChannelInfo&, std::span<const drivers::SensorSample>) {}
  virtual void on_stage(const ChannelInfo&, const drivers::StageSample&) {}
  virtual void on_probe(const ChannelInfo&, const drivers::ProbeTrigger&) {}
  virtual void on_event(const ChannelInfo&, drivers::Timestamp, std::string_view /*json*/) {}
  virtual void on_parameters(const ChannelInfo&, drivers::Timestamp, std::string_view /*json*/) {}
  /// Messages of other channels (not written by scanmesh).
  virtual void on_other(const ChannelInfo&, const mcap::Message&) {}
};

struct ChannelTotals {
  ChannelInfo channel;
  std::uint64_t messages = 0;
  std::uint64_t samples = 0;      ///< sensor samples, stage samples, probe triggers
  std::uint64_t undecodable = 0;  ///< messages in good chunks whose payload does not decode
};

/// What reading a journal found: the container's scan plus per-channel totals.
struct JournalReport {
  mcap::ScanReport scan;
  std::vector<ChannelTotals> channels;  ///< by channel id
  std::uint64_t samples = 0;
  std::uint64_t undecodable_messages = 0;
  std::int64_t first_sample_ns = 0;  ///< earliest and latest sample time (host)
  std::int64_t last_sample_ns = 0;
  bool being_written = false;  ///< another process holds the file's lock (check only)
};

struct ReadOptions {
  /// Skip damaged chunks and stop at a torn tail instead of throwing InputError.
  bool tolerate_damage = false;
};

/// Reads every record into `visitor`. Throws InputError naming the file and byte offset at
/// damage or a torn tail unless tolerated, or when the file is not a journal.
JournalReport read_journal(const std::filesystem::path& file, JournalVisitor& visitor,
                           ReadOptions options = {});
/// Reads every record of every segment in turn (a resumed scan); one report per segment.
std::vector<JournalReport> read_journals(std::span<const std::filesystem::path> files,
                                         JournalVisitor& visitor, ReadOptions options = {});

/// Read-only check: chunks, records per channel, samples, time span, CRC failures, torn tail,
/// summary consistency. Never throws for damage (it reports it); InputError when unreadable.
JournalReport check_journal(const std::filesystem::path& file);

struct JournalRecovery {
  mcap::RecoveryReport mcap;
  JournalReport kept;  ///< what the recovered file holds
};

/// mcap::recover with per-channel totals of what was kept.
JournalRecovery recover_journal(const std::filesystem::path& file);

/// The one JSON form of each report (the CLI's --json, the daemon).
nlohmann::json to_json(const JournalReport& report);
nlohmann::json to_json(const JournalRecovery& recovery);

}  // namespace scanmesh::acq
