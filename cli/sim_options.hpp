// The simulated scanner's options, shared by `scanmesh simulate` and `scanmesh scan --sim`.
// SPDX-License-Identifier: MIT
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "scanmesh/recon/mesh.hpp"
#include "scanmesh/sim/scan_settings.hpp"

namespace scanmesh::cli {

/// Registers --sensor --path --spacing --line-spacing --noise --dropout --spike --missing
/// --stage-noise --latency-us --speed --accel --views --profile-points --threads --seed.
void add_sim_scan_options(CLI::App* cmd, sim::ScanSettings& settings);

/// A built-in part by name, else a mesh file (which must have triangles). Throws InputError.
recon::Mesh load_scan_target(const std::string& part_or_mesh);

}  // namespace scanmesh::cli
