// `scanmesh generate`: a synthetic scan. Samples a built-in reference part (or a given mesh)
// into a point file, optionally writing the exact reference mesh beside it.
// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstdint>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/sampling.hpp"

namespace scanmesh::cli {
namespace {

struct GenerateArgs {
  std::string part;
  std::string mesh_in;
  double spacing_mm = 0.5;
  std::size_t target_points = 0;  ///< 0: use spacing_mm
  double noise_mm = 0;
  std::uint64_t seed = 1;
  std::string output;
  std::string mesh_out;
  bool json = false;
};

int run_generate(const GenerateArgs& args) {
  if (args.part.empty() && args.mesh_in.empty())
    throw ConfigError("give --part NAME or --mesh-in FILE");
  recon::Mesh mesh;
  if (!args.part.empty()) {
    mesh = sim::make_part(args.part);
  } else {
    mesh = meshio::read_mesh(args.mesh_in);
    if (mesh.triangles.empty())
      throw InputError(args.mesh_in + ": no triangles to sample (a point cloud?)");
  }
  double spacing = args.spacing_mm;
  if (args.target_points > 0) {
    const double area = sim::surface_area(mesh);
    if (!(area > 0) || !std::isfinite(area))
      throw InputError((args.mesh_in.empty() ? args.part : args.mesh_in) +
                       ": the surface has no area to sample");
    spacing = std::sqrt(area / static_cast<double>(args.target_points));
  }
  const std::vector<recon::Vec3> points =
      sim::sample_surface(mesh, spacing, args.seed, args.noise_mm);
  if (points.empty())
    throw ConfigError("spacing " + std::to_string(spacing) +
                      " mm is too coarse: no points on the surface");
  meshio::write_points_xyz(points, args.output);
  if (!args.mesh_out.empty()) meshio::write_mesh(mesh, args.mesh_out);

  if (args.json) {
    nlohmann::json j;
    j["part"] = args.part.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.part);
    j["mesh_in"] = args.mesh_in.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.mesh_in);
    j["points"] = points.size();
    j["spacing"] = spacing;
    j["noise"] = args.noise_mm;
    j["seed"] = args.seed;
    j["output"] = args.output;
    j["mesh"] = args.mesh_out.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.mesh_out);
    std::cout << j.dump() << "\n";
  } else {
    std::cout << "generated " << points.size() << " points on "
              << (args.part.empty() ? args.mesh_in : "part '" + args.part + "'") << " (spacing "
              << spacing << " mm, noise " << args.noise_mm << " mm, seed " << args.seed << ") -> "
              << args.output;
    if (!args.mesh_out.empty()) std::cout << ", reference mesh -> " << args.mesh_out;
    std::cout << "\n";
  }
  return kExitOk;
}

}  // namespace

void add_generate_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<GenerateArgs>();
  std::string parts;
  for (const auto& p : sim::part_catalog())
    parts += "\n  " + p.name + ": " + p.description + " (genus " + std::to_string(p.genus) + ")";
  CLI::App* cmd = app.add_subcommand(
      "generate", "Sample a built-in reference part (or a mesh) into a synthetic point cloud");
  cmd->footer("Built-in parts (millimetres):" + parts);
  auto* part = cmd->add_option("--part", args->part, "built-in part to sample")
                   ->check(CLI::IsMember(sim::part_names()));
  auto* mesh_in =
      cmd->add_option("--mesh-in", args->mesh_in, "sample this mesh (.stl .ply .obj) instead");
  part->excludes(mesh_in);
  mesh_in->excludes(part);
  auto* spacing = cmd->add_option("--spacing", args->spacing_mm, "mean point spacing, mm")
                      ->capture_default_str()
                      ->check(kPositive);
  auto* points_opt =
      cmd->add_option("--points", args->target_points,
                      "about this many points instead of --spacing (spacing from the area)")
          ->check(CLI::Range(std::size_t{1}, std::size_t{50'000'000}));
  points_opt->excludes(spacing);
  spacing->excludes(points_opt);
  cmd->add_option("--noise", args->noise_mm,
                  "standard deviation of Gaussian noise along the surface normal, mm")
      ->capture_default_str()
      ->check(kNonNegative);
  cmd->add_option("--seed", args->seed, "random seed (same seed, same points)")
      ->capture_default_str();
  cmd->add_option("-o,--output", args->output, "point file to write (.xyz)")
      ->required()
      ->check(points_output());
  cmd->add_option("--mesh", args->mesh_out, "also write the exact reference mesh: .stl .ply .obj")
      ->check(mesh_output());
  cmd->add_flag("--json", args->json, "print one JSON object instead of the summary line");
  cmd->callback([args, &run] { run = [args] { return run_generate(*args); }; });
}

}  // namespace scanmesh::cli
