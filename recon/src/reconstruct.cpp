// Point cloud -> manifold mesh pipeline.
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/reconstruct.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/normals.hpp"
#include "loop_measure.hpp"
#include "peel.hpp"
#include "restore.hpp"

namespace scanmesh::recon {
namespace detail {

LoopCheck check_loops(std::span<const Vec3> points, std::span<const Triangle> triangles,
                      std::span<const VertexState> state, std::span<const float> spacing,
                      std::size_t max_edges, double factor, double band) {
  LoopCheck check;
  auto on_boundary = [&](std::uint32_t v) { return state[v] == VertexState::kBoundary; };
  std::vector<std::uint64_t> half;  // half-edges between boundary vertices: (from << 32) | to
  for (const Triangle& t : triangles)
    for (int k = 0; k < 3; ++k)
      if (on_boundary(t[k]) && on_boundary(t[(k + 1) % 3]))
        half.push_back((std::uint64_t{t[k]} << 32) | t[(k + 1) % 3]);
  std::sort(half.begin(), half.end());
  auto has = [&](std::uint32_t u, std::uint32_t v) {
    return std::binary_search(half.begin(), half.end(), (std::uint64_t{u} << 32) | v);
  };
  // The boundary half-edges (no twin), by their start and by their end; a vertex-manifold mesh
  // has one of each per boundary vertex (more only where two holes touch: the walk then just
  // follows the first; see below).
  using Links = std::vector<std::pair<std::uint32_t, std::uint32_t>>;
  Links next, prev;  // (from, to), (to, from)
  for (const std::uint64_t h : half) {
    const auto u = static_cast<std::uint32_t>(h >> 32), v = static_cast<std::uint32_t>(h);
    if (has(v, u)) continue;
    next.emplace_back(u, v);
    prev.emplace_back(v, u);
  }
  std::sort(prev.begin(), prev.end());
  // The position of the first link out of u, or links.size().
  auto link_from = [](const Links& links, std::uint32_t u) {
    const auto it = std::lower_bound(links.begin(), links.end(), std::make_pair(u, std::uint32_t{0}));
    return it != links.end() && it->first == u ? static_cast<std::size_t>(it - links.begin()) : links.size();
  };
  // Where the first link out of u leads (u itself when there is none).
  auto step = [&](const Links& links, std::uint32_t u) {
    const std::size_t e = link_from(links, u);
    return e < links.size() ? links[e].second : u;
  };
  // x lies along u -> v: strictly between the ends, within band spacings of the line.
  auto along = [&](std::uint32_t u, std::uint32_t v, std::uint32_t x) {
    double at = 0;
    return x != u && x != v &&
           lies_along(points[u], points[v], points[x], band * spacing[x], at) && at > 0 &&
           at < (points[v] - points[u]).norm();
  };
  // A loop of at most max_edges edges from start -> first, within the perimeter limit.
  auto small_gap_from = [&](std::uint32_t start, std::uint32_t first) {
    LoopMeasure measure;
    measure.add(points[start], points[first], spacing[start], spacing[first]);
    std::size_t edges = 1;
    std::uint32_t u = first;
    while (u != start && edges < max_edges) {
      const std::uint32_t v = step(next, u);
      if (v == u) break;  // not a closed walk
      measure.add(points[u], points[v], spacing[u], spacing[v]);
      ++edges;
      u = v;
    }
    return u == start && measure.within(factor);
  };
  // Each loop is walked once, from its first boundary edge in (start, end) order, all the way
  // round, and its edges are not walked again: every edge is visited once, whatever the loops'
  // lengths. Where two loops touch at a vertex (the walk follows the first edge out of it and
  // may not come back to its start), each edge of that walk gets the bounded walk of its own.
  std::vector<std::uint8_t> walked(next.size(), 0);
  std::vector<std::size_t> trail;
  for (std::size_t e0 = 0; e0 < next.size(); ++e0) {
    const auto [start, first] = next[e0];
    if (!check.slit && band > 0)
      check.slit = along(start, first, step(next, first)) || along(start, first, step(prev, start));
    if (check.gap || walked[e0]) continue;
    walked[e0] = 1;
    trail.assign(1, e0);
    LoopMeasure measure;
    measure.add(points[start], points[first], spacing[start], spacing[first]);
    std::uint32_t u = first;
    while (u != start) {
      const std::size_t e = link_from(next, u);
      if (e == next.size() || walked[e]) break;
      walked[e] = 1;
      trail.push_back(e);
      const std::uint32_t v = next[e].second;
      if (trail.size() <= max_edges) measure.add(points[u], points[v], spacing[u], spacing[v]);
      u = v;
    }
    if (u == start)
      check.gap = trail.size() <= max_edges && measure.within(factor);
    else
      for (std::size_t k = 0; k < trail.size() && !check.gap; ++k)
        check.gap = small_gap_from(next[trail[k]].first, next[trail[k]].second);
  }
  return check;
}

}  // namespace detail

namespace {

void check_values(std::span<const Vec3> points) {
  if (points.empty()) throw GeometryError("no points: the input is empty");
  std::size_t bad = 0, first_bad = 0;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!points[i].allFinite() && bad++ == 0) first_bad = i;
  if (bad > 0)
    throw GeometryError(std::to_string(bad) + " point(s) have non-finite coordinates (first: #" +
                        std::to_string(first_bad) + ")");
  // Squared distances must neither overflow nor underflow in double precision.
  constexpr double kHuge = 1e100, kTiny = 1e-100;
  const Eigen::AlignedBox3d box = bounding_box(points);
  if (std::max(box.min().cwiseAbs().maxCoeff(), box.max().cwiseAbs().maxCoeff()) > kHuge) {
    for (std::size_t i = 0; i < points.size(); ++i)  // only to name them
      if (points[i].cwiseAbs().maxCoeff() > kHuge && bad++ == 0) first_bad = i;
    throw GeometryError(std::to_string(bad) + " point(s) have coordinates beyond +-1e100 (first: #" +
                        std::to_string(first_bad) +
                        "): too large to square in double precision; check the input's units");
  }
  const double extent = box.sizes().maxCoeff();
  if (extent > 0 && extent < kTiny) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "the cloud spans only %.3g", extent);
    throw GeometryError(std::string(buf) +
                        ": too small to mesh in double precision (its squared distances vanish); "
                        "scale the input");
  }
}

/// Distinct points and collinearity, after the far points are set aside (they would dominate
/// the covariance).
void check_shape(std::span<const Vec3> points) {
  // Distinct points and collinearity from the covariance of the cloud.
  std::size_t distinct = 1;
  for (std::size_t i = 1; i < points.size() && distinct < 3; ++i) {
    bool seen = false;
    for (std::size_t j = 0; j < i && !seen; ++j) seen = points[j] == points[i];
    if (!seen) ++distinct;
    if (i > 64) {
      distinct = 3;  // large clouds: decided by the covariance below
      break;
    }
  }
  if (distinct < 3)
    throw GeometryError("only " + std::to_string(distinct) +
                        " distinct point(s): a surface needs at least 3");
  Vec3 mean = Vec3::Zero();
  for (const Vec3& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Vec3& p : points) cov += (p - mean) * (p - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov, Eigen::EigenvaluesOnly);
  const Vec3 ev = es.eigenvalues();
  if (!(ev[2] > 0)) throw GeometryError("all points coincide (fewer than 3 distinct points): no surface");
  if (ev[1] <= 1e-18 * ev[2])
    throw GeometryError("all points are collinear: they span no surface");
}

}  // namespace

std::vector<std::string> ReconstructOptions::validate() const {
  std::vector<std::string> errors = front.validate();
  for (auto& e : refine.validate()) errors.push_back(std::move(e));
  for (auto& e : fill.validate()) errors.push_back(std::move(e));
  if (denoise)
    for (auto& e : denoise_options.validate()) errors.push_back(std::move(e));
  if (sharpen)
    for (auto& e : sharpen_options.validate()) errors.push_back(std::move(e));
  if (cube_mode == CubeMode::kFixed && !(cube_mm > 0 && std::isfinite(cube_mm)))
    errors.push_back("cube size must be a positive number");
  if (gap_max_edges > FillOptions::kLimit)
    errors.push_back("sampling gaps are closed up to " + std::to_string(FillOptions::kLimit) +
                     " edges, got " + std::to_string(gap_max_edges));
  if (!(zip_band >= 0 && zip_band <= 2))
    errors.push_back("slit zipping band must be in [0, 2] spacings");
  if (normals.neighbours < 6 || normals.neighbours > 64)
    errors.push_back("normal neighbourhood must be in [6, 64]");
  if (!(project_flat_factor >= 0 && project_flat_factor <= 1000))
    errors.push_back("projection flatness factor must be in [0, 1000] (0: off)");
  if (!(peel_apex_deg == 0 || (peel_apex_deg >= 90 && peel_apex_deg < 180)))
    errors.push_back("border chord apex angle must be in [90, 180) degrees (0: off)");
  return errors;
}

ReconstructResult reconstruct(std::span<const Vec3> points, const ReconstructOptions& options,
                              const StageObserver& observer, std::span<const Vec3> towards_sensor) {
  auto stage = [&](std::string_view name) {
    if (observer) observer(name);
  };
  if (const auto errors = options.validate(); !errors.empty()) {
    std::string msg = "invalid reconstruction options:";
    for (const auto& e : errors) msg += " " + e + ";";
    throw ConfigError(msg);
  }
  check_values(points);
  if (!towards_sensor.empty() && towards_sensor.size() != points.size())
    throw ConfigError("sensor directions: " + std::to_string(towards_sensor.size()) +
                      " given for " + std::to_string(points.size()) +
                      " points (one per point, or none)");
  ReconstructResult res;
  res.input_points = points.size();

  stage("reduce");
  // Stray points far outside the body of the cloud would stretch every grid beyond its reach:
  // they go to the outliers (reported, not meshed), as long as they are a few.
  std::vector<Vec3> far, near_points, near_sensor;
  if (const auto far_idx = far_points(points); !far_idx.empty()) {
    if (far_idx.size() * 100 > points.size()) {
      char buf[256];
      const Vec3& p = points[far_idx.front()];
      std::snprintf(buf, sizeof buf,
                    "%zu of %zu points (first: #%u at %.6g %.6g %.6g) lie far outside the body of "
                    "the cloud, too many to be stray readings, too far to mesh with it: scans in "
                    "different units or placements? Split the input",
                    far_idx.size(), points.size(), far_idx.front(), p.x(), p.y(), p.z());
      throw GeometryError(buf);
    }
    near_points.reserve(points.size() - far_idx.size());
    std::size_t next = 0;  // far_idx is ascending
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (next < far_idx.size() && far_idx[next] == i) {
        far.push_back(points[i]);
        ++next;
        continue;
      }
      near_points.push_back(points[i]);
      if (!towards_sensor.empty()) near_sensor.push_back(towards_sensor[i]);
    }
    points = near_points;
    towards_sensor = near_sensor;
  }
  check_shape(points);
  res.far_points = far.size();

  res.spacing = estimate_spacing(points);
  std::vector<std::uint32_t> kept;
  if (options.cube_mode == ReconstructOptions::CubeMode::kNone) {
    // Every point, but exact duplicates collapse (they cannot be separate vertices): points
    // within a thousandth of the spacing, or, where the cloud spans more than the grid's 2
    // million cells of that size per axis, within the cell that fits (at most a tenth).
    double tiny = std::max(res.spacing.nearest_mm * 1e-3, 1e-12);
    const double extent = bounding_box(points).sizes().maxCoeff();
    constexpr double kCells = 1.5e6;
    if (extent > kCells * tiny) {
      tiny = extent / kCells;
      if (tiny > 0.1 * res.spacing.nearest_mm) {
        char buf[256];
        std::snprintf(buf, sizeof buf,
                      "without cubes every point is kept, but the cloud spans %.6g, over "
                      "150,000 times its point spacing (%.3g): too far for one grid; use a cube "
                      "size (auto)",
                      extent, res.spacing.nearest_mm);
        throw GeometryError(buf);
      }
    }
    kept = cube_reduce(points, tiny);
    res.cube_mm = 0;
  } else {
    res.cube_mm = options.cube_mode == ReconstructOptions::CubeMode::kFixed
                      ? options.cube_mm
                      : auto_cube_size(res.spacing);
    if (!(res.cube_mm > 0)) res.cube_mm = std::max(res.spacing.nearest_mm, 1e-9);
    kept = cube_reduce_thin(points, res.cube_mm);
  }
  std::vector<Vec3> reduced;
  // Representatives whose projection cut across a feature (a sharp edge, a corner, a step):
  // the front meshes their projected positions, the output has their measured ones where the
  // mesh stays valid (restore_positions): their positions in `reduced`, with the measured point.
  std::vector<std::pair<std::uint32_t, Vec3>> measured;
  if (options.project && res.cube_mm > 0) {
    const double max_plane_rms = options.project_flat_factor > 0
                                     ? options.project_flat_factor * res.spacing.thickness_mm
                                     : std::numeric_limits<double>::infinity();
    std::vector<std::uint32_t> features;
    reduced = project_to_local_planes(points, kept, options.project_radius_factor * res.cube_mm,
                                      0.5 * res.cube_mm, options.project_second_order,
                                      max_plane_rms,
                                      options.project_flat_factor > 0 ? &features : nullptr);
    measured.reserve(features.size());
    for (std::uint32_t f : features) measured.emplace_back(f, points[kept[f]]);
  } else {
    reduced.resize(kept.size());
    for (std::size_t i = 0; i < kept.size(); ++i) reduced[i] = points[kept[i]];
  }
  if (reduced.size() < 3)
    throw GeometryError("only " + std::to_string(reduced.size()) +
                        " point(s) left after cube reduction; use a smaller --cube");

  // Each kept point's direction towards its sensor, when known.
  std::vector<Vec3> views;
  if (!towards_sensor.empty()) {
    views.resize(kept.size());
    for (std::size_t i = 0; i < kept.size(); ++i) views[i] = towards_sensor[kept[i]];
  }
  std::vector<std::uint32_t>().swap(kept);  // memory: each stage frees what it no longer needs

  FrontResult fr;
  std::vector<float> spacing;  // of each reduced point, as the front saw it: for closing gaps
  {
    stage("normals");
    // Spatially sort the reduced points (grid order) so the front walks memory coherently.
    const double typical = std::max(res.cube_mm, res.spacing.nearest_mm);
    PointGrid grid;
    grid.build(reduced, 2.5 * std::max(typical, 1e-12));
    {
      std::vector<Vec3> sorted(reduced.size());
      const auto& order = grid.order();
      for (std::size_t i = 0; i < order.size(); ++i) sorted[i] = reduced[order[i]];
      reduced.swap(sorted);
      if (!measured.empty()) {
        std::vector<std::uint32_t> at(order.size());  // old position -> new
        for (std::size_t i = 0; i < order.size(); ++i) at[order[i]] = static_cast<std::uint32_t>(i);
        for (auto& m : measured) m.first = at[m.first];
        std::sort(measured.begin(), measured.end(),
                  [](const auto& a, const auto& b) { return a.first < b.first; });
      }
      if (!views.empty()) {
        for (std::size_t i = 0; i < order.size(); ++i) sorted[i] = views[order[i]];
        views.swap(sorted);
      }
    }
    grid.renumber_in_order();  // the grid of the sorted points (no second build)
    const LocalFrames frames = estimate_frames(reduced, grid, options.normals, views);
    std::vector<Vec3>().swap(views);
    // Re-grid with the measured local spacing so that one ring of cells covers the front's scan
    // radius (1.5 x radius_factor spacings plus half an edge): 9 rows a query, where cells half
    // that size made the row look-ups cost more than the extra points the larger cells bring.
    {
      std::vector<float> sp = frames.spacing;
      std::nth_element(sp.begin(), sp.begin() + static_cast<std::ptrdiff_t>(sp.size() / 2),
                       sp.end());
      const double median = sp[sp.size() / 2];
      if (median > 0)
        grid.build(reduced, (options.front.radius_factor * 1.5 + 0.6) * median);
    }
    res.reduced_points = reduced.size();

    stage("front");
    fr = advance_front(reduced, frames, grid, options.front, observer);

    stage("refine");
    res.refine = insert_unused_points(reduced, frames, grid, fr, options.refine);
    // The front's own measure, as in its own gap closing.
    if (options.close_gaps) spacing = std::move(fr.spacing);
    std::vector<float>().swap(fr.spacing);
  }  // frames and grid are freed here, before the output copy

  stage("output");
  // Only vertices used by triangles, in order of first use; the triangles are renumbered in
  // place (moved, not copied).
  std::vector<std::uint32_t> remap(reduced.size(), 0xffffffffu);
  std::size_t used = 0;
  for (const Triangle& t : fr.triangles)
    for (std::uint32_t v : t)
      if (remap[v] == 0xffffffffu) remap[v] = static_cast<std::uint32_t>(used++);
  res.mesh.vertices.resize(used);
  for (std::size_t v = 0; v < reduced.size(); ++v)
    if (remap[v] != 0xffffffffu) res.mesh.vertices[remap[v]] = reduced[v];
  const detail::LoopCheck loops = options.close_gaps
                              ? detail::check_loops(reduced, fr.triangles, fr.state, spacing,
                                            options.gap_max_edges,
                                            options.front.fill_perimeter_factor, options.zip_band)
                              : detail::LoopCheck{};
  const bool gaps = options.close_gaps && options.gap_max_edges > 0 && loops.gap;
  if (!gaps && !loops.slit) std::vector<float>().swap(spacing);
  res.mesh.triangles = std::move(fr.triangles);
  for (Triangle& t : res.mesh.triangles)
    for (std::uint32_t& v : t) v = remap[v];
  res.outliers.reserve(fr.outliers.size());
  for (std::uint32_t v : fr.outliers) {
    // A feature's outlier as measured (its projection cut across the feature).
    const auto m = std::lower_bound(measured.begin(), measured.end(), v,
                                    [](const auto& a, std::uint32_t key) { return a.first < key; });
    res.outliers.push_back(m != measured.end() && m->first == v ? m->second : reduced[v]);
  }
  res.outliers.insert(res.outliers.end(), far.begin(), far.end());
  std::vector<Vec3>().swap(far);
  res.seeds = fr.seeds;
  res.relaxed_triangles = fr.relaxed_triangles;
  res.filled_gaps = fr.filled_gaps;
  res.removed_fan_triangles = fr.removed_fan_triangles;
  res.edge_evaluations = fr.edge_evaluations;
  res.points_scanned = fr.points_scanned;
  res.skipped_evaluations = fr.skipped_evaluations;
  res.seed_attempts = fr.seed_attempts;
  res.turning_points = fr.turning_points;
  res.bulk_patches = fr.bulk_patches;
  res.bulk_triangles = fr.bulk_triangles;
  res.dropped_components = fr.dropped_components;
  res.dropped_specks = fr.dropped_specks;
  if (gaps || loops.slit) {
    stage("gaps");
    std::vector<float> vertex_spacing(used);
    for (std::size_t v = 0; v < reduced.size(); ++v)
      if (remap[v] != 0xffffffffu) vertex_spacing[remap[v]] = spacing[v];
    std::vector<float>().swap(spacing);
    if (loops.slit) {
      std::vector<std::uint8_t> boundary(used, 0);
      for (std::size_t v = 0; v < reduced.size(); ++v)
        if (remap[v] != 0xffffffffu) boundary[remap[v]] = fr.state[v] == VertexState::kBoundary ? 1 : 0;
      res.zip = zip_slits(res.mesh, vertex_spacing, options.zip_band, boundary);
    }
    // What a zip leaves of a loop may be a sampling gap now.
    if (options.gap_max_edges > 0 && (gaps || res.zip.zipped > 0)) {
      FillOptions gap_fill;
      gap_fill.max_edges = options.gap_max_edges;
      gap_fill.max_perimeter_spacings = options.front.fill_perimeter_factor;
      gap_fill.refine = false;
      res.gaps = fill_holes(res.mesh, gap_fill, vertex_spacing);
      if (options.untangle_gaps && res.gaps.crossing > 0)
        res.untangle = untangle_gaps(res.mesh, gap_fill, vertex_spacing, res.gaps);
    }
  }
  if (!res.untangle.renumber.empty()) {
    // Vertices the untangling left out are outliers now (as measured, for a feature's), before
    // the far points.
    std::vector<Vec3> left_out;
    for (std::size_t v = 0; v < reduced.size(); ++v) {
      if (remap[v] == 0xffffffffu) continue;
      remap[v] = res.untangle.renumber[remap[v]];
      if (remap[v] != 0xffffffffu) continue;
      const auto m =
          std::lower_bound(measured.begin(), measured.end(), static_cast<std::uint32_t>(v),
                           [](const auto& a, std::uint32_t key) { return a.first < key; });
      left_out.push_back(m != measured.end() && m->first == v ? m->second : reduced[v]);
    }
    res.outliers.insert(res.outliers.end() - static_cast<std::ptrdiff_t>(res.far_points),
                        left_out.begin(), left_out.end());
  }
  if (!measured.empty()) {
    // The features' vertices back where they were measured (the front meshed their projections).
    std::vector<std::pair<std::uint32_t, Vec3>> targets;
    for (const auto& [v, p] : measured)
      if (remap[v] != 0xffffffffu) targets.emplace_back(remap[v], p);
    std::sort(targets.begin(), targets.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    res.features = measured.size();
    res.restored = detail::restore_positions(res.mesh, targets);
  }
  if (options.peel_apex_deg > 0)
    res.peeled_chords = detail::peel_border_chords(res.mesh, options.peel_apex_deg);
  // Before the fill, whose patches then continue the recovered faces and stay the last
  // triangles (sharpening moves the triangles it changes to the end).
  // The noise first: the faces the edge recovery extends are then flat.
  if (options.denoise) {
    stage("denoise");
    res.denoise = denoise_mesh(res.mesh, options.denoise_options);
  }
  if (options.sharpen) {
    stage("sharpen");
    res.sharpen = sharpen_edges(res.mesh, options.sharpen_options);
  }
  if (options.fill.max_edges > 0) {
    stage("fill");
    res.fill = fill_holes(res.mesh, options.fill);
  }
  stage("done");
  return res;
}

}  // namespace scanmesh::recon
