// `scanmesh sharpen`: recover the sharp edges and corners a scan bevelled (a machined part's
// edges come out cut by the last samples on each face), for CAD: new vertices where the faces
// meet, the measured samples unmoved.
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
#include "scanmesh/recon/sharpen.hpp"

namespace scanmesh::cli {
namespace {

struct SharpenArgs : MeshEditArgs {
  recon::SharpenOptions options;
};

int run_sharpen(const SharpenArgs& args) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  if (const auto errors = args.options.validate(); !errors.empty())
    throw ConfigError(errors.front());
  recon::Mesh mesh;
  read_clean_mesh(args.mesh, "edges can only be sharpened", mesh);
  const recon::SharpenStats stats = recon::sharpen_edges(mesh, args.options);
  write_mesh_file(mesh, args.output, args.ascii);
  const recon::MeshReport after = recon::analyze(mesh);
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  report_edited_mesh(
      args, mesh, after, seconds, [&](nlohmann::json& j) { put_sharpen(j, stats); },
      [&](std::ostream& out) {
        out << "bevel triangles  " << stats.bevel_triangles << "\n"
            << "new vertices     " << stats.edge_vertices << " on edges, " << stats.corner_vertices
            << " at corners (" << stats.flipped << " edges flipped along them, " << stats.tidied
            << " slivers beside the faces flipped away; " << stats.refused
            << " refused: they would cross or fold)\n"
            << "left round       " << stats.rounded
            << " bevel triangles on fillets (a corner on neither face, off both planes)\n";
      });
  return kExitOk;
}

}  // namespace

void add_sharpen_options(CLI::App& cmd, recon::SharpenOptions& options, const std::string& when) {
  cmd.add_option("--face-angle", options.smooth_deg,
                 when + "neighbouring triangles whose normals differ by at most DEG belong to "
                        "one face")
      ->capture_default_str()
      ->check(kPositive);
  cmd.add_option("--feature-angle", options.feature_deg,
                 when + "recover an edge only between faces whose normals differ by at least DEG")
      ->capture_default_str()
      ->check(kPositive);
  cmd.add_option("--passes", options.passes,
                 when + "passes over the mesh, each on the one before's output: 2 brings the "
                        "edges closer, with about twice as many thin triangles (1 to " +
                     std::to_string(recon::SharpenOptions::kMaxPasses) + ")")
      ->capture_default_str()
      ->check(CLI::Range(1, recon::SharpenOptions::kMaxPasses));
}

void add_sharpen_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<SharpenArgs>();
  CLI::App* cmd = app.add_subcommand(
      "sharpen", "Recover the sharp edges and corners a scan bevelled (new vertices where the "
                 "faces meet)");
  add_mesh_edit_args(*cmd, *args);
  add_sharpen_options(*cmd, args->options, "");
  cmd->callback([args, &run] { run = [args] { return run_sharpen(*args); }; });
}

}  // namespace scanmesh::cli
