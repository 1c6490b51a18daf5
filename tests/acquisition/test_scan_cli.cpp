// `scanmesh scan` end to end: a simulated scan through the pipeline into a mesh file, checked
// with the independent mesh readers and analysis; usage and input errors.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "scanmesh/acquisition/catalog.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/sim/parts.hpp"
#include "support/process.hpp"

using namespace scanmesh;

TEST_CASE("scan --sim: a simulated scan of the steps meshed while it runs", "[acq][cli]") {
  test::TempDir dir;
  const auto out = dir / "steps.ply";
  const auto png = dir / "steps.png";
  const auto r = test::run_program(SCANMESH_EXE, dir,
                                   {"scan", "--sim", "steps", "--sensor", "line", "--spacing",
                                    "0.3", "--noise", "0.01", "--journal",
                                    (dir / "steps.mcap").string(), "--catalog",
                                    (dir / "catalog.sqlite").string(), "--name", "steps-1", "-o",
                                    out.string(), "--preview", png.string(), "--json"});
  INFO(r.err);
  REQUIRE(r.status == 0);
  const auto j = nlohmann::json::parse(r.out);
  CHECK(j["state"] == "completed");
  CHECK(j["mesher"] == "incremental");
  CHECK(j["samples"].get<long>() > 10000);
  CHECK(j["points"].get<long>() + j["invalid"].get<long>() + j["no_pose"].get<long>() ==
        j["samples"].get<long>());
  CHECK(j["meshing_lag"] == 0);
  // Every record acknowledged by the journal: sensor samples and stage reports.
  CHECK(j["recorded"].get<long>() == j["samples"].get<long>() + j["stage_samples"].get<long>());
  CHECK(j["journal_bytes"].get<long>() == static_cast<long>(std::filesystem::file_size(dir / "steps.mcap")));
  // The file is what the JSON says, and lies on the part.
  const recon::Mesh mesh = meshio::read_mesh(out);
  CHECK(mesh.triangles.size() == j["mesh"]["triangles"].get<std::size_t>());
  const auto rep = recon::analyze(mesh);
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.orientation_consistent);
  const recon::SurfaceDistance part(sim::make_part("steps"));
  double worst = 0;
  for (const auto& v : mesh.vertices) worst = std::max(worst, part.distance(v));
  CHECK(worst < 0.1);
  CHECK(std::filesystem::file_size(png) > 1000);
  CHECK(test::slurp(png).substr(1, 3) == "PNG");
  // The catalog's row: completed, the acknowledged count, the journal and both outputs.
  const auto catalog = acq::Catalog::open_read_only(dir / "catalog.sqlite");
  const auto rec = catalog.scan(j["scan_id"].get<std::int64_t>());
  REQUIRE(rec);
  CHECK(rec->name == "steps-1");
  CHECK(rec->state == acq::ScanState::kCompleted);
  CHECK(rec->samples == j["recorded"].get<std::uint64_t>());
  CHECK(rec->points == j["points"].get<std::uint64_t>());
  REQUIRE(rec->segments.size() == 1);
  CHECK(std::filesystem::path(rec->segments[0].path).filename() == "steps.mcap");
  CHECK(rec->outputs.size() == 2);
  CHECK(rec->meshing["mesher"] == "incremental");
  CHECK(rec->devices["sensors"][0]["config"]["kind"] == "line");
}

TEST_CASE("scan: usage and input errors", "[acq][cli]") {
  test::TempDir dir;
  auto run = [&](std::vector<std::string> args) { return test::run_program(SCANMESH_EXE, dir, args); };
  const std::string jl = (dir / "j.mcap").string();
  auto r = run({"scan", "--sim", "steps", "--journal", jl, "-o", (dir / "x.off").string()});
  CHECK(r.status == 2);
  CHECK(r.err.find(".off") != std::string::npos);
  r = run({"scan", "--sim", "steps", "--sensor", "laser", "--journal", jl, "-o",
           (dir / "x.stl").string()});
  CHECK(r.status == 2);
  r = run({"scan", "--sim", (dir / "missing.stl").string(), "--journal", jl, "-o",
           (dir / "x.stl").string()});
  CHECK(r.status == 3);
  CHECK(r.err.find("missing.stl") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(dir / "x.stl"));
  CHECK_FALSE(std::filesystem::exists(jl));
  r = run({"scan", "--sim", "steps", "-o", (dir / "x.stl").string()});  // --journal is required
  CHECK(r.status == 2);
  // An existing journal is never overwritten.
  test::spit(jl, "keep me");
  r = run({"scan", "--sim", "steps", "--journal", jl, "-o", (dir / "x.stl").string()});
  CHECK(r.status != 0);
  CHECK(r.err.find("j.mcap") != std::string::npos);
  CHECK(test::slurp(jl) == "keep me");
  // replay: a missing journal, a file that is not a journal.
  r = run({"replay", (dir / "none.mcap").string(), "-o", (dir / "x.stl").string()});
  CHECK(r.status == 3);
  CHECK(r.err.find("none.mcap") != std::string::npos);
  r = run({"replay", jl, "-o", (dir / "x.stl").string()});
  CHECK(r.status == 3);
  CHECK(r.err.find("j.mcap") != std::string::npos);
}

TEST_CASE("replay: a journal meshes into the live scan's mesh byte for byte, also when cut short",
          "[acq][cli]") {
  test::TempDir dir;
  const std::string journal = (dir / "scan.mcap").string();
  // Live at 4x the scan's pace: meshing runs on many small batches while samples arrive.
  const auto live = test::run_program(
      SCANMESH_EXE, dir,
      {"scan", "--sim", "container", "--sensor", "line", "--spacing", "0.4", "--noise", "0.01",
       "--pace", "4", "--journal", journal, "-o", (dir / "live.ply").string(), "--json"});
  INFO(live.err);
  REQUIRE(live.status == 0);
  const auto rep = test::run_program(
      SCANMESH_EXE, dir, {"replay", journal, "-o", (dir / "replay.ply").string(), "--json"});
  INFO(rep.err);
  REQUIRE(rep.status == 0);
  const auto jl = nlohmann::json::parse(live.out);
  const auto jr = nlohmann::json::parse(rep.out);
  CHECK(jr["samples"] == jl["samples"]);
  CHECK(jr["points"] == jl["points"]);
  CHECK(test::slurp(dir / "replay.ply") == test::slurp(dir / "live.ply"));
  // Another cube on replay: another mesh from the same samples.
  const auto coarse = test::run_program(
      SCANMESH_EXE, dir,
      {"replay", journal, "--cube", "1.5", "-o", (dir / "coarse.ply").string(), "--json"});
  REQUIRE(coarse.status == 0);
  CHECK(nlohmann::json::parse(coarse.out)["kept_points"].get<long>() <
        jl["kept_points"].get<long>() / 4);
  // A journal cut in the middle of a chunk (a crash): replayed up to its last whole chunk.
  const std::string whole = test::slurp(journal);
  test::spit(dir / "cut.mcap", whole.substr(0, whole.size() * 6 / 10 + 7));
  const auto cut = test::run_program(
      SCANMESH_EXE, dir,
      {"replay", (dir / "cut.mcap").string(), "-o", (dir / "cut.ply").string(), "--json"});
  INFO(cut.err);
  REQUIRE(cut.status == 0);
  const auto jc = nlohmann::json::parse(cut.out);
  CHECK(jc["samples"].get<long>() > jl["samples"].get<long>() / 2);
  CHECK(jc["samples"].get<long>() < jl["samples"].get<long>());
  CHECK(jc["mesh"]["non_manifold_edges"] == 0);
}
