// `scanmesh scan`: a whole simulated scan through the real pipeline: the simulated scanner
// delivers its sample streams, the journal records them, the accumulator maps them, the
// incremental core meshes while the scan runs; the final mesh is written at the end.
// SPDX-License-Identifier: MIT
#include <memory>
#include <string>

#include "commands.hpp"
#include "scan_common.hpp"
#include "scanmesh/acquisition/journal_backend.hpp"
#include "scanmesh/acquisition/meshers.hpp"
#include "scanmesh/acquisition/scanner_json.hpp"
#include "scanmesh/sim/scanner_backend.hpp"
#include "sim_options.hpp"

namespace scanmesh::cli {
namespace {

struct ScanArgs {
  std::string sim;
  std::string journal;
  sim::ScanSettings scan;
  std::string cube = "auto";
  std::string mesher = "incremental";
  double pace = 0;
  ScanOutput out;
  bool progress = false;
};

int run_scan(const ScanArgs& args) {
  recon::Mesh part = load_scan_target(args.sim);
  sim::SimulatedScannerOptions so;
  so.speed = args.pace;
  sim::SimulatedScanner backend(std::move(part), args.scan.to_config(), so);
  const nlohmann::json meshing{{"mesher", args.mesher}, {"cube", args.cube}};
  auto mesher = acq::make_mesher(meshing);  // checks --cube before anything is written
  acq::PipelineConfig pc;
  pc.parameters_json = nlohmann::json{{"kind", "scan"},
                                      {"source", args.sim},
                                      {"scanner", acq::to_json(backend.model())},
                                      {"meshing", meshing}}
                           .dump();
  auto recorder = std::make_unique<acq::JournalRecorder>(args.journal, backend.model());
  acq::Pipeline pipeline(backend, std::move(recorder), std::move(mesher), pc);
  const acq::PipelineStats st = run_pipeline(pipeline, args.progress);
  ScanOutput out = args.out;
  out.what = "scan of " + args.sim + " (journal " + args.journal + ")";
  return report_scan(pipeline, st, out,
                     {{"source", args.sim},
                      {"sensor", args.scan.sensor},
                      {"path", args.scan.path},
                      {"mesher", args.mesher},
                      {"journal", args.journal}});
}

}  // namespace

void add_scan_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<ScanArgs>();
  CLI::App* cmd = app.add_subcommand(
      "scan", "Run a whole simulated scan through the acquisition pipeline into a mesh");
  cmd->footer(
      "The simulated scanner delivers timestamped sensor and stage samples; the journal records "
      "every one of them (MCAP), the accumulator joins them (pose at each sample's instant, the "
      "sensor's calibration), and the incremental core meshes the regions the scan has left "
      "while it runs. `scanmesh replay JOURNAL` meshes the recording again.");
  cmd->add_option("--sim", args->sim, "built-in part name or a mesh file (.stl .ply .obj) to scan")
      ->required();
  add_sim_scan_options(cmd, args->scan);
  cmd->add_option("--journal", args->journal,
                  "the scan journal to record every sample into (.mcap; must not exist)")
      ->required();
  cmd->add_option("--cube", args->cube,
                  "cube reduction edge, mm, or 'auto' (from the measured spacing)")
      ->capture_default_str();
  cmd->add_option("--mesher", args->mesher,
                  "meshing while scanning ('incremental') or once at the end ('batch')")
      ->capture_default_str()
      ->check(CLI::IsMember({"incremental", "batch"}));
  cmd->add_option("--pace", args->pace,
                  "playback speed relative to the scan (1: live), 0: as fast as possible")
      ->capture_default_str()
      ->check(kNonNegative);
  add_mesh_output_option(*cmd, args->out.output);
  cmd->add_option("--preview", args->out.preview, "also write a shaded picture of the mesh (.png)")
      ->check(png_output());
  cmd->add_flag("--json", args->out.json, "print one JSON object instead of the summary line");
  cmd->add_flag("--progress", args->progress,
                "show a live progress line on stderr: samples, points, triangles, rate, lag");
  cmd->callback([args, &run] { run = [args] { return run_scan(*args); }; });
}

}  // namespace scanmesh::cli
