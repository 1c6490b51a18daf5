// The whole point-cloud-to-mesh pipeline: validation, spacing, cube reduction, frames,
// advancing front, output mesh. Pure and deterministic; stage timing is left to the caller
// through the observer (the core reads no clock).
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/recon/denoise.hpp"
#include "scanmesh/recon/fill.hpp"
#include "scanmesh/recon/sharpen.hpp"
#include "scanmesh/recon/front.hpp"
#include "scanmesh/recon/mesh.hpp"
#include "scanmesh/recon/reduce.hpp"
#include "scanmesh/recon/refine.hpp"

namespace scanmesh::recon {

struct ReconstructOptions {
  enum class CubeMode { kAuto, kFixed, kNone };
  CubeMode cube_mode = CubeMode::kAuto;  ///< auto: derived from the measured spacing
  double cube_mm = 0;                    ///< cube edge when kFixed (input units), > 0
  /// Move each cube representative onto the local least-squares plane of the input points
  /// (radius = project_radius_factor cubes, at most half a cube): collapses noisy multi-view
  /// shells into one layer.
  bool project = true;
  double project_radius_factor = 1.5;
  /// Onto the local least-squares quadric instead of the plane (second-order MLS) where the
  /// ball holds enough points: the plane lies inside a curved surface by about radius^2 / (4 R).
  bool project_second_order = true;
  /// A ball whose points lie farther from their plane (RMS) than project_flat_factor times the
  /// scan's shell thickness (SpacingEstimate::thickness_mm, the noise), and that no quadric
  /// explains, straddles a sharp edge, a corner or a step: its plane cuts across the feature,
  /// up to half a cube inside the part. The front meshes the projected point (it follows a
  /// rounded feature more surely), and the output has the measured one wherever the mesh stays
  /// valid. 0: the projected point (as before stop 43).
  double project_flat_factor = 8.0;
  /// A border triangle whose border edge lies opposite an angle over peel_apex_deg at a vertex
  /// inside the mesh runs that edge as a chord past the measured point at the apex: it is
  /// peeled off, until none is left, so the border passes through the samples (where a curved
  /// scan line ends the surface, the chords are fans in the line's plane, inside the part).
  /// Loops, components, genus and used points do not change. 0: off (as before stop 44).
  double peel_apex_deg = 110.0;
  FrontOptions front;
  NormalOptions normals;
  RefineOptions refine;
  /// Sampling gaps the front and the insertion left (loops of at most gap_max_edges edges and
  /// front.fill_perimeter_factor local spacings) are closed at the end with their own vertices
  /// (the minimum-weight patch of fill.hpp, never crossing the mesh). Off only for comparison.
  bool close_gaps = true;
  /// More than the front's own fill_max_edges (8): an evenly sampled loop within the perimeter
  /// limit has about 10 edges at most anyway, while a gap on the seam between a dense and a
  /// coarse sampling has many short edges on its dense side (a fan of 30 dense points onto one
  /// coarse point). The search costs O(n^3) for a loop of n edges.
  std::size_t gap_max_edges = 64;
  /// Those gaps that stay open because their patch would cross the mesh are untangled where a
  /// few triangles reach through them (fill.hpp: untangle_gaps). Off only for comparison.
  bool untangle_gaps = true;
  /// Slits (a boundary edge with its loop's next or previous vertices lying along it, within
  /// this many of their spacings of it: where a coarse row meets a dense one) are zipped before
  /// the gaps are closed (fill.hpp: zip_slits), as part of close_gaps; 0: none.
  double zip_band = 0.5;
  /// Off by default: real holes stay open. On request, small loops are closed at the end.
  FillOptions fill;
  /// Off by default: on request, the scan's noise is removed at the end, before the sharp edges
  /// are recovered (denoise.hpp: filtered triangle normals, the vertices fitted to them; only
  /// vertex positions change), with these options.
  bool denoise = false;
  DenoiseOptions denoise_options;
  /// Off by default: on request, the sharp edges and corners the scan bevelled are recovered at
  /// the end, before the fill (sharpen.hpp: new vertices where the faces meet), with these
  /// angles.
  bool sharpen = false;
  SharpenOptions sharpen_options;
  /// Reports every bad field at once (empty when valid).
  [[nodiscard]] std::vector<std::string> validate() const;
};

struct ReconstructResult {
  Mesh mesh;  ///< only vertices used by triangles; consistently oriented
  std::size_t input_points = 0;
  std::size_t reduced_points = 0;  ///< points handed to the front
  double cube_mm = 0;              ///< cube edge used (0 = none)
  SpacingEstimate spacing;
  /// Reduced points the front never reached, then those the gap untangling left out
  /// (`untangle.dropped`), then the far points (input points far outside the body of the
  /// cloud, see far_points in reduce.hpp: stray readings, not meshed).
  std::vector<Vec3> outliers;
  std::size_t far_points = 0;  ///< of which far points (the last ones in `outliers`)
  std::size_t seeds = 0, relaxed_triangles = 0, filled_gaps = 0, removed_fan_triangles = 0;
  /// Representatives whose projection cut across a feature (a sharp edge, a corner, a step:
  /// ReconstructOptions::project_flat_factor), and how many of their vertices the mesh has at
  /// the measured point instead (the rest keep the projection, where the measured point would
  /// fold or cross a triangle).
  std::size_t features = 0, restored = 0;
  /// Border triangles peeled off (ReconstructOptions::peel_apex_deg).
  std::size_t peeled_chords = 0;
  RefineStats refine;  ///< points the front left out that were inserted afterwards
  ZipStats zip;        ///< slits zipped at the end (options.close_gaps, zip_band)
  FillStats gaps;      ///< sampling gaps closed at the end (options.close_gaps)
  /// Gaps left open because their patch would cross the mesh, untangled (fill.hpp).
  UntangleStats untangle;
  FillStats fill;      ///< holes closed on request (options.fill)
  DenoiseStats denoise;  ///< noise removed on request (options.denoise)
  SharpenStats sharpen;  ///< edges recovered on request (options.sharpen)
  std::size_t edge_evaluations = 0, points_scanned = 0, seed_attempts = 0;  ///< cost counters
  /// Front edge evaluations not run: known to find no candidate (cost counter).
  std::size_t skipped_evaluations = 0;
  /// Planar Delaunay patches the front started from, and the triangles they gave (front.hpp).
  std::size_t bulk_patches = 0, bulk_triangles = 0;
  std::size_t turning_points = 0;  ///< points the crossing guard tests against everything near
  /// Small components the front removed because they crossed another (points then inserted).
  std::size_t dropped_components = 0;
  /// Lone one- or two-triangle pieces beside a large component, removed (front.hpp).
  std::size_t dropped_specks = 0;
};

/// Throws GeometryError with a clear message for inputs that cannot make a surface: no points,
/// fewer than 3 distinct points, non-finite coordinates or coordinates beyond +-1e100, a cloud
/// spanning less than 1e-100, all points collinear, more than 1 % of the points far outside
/// the body of the cloud (a few such stray points become outliers).
/// `observer` (StageObserver, front.hpp) hears the name of each stage when it starts ("reduce",
/// "normals", "front", "refine", "output", "gaps" when sampling gaps are closed, "denoise" when the noise is to be removed, "sharpen" when
/// edges are to be recovered, and "fill" when holes are to be closed) and "done" at the end. Steps within a stage carry the stage's name
/// and a slash ("front/growth", see advance_front): a caller that times stages only counts them
/// into the stage.
/// `towards_sensor` (empty, or one per point): a vector from each point towards the sensor that
/// measured it; each part of the surface then faces its sensors (estimate_frames). Closed parts
/// face outward either way.
ReconstructResult reconstruct(std::span<const Vec3> points, const ReconstructOptions& options = {},
                              const StageObserver& observer = {},
                              std::span<const Vec3> towards_sensor = {});

}  // namespace scanmesh::recon
