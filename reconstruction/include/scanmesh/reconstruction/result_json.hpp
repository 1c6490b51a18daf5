// The one JSON form of a reconstruction's result (`scanmesh reconstruct --json`, and the
// mesh-editing commands' shared fields): field names are an interface.
// SPDX-License-Identifier: MIT
#pragma once

#include <nlohmann/json.hpp>

#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/denoise.hpp"
#include "scanmesh/recon/fill.hpp"
#include "scanmesh/recon/sharpen.hpp"
#include "scanmesh/reconstruction/reconstruction.hpp"

namespace scanmesh::reconstruction {

/// boundary_loops, boundary_loop_lengths, components, genus, non_manifold_edges,
/// non_manifold_vertices, orientation_consistent.
void put_topology(nlohmann::json& j, const recon::MeshReport& r);
/// filled_holes, fill_triangles, fill_vertices, faired_holes, crossing_loops.
void put_fill(nlohmann::json& j, const recon::FillStats& f);
/// bevel_triangles, edge_vertices, corner_vertices, flipped_edges, refused_bevels,
/// tidied_edges, rounded_bevels.
void put_sharpen(nlohmann::json& j, const recon::SharpenStats& s);
/// denoised_vertices, denoise_refused, denoise_clamped, denoise_mean_move, denoise_max_move,
/// denoise_noise_deg, denoise_feature_deg, denoise_noise.
void put_denoise(nlohmann::json& j, const recon::DenoiseStats& s);

/// The batch path's figures (input_points, reduced_points, vertices, triangles, the topology of
/// `report`, outliers, cube, spacing, the front's and the passes' counters, notes, seconds,
/// step_seconds). `options` says which passes ran. The caller adds what it wrote ("output",
/// "preview") and its own times ("seconds_total", seconds "write" / "preview").
nlohmann::json to_json(const BatchOutcome& outcome, const recon::ReconstructOptions& options,
                       const recon::MeshReport& report);
/// The streamed path's figures (input_points, ..., stream, batches, deltas, reopened_blocks,
/// meshing steps and times, notes, seconds: "read" and the core's stages).
nlohmann::json to_json(const StreamOutcome& outcome, const recon::ReconstructOptions& options,
                       const recon::MeshReport& report);

}  // namespace scanmesh::reconstruction
