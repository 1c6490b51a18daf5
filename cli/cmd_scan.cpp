// `scanmesh scan`: a whole simulated scan through the real pipeline: the simulated scanner
// delivers its sample streams, the journal records them, the accumulator maps them, the
// incremental core meshes while the scan runs; the final mesh is written at the end.
// SPDX-License-Identifier: MIT
#include <memory>
#include <string>

#include "commands.hpp"
#include "scan_common.hpp"
#include "scanmesh/acquisition/catalog.hpp"
#include "scanmesh/acquisition/journal_backend.hpp"
#include "scanmesh/acquisition/meshers.hpp"
#include "scanmesh/acquisition/scanner_json.hpp"
#include "scanmesh/sim/emulators/emulated_backend.hpp"
#include "scanmesh/sim/scanner_backend.hpp"
#include "sim_options.hpp"

namespace scanmesh::cli {
namespace {

struct ScanArgs {
  std::string sim;
  std::string journal;
  std::string catalog;
  std::string name;
  sim::ScanSettings scan;
  std::string cube = "auto";
  std::string mesher = "incremental";
  double pace = 0;
  std::string transport = "auto";
  bool in_process = false;
  ScanOutput out;
  bool progress = false;
};

acq::WallTime wall_now() { return std::chrono::system_clock::now(); }

/// "emulators" or "in-process": --in-process wins; "auto" is the emulators for a point sensor
/// (the ILD1420 emulator) and the in-process simulation for the others (no emulator for them).
std::string transport_of(const ScanArgs& args) {
  if (args.in_process) return "in-process";
  if (args.transport != "auto") return args.transport;
  return args.scan.sensor == "point" ? "emulators" : "in-process";
}

int run_scan(const ScanArgs& args) {
  recon::Mesh part = load_scan_target(args.sim);
  const std::string transport = transport_of(args);
  std::unique_ptr<acq::ScanBackend> backend_ptr;
  if (transport == "emulators") {
    backend_ptr = std::make_unique<sim::EmulatedScanBackend>(std::move(part), args.scan);
  } else {
    sim::SimulatedScannerOptions so;
    so.speed = args.pace;
    backend_ptr =
        std::make_unique<sim::SimulatedScanner>(std::move(part), args.scan.to_config(), so);
  }
  acq::ScanBackend& backend = *backend_ptr;
  const nlohmann::json meshing{{"mesher", args.mesher}, {"cube", args.cube}};
  auto mesher = acq::make_mesher(meshing);  // checks --cube before anything is written
  acq::PipelineConfig pc;
  pc.parameters_json = nlohmann::json{{"kind", "scan"},
                                      {"source", args.sim},
                                      {"scanner", acq::to_json(backend.model())},
                                      {"meshing", meshing}}
                           .dump();
  // The catalog (if asked) is opened first: a scan it cannot record does not start.
  std::optional<acq::Catalog> catalog;
  std::int64_t scan_id = 0;
  if (!args.catalog.empty()) catalog.emplace(acq::Catalog::open(args.catalog, wall_now()));
  auto recorder = std::make_unique<acq::JournalRecorder>(args.journal, backend.model());
  if (catalog) {
    const nlohmann::json model = acq::to_json(backend.model());
    acq::NewScan ns;
    ns.name = args.name.empty() ? args.sim : args.name;
    ns.journal = std::filesystem::absolute(args.journal);
    ns.devices = nlohmann::json{{"backend", "sim"},        {"transport", transport},
                                {"source", args.sim},      {"sensors", model["sensors"]},
                                {"stage", model["stage"]}};
    nlohmann::json calibration = nlohmann::json::array();
    for (const auto& s : model["sensors"]) calibration.push_back(s["calibration"]);
    ns.calibration = nlohmann::json{{"sensors", calibration}, {"accumulator", model["accumulator"]}};
    ns.reduction = nlohmann::json{{"cube", args.cube}};
    ns.meshing = meshing;
    scan_id = catalog->create_scan(ns, wall_now());
  }
  acq::Pipeline pipeline(backend, std::move(recorder), std::move(mesher), pc);
  const acq::PipelineStats st = run_pipeline(pipeline, args.progress);
  ScanOutput out = args.out;
  out.what = "scan of " + args.sim + " (journal " + args.journal + ")";
  nlohmann::json extra{{"source", args.sim},
                       {"sensor", args.scan.sensor},
                       {"path", args.scan.path},
                       {"mesher", args.mesher},
                       {"transport", transport},
                       {"journal", args.journal}};
  if (catalog) extra["scan_id"] = scan_id;
  int status = kExitOk;
  std::exception_ptr report_error;
  try {
    status = report_scan(pipeline, st, out, extra);
  } catch (...) {
    report_error = std::current_exception();
  }
  if (catalog) {
    const acq::ScanState state = st.state == acq::PipelineState::kCompleted ? acq::ScanState::kCompleted
                                 : st.state == acq::PipelineState::kStopped ? acq::ScanState::kStopped
                                                                            : acq::ScanState::kFailed;
    catalog->finish(scan_id, state, st.reason, st.samples_recorded, st.points, wall_now());
    if (!report_error && !pipeline.result().triangles.empty()) {
      catalog->add_output(scan_id, std::filesystem::absolute(out.output), "mesh", wall_now());
      if (!out.preview.empty())
        catalog->add_output(scan_id, std::filesystem::absolute(out.preview), "preview", wall_now());
    }
  }
  if (report_error) std::rethrow_exception(report_error);
  return status;
}

}  // namespace

void add_scan_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<ScanArgs>();
  CLI::App* cmd = app.add_subcommand(
      "scan", "Run a whole simulated scan through the acquisition pipeline into a mesh");
  cmd->footer(
      "The simulated scanner drives the GRBL and ILD1420 protocol emulators on ptys and the real "
      "drivers read them (a point sensor; --in-process, and any line or probe scan, simulate in "
      "process instead); the journal records "
      "every one of them (MCAP), the accumulator joins them (pose at each sample's instant, the "
      "sensor's calibration), and the incremental core meshes the regions the scan has left "
      "while it runs. `scanmesh replay JOURNAL` meshes the recording again.");
  cmd->add_option("--sim", args->sim, "built-in part name or a mesh file (.stl .ply .obj) to scan")
      ->required();
  add_sim_scan_options(cmd, args->scan);
  cmd->add_option("--journal", args->journal,
                  "the scan journal to record every sample into (.mcap; must not exist)")
      ->required();
  cmd->add_option("--catalog", args->catalog,
                  "also record the scan in this scan catalog (SQLite; created if missing)");
  cmd->add_option("--name", args->name, "the scan's name in the catalog (default: the --sim value)");
  cmd->add_option("--cube", args->cube,
                  "cube reduction edge, mm, or 'auto' (from the measured spacing)")
      ->capture_default_str();
  cmd->add_option("--mesher", args->mesher,
                  "meshing while scanning ('incremental') or once at the end ('batch')")
      ->capture_default_str()
      ->check(CLI::IsMember({"incremental", "batch"}));
  cmd->add_option("--pace", args->pace,
                  "in-process only: playback speed relative to the scan (1: live), 0: as fast as "
                  "possible (the emulators always run live)")
      ->capture_default_str()
      ->check(kNonNegative);
  cmd->add_option("--transport", args->transport,
                  "'emulators': the GRBL and ILD1420 protocol emulators on ptys, read by the real "
                  "drivers (point sensor only); 'in-process': the simulator delivers its samples "
                  "directly (deterministic); 'auto': emulators for a point sensor, else in-process")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "emulators", "in-process"}));
  cmd->add_flag("--in-process", args->in_process, "same as --transport in-process");
  add_mesh_output_option(*cmd, args->out.output);
  cmd->add_option("--preview", args->out.preview, "also write a shaded picture of the mesh (.png)")
      ->check(png_output());
  cmd->add_flag("--json", args->out.json, "print one JSON object instead of the summary line");
  cmd->add_flag("--progress", args->progress,
                "show a live progress line on stderr: samples, points, triangles, rate, lag");
  cmd->callback([args, &run] { run = [args] { return run_scan(*args); }; });
}

}  // namespace scanmesh::cli
