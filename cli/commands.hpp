// Subcommands of the `scanmesh` tool. Each registers itself on the CLI11 app and sets `run`.
// SPDX-License-Identifier: MIT
#pragma once

#include <CLI/CLI.hpp>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/denoise.hpp"
#include "scanmesh/recon/fill.hpp"
#include "scanmesh/recon/mesh.hpp"
#include "scanmesh/recon/sharpen.hpp"
#include "scanmesh/reconstruction/result_json.hpp"

namespace scanmesh::cli {

/// Exit statuses shared by every subcommand (part of the command's interface).
enum ExitCode : int {
  kExitOk = 0,
  kExitUsage = 2,   ///< bad flags or arguments
  kExitInput = 3,   ///< unreadable or malformed input
  kExitOutput = 4,  ///< cannot write output
  kExitDevice = 5,  ///< device did not answer
};

using Runner = std::function<int()>;

/// Checks for numeric options whose messages read as a sentence (CLI11's PositiveNumber and
/// NonNegativeNumber print their bound as a 300-digit number). NaN and infinities are refused.
inline CLI::Validator number_above(bool or_zero) {
  return CLI::Validator(
      [or_zero](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || end != text.c_str() + text.size())
          return "'" + text + "' is not a number";
        if (!std::isfinite(v)) return "must be a finite number, got " + text;
        if (or_zero ? v < 0 : v <= 0)
          return std::string(or_zero ? "must be 0 or more" : "must be more than 0") + ", got " +
                 text;
        return {};
      },
      or_zero ? "NUMBER >= 0" : "NUMBER > 0");
}
inline const CLI::Validator kPositive = number_above(false);
inline const CLI::Validator kNonNegative = number_above(true);

/// The world axis named by --up ("x", "y", anything else z) for the rendered pictures.
inline recon::Vec3 axis_of(const std::string& name) {
  if (name == "x") return recon::Vec3::UnitX();
  if (name == "y") return recon::Vec3::UnitY();
  return recon::Vec3::UnitZ();
}

// The JSON fields of a mesh's topology and of the passes (fill, sharpen, denoise): one form,
// reconstruction/'s.
using reconstruction::put_denoise;
using reconstruction::put_fill;
using reconstruction::put_sharpen;
using reconstruction::put_topology;

/// Reads the mesh a command works on (fill, sharpen): a file of vertices only (a point cloud)
/// is refused, naming the command that meshes it.
inline recon::Mesh read_triangle_mesh(const std::string& file) {
  recon::Mesh mesh = meshio::read_mesh(file);
  if (mesh.triangles.empty())
    throw InputError(file + ": no triangles (" + std::to_string(mesh.vertices.size()) +
                     " vertices only: a point cloud? `scanmesh reconstruct` meshes it); nothing "
                     "written");
  return mesh;
}

/// Reads the mesh a command changes in place (fill, sharpen, denoise) into `mesh`, with its
/// report: refused (InputError: exit 3, nothing written) when it has no triangles or is not
/// manifold and consistently oriented, which `what` ("holes can only be filled") needs.
inline recon::MeshReport read_clean_mesh(const std::string& file, const std::string& what,
                                         recon::Mesh& mesh) {
  mesh = read_triangle_mesh(file);
  recon::MeshReport report = recon::analyze(mesh);
  if (report.non_manifold_edges > 0 || report.non_manifold_vertices > 0 ||
      !report.orientation_consistent)
    throw InputError(file + ": " + what + " in a manifold, consistently oriented mesh; this one " +
                     "has " + std::to_string(report.non_manifold_edges) + " non-manifold edge(s), " +
                     std::to_string(report.non_manifold_vertices) + " non-manifold vertex(es) and " +
                     std::to_string(report.inconsistent_edges) +
                     " inconsistently oriented edge(s) (see scanmesh inspect); nothing written");
  return report;
}

/// Writes `mesh` like meshio::write_mesh, and warns on stderr when the file is binary STL
/// (float32 by its format) and float cannot hold the mesh to its edge lengths (a part far from
/// the origin): PLY, OBJ and ascii STL then keep double precision, binary STL cannot.
inline void write_mesh_file(const recon::Mesh& mesh, const std::string& file, bool ascii) {
  if (meshio::write_mesh(mesh, file, meshio::WriteOptions{ascii}).float_rounds_mesh)
    std::fprintf(stderr,
                 "scanmesh: warning: %s: binary STL stores float32 coordinates, which round this "
                 "mesh (far from the origin) by more than 1e-4 of its mean edge; write .ply, .obj "
                 "or --ascii STL to keep double precision\n",
                 file.c_str());
}

/// A check of a file the command will write: its extension (any case) must be one its writer
/// knows, or the arguments are a usage error (exit 2) before any input is read. `use` lists
/// them for the message ("use .stl, .ply or .obj").
inline CLI::Validator output_extension(bool (*known)(const std::filesystem::path&),
                                       std::string use) {
  return CLI::Validator(
      [known, use](std::string& file) -> std::string {
        if (known(file)) return {};
        const std::string ext = std::filesystem::path(file).extension().string();
        return (ext.empty() ? std::string("no extension") : "unknown extension '" + ext + "'") +
               " (use " + use + ")";
      },
      "", "output extension");
}
inline bool is_png_file(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".png";
}
/// Mesh files (meshio::write_mesh), point files (meshio::write_points_xyz), PNG pictures.
inline CLI::Validator mesh_output() {
  return output_extension(meshio::writes_mesh_extension, ".stl, .ply or .obj");
}
inline CLI::Validator points_output() {
  return output_extension(meshio::writes_points_extension, ".xyz, .txt or .asc");
}
inline CLI::Validator png_output() { return output_extension(is_png_file, ".png"); }

/// -o/--output naming a mesh to write.
inline CLI::Option* add_mesh_output_option(CLI::App& cmd, std::string& output) {
  return cmd.add_option("-o,--output", output, "output mesh: .stl .ply .obj")
      ->required()
      ->check(mesh_output());
}

/// The file arguments every command that changes a mesh takes (fill, sharpen, denoise).
struct MeshEditArgs {
  std::string mesh;
  std::string output;
  bool ascii = false;
  bool json = false;
};

/// MESH, -o/--output, --ascii and --json on `cmd`.
inline void add_mesh_edit_args(CLI::App& cmd, MeshEditArgs& args) {
  cmd.add_option("MESH", args.mesh, "mesh file: .ply .stl .obj")->required();
  add_mesh_output_option(cmd, args.output);
  cmd.add_flag("--ascii", args.ascii, "write ASCII STL instead of binary");
  cmd.add_flag("--json", args.json, "print one JSON object with the figures");
}

/// What `sharpen` and `denoise` say after writing the mesh they changed: one JSON object (the
/// files, the command's own fields from `put`, the mesh's size and topology, the time), or the
/// command's own summary lines from `print` followed by the mesh's.
template <class Put, class Print>
void report_edited_mesh(const MeshEditArgs& args, const recon::Mesh& mesh,
                        const recon::MeshReport& after, double seconds, Put&& put, Print&& print) {
  if (args.json) {
    nlohmann::json j;
    j["input"] = args.mesh;
    j["output"] = args.output;
    put(j);
    j["vertices"] = mesh.vertices.size();
    j["triangles"] = mesh.triangles.size();
    put_topology(j, after);
    j["seconds_total"] = seconds;
    std::cout << j.dump() << "\n";
    return;
  }
  print(std::cout);
  std::cout << "vertices         " << mesh.vertices.size() << "\n"
            << "triangles        " << mesh.triangles.size() << "\n"
            << "boundary loops   " << after.boundary_loops << "\n"
            << "genus            " << after.genus << "\n"
            << "written          " << args.output << "\n"
            << std::fixed << std::setprecision(3) << "seconds          " << seconds << "\n";
}

void add_reconstruct_command(CLI::App& app, Runner& run);
void add_inspect_command(CLI::App& app, Runner& run);
void add_fill_command(CLI::App& app, Runner& run);
void add_sharpen_command(CLI::App& app, Runner& run);
/// --face-angle and --feature-angle on `cmd`, help lines prefixed by `when`.
void add_sharpen_options(CLI::App& cmd, recon::SharpenOptions& options, const std::string& when);
void add_denoise_command(CLI::App& app, Runner& run);
/// --denoise-angle, --normal-iterations and --vertex-iterations on `cmd`, help lines prefixed
/// by `when`.
void add_denoise_options(CLI::App& cmd, recon::DenoiseOptions& options, const std::string& when);
void add_deviation_command(CLI::App& app, Runner& run);
void add_generate_command(CLI::App& app, Runner& run);
void add_simulate_command(CLI::App&, Runner&);
void add_devices_command(CLI::App& app, Runner& run);
void add_profiler_command(CLI::App& app, Runner& run);
void add_scan_command(CLI::App& app, Runner& run);
void add_replay_command(CLI::App& app, Runner& run);
void add_stage_command(CLI::App& app, Runner& run);
/// `journal check`, `journal recover` and `scans` (cmd_journal.cpp).
void add_journal_commands(CLI::App& app, Runner& run);

}  // namespace scanmesh::cli
