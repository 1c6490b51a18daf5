// The scan catalog in SQLite (see catalog.hpp): schema version 1 created or checked through
// PRAGMA user_version, WAL journal, synchronous=FULL, every change one transaction.
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/catalog.hpp"

#include <time.h>

#include <array>

#include "file.hpp"
#include "sqlite.hpp"

namespace scanmesh::acq {

using detail::Database;
using detail::Statement;
using detail::Transaction;

namespace {

constexpr int kSchemaVersion = 1;

constexpr const char* kSchema = R"sql(
CREATE TABLE scans (
  id          INTEGER PRIMARY KEY,
  name        TEXT NOT NULL,
  state       TEXT NOT NULL CHECK (state IN ('running', 'paused', 'completed', 'stopped',
                                             'failed', 'interrupted')),
  started_at  TEXT NOT NULL,
  stopped_at  TEXT,
  updated_at  TEXT NOT NULL,
  devices     TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(devices)),
  calibration TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(calibration)),
  reduction   TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(reduction)),
  meshing     TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(meshing)),
  samples     INTEGER NOT NULL DEFAULT 0,
  points      INTEGER NOT NULL DEFAULT 0,
  stop_reason TEXT NOT NULL DEFAULT ''
);
CREATE INDEX scans_by_state ON scans(state);
CREATE TABLE journal_segments (
  scan_id    INTEGER NOT NULL REFERENCES scans(id) ON DELETE CASCADE,
  segment    INTEGER NOT NULL,
  path       TEXT NOT NULL,
  state      TEXT NOT NULL CHECK (state IN ('open', 'closed', 'recovered')),
  started_at TEXT NOT NULL,
  closed_at  TEXT,
  samples    INTEGER NOT NULL DEFAULT 0,
  note       TEXT NOT NULL DEFAULT '',
  PRIMARY KEY (scan_id, segment)
);
CREATE TABLE output_files (
  scan_id    INTEGER NOT NULL REFERENCES scans(id) ON DELETE CASCADE,
  path       TEXT NOT NULL,
  kind       TEXT NOT NULL,
  created_at TEXT NOT NULL,
  PRIMARY KEY (scan_id, path)
);
)sql";

constexpr std::array kStates{ScanState::kRunning, ScanState::kPaused, ScanState::kCompleted,
                             ScanState::kStopped, ScanState::kFailed, ScanState::kInterrupted};

int user_version(const Database& db) {
  Statement s(db, "PRAGMA user_version");
  return s.step("reading the schema version") ? static_cast<int>(s.int64(0)) : 0;
}

/// Whether the journal at `path` is locked by a live writer (a scan still running elsewhere).
bool journal_in_use(const std::string& path) {
  try {
    return acq::detail::File::open_read(path).locked_elsewhere();
  } catch (const Error&) {
    return false;  // missing or unreadable: nobody writes it
  }
}

}  // namespace

std::string_view to_string(ScanState state) {
  switch (state) {
    case ScanState::kRunning:
      return "running";
    case ScanState::kPaused:
      return "paused";
    case ScanState::kCompleted:
      return "completed";
    case ScanState::kStopped:
      return "stopped";
    case ScanState::kFailed:
      return "failed";
    case ScanState::kInterrupted:
      return "interrupted";
  }
  return "failed";
}

std::optional<ScanState> scan_state_from_string(std::string_view word) {
  for (const ScanState s : kStates)
    if (to_string(s) == word) return s;
  return std::nullopt;
}

std::string iso_time(WallTime t) {
  const auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count();
  const time_t secs = static_cast<time_t>(ms >= 0 ? ms / 1000 : (ms - 999) / 1000);
  const long frac = static_cast<long>(ms - static_cast<long long>(secs) * 1000);
  struct tm tm {};
  gmtime_r(&secs, &tm);
  char buf[40];
  const std::size_t n = std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  std::snprintf(buf + n, sizeof buf - n, ".%03ldZ", frac);
  return buf;
}

struct Catalog::Impl {
  Impl(const std::filesystem::path& p, bool read_only) : path(p), db(p.string(), read_only) {}
  std::filesystem::path path;
  Database db;
  bool read_only = false;
  bool has_schema = true;
  std::vector<std::int64_t> interrupted;

  [[noreturn]] void refuse(std::int64_t id, const std::string& what) const {
    throw CatalogError("catalog " + path.string() + ": scan " + std::to_string(id) + ": " + what);
  }

  void require_writable() const {
    if (read_only) throw CatalogError("catalog " + path.string() + ": opened read-only");
  }

  ScanState state_of(std::int64_t id) const {
    Statement s(db, "SELECT state FROM scans WHERE id = ?");
    s.bind(1, id);
    if (!s.step("reading a scan")) refuse(id, "no such scan");
    return scan_state_from_string(s.text(0)).value_or(ScanState::kFailed);
  }

  void create_schema() {
    Transaction t(db);
    const int v = user_version(db);
    if (v == 0) {
      db.exec(kSchema, "creating the schema");
      db.exec("PRAGMA user_version = " + std::to_string(kSchemaVersion),
              "setting the schema version");
    }
    t.commit();
  }

  void check_version() {
    const int v = user_version(db);
    if (v > kSchemaVersion)
      throw CatalogError("catalog " + path.string() + ": schema version " + std::to_string(v) +
                         " is newer than this scanmesh knows (" + std::to_string(kSchemaVersion) +
                         "); use a newer scanmesh");
    has_schema = v > 0;
  }

  void mark_interrupted(WallTime now) {
    Transaction t(db);
    std::vector<std::pair<std::int64_t, std::string>> left;
    {
      Statement s(db,
                  "SELECT id, state FROM scans WHERE state IN ('running', 'paused') ORDER BY id");
      while (s.step("listing running scans")) left.emplace_back(s.int64(0), s.text(1));
    }
    for (const auto& [id, state] : left) {
      bool live = false;
      Statement seg(db, "SELECT path FROM journal_segments WHERE scan_id = ? AND state = 'open'");
      seg.bind(1, id);
      while (seg.step("listing open segments")) live = live || journal_in_use(seg.text(0));
      if (live) continue;
      Statement u(db,
                  "UPDATE scans SET state = 'interrupted', stopped_at = ?, updated_at = ?, "
                  "stop_reason = ? WHERE id = ?");
      const std::string at = iso_time(now);
      u.bind(1, at)
          .bind(2, at)
          .bind(3, "interrupted: the daemon stopped while the scan was " + state +
                       " (found at start-up)")
          .bind(4, id);
      u.step("marking a scan interrupted");
      interrupted.push_back(id);
    }
    t.commit();
  }
};

Catalog::Catalog(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Catalog::Catalog(Catalog&&) noexcept = default;
Catalog& Catalog::operator=(Catalog&&) noexcept = default;
Catalog::~Catalog() = default;

Catalog Catalog::open(const std::filesystem::path& file, WallTime now) {
  auto impl = std::make_unique<Impl>(file, false);
  const Database& db = impl->db;
  {
    Statement wal(db, "PRAGMA journal_mode = WAL");
    if (!wal.step("switching to WAL") || wal.text(0) != "wal")
      throw CatalogError("catalog " + file.string() + ": cannot use WAL mode (got '" + wal.text(0) +
                         "')");
  }
  db.exec("PRAGMA synchronous = FULL", "setting synchronous");
  db.exec("PRAGMA foreign_keys = ON", "enabling foreign keys");
  impl->check_version();
  impl->create_schema();
  impl->has_schema = true;
  impl->mark_interrupted(now);
  return Catalog(std::move(impl));
}

Catalog Catalog::open_read_only(const std::filesystem::path& file) {
  if (!std::filesystem::exists(file))
    throw CatalogError("catalog " + file.string() + ": no such file");
  auto impl = std::make_unique<Impl>(file, true);
  impl->read_only = true;
  impl->check_version();
  return Catalog(std::move(impl));
}

const std::vector<std::int64_t>& Catalog::newly_interrupted() const noexcept {
  return impl_->interrupted;
}
const std::filesystem::path& Catalog::path() const noexcept { return impl_->path; }

std::int64_t Catalog::create_scan(const NewScan& scan, WallTime now) {
  Impl& c = *impl_;
  c.require_writable();
  const std::string at = iso_time(now);
  Transaction t(c.db);
  Statement s(c.db,
              "INSERT INTO scans (name, state, started_at, updated_at, devices, calibration, "
              "reduction, meshing) VALUES (?, 'running', ?, ?, ?, ?, ?, ?)");
  s.bind(1, scan.name)
      .bind(2, at)
      .bind(3, at)
      .bind(4, scan.devices.dump())
      .bind(5, scan.calibration.dump())
      .bind(6, scan.reduction.dump())
      .bind(7, scan.meshing.dump());
  s.step("adding a scan");
  const std::int64_t id = sqlite3_last_insert_rowid(c.db.get());
  Statement seg(c.db,
                "INSERT INTO journal_segments (scan_id, segment, path, state, started_at) "
                "VALUES (?, 1, ?, 'open', ?)");
  seg.bind(1, id).bind(2, scan.journal.string()).bind(3, at);
  seg.step("adding a journal segment");
  t.commit();
  return id;
}

void Catalog::set_paused(std::int64_t id, bool paused, WallTime now) {
  Impl& c = *impl_;
  c.require_writable();
  Transaction t(c.db);
  const ScanState s = c.state_of(id);
  if (s != ScanState::kRunning && s != ScanState::kPaused)
    c.refuse(id, "is " + std::string(to_string(s)) + "; only a running scan pauses or resumes");
  Statement u(c.db, "UPDATE scans SET state = ?, updated_at = ? WHERE id = ?");
  u.bind(1, paused ? "paused" : "running").bind(2, iso_time(now)).bind(3, id);
  u.step("pausing a scan");
  t.commit();
}

void Catalog::update_counts(std::int64_t id, std::uint64_t samples, std::uint64_t points,
                            WallTime now) {
  Impl& c = *impl_;
  c.require_writable();
  Statement u(c.db, "UPDATE scans SET samples = ?, points = ?, updated_at = ? WHERE id = ?");
  u.bind(1, static_cast<std::int64_t>(samples))
      .bind(2, static_cast<std::int64_t>(points))
      .bind(3, iso_time(now))
      .bind(4, id);
  u.step("updating a scan's counts");
  if (sqlite3_changes(c.db.get()) == 0) c.refuse(id, "no such scan");
}

void Catalog::finish(std::int64_t id, ScanState state, const std::string& reason,
                     std::uint64_t samples, std::uint64_t points, WallTime now) {
  Impl& c = *impl_;
  c.require_writable();
  if (state != ScanState::kCompleted && state != ScanState::kStopped && state != ScanState::kFailed)
    c.refuse(id,
             "a scan finishes completed, stopped or failed, not " + std::string(to_string(state)));
  Transaction t(c.db);
  const ScanState s = c.state_of(id);
  if (s != ScanState::kRunning && s != ScanState::kPaused)
    c.refuse(id, "is " + std::string(to_string(s)) + " already");
  const std::string at = iso_time(now);
  Statement u(c.db,
              "UPDATE scans SET state = ?, stopped_at = ?, updated_at = ?, stop_reason = ?, "
              "samples = ?, points = ? WHERE id = ?");
  u.bind(1, to_string(state))
      .bind(2, at)
      .bind(3, at)
      .bind(4, reason)
      .bind(5, static_cast<std::int64_t>(samples))
      .bind(6, static_cast<std::int64_t>(points))
      .bind(7, id);
  u.step("finishing a scan");
  // The open segment holds what the earlier segments do not.
  Statement before(c.db,
                   "SELECT COALESCE(SUM(samples), 0) FROM journal_segments WHERE scan_id = ? AND "
                   "state != 'open'");
  before.bind(1, id);
  before.step("summing segments");
  const std::int64_t earlier = before.int64(0);
  Statement seg(c.db,
                "UPDATE journal_segments SET state = 'closed', closed_at = ?, samples = ?, "
                "note = ? WHERE scan_id = ? AND state = 'open'");
  seg.bind(1, at)
      .bind(2, std::max<std::int64_t>(0, static_cast<std::int64_t>(samples) - earlier))
      .bind(3, "closed: scan " + std::string(to_string(state)))
      .bind(4, id);
  seg.step("closing a journal segment");
  t.commit();
}

void Catalog::close_segment(std::int64_t id, int segment, std::string_view state,
                            std::uint64_t samples, const std::string& note, WallTime now) {
  Impl& c = *impl_;
  c.require_writable();
  if (state != "closed" && state != "recovered")
    c.refuse(id, "a segment closes as 'closed' or 'recovered', not '" + std::string(state) + "'");
  Statement u(c.db,
              "UPDATE journal_segments SET state = ?, closed_at = ?, samples = ?, note = ? "
              "WHERE scan_id = ? AND segment = ?");
  u.bind(1, state)
      .bind(2, iso_time(now))
      .bind(3, static_cast<std::int64_t>(samples))
      .bind(4, note)
      .bind(5, id)
      .bind(6, segment);
  u.step("closing a journal segment");
  if (sqlite3_changes(c.db.get()) == 0) c.refuse(id, "no segment " + std::to_string(segment));
}

int Catalog::resume(std::int64_t id, const std::filesystem::path& journal, WallTime now) {
  Impl& c = *impl_;
  c.require_writable();
  Transaction t(c.db);
  const ScanState s = c.state_of(id);
  if (s != ScanState::kInterrupted)
    c.refuse(id, "is " + std::string(to_string(s)) + "; only an interrupted scan resumes");
  Statement open(c.db,
                 "SELECT COUNT(*), COALESCE(MAX(segment), 0) FROM journal_segments WHERE scan_id "
                 "= ? AND state = 'open'");
  open.bind(1, id);
  open.step("listing segments");
  if (open.int64(0) > 0)
    c.refuse(id, "segment " + std::to_string(open.int64(1)) +
                     " is still open: recover its journal first");
  Statement last(c.db, "SELECT COALESCE(MAX(segment), 0) FROM journal_segments WHERE scan_id = ?");
  last.bind(1, id);
  last.step("listing segments");
  const int segment = static_cast<int>(last.int64(0)) + 1;
  const std::string at = iso_time(now);
  Statement seg(c.db,
                "INSERT INTO journal_segments (scan_id, segment, path, state, started_at) VALUES "
                "(?, ?, ?, 'open', ?)");
  seg.bind(1, id).bind(2, segment).bind(3, journal.string()).bind(4, at);
  seg.step("adding a journal segment");
  Statement u(c.db,
              "UPDATE scans SET state = 'running', stopped_at = NULL, stop_reason = '', "
              "updated_at = ? WHERE id = ?");
  u.bind(1, at).bind(2, id);
  u.step("resuming a scan");
  t.commit();
  return segment;
}

void Catalog::close_interrupted(std::int64_t id, const std::string& reason, WallTime now) {
  Impl& c = *impl_;
  c.require_writable();
  Transaction t(c.db);
  const ScanState s = c.state_of(id);
  if (s != ScanState::kInterrupted)
    c.refuse(id, "is " + std::string(to_string(s)) + "; only an interrupted scan is closed so");
  const std::string at = iso_time(now);
  Statement u(c.db,
              "UPDATE scans SET state = 'stopped', stopped_at = ?, updated_at = ?, stop_reason = ? "
              "WHERE id = ?");
  u.bind(1, at).bind(2, at).bind(3, reason).bind(4, id);
  u.step("closing a scan");
  t.commit();
}

void Catalog::add_output(std::int64_t id, const std::filesystem::path& file, std::string_view kind,
                         WallTime now) {
  Impl& c = *impl_;
  c.require_writable();
  Transaction t(c.db);
  (void)c.state_of(id);
  Statement s(c.db,
              "INSERT INTO output_files (scan_id, path, kind, created_at) VALUES (?, ?, ?, ?) "
              "ON CONFLICT (scan_id, path) DO UPDATE SET kind = excluded.kind, created_at = "
              "excluded.created_at");
  s.bind(1, id).bind(2, file.string()).bind(3, kind).bind(4, iso_time(now));
  s.step("adding an output file");
  t.commit();
}

namespace {

nlohmann::json parse_column(const std::string& text) {
  return nlohmann::json::parse(text, nullptr, false);  // json_valid() holds it valid
}

ScanRecord read_row(const Database& db, Statement& s) {
  ScanRecord r;
  r.id = s.int64(0);
  r.name = s.text(1);
  r.state = scan_state_from_string(s.text(2)).value_or(ScanState::kFailed);
  r.started_at = s.text(3);
  r.stopped_at = s.text(4);
  r.updated_at = s.text(5);
  r.devices = parse_column(s.text(6));
  r.calibration = parse_column(s.text(7));
  r.reduction = parse_column(s.text(8));
  r.meshing = parse_column(s.text(9));
  r.samples = static_cast<std::uint64_t>(s.int64(10));
  r.points = static_cast<std::uint64_t>(s.int64(11));
  r.stop_reason = s.text(12);
  Statement seg(db,
                "SELECT segment, path, state, started_at, COALESCE(closed_at, ''), samples, note "
                "FROM journal_segments WHERE scan_id = ? ORDER BY segment");
  seg.bind(1, r.id);
  while (seg.step("reading journal segments")) {
    r.segments.push_back({static_cast<int>(seg.int64(0)), seg.text(1), seg.text(2), seg.text(3),
                          seg.text(4), static_cast<std::uint64_t>(seg.int64(5)), seg.text(6)});
  }
  Statement out(db,
                "SELECT path, kind, created_at FROM output_files WHERE scan_id = ? ORDER BY "
                "created_at, path");
  out.bind(1, r.id);
  while (out.step("reading output files"))
    r.outputs.push_back({out.text(0), out.text(1), out.text(2)});
  return r;
}

constexpr const char* kSelectScans =
    "SELECT id, name, state, started_at, COALESCE(stopped_at, ''), updated_at, devices, "
    "calibration, reduction, meshing, samples, points, stop_reason FROM scans";

}  // namespace

std::optional<ScanRecord> Catalog::scan(std::int64_t id) const {
  const Impl& c = *impl_;
  if (!c.has_schema) return std::nullopt;
  Statement s(c.db, std::string(kSelectScans) + " WHERE id = ?");
  s.bind(1, id);
  if (!s.step("reading a scan")) return std::nullopt;
  return read_row(c.db, s);
}

std::vector<ScanRecord> Catalog::scans() const {
  const Impl& c = *impl_;
  std::vector<ScanRecord> out;
  if (!c.has_schema) return out;
  Statement s(c.db, std::string(kSelectScans) + " ORDER BY id");
  while (s.step("listing scans")) out.push_back(read_row(c.db, s));
  return out;
}

std::vector<JournalRecovery> recover_interrupted(Catalog& catalog, std::int64_t id, WallTime now) {
  const auto scan = catalog.scan(id);
  if (!scan)
    throw CatalogError("catalog " + catalog.path().string() + ": scan " + std::to_string(id) +
                       ": no such scan");
  if (scan->state != ScanState::kInterrupted)
    throw CatalogError("catalog " + catalog.path().string() + ": scan " + std::to_string(id) +
                       ": is " + std::string(to_string(scan->state)) + ", not interrupted");
  std::vector<JournalRecovery> reports;
  std::uint64_t total = 0;
  for (const JournalSegment& seg : scan->segments) {
    if (seg.state != "open") {
      total += seg.samples;
      continue;
    }
    if (!std::filesystem::exists(seg.path)) {
      catalog.close_segment(id, seg.segment, "closed", 0,
                            "the journal file was missing when the scan was recovered", now);
      continue;
    }
    JournalRecovery r = recover_journal(seg.path);
    const std::string note =
        r.mcap.already_complete
            ? "recovered: the journal was complete"
            : "recovered: kept " + std::to_string(r.mcap.kept_chunks) + " chunks (" +
                  std::to_string(r.kept.samples) + " samples), cut " +
                  std::to_string(r.mcap.cut_bytes) + " bytes at byte " +
                  std::to_string(r.mcap.cut_offset) +
                  (r.mcap.wrapped_regions > 0
                       ? ", " + std::to_string(r.mcap.wrapped_regions) + " damaged regions skipped"
                       : "");
    catalog.close_segment(id, seg.segment, "recovered", r.kept.samples, note, now);
    total += r.kept.samples;
    reports.push_back(std::move(r));
  }
  catalog.update_counts(id, total, scan->points, now);
  return reports;
}

nlohmann::json to_json(const ScanRecord& s) {
  nlohmann::json segments = nlohmann::json::array();
  for (const auto& g : s.segments) {
    segments.push_back(
        {{"segment", g.segment},
         {"path", g.path},
         {"state", g.state},
         {"started_at", g.started_at},
         {"closed_at", g.closed_at.empty() ? nlohmann::json(nullptr) : nlohmann::json(g.closed_at)},
         {"samples", g.samples},
         {"note", g.note}});
  }
  nlohmann::json outputs = nlohmann::json::array();
  for (const auto& o : s.outputs)
    outputs.push_back({{"path", o.path}, {"kind", o.kind}, {"created_at", o.created_at}});
  return {
      {"id", s.id},
      {"name", s.name},
      {"state", std::string(to_string(s.state))},
      {"started_at", s.started_at},
      {"stopped_at", s.stopped_at.empty() ? nlohmann::json(nullptr) : nlohmann::json(s.stopped_at)},
      {"updated_at", s.updated_at},
      {"devices", s.devices},
      {"calibration", s.calibration},
      {"reduction", s.reduction},
      {"meshing", s.meshing},
      {"samples", s.samples},
      {"points", s.points},
      {"stop_reason", s.stop_reason},
      {"journal_files", segments},
      {"output_files", outputs}};
}

}  // namespace scanmesh::acq
