// The simulated scanner through the protocol emulators and the real drivers: the GRBL and ILD1420
// emulators on ptys, the grbl and microepsilon-ild1420 drivers reading them, the DevicesBackend
// running the scan program, the pipeline mapping, recording and meshing. Real time: each scan
// takes seconds.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <catch2/catch.hpp>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "scanmesh/acquisition/journal.hpp"
#include "scanmesh/acquisition/journal_backend.hpp"
#include "scanmesh/acquisition/meshers.hpp"
#include "scanmesh/acquisition/pipeline.hpp"
#include "scanmesh/acquisition/scanner_json.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/sim/emulators/emulated_backend.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/scanner_backend.hpp"
#include "support/process.hpp"
#include "pipeline_events.hpp"

using namespace scanmesh;
using namespace std::chrono_literals;

namespace {

/// A short raster over the sphere: 2 mm lines at 100 mm/s (about 15 s).
sim::ScanSettings sphere_scan(double line_spacing_mm = 2) {
  sim::ScanSettings s;
  s.sensor = "point";
  s.path = "serpentine";
  s.line_spacing_mm = line_spacing_mm;
  s.speed_mm_s = 100;
  s.noise_mm = 0.005;
  s.seed = 3;
  return s;
}

using Events = test::PipelineEvents;

/// How far a mesh's vertices lie from the part: the largest distance and the 99th percentile.
struct Deviation {
  double worst = 0;
  double p99 = 0;
  double p90 = 0;
  double median = 0;
};

Deviation vertex_deviation(const recon::Mesh& mesh, const recon::Mesh& part) {
  const recon::SurfaceDistance to_part(part);
  std::vector<double> d;
  for (const auto& v : mesh.vertices) d.push_back(to_part.distance(v));
  if (d.empty()) return {};
  std::sort(d.begin(), d.end());
  return {d.back(), d[d.size() * 99 / 100], d[d.size() * 9 / 10], d[d.size() / 2]};
}

/// The same scan simulated in process (no devices, no timing): what the cube reduction and the
/// mesher make of it is the reference the emulated scan is compared with.
Deviation in_process_deviation(const recon::Mesh& part, const sim::ScanSettings& settings) {
  sim::SimulatedScanner backend(part, settings.to_config(), {});
  const nlohmann::json meshing{{"mesher", "incremental"}, {"cube", "2"}};
  acq::Pipeline pipeline(backend, nullptr, acq::make_mesher(meshing));
  pipeline.start();
  REQUIRE(pipeline.wait() == acq::PipelineState::kCompleted);
  return vertex_deviation(pipeline.result(), part);
}

/// The tolerance the emulated scans are held to: the median vertex distance to the part within
/// 0.08 mm of the in-process simulation's (the 2 mm cubes' representatives lie about 0.16 mm
/// inside the sphere either way), the 90th percentile below 1 mm (a wrong mounting, axis or
/// clock join is millimetres off everywhere). Not tighter: the sensor's samples and GRBL's status
/// reports are stamped by their drivers on receipt (GRBL has no timestamps), and a host that
/// reads one late shifts that pose by the delay times the speed (10 ms at 100 mm/s is 1 mm). On
/// an idle machine the 90th percentile is 0.19 mm, as in process; with other builds on both
/// cores 0.2 to 0.8 mm (acquisition/NOTEBOOK.md).
void check_on_part(const recon::Mesh& mesh, const recon::Mesh& part, const Deviation& reference) {
  const Deviation dev = vertex_deviation(mesh, part);
  INFO("vertex distance to the part: median "
       << dev.median << " mm, 90th percentile " << dev.p90 << " mm, 99th " << dev.p99
       << " mm, worst " << dev.worst << " mm; in process: median " << reference.median << ", 90th "
       << reference.p90);
  CHECK(dev.median < reference.median + 0.08);
  CHECK(dev.p90 < 1.0);
}

std::unique_ptr<acq::Pipeline> make_pipeline(acq::ScanBackend& backend,
                                             const std::filesystem::path& journal, Events& events) {
  const nlohmann::json meshing{{"mesher", "incremental"}, {"cube", "2"}};
  acq::PipelineConfig pc;
  pc.parameters_json = nlohmann::json{
      {"kind", "scan"},
      {"scanner", acq::to_json(backend.model())},
      {"meshing", meshing}}.dump();
  return std::make_unique<acq::Pipeline>(
      backend, std::make_unique<acq::JournalRecorder>(journal, backend.model()),
      acq::make_mesher(meshing), pc, events.callback());
}

}  // namespace

TEST_CASE(
    "scan --sim through the emulators and the real drivers: a mesh on the part, replayed "
    "byte for byte",
    "[acq][emulators]") {
  test::TempDir dir;
  const std::string journal = (dir / "scan.mcap").string();
  const auto live = test::run_program(
      SCANMESH_EXE, dir,
      {"scan", "--sim", "sphere", "--line-spacing", "2", "--speed", "100", "--noise", "0.005",
       "--cube", "2", "--journal", journal, "-o", (dir / "live.ply").string(), "--json"});
  INFO(live.err);
  REQUIRE(live.status == 0);
  const auto j = nlohmann::json::parse(live.out);
  CHECK(j["transport"] == "emulators");
  CHECK(j["state"] == "completed");
  // A 10 kHz sensor over about 15 s of motion.
  CHECK(j["samples"].get<long>() > 50000);
  CHECK(j["points"].get<long>() > 20000);
  CHECK(j["recorded"].get<long>() == j["samples"].get<long>() + j["stage_samples"].get<long>());
  CHECK(j["stage_samples"].get<long>() > 1000);  // 200 Hz status reports
  const recon::Mesh mesh = meshio::read_mesh(dir / "live.ply");
  const auto rep = recon::analyze(mesh);
  CHECK(rep.triangles > 300);
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.non_manifold_vertices == 0);
  CHECK(rep.orientation_consistent);
  check_on_part(mesh, sim::make_part("sphere"),
                in_process_deviation(sim::make_part("sphere"), sphere_scan()));
  // The journal meshes again into the same bytes.
  const auto rep_run = test::run_program(
      SCANMESH_EXE, dir, {"replay", journal, "-o", (dir / "replay.ply").string(), "--json"});
  INFO(rep_run.err);
  REQUIRE(rep_run.status == 0);
  const auto jr = nlohmann::json::parse(rep_run.out);
  CHECK(jr["samples"] == j["samples"]);
  CHECK(jr["points"] == j["points"]);
  CHECK(test::slurp(dir / "replay.ply") == test::slurp(dir / "live.ply"));
}

TEST_CASE(
    "DevicesBackend over the emulators: a pause halts the stage (feed hold), resume runs the "
    "line again",
    "[acq][emulators]") {
  test::TempDir dir;
  const recon::Mesh part = sim::make_part("sphere");
  sim::EmulatedScanBackend backend(part, sphere_scan(2));
  Events events;
  auto pipeline = make_pipeline(backend, dir / "scan.mcap", events);
  pipeline->start();
  while (pipeline->stats().points < 3000) REQUIRE_FALSE(pipeline->wait_for(5ms));
  pipeline->pause();
  auto& grbl = backend.scanner().stage_emulator();
  // The controller got the feed hold, and the axes stand.
  const auto t0 = std::chrono::steady_clock::now();
  while (grbl.motion().moving(drivers::monotonic_now())) {
    REQUIRE(std::chrono::steady_clock::now() - t0 < 5s);
    REQUIRE_FALSE(pipeline->wait_for(5ms));
  }
  CHECK(grbl.received().find('!') != std::string::npos);
  const drivers::StagePose held = grbl.motion().pose(drivers::monotonic_now());
  const std::uint64_t samples = pipeline->stats().samples_received;
  REQUIRE_FALSE(pipeline->wait_for(200ms));
  CHECK(pipeline->stats().state == acq::PipelineState::kPaused);
  CHECK(grbl.motion().pose(drivers::monotonic_now()) == held);
  CHECK(pipeline->stats().samples_received - samples < 50);  // nothing while held
  pipeline->resume();
  REQUIRE(pipeline->wait() == acq::PipelineState::kCompleted);
  CHECK(backend.devices_backend().halts() == 1);
  CHECK(events.saw_state(acq::PipelineState::kPaused, "paused by request"));
  const auto st = pipeline->stats();
  CHECK(st.samples_recorded == st.samples_received + st.stage_samples);
  const auto rep = recon::analyze(pipeline->result());
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.triangles > 100);
  check_on_part(pipeline->result(), part, in_process_deviation(part, sphere_scan()));
  // The journal holds every sample the pipeline received.
  CHECK(acq::check_journal(dir / "scan.mcap").samples == st.samples_received + st.stage_samples);
}

TEST_CASE(
    "DevicesBackend over the emulators: the sensor going silent is a lost device, the scan "
    "pauses and continues when it is back",
    "[acq][emulators]") {
  test::TempDir dir;
  const recon::Mesh part = sim::make_part("sphere");
  sim::EmulatedScanBackend backend(part, sphere_scan(2));
  Events events;
  auto pipeline = make_pipeline(backend, dir / "scan.mcap", events);
  pipeline->start();
  while (pipeline->stats().points < 3000) REQUIRE_FALSE(pipeline->wait_for(5ms));
  auto& ild = backend.scanner().sensor_emulator();
  sim::SerialFaults faults;
  faults.silent = true;
  ild.set_faults(faults);
  const auto t0 = std::chrono::steady_clock::now();
  while (pipeline->stats().state != acq::PipelineState::kPaused) {
    REQUIRE(std::chrono::steady_clock::now() - t0 < 5s);
    REQUIRE_FALSE(pipeline->wait_for(5ms));
  }
  CHECK(pipeline->stats().reason.find("ild0") != std::string::npos);
  const auto devices = backend.devices();
  REQUIRE(devices.size() == 2);
  CHECK(devices[0].name == "ild0");
  CHECK(devices[0].driver == "microepsilon-ild1420");
  CHECK(devices[0].state == drivers::DeviceState::kLost);
  CHECK(devices[1].name == "grbl0");
  // The stage was halted while the sensor is away.
  const auto t1 = std::chrono::steady_clock::now();
  auto& grbl = backend.scanner().stage_emulator();
  while (grbl.motion().moving(drivers::monotonic_now())) {
    REQUIRE(std::chrono::steady_clock::now() - t1 < 5s);
    REQUIRE_FALSE(pipeline->wait_for(5ms));
  }
  ild.set_faults({});
  REQUIRE(pipeline->wait() == acq::PipelineState::kCompleted);
  CHECK(events.saw_device("ild0", ""));
  CHECK(events.saw_state(acq::PipelineState::kPaused, "ild0"));
  const auto st = pipeline->stats();
  CHECK(st.samples_recorded ==
        st.samples_received + st.stage_samples);  // nothing acknowledged was lost
  CHECK(acq::check_journal(dir / "scan.mcap").samples == st.samples_received + st.stage_samples);
  const auto rep = recon::analyze(pipeline->result());
  CHECK(rep.non_manifold_edges == 0);
  CHECK(rep.triangles > 100);
  check_on_part(pipeline->result(), part, in_process_deviation(part, sphere_scan()));
}
