// The commands through the real scanmesh binary: `journal check` and `journal recover` on a
// complete, a torn and a foreign file; `scans` on a catalog and without one.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include "journal/journal_support.hpp"
#include "journal/scenario.hpp"
#include "scanmesh/acquisition/catalog.hpp"

using namespace scanmesh;
using namespace scanmesh::test;

namespace {

RunResult scanmesh_cli(const TempDir& dir, const std::vector<std::string>& args) {
  return run_program(SCANMESH_EXE, dir, args);
}

std::vector<Item> closed_journal(const std::filesystem::path& p) {
  acq::JournalWriter w(p);
  Scenario sc;
  sc.milliseconds = 300;
  return write_scenario(w, sc);
}

}  // namespace

TEST_CASE("scanmesh journal check and recover", "[acq][journal][cli]") {
  TempDir dir;
  const auto p = dir / "scan.mcap";
  const auto written = closed_journal(p);
  const std::uint64_t samples = sample_count(written);

  auto r = scanmesh_cli(dir, {"journal", "check", p.string(), "--json"});
  CHECK(r.status == 0);
  auto j = nlohmann::json::parse(r.out);
  CHECK(j["complete"] == true);
  CHECK(j["samples"] == samples);
  CHECK(j["crc_failures"] == 0);
  CHECK(j["torn_tail"].is_null());
  CHECK(j["channels"].size() == 6);

  r = scanmesh_cli(dir, {"journal", "check", p.string()});
  CHECK(r.status == 0);
  CHECK_THAT(r.out, Catch::Contains("state         complete") && Catch::Contains("/sensors/lkg0") &&
                        Catch::Contains(std::to_string(samples)));

  // Cut inside a chunk, as a crash leaves it.
  const auto full = acq::check_journal(p);
  const auto& c = full.scan.chunks[full.scan.chunks.size() / 2];
  std::filesystem::resize_file(p, c.offset + c.length / 3);
  r = scanmesh_cli(dir, {"journal", "check", p.string()});
  CHECK(r.status == 3);
  CHECK_THAT(r.out, Catch::Contains("torn tail") && Catch::Contains("scanmesh journal recover"));
  r = scanmesh_cli(dir, {"journal", "check", p.string(), "--json"});
  CHECK(r.status == 3);
  j = nlohmann::json::parse(r.out);
  CHECK(j["torn_tail"]["offset"] == c.offset);
  const std::uint64_t kept = j["samples"];
  CHECK(kept < samples);

  r = scanmesh_cli(dir, {"journal", "recover", p.string(), "--json"});
  CHECK(r.status == 0);
  j = nlohmann::json::parse(r.out);
  CHECK(j["already_complete"] == false);
  CHECK(j["kept"]["samples"] == kept);
  CHECK(j["cut"]["offset"] == c.offset);
  CHECK(j["cut"]["bytes"] == c.length / 3);
  CHECK(scanmesh_cli(dir, {"journal", "check", p.string()}).status == 0);
  r = scanmesh_cli(dir, {"journal", "recover", p.string()});
  CHECK(r.status == 0);
  CHECK_THAT(r.out, Catch::Contains("complete already: nothing changed"));

  // Not a journal, and no file at all: exit 3 naming it.
  spit(dir / "notes.mcap", "not a journal at all, just text\n");
  r = scanmesh_cli(dir, {"journal", "recover", (dir / "notes.mcap").string()});
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains("notes.mcap") && Catch::Contains("not an MCAP file"));
  r = scanmesh_cli(dir, {"journal", "check", (dir / "gone.mcap").string()});
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains("gone.mcap") && Catch::Contains("No such file"));
  CHECK(scanmesh_cli(dir, {"journal"}).status == 2);
}

TEST_CASE("scanmesh scans lists the catalog", "[acq][catalog][cli]") {
  TempDir dir;
  const auto db = dir / "catalog.sqlite";
  const auto now = std::chrono::system_clock::now();
  {
    auto c = acq::Catalog::open(db, now);
    const auto a = c.create_scan({"bracket", dir / "bracket-1.mcap", {}, {}, {}, {}}, now);
    c.finish(a, acq::ScanState::kFailed,
             "journal bracket-1.mcap: write failed: No space left on device", 123, 45, now);
    (void)c.create_scan({"housing", dir / "housing-1.mcap", {}, {}, {}, {}}, now);
  }
  auto r = scanmesh_cli(dir, {"scans", "--catalog", db.string(), "--json"});
  CHECK(r.status == 0);
  const auto j = nlohmann::json::parse(r.out);
  REQUIRE(j["scans"].size() == 2);
  CHECK(j["scans"][0]["name"] == "bracket");
  CHECK(j["scans"][0]["state"] == "failed");
  CHECK(j["scans"][0]["samples"] == 123);
  CHECK_THAT(j["scans"][0]["stop_reason"].get<std::string>(), Catch::Contains("No space left"));
  CHECK(j["scans"][0]["journal_files"][0]["path"] == (dir / "bracket-1.mcap").string());
  CHECK(j["scans"][1]["state"] == "running");
  r = scanmesh_cli(dir, {"scans", "--catalog", db.string()});
  CHECK(r.status == 0);
  CHECK_THAT(r.out, Catch::Contains("bracket") && Catch::Contains("failed") &&
                        Catch::Contains("housing") && Catch::Contains("running"));
  // Listing changes nothing: the running scan stays running (only the daemon's open marks it).
  CHECK(acq::Catalog::open_read_only(db).scans()[1].state == acq::ScanState::kRunning);
  r = scanmesh_cli(dir, {"scans", "--catalog", (dir / "none.sqlite").string()});
  CHECK(r.status == 3);
  CHECK_THAT(r.err, Catch::Contains("none.sqlite") && Catch::Contains("no such file"));
}
