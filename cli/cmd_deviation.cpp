// `scanmesh deviation`: distances between a mesh and a reference surface (both directions,
// Hausdorff), optionally a colour-mapped picture of the signed deviation of the mesh.
// SPDX-License-Identifier: MIT
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/preview/render.hpp"
#include "scanmesh/recon/deviation.hpp"

namespace scanmesh::cli {
namespace {

struct DeviationArgs {
  std::string mesh;
  std::string ref;
  std::string png;
  std::string up = "z";
  bool json = false;
};

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

nlohmann::json to_json(const recon::DistanceStats& s) {
  return {{"count", s.count}, {"mean", s.mean}, {"rms", s.rms}, {"p95", s.p95}, {"max", s.max}};
}

int run_deviation(const DeviationArgs& args) {
  const recon::Mesh mesh = meshio::read_mesh(args.mesh);
  if (mesh.triangles.empty()) {
    throw InputError(args.mesh +
                     ": no triangles (a point cloud?); deviation compares a mesh "
                     "with a reference surface");
  }
  const recon::Mesh ref = meshio::read_mesh(args.ref);
  if (ref.triangles.empty()) {
    throw InputError(args.ref +
                     ": the reference has no triangles (a point cloud?); it must be a "
                     "surface mesh");
  }
  const recon::DeviationReport report = recon::deviation(mesh, ref);
  const double hausdorff = report.hausdorff().max;

  if (!args.png.empty()) {
    preview::RenderOptions options;
    options.up = axis_of(args.up);
    options.title = "signed deviation of " + std::filesystem::path(args.mesh).filename().string() +
                    " from " + std::filesystem::path(args.ref).filename().string();
    preview::render_deviation_png(mesh, report.vertex_signed_distance, args.png, options);
  }

  if (args.json) {
    nlohmann::json j;
    j["mesh_to_ref"] = to_json(report.mesh_to_ref);
    j["ref_to_mesh"] = to_json(report.ref_to_mesh);
    j["hausdorff"] = hausdorff;
    j["png"] = args.png.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.png);
    std::cout << j.dump() << "\n";
    return kExitOk;
  }
  auto row = [](const char* label, const recon::DistanceStats& s) {
    std::cout << std::left << std::setw(13) << label << std::right << std::setw(10) << s.count
              << std::setw(13) << num(s.mean) << std::setw(13) << num(s.rms) << std::setw(13)
              << num(s.p95) << std::setw(13) << num(s.max) << "\n";
  };
  std::cout << std::left << std::setw(13) << "mesh" << args.mesh << " (" << mesh.vertices.size()
            << " vertices, " << mesh.triangles.size() << " triangles)\n"
            << std::setw(13) << "reference" << args.ref << " (" << ref.vertices.size()
            << " vertices, " << ref.triangles.size() << " triangles)\n"
            << std::setw(13) << "" << std::right << std::setw(10) << "samples" << std::setw(13)
            << "mean" << std::setw(13) << "rms" << std::setw(13) << "p95" << std::setw(13) << "max"
            << "\n";
  row("mesh -> ref", report.mesh_to_ref);
  row("ref -> mesh", report.ref_to_mesh);
  std::cout << std::left << std::setw(13) << "hausdorff" << num(hausdorff) << "\n";
  if (!args.png.empty()) std::cout << std::setw(13) << "png" << args.png << "\n";
  return kExitOk;
}

}  // namespace

void add_deviation_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<DeviationArgs>();
  CLI::App* cmd =
      app.add_subcommand("deviation",
                         "Distances between a mesh and a reference surface (mean, RMS, p95, max, "
                         "Hausdorff)");
  cmd->add_option("MESH", args->mesh, "mesh to check: .ply .stl .obj")->required();
  cmd->add_option("--ref", args->ref, "reference surface: .ply .stl .obj (must have triangles)")
      ->required();
  cmd->add_option("--png", args->png,
                  "write a picture of MESH coloured by its signed deviation from the reference "
                  "(.png)")
      ->check(png_output());
  cmd->add_option("--up", args->up, "world axis shown upwards in the picture (x, y or z)")
      ->capture_default_str()
      ->check(CLI::IsMember({"x", "y", "z"}));
  cmd->add_flag("--json", args->json, "print one JSON object instead of the text table");
  cmd->callback([args, &run] { run = [args] { return run_deviation(*args); }; });
}

}  // namespace scanmesh::cli
