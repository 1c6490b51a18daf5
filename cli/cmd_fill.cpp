// `scanmesh fill`: close the holes of an existing mesh (one from `reconstruct`, or from another
// tool) for CAD: every boundary loop up to a size gets a refined, faired patch (or a flat one).
// SPDX-License-Identifier: MIT
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/preview/render.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/fill.hpp"

namespace scanmesh::cli {
namespace {

struct FillArgs : MeshEditArgs {
  // Holes, not borders: a single range scan's border runs to hundreds of edges (the bunny's
  // bun000: 781), its holes to tens (the bunny's base: 13-74). --max-width limits by size.
  std::size_t max_edges = 100;
  double max_width = 0;
  bool flat = false;
  std::string preview;
  std::string up = "z";
};

int run_fill(const FillArgs& args) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  recon::FillOptions opt;
  opt.max_edges = args.max_edges;
  opt.max_width = args.max_width;
  opt.refine = !args.flat;
  if (const auto errors = opt.validate(); !errors.empty()) throw ConfigError(errors.front());
  // The patches are only defined where every vertex has one fan and the sides agree; say which
  // test failed rather than writing the mesh back unchanged.
  recon::Mesh mesh;
  const recon::MeshReport before = read_clean_mesh(args.mesh, "holes can only be filled", mesh);
  const recon::FillStats stats = recon::fill_holes(mesh, opt);
  write_mesh_file(mesh, args.output, args.ascii);
  const recon::MeshReport after = recon::analyze(mesh);
  if (!args.preview.empty()) {
    preview::RenderOptions options;
    options.up = axis_of(args.up);
    options.highlight_from = mesh.triangles.size() - stats.triangles;
    options.title = std::filesystem::path(args.output).filename().string() + ": " +
                    std::to_string(stats.filled) + " holes filled (amber), " +
                    std::to_string(after.boundary_loops) + " boundary loops, genus " +
                    std::to_string(after.genus);
    preview::render_mesh_png(mesh, args.preview, options);
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  if (args.json) {
    nlohmann::json j;
    j["input"] = args.mesh;
    j["output"] = args.output;
    j["boundary_loops_before"] = before.boundary_loops;
    put_fill(j, stats);
    j["kept_loops"] = stats.kept;
    j["vertices"] = mesh.vertices.size();
    j["triangles"] = mesh.triangles.size();
    put_topology(j, after);
    j["signed_volume"] = after.signed_volume;
    if (!args.preview.empty()) j["preview"] = args.preview;
    j["seconds_total"] = seconds;
    std::cout << j.dump() << "\n";
  } else {
    std::cout << std::fixed << std::setprecision(3)
              << "boundary loops   " << before.boundary_loops << " -> " << after.boundary_loops
              << "\n"
              << "filled holes     " << stats.filled << " (" << stats.triangles << " triangles, "
              << stats.vertices << " new vertices; " << stats.kept << " loops kept, "
              << stats.crossing << " of them because a patch would cross the mesh)\n"
              << "vertices         " << mesh.vertices.size() << "\n"
              << "triangles        " << mesh.triangles.size() << "\n"
              << "genus            " << after.genus << "\n"
              << "written          " << args.output << "\n"
              << "seconds          " << seconds << "\n";
  }
  return kExitOk;
}

}  // namespace

void add_fill_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<FillArgs>();
  CLI::App* cmd = app.add_subcommand(
      "fill", "Close a mesh's holes up to a size (refined, faired patches) for a closed mesh");
  add_mesh_edit_args(*cmd, *args);
  cmd->add_option("--max-edges", args->max_edges,
                  "close the boundary loops of at most N edges; longer ones (a scan's border) "
                  "are kept")
      ->capture_default_str()
      ->check(CLI::Range(std::size_t{1}, recon::FillOptions::kLimit));
  cmd->add_option("--max-width", args->max_width,
                  "close only the loops at most SIZE across, in the mesh's units (the largest "
                  "distance between two of a loop's vertices: a round hole's diameter); 0: no "
                  "width limit")
      ->check(kNonNegative);
  cmd->add_flag("--flat", args->flat,
                "patch each hole with triangles of its rim's vertices only (no new vertex, no "
                "fairing)");
  cmd->add_option("--preview", args->preview,
                  "also write a shaded picture of the result (.png; the patches amber)")
      ->check(png_output());
  cmd->add_option("--up", args->up, "world axis shown upwards in the preview (x, y or z)")
      ->capture_default_str()
      ->check(CLI::IsMember({"x", "y", "z"}));
  cmd->callback([args, &run] { run = [args] { return run_fill(*args); }; });
}

}  // namespace scanmesh::cli
