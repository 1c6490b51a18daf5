// `scanmesh scan`: a whole simulated scan through the real pipeline: the simulated scanner
// delivers its sample streams, the accumulator maps them, the incremental core meshes while the
// scan runs; the final mesh is written at the end.
// SPDX-License-Identifier: MIT
#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "commands.hpp"
#include "progress_bar.hpp"
#include "scanmesh/acquisition/meshers.hpp"
#include "scanmesh/acquisition/pipeline.hpp"
#include "scanmesh/acquisition/pipeline_json.hpp"
#include "scanmesh/preview/render.hpp"
#include "scanmesh/sim/scanner_backend.hpp"
#include "sim_options.hpp"

namespace scanmesh::cli {
namespace {

struct ScanArgs {
  std::string sim;
  sim::ScanSettings scan;
  std::string cube = "auto";
  std::string mesher = "incremental";
  double pace = 0;
  std::string output;
  std::string preview;
  bool json = false;
  bool progress = false;
};

/// --cube: "auto" or a positive size in mm.
void apply_scan_cube(const std::string& text, recon::ReconstructOptions& o) {
  if (text == "auto") {
    o.cube_mode = recon::ReconstructOptions::CubeMode::kAuto;
    return;
  }
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v) || v <= 0)
    throw ConfigError("--cube must be 'auto' or a positive size, got '" + text + "'");
  o.cube_mode = recon::ReconstructOptions::CubeMode::kFixed;
  o.cube_mm = v;
}

int exit_for(const acq::PipelineStats& st) {
  switch (st.state) {
    case acq::ScanState::kCompleted:
    case acq::ScanState::kStopped:
      return kExitOk;
    default:
      return st.reason.rfind("journal:", 0) == 0 ? kExitOutput : kExitDevice;
  }
}

int run_scan(const ScanArgs& args) {
  recon::Mesh part = load_scan_target(args.sim);
  sim::SimulatedScannerOptions so;
  so.speed = args.pace;
  sim::SimulatedScanner backend(std::move(part), args.scan.to_config(), so);

  recon::ReconstructOptions ro;
  apply_scan_cube(args.cube, ro);
  std::unique_ptr<acq::Mesher> mesher;
  if (args.mesher == "batch") {
    mesher = std::make_unique<acq::BatchMesher>(ro);
  } else {
    recon::IncrementalOptions io;
    io.reconstruct = ro;
    mesher = std::make_unique<acq::IncrementalMesher>(io);
  }
  acq::Pipeline pipeline(backend, nullptr, std::move(mesher));
  ProgressBar bar(args.progress);
  pipeline.start();
  while (!pipeline.wait_for(std::chrono::milliseconds(100))) bar.show(pipeline.stats());
  const acq::PipelineStats st = pipeline.stats();
  bar.done(st);

  const recon::Mesh& mesh = pipeline.result();
  if (!mesh.triangles.empty()) write_mesh_file(mesh, args.output, false);
  const recon::MeshReport rep = recon::analyze(mesh);
  if (!args.preview.empty() && !mesh.triangles.empty()) {
    preview::RenderOptions options;
    options.title = std::filesystem::path(args.output).filename().string() + ": " +
                    std::to_string(mesh.triangles.size()) + " triangles, " +
                    std::to_string(rep.boundary_loops) + " boundary loops, genus " +
                    std::to_string(rep.genus);
    preview::render_mesh_png(mesh, args.preview, options);
  }
  if (args.json) {
    nlohmann::json j = acq::to_json(st);
    j["source"] = args.sim;
    j["sensor"] = args.scan.sensor;
    j["path"] = args.scan.path;
    j["mesher"] = args.mesher;
    j["output"] = mesh.triangles.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.output);
    if (!args.preview.empty()) j["preview"] = args.preview;
    nlohmann::json m;
    m["vertices"] = mesh.vertices.size();
    m["triangles"] = mesh.triangles.size();
    put_topology(m, rep);
    j["mesh"] = m;
    std::cout << j.dump() << "\n";
  } else {
    std::cout << "scan of " << args.sim << " " << acq::to_string(st.state)
              << (st.reason.empty() ? "" : " (" + st.reason + ")") << ": " << st.samples_received
              << " samples, " << st.points << " points, " << st.mesh.kept_points
              << " kept -> " << mesh.triangles.size() << " triangles, "
              << rep.boundary_loops << " boundary loops";
    if (!mesh.triangles.empty()) std::cout << " -> " << args.output;
    if (!args.preview.empty() && !mesh.triangles.empty()) std::cout << ", " << args.preview;
    std::cout << "\n";
  }
  if (mesh.triangles.empty() && st.state == acq::ScanState::kCompleted)
    throw GeometryError("the scan measured no surface to mesh (is the part in range?)");
  return exit_for(st);
}

}  // namespace

void add_scan_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<ScanArgs>();
  CLI::App* cmd = app.add_subcommand(
      "scan", "Run a whole simulated scan through the acquisition pipeline into a mesh");
  cmd->footer(
      "The simulated scanner delivers timestamped sensor and stage samples; the accumulator "
      "joins them (pose at each sample's instant, the sensor's calibration), and the "
      "incremental core meshes the regions the scan has left while it runs.");
  cmd->add_option("--sim", args->sim, "built-in part name or a mesh file (.stl .ply .obj) to scan")
      ->required();
  add_sim_scan_options(cmd, args->scan);
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
  add_mesh_output_option(*cmd, args->output);
  cmd->add_option("--preview", args->preview, "also write a shaded picture of the mesh (.png)")
      ->check(png_output());
  cmd->add_flag("--json", args->json, "print one JSON object instead of the summary line");
  cmd->add_flag("--progress", args->progress,
                "show a live progress line on stderr: samples, points, triangles, rate, lag");
  cmd->callback([args, &run] { run = [args] { return run_scan(*args); }; });
}

}  // namespace scanmesh::cli
