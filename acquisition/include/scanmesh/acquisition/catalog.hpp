// The scan catalog: one SQLite database (WAL) holding a row per scan (name, state, times, the
// device and calibration snapshot, reduction and meshing parameters, counts, the reason it
// stopped) with its journal segments and output files. Schema and states: acquisition/JOURNAL.md.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/acquisition/journal.hpp"
#include "scanmesh/common/error.hpp"

namespace scanmesh::acq {

/// The catalog cannot be opened or written (the message names the file and SQLite's words), or
/// an operation does not fit the scan's state (the message names the scan).
class CatalogError : public Error {
 public:
  using Error::Error;
};

/// Where the daemon keeps its catalog unless told otherwise (systemd's StateDirectory=scanmesh).
inline constexpr std::string_view kDefaultCatalogPath = "/var/lib/scanmesh/catalog.sqlite";

/// A scan's state as the catalog keeps it (the pipeline's live PipelineState has more steps;
/// the catalog adds `interrupted`: the process that ran the scan died).
enum class ScanState { kRunning, kPaused, kCompleted, kStopped, kFailed, kInterrupted };

std::string_view to_string(ScanState state);
std::optional<ScanState> scan_state_from_string(std::string_view word);

using WallTime = std::chrono::system_clock::time_point;

struct JournalSegment {
  int segment = 0;  ///< 1, 2, ... in the order written
  std::string path;
  std::string state;  ///< "open" (being written), "closed", "recovered" (after a crash)
  std::string started_at;
  std::string closed_at;      ///< empty while open
  std::uint64_t samples = 0;  ///< acknowledged samples in the file (when closed or recovered)
  std::string note;           ///< what closing or recovery said
};

struct OutputFile {
  std::string path;
  std::string kind;  ///< "mesh", "preview", "points", ...
  std::string created_at;
};

/// One scan. Times are ISO 8601 UTC with milliseconds ("2026-05-14T09:30:00.125Z").
struct ScanRecord {
  std::int64_t id = 0;
  std::string name;
  ScanState state = ScanState::kRunning;
  std::string started_at;
  std::string stopped_at;  ///< empty unless completed, stopped, failed or interrupted
  std::string updated_at;
  nlohmann::json devices = nlohmann::json::object();      ///< device snapshot
  nlohmann::json calibration = nlohmann::json::object();  ///< calibration snapshot
  nlohmann::json reduction = nlohmann::json::object();    ///< reduction parameters
  nlohmann::json meshing = nlohmann::json::object();      ///< meshing parameters
  std::uint64_t samples = 0;                              ///< acknowledged samples, all segments
  std::uint64_t points = 0;                               ///< points mapped
  std::string stop_reason;  ///< why it stopped (the error of a failed scan)
  std::vector<JournalSegment> segments;
  std::vector<OutputFile> outputs;
};

struct NewScan {
  std::string name;
  std::filesystem::path journal;  ///< segment 1
  nlohmann::json devices = nlohmann::json::object();
  nlohmann::json calibration = nlohmann::json::object();
  nlohmann::json reduction = nlohmann::json::object();
  nlohmann::json meshing = nlohmann::json::object();
};

/// The catalog, one connection. Every change is one transaction. Not thread-safe: one owner
/// (the daemon's io thread); other processes may read at the same time (WAL).
class Catalog {
 public:
  /// Opens or creates the catalog read-write (creating its schema or checking its version) and
  /// marks scans left running or paused as interrupted (a daemon that died), unless the journal
  /// they are writing is still locked by a live process. Throws CatalogError.
  static Catalog open(const std::filesystem::path& file, WallTime now);
  /// Opens an existing catalog to read it (`scanmesh scans`); changes nothing.
  static Catalog open_read_only(const std::filesystem::path& file);

  Catalog(Catalog&&) noexcept;
  Catalog& operator=(Catalog&&) noexcept;
  ~Catalog();

  /// Scans open() marked interrupted.
  [[nodiscard]] const std::vector<std::int64_t>& newly_interrupted() const noexcept;
  [[nodiscard]] const std::filesystem::path& path() const noexcept;

  /// A new scan, running, with its first journal segment open. Returns its id.
  std::int64_t create_scan(const NewScan& scan, WallTime now);
  /// running <-> paused.
  void set_paused(std::int64_t id, bool paused, WallTime now);
  /// Acknowledged samples (all segments) and mapped points so far.
  void update_counts(std::int64_t id, std::uint64_t samples, std::uint64_t points, WallTime now);
  /// Ends a running or paused scan: completed, stopped or failed, with the reason; closes its
  /// open segment with the samples it holds.
  void finish(std::int64_t id, ScanState state, const std::string& reason, std::uint64_t samples,
              std::uint64_t points, WallTime now);
  /// Marks a segment closed or recovered with its acknowledged samples and a note.
  void close_segment(std::int64_t id, int segment, std::string_view state, std::uint64_t samples,
                     const std::string& note, WallTime now);
  /// Resumes an interrupted scan: a new segment (the next number) writing `journal`, state
  /// running. Its open segments must have been closed or recovered first.
  int resume(std::int64_t id, const std::filesystem::path& journal, WallTime now);
  /// Closes an interrupted scan for good: stopped, with the reason.
  void close_interrupted(std::int64_t id, const std::string& reason, WallTime now);
  void add_output(std::int64_t id, const std::filesystem::path& file, std::string_view kind,
                  WallTime now);

  [[nodiscard]] std::optional<ScanRecord> scan(std::int64_t id) const;
  /// Every scan, by id.
  [[nodiscard]] std::vector<ScanRecord> scans() const;

 private:
  struct Impl;
  explicit Catalog(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// For the daemon at start: recovers every open journal segment of an interrupted scan
/// (recover_journal), records each as recovered with the samples kept, and sets the scan's
/// sample count to the sum over its segments. A segment whose file is missing is recorded as
/// closed with 0 samples and a note saying so.
std::vector<JournalRecovery> recover_interrupted(Catalog& catalog, std::int64_t id, WallTime now);

/// ISO 8601 UTC with milliseconds.
std::string iso_time(WallTime t);

/// The one JSON form of a scan (`scanmesh scans --json`, the daemon).
nlohmann::json to_json(const ScanRecord& scan);

}  // namespace scanmesh::acq
