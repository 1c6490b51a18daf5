// What `scan` and `replay` share: running a pipeline with the progress line, and writing and
// reporting its mesh.
// SPDX-License-Identifier: MIT
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "scanmesh/acquisition/pipeline.hpp"

namespace scanmesh::cli {

/// Starts the pipeline and waits for its end, showing the progress line on stderr if asked.
acq::PipelineStats run_pipeline(acq::Pipeline& pipeline, bool progress);

struct ScanOutput {
  std::string output;   ///< mesh file (.stl .ply .obj)
  std::string preview;  ///< .png or empty
  bool json = false;
  std::string what;     ///< "scan of container", "replay of x.mcap"
};

/// Writes the final mesh (and preview), prints the one JSON object (the pipeline's stats plus
/// `extra` and a "mesh" object) or a summary line; returns the exit status: 0 when the scan
/// completed or was stopped, 4 when the journal failed, 5 when a device failed.
int report_scan(const acq::Pipeline& pipeline, const acq::PipelineStats& stats,
                const ScanOutput& out, nlohmann::json extra);

}  // namespace scanmesh::cli
