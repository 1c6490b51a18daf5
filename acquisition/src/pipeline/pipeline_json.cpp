// PipelineStats as JSON.
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/pipeline_json.hpp"

namespace scanmesh::acq {

nlohmann::json to_json(const PipelineStats& s) {
  const double elapsed = std::chrono::duration<double>(s.elapsed).count();
  nlohmann::json j;
  j["state"] = std::string(to_string(s.state));
  j["reason"] = s.reason;
  j["samples"] = s.samples_received;
  j["recorded"] = s.samples_recorded;
  j["stage_samples"] = s.stage_samples;
  j["points"] = s.points;
  j["invalid"] = s.invalid;
  j["no_pose"] = s.no_pose;
  j["lost"] = s.lost;
  j["journal_bytes"] = s.journal_bytes;
  j["meshing_lag"] = s.meshing_lag;
  j["kept_points"] = s.mesh.kept_points;
  j["vertices"] = s.mesh.vertices;
  j["triangles"] = s.mesh.triangles;
  j["deltas"] = s.mesh.deltas;
  j["reopened_blocks"] = s.mesh.reopened_blocks;
  j["elapsed_s"] = elapsed;
  j["samples_per_s"] = elapsed > 0 ? static_cast<double>(s.samples_received) / elapsed : 0.0;
  return j;
}

}  // namespace scanmesh::acq
