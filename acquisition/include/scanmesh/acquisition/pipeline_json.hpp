// The one JSON form of a scan's progress and result (PipelineStats), used by `scanmesh scan`,
// `scanmesh replay`, the daemon's status and events, and the tests.
// SPDX-License-Identifier: MIT
#pragma once

#include <nlohmann/json.hpp>

#include "scanmesh/acquisition/pipeline.hpp"

namespace scanmesh::acq {

/// Fields: state, reason, samples, recorded, stage_samples, points, invalid, no_pose, lost,
/// journal_bytes, meshing_lag, kept_points, vertices, triangles, deltas, reopened_blocks,
/// elapsed_s, samples_per_s (over the elapsed time).
nlohmann::json to_json(const PipelineStats& stats);

}  // namespace scanmesh::acq
