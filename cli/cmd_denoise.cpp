// `scanmesh denoise`: remove a scan's noise from a mesh while keeping its sharp edges (filtered
// triangle normals, then the vertices fitted to the planes they give). Only vertices move.
// SPDX-License-Identifier: MIT
#include <chrono>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/denoise.hpp"

namespace scanmesh::cli {
namespace {

struct DenoiseArgs : MeshEditArgs {
  recon::DenoiseOptions options;
};

int run_denoise(const DenoiseArgs& args) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  if (const auto errors = args.options.validate(); !errors.empty())
    throw ConfigError(errors.front());
  recon::Mesh mesh;
  read_clean_mesh(args.mesh, "noise can only be removed", mesh);
  recon::DenoiseStats stats;
  try {
    stats = recon::denoise_mesh(mesh, args.options);
  } catch (const GeometryError& e) {
    throw InputError(args.mesh + ": " + e.what() + "; nothing written");
  }
  write_mesh_file(mesh, args.output, args.ascii);
  const recon::MeshReport after = recon::analyze(mesh);
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  report_edited_mesh(
      args, mesh, after, seconds, [&](nlohmann::json& j) { put_denoise(j, stats); },
      [&](std::ostream& out) {
        out << std::setprecision(4) << "noise            " << stats.noise_mm
            << " (measured on the vertices unless given), normals' scatter " << stats.noise_deg
            << " deg, range " << stats.feature_deg << " deg\n"
            << "moved            " << stats.moved << " vertices, " << stats.mean_move
            << " on average, " << stats.max_move << " at most (" << stats.clamped
            << " cut to the largest move)\n"
            << "left             " << stats.refused
            << " vertices where they were (a move would fold or cross)\n";
      });
  return kExitOk;
}

}  // namespace

void add_denoise_options(CLI::App& cmd, recon::DenoiseOptions& options, const std::string& when) {
  cmd.add_option("--denoise-angle", options.feature_deg,
                 when + "triangles whose normals are this many degrees apart weigh exp(-1/2) in "
                        "each other's average (twice as far: exp(-2)); above the noise's normal "
                        "scatter, below the edges to keep; 0: twice the median angle between "
                        "neighbouring triangles (the noise's scatter), at most 15")
      ->capture_default_str()
      ->check(kNonNegative);
  cmd.add_option("--noise-sigma", options.noise_mm,
                 when + "the scan's noise (standard deviation, mesh units); 0: measured on the "
                        "vertices (quadric fits through their 20 nearest neighbours)")
      ->capture_default_str()
      ->check(kNonNegative);
  cmd.add_option("--max-noise-moves", options.noise_moves,
                 when + "a vertex moves at most this many times the noise")
      ->capture_default_str()
      ->check(kPositive);
  cmd.add_option("--normal-iterations", options.normal_iterations,
                 when + "rounds of the normal filter (each reaches one ring further)")
      ->capture_default_str()
      ->check(CLI::Range(1, recon::DenoiseOptions::kMaxIterations));
  cmd.add_option("--vertex-iterations", options.vertex_iterations,
                 when + "rounds of the vertex update towards the filtered planes")
      ->capture_default_str()
      ->check(CLI::Range(1, recon::DenoiseOptions::kMaxIterations));
}

void add_denoise_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<DenoiseArgs>();
  CLI::App* cmd = app.add_subcommand(
      "denoise", "Remove a scan's noise from a mesh, keeping its sharp edges (only vertices move)");
  add_mesh_edit_args(*cmd, *args);
  add_denoise_options(*cmd, args->options, "");
  cmd->callback([args, &run] { run = [args] { return run_denoise(*args); }; });
}

}  // namespace scanmesh::cli
