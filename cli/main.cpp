// Entry point of the `scanmesh` command-line tool: dispatches to the subcommands and maps errors
// to the documented exit statuses.
// SPDX-License-Identifier: MIT
#include <CLI/CLI.hpp>
#include <iostream>

#include "commands.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

int main(int argc, char** argv) {
  using namespace scanmesh;
  CLI::App app{"scanmesh: point clouds to manifold triangle meshes"};
  app.require_subcommand(1);
  cli::Runner run;
  cli::add_reconstruct_command(app, run);
  cli::add_inspect_command(app, run);
  cli::add_fill_command(app, run);
  cli::add_sharpen_command(app, run);
  cli::add_denoise_command(app, run);
  cli::add_deviation_command(app, run);
  cli::add_generate_command(app, run);
  cli::add_simulate_command(app, run);
  cli::add_devices_command(app, run);
  cli::add_scan_command(app, run);
  cli::add_replay_command(app, run);
  cli::add_stage_command(app, run);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return cli::kExitUsage;
  }
  try {
    return run ? run() : cli::kExitUsage;
  } catch (const drivers::DeviceError& e) {
    std::cerr << "scanmesh: " << e.what() << "\n";
    return cli::kExitDevice;
  } catch (const ConfigError& e) {
    std::cerr << "scanmesh: " << e.what() << "\n";
    return cli::kExitUsage;
  } catch (const InputError& e) {
    std::cerr << "scanmesh: " << e.what() << "\n";
    return cli::kExitInput;
  } catch (const GeometryError& e) {
    std::cerr << "scanmesh: " << e.what() << "\n";
    return cli::kExitInput;
  } catch (const OutputError& e) {
    std::cerr << "scanmesh: " << e.what() << "\n";
    return cli::kExitOutput;
  } catch (const std::bad_alloc&) {
    std::cerr << "scanmesh: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "scanmesh: internal error: " << e.what() << "\n";
    return 1;
  }
}
