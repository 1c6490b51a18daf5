// The scan catalog in SQLite: the schema and its version, a scan's life, scans left running
// marked interrupted at open (unless their journal is still being written), recovery of their
// journals, resume as a new segment, close; read-only access beside a writer; refusals.
// SPDX-License-Identifier: MIT
#include <sqlite3.h>

#include <catch2/catch.hpp>
#include <fstream>

#include "journal/journal_support.hpp"
#include "journal/scenario.hpp"
#include "scanmesh/acquisition/catalog.hpp"

using namespace scanmesh;
using namespace scanmesh::test;
using acq::ScanState;

namespace {

acq::WallTime at(int seconds) {
  return acq::WallTime{} + std::chrono::hours(24 * 365 * 56) + std::chrono::seconds(seconds);
}

/// One value from the database, through SQLite's own API (not the catalog's).
std::string query(const std::filesystem::path& db, const std::string& sql) {
  sqlite3* h = nullptr;
  REQUIRE(sqlite3_open_v2(db.c_str(), &h, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK);
  sqlite3_stmt* s = nullptr;
  REQUIRE(sqlite3_prepare_v2(h, sql.c_str(), -1, &s, nullptr) == SQLITE_OK);
  std::string out;
  if (sqlite3_step(s) == SQLITE_ROW && sqlite3_column_text(s, 0) != nullptr)
    out = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
  sqlite3_finalize(s);
  sqlite3_close(h);
  return out;
}

/// A journal of the scenario whose writer "crashed": closed, then cut inside its last chunks.
std::uint64_t crashed_journal(const std::filesystem::path& p) {
  {
    acq::JournalWriter w(p);
    Scenario sc;
    sc.milliseconds = 300;
    (void)write_scenario(w, sc);
  }
  const auto full = acq::check_journal(p);
  const auto& last = full.scan.chunks[full.scan.chunks.size() - 3];
  std::filesystem::resize_file(p, last.offset + last.length / 2);
  return acq::check_journal(p).samples;
}

}  // namespace

TEST_CASE("The catalog: schema version 1 in WAL mode, and a scan's life", "[acq][catalog]") {
  TempDir dir;
  const auto db = dir / "catalog.sqlite";
  std::int64_t id = 0;
  {
    auto c = acq::Catalog::open(db, at(0));
    CHECK(c.newly_interrupted().empty());
    id = c.create_scan({"bracket",
                        dir / "bracket-1.mcap",
                        {{"lkg0", {{"driver", "keyence-lkg"}}}},
                        {{"sphere_residual_mm", 0.004}},
                        {{"cube_mm", 0.2}},
                        {{"min_angle_deg", 30}}},
                       at(1));
    c.set_paused(id, true, at(2));
    CHECK(c.scan(id)->state == ScanState::kPaused);
    c.set_paused(id, false, at(3));
    c.update_counts(id, 1000, 900, at(4));
    c.finish(id, ScanState::kCompleted, "done", 5000, 4800, at(5));
    c.add_output(id, dir / "bracket.stl", "mesh", at(6));
    CHECK_THROWS_WITH(
        c.set_paused(id, true, at(7)),
        Catch::Contains("scan " + std::to_string(id)) && Catch::Contains("completed"));
    CHECK_THROWS_WITH(c.finish(id, ScanState::kStopped, "", 0, 0, at(7)),
                      Catch::Contains("already"));
    CHECK_THROWS_WITH(c.update_counts(99, 0, 0, at(7)), Catch::Contains("scan 99: no such scan"));
  }
  CHECK(query(db, "PRAGMA user_version") == "1");
  CHECK(query(db, "PRAGMA journal_mode") == "wal");
  CHECK(query(db, "SELECT state FROM scans WHERE id = " + std::to_string(id)) == "completed");
  CHECK(query(db, "SELECT json_extract(devices, '$.lkg0.driver') FROM scans") == "keyence-lkg");

  const auto c = acq::Catalog::open_read_only(db);
  const auto s = c.scan(id);
  REQUIRE(s);
  CHECK(s->name == "bracket");
  CHECK(s->state == ScanState::kCompleted);
  CHECK(s->started_at == acq::iso_time(at(1)));
  CHECK(s->stopped_at == acq::iso_time(at(5)));
  CHECK(s->samples == 5000);
  CHECK(s->points == 4800);
  CHECK(s->stop_reason == "done");
  CHECK(s->calibration["sphere_residual_mm"] == 0.004);
  CHECK(s->reduction["cube_mm"] == 0.2);
  REQUIRE(s->segments.size() == 1);
  CHECK(s->segments[0].state == "closed");
  CHECK(s->segments[0].samples == 5000);
  REQUIRE(s->outputs.size() == 1);
  CHECK(s->outputs[0].kind == "mesh");
  const auto j = acq::to_json(*s);
  CHECK(j["state"] == "completed");
  CHECK(j["journal_files"][0]["path"] == (dir / "bracket-1.mcap").string());
  CHECK(j["output_files"][0]["path"] == (dir / "bracket.stl").string());
  CHECK(acq::iso_time(at(0) + std::chrono::milliseconds(125)).ends_with(".125Z"));
}

TEST_CASE("Scans left running are interrupted at open, recovered, then resumed or closed",
          "[acq][catalog]") {
  TempDir dir;
  const auto db = dir / "catalog.sqlite";
  const auto a1 = dir / "a-1.mcap";
  std::int64_t a = 0;
  std::int64_t b = 0;
  std::int64_t live = 0;
  std::uint64_t a1_samples = 0;
  acq::JournalWriter live_writer(dir / "live-1.mcap");  // a scan still being written elsewhere
  {
    auto c = acq::Catalog::open(db, at(0));
    a = c.create_scan({"a", a1, {}, {}, {}, {}}, at(1));
    b = c.create_scan({"b", dir / "b-1.mcap", {}, {}, {}, {}}, at(2));
    c.set_paused(b, true, at(3));
    live = c.create_scan({"live", live_writer.path(), {}, {}, {}, {}}, at(4));
    a1_samples = crashed_journal(a1);
    REQUIRE(a1_samples > 0);
  }  // the daemon dies here: nothing finished

  auto c = acq::Catalog::open(db, at(10));
  CHECK(c.newly_interrupted() == std::vector<std::int64_t>{a, b});
  CHECK(c.scan(a)->state == ScanState::kInterrupted);
  CHECK(c.scan(b)->state == ScanState::kInterrupted);
  CHECK_THAT(c.scan(b)->stop_reason, Catch::Contains("paused"));
  CHECK(c.scan(b)->stopped_at == acq::iso_time(at(10)));
  CHECK(c.scan(live)->state == ScanState::kRunning);

  // Resume needs the open segment's journal recovered first.
  CHECK_THROWS_WITH(c.resume(a, dir / "a-2.mcap", at(11)),
                    Catch::Contains("segment 1 is still open: recover its journal first"));
  const auto reports = acq::recover_interrupted(c, a, at(12));
  REQUIRE(reports.size() == 1);
  CHECK(reports[0].kept.samples == a1_samples);
  CHECK(acq::check_journal(a1).scan.complete());
  auto s = c.scan(a);
  CHECK(s->samples == a1_samples);
  CHECK(s->segments[0].state == "recovered");
  CHECK(s->segments[0].samples == a1_samples);
  CHECK_THAT(s->segments[0].note, Catch::Contains("cut"));

  // Resume: segment 2, running; it finishes with the samples of both segments.
  CHECK(c.resume(a, dir / "a-2.mcap", at(13)) == 2);
  s = c.scan(a);
  CHECK(s->state == ScanState::kRunning);
  CHECK(s->stop_reason.empty());
  CHECK(s->stopped_at.empty());
  REQUIRE(s->segments.size() == 2);
  CHECK(s->segments[1].state == "open");
  CHECK(s->segments[1].path == (dir / "a-2.mcap").string());
  c.finish(a, ScanState::kCompleted, "done", a1_samples + 777, 10, at(20));
  s = c.scan(a);
  CHECK(s->segments[1].state == "closed");
  CHECK(s->segments[1].samples == 777);
  CHECK(s->samples == a1_samples + 777);

  // Close: b's journal never existed (the daemon died before writing it).
  CHECK(acq::recover_interrupted(c, b, at(21)).empty());
  CHECK_THAT(c.scan(b)->segments[0].note, Catch::Contains("missing"));
  c.close_interrupted(b, "closed by the operator after a crash", at(22));
  CHECK(c.scan(b)->state == ScanState::kStopped);
  CHECK(c.scan(b)->stop_reason == "closed by the operator after a crash");
  CHECK_THROWS_WITH(c.resume(b, dir / "b-2.mcap", at(23)),
                    Catch::Contains("only an interrupted scan resumes"));

  // A reader beside the writer connection (WAL) sees the same.
  const auto r = acq::Catalog::open_read_only(db);
  CHECK(r.scans().size() == 3);
  CHECK(r.scan(a)->segments.size() == 2);
  CHECK_THROWS_WITH(
      acq::Catalog::open_read_only(r.path()).create_scan({"x", "x.mcap", {}, {}, {}, {}}, at(30)),
      Catch::Contains("read-only"));
}

TEST_CASE("The catalog refuses what it cannot read", "[acq][catalog]") {
  TempDir dir;
  CHECK_THROWS_WITH(acq::Catalog::open_read_only(dir / "none.sqlite"),
                    Catch::Contains("none.sqlite") && Catch::Contains("no such file"));
  const auto db = dir / "future.sqlite";
  { (void)acq::Catalog::open(db, at(0)); }
  {
    sqlite3* h = nullptr;
    REQUIRE(sqlite3_open(db.c_str(), &h) == SQLITE_OK);
    REQUIRE(sqlite3_exec(h, "PRAGMA user_version = 2", nullptr, nullptr, nullptr) == SQLITE_OK);
    sqlite3_close(h);
  }
  CHECK_THROWS_WITH(acq::Catalog::open(db, at(1)),
                    Catch::Contains("schema version 2 is newer than this scanmesh knows (1)"));
  spit(dir / "text.sqlite", "this is not a database, it is a shopping list\n");
  CHECK_THROWS_WITH(acq::Catalog::open(dir / "text.sqlite", at(1)),
                    Catch::Contains("text.sqlite") && Catch::Contains("not a database"));
}
