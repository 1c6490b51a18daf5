// Subcommands of the `scanmesh` tool. Each registers itself on the CLI11 app and sets `run`.
// SPDX-License-Identifier: MIT
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>

#include "scanmesh/recon/mesh.hpp"

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

/// The world axis named by --up ("x", "y", anything else z) for the rendered pictures.
inline recon::Vec3 axis_of(const std::string& name) {
  if (name == "x") return recon::Vec3::UnitX();
  if (name == "y") return recon::Vec3::UnitY();
  return recon::Vec3::UnitZ();
}

void add_reconstruct_command(CLI::App& app, Runner& run);
void add_inspect_command(CLI::App& app, Runner& run);
void add_fill_command(CLI::App& app, Runner& run);
void add_deviation_command(CLI::App& app, Runner& run);
void add_generate_command(CLI::App& app, Runner& run);
void add_simulate_command(CLI::App&, Runner&);
void add_devices_command(CLI::App& app, Runner& run);

}  // namespace scanmesh::cli
