// The one JSON form of a reconstruction's result (result_json.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/reconstruction/result_json.hpp"

namespace scanmesh::reconstruction {

void put_topology(nlohmann::json& j, const recon::MeshReport& r) {
  j["boundary_loops"] = r.boundary_loops;
  j["boundary_loop_lengths"] = r.boundary_loop_lengths;
  j["components"] = r.components;
  j["genus"] = r.genus;
  j["non_manifold_edges"] = r.non_manifold_edges;
  j["non_manifold_vertices"] = r.non_manifold_vertices;
  j["orientation_consistent"] = r.orientation_consistent;
}

void put_fill(nlohmann::json& j, const recon::FillStats& f) {
  j["filled_holes"] = f.filled;
  j["fill_triangles"] = f.triangles;
  j["fill_vertices"] = f.vertices;
  j["faired_holes"] = f.faired;
  j["crossing_loops"] = f.crossing;
}

void put_sharpen(nlohmann::json& j, const recon::SharpenStats& s) {
  j["bevel_triangles"] = s.bevel_triangles;
  j["edge_vertices"] = s.edge_vertices;
  j["corner_vertices"] = s.corner_vertices;
  j["flipped_edges"] = s.flipped;
  j["refused_bevels"] = s.refused;
  j["tidied_edges"] = s.tidied;
  j["rounded_bevels"] = s.rounded;
}

void put_denoise(nlohmann::json& j, const recon::DenoiseStats& s) {
  j["denoised_vertices"] = s.moved;
  j["denoise_refused"] = s.refused;
  j["denoise_clamped"] = s.clamped;
  j["denoise_mean_move"] = s.mean_move;
  j["denoise_max_move"] = s.max_move;
  j["denoise_noise_deg"] = s.noise_deg;
  j["denoise_feature_deg"] = s.feature_deg;
  j["denoise_noise"] = s.noise_mm;
}

nlohmann::json to_json(const BatchOutcome& outcome, const recon::ReconstructOptions& options,
                       const recon::MeshReport& report) {
  const recon::ReconstructResult& res = outcome.result;
  nlohmann::json j;
  j["input_points"] = res.input_points;
  j["reduced_points"] = res.reduced_points;
  j["vertices"] = res.mesh.vertices.size();
  j["triangles"] = res.mesh.triangles.size();
  put_topology(j, report);
  j["outliers"] = res.outliers.size();
  j["far_points"] = res.far_points;
  j["cube"] = res.cube_mm;
  j["spacing"] = {{"nearest", res.spacing.nearest_mm},
                  {"cross", res.spacing.cross_mm},
                  {"thickness", res.spacing.thickness_mm},
                  {"thickness_few", res.spacing.thickness_few_mm},
                  {"thickness_shape", res.spacing.thickness_shape}};
  j["seeds"] = res.seeds;
  j["relaxed_triangles"] = res.relaxed_triangles;
  j["filled_gaps"] = res.filled_gaps;
  j["closed_gaps"] = res.gaps.filled;
  j["zipped_slits"] = res.zip.zipped;
  j["untangled_gaps"] = res.untangle.closed;
  j["untangle_removed_triangles"] = res.untangle.removed;
  j["untangle_skipped_gaps"] = res.untangle.skipped;
  j["untangle_split_fans"] = res.untangle.split_fans;
  j["untangle_widened"] = res.untangle.widened;
  j["untangle_unfillable"] = res.untangle.unfillable;
  j["untangle_dropped_points"] = res.untangle.dropped.size();
  j["removed_fan_triangles"] = res.removed_fan_triangles;
  j["inserted_points"] = res.refine.inserted;
  j["inserted_by_edge_split"] = res.refine.edge_splits;
  j["refine_flips"] = res.refine.flips;
  j["sliver_flips"] = res.refine.sliver_flips;
  put_fill(j, res.fill);
  if (options.denoise) put_denoise(j, res.denoise);
  if (options.sharpen) put_sharpen(j, res.sharpen);
  j["edge_evaluations"] = res.edge_evaluations;
  j["points_scanned"] = res.points_scanned;
  j["skipped_evaluations"] = res.skipped_evaluations;
  j["turning_points"] = res.turning_points;
  j["bulk_patches"] = res.bulk_patches;
  j["bulk_triangles"] = res.bulk_triangles;
  j["dropped_components"] = res.dropped_components;
  j["dropped_specks"] = res.dropped_specks;
  // Representatives whose projection cut across a sharp edge, a corner or a step, and of those
  // the vertices the mesh has at the measured point.
  j["feature_points"] = res.features;
  j["feature_points_measured"] = res.restored;
  j["peeled_chords"] = res.peeled_chords;
  j["notes"] = outcome.notes;
  j["seconds"] = outcome.seconds;
  j["step_seconds"] = outcome.step_seconds;
  return j;
}

nlohmann::json to_json(const StreamOutcome& outcome, const recon::ReconstructOptions& options,
                       const recon::MeshReport& report) {
  const recon::IncrementalResult& res = outcome.result;
  const recon::IncrementalStats& st = res.stats;
  nlohmann::json j;
  j["input_points"] = st.points_in;
  j["reduced_points"] = res.mesh.vertices.size() + res.outliers.size() - res.far_points;
  j["vertices"] = res.mesh.vertices.size();
  j["triangles"] = res.mesh.triangles.size();
  put_topology(j, report);
  j["outliers"] = res.outliers.size();
  j["far_points"] = res.far_points;
  j["cube"] = st.cube_mm;
  j["stream"] = outcome.stream;
  j["batches"] = outcome.batches;
  j["max_batch_seconds"] = outcome.max_batch_seconds;
  j["finish_seconds"] = outcome.finish_seconds;
  j["deltas"] = outcome.deltas;
  j["reopened_blocks"] = st.reopened_blocks;
  j["meshing_steps"] = st.meshing_steps;
  j["meshed_blocks"] = st.meshed_blocks_total;
  j["settle_to_mesh_p99_seconds"] = st.settle_to_mesh_p99_seconds;
  j["take_delta_seconds"] = outcome.take_delta_seconds;
  if (options.fill.max_edges > 0) put_fill(j, outcome.fill);
  if (options.denoise) put_denoise(j, outcome.denoise);
  if (options.sharpen) put_sharpen(j, outcome.sharpen);
  j["notes"] = outcome.notes;
  nlohmann::json seconds = {{"read", outcome.read_seconds}};
  for (const auto& [k, v] : st.seconds) seconds[k] = v;
  j["seconds"] = seconds;
  return j;
}

}  // namespace scanmesh::reconstruction
