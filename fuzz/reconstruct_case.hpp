// One reconstruction case made from bytes, shared by the fuzz target (fuzz_reconstruct.cpp) and
// the test that replays its seeds and every input it once failed on (tests/recon/
// test_fuzz_cases.cpp).
//
// The first byte picks the shape and the options, the second is a shape parameter, the rest
// shapes the points:
//   shape 0: free points, three int16 each (any cloud: blobs, duplicates, planes, lines);
//   shape 1: a height field over a grid 4-64 points wide, one byte a height (folds, spikes,
//            cliffs), each point moved within the plane by up to a third of the spacing;
//   shape 2: a sphere whose radius each byte perturbs (a closed surface, bumpy);
//   shape 3: a height field and its copy 1/8-8/8 spacing below (a thin wall seen from both
//            sides).
// Option bits: 4 --cube none instead of auto, 8 the bulk off, 16 holes of up to 16 edges filled,
// 32 the sensor directions (+z) given, 64 sharp edges recovered (--sharpen).
// Bit 128: the incremental path instead (recon/incremental.hpp; bits 4, 16 and 64 ignored): the
// points fed in batches cut where the bytes say, some fed a second time shifted by a fraction
// of their spacing after the first pass settled (re-opening meshed blocks); every snapshot
// must be a valid mesh and the deltas must rebuild the final mesh exactly.
//
// Only scanmesh::Error (GeometryError for clouds that cannot make a surface) is an expected
// outcome. Otherwise the output must keep the core's promises (reconstruct.hpp, recon/README
// "At a glance"): no non-manifold edge or vertex, one orientation, no degenerate or duplicate
// triangle, no two triangles crossing, only used vertices, and every reduced point either a
// vertex or an outlier.
// SPDX-License-Identifier: MIT
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/incremental.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reconstruct.hpp"
#include "support/shapes.hpp"

namespace scanmesh::fuzz {

/// Keeps a run with the debug checks on under a second.
inline constexpr std::size_t kMaxCasePoints = 3000;

namespace detail {

inline std::int16_t int16_at(const std::uint8_t* p) {
  std::uint16_t u = 0;
  std::memcpy(&u, p, 2);
  return static_cast<std::int16_t>(u);
}

/// Points of a grid w wide at unit spacing, one a byte: the byte sets the height (+-4 spacings)
/// and, by its low four bits, an offset within the plane of up to a third of the spacing.
inline void height_field(const std::uint8_t* d, std::size_t n, std::size_t w, double z0,
                         std::vector<recon::Vec3>& out) {
  for (std::size_t i = 0; i < n; ++i) {
    const double h = (static_cast<double>(d[i]) - 128.0) / 32.0;
    const double jx = static_cast<double>(d[i] & 3u) / 9.0;
    const double jy = static_cast<double>((d[i] >> 2) & 3u) / 9.0;
    out.emplace_back(static_cast<double>(i % w) + jx, static_cast<double>(i / w) + jy, z0 + h);
  }
}

}  // namespace detail

/// The case's points.
inline std::vector<recon::Vec3> case_points(const std::uint8_t* data, std::size_t size) {
  std::vector<recon::Vec3> points;
  if (size < 2) return points;
  const std::uint8_t param = data[1];
  const std::uint8_t* d = data + 2;
  const std::size_t n = size - 2;
  switch (data[0] & 3u) {
    case 0:
      for (std::size_t i = 0; i + 6 <= n && points.size() < kMaxCasePoints; i += 6)
        points.emplace_back(detail::int16_at(d + i) / 256.0, detail::int16_at(d + i + 2) / 256.0,
                            detail::int16_at(d + i + 4) / 256.0);
      break;
    case 1:
      detail::height_field(d, std::min(n, kMaxCasePoints), 4 + param % 61, 0.0, points);
      break;
    case 2:  // Fibonacci sphere of radius 10 (+-1.25), one point a byte
      points = test::sphere_points(std::min(n, kMaxCasePoints));
      for (std::size_t i = 0; i < points.size(); ++i)
        points[i] *= 1.0 + (static_cast<double>(d[i]) - 128.0) / 1024.0;
      break;
    default: {
      const std::size_t m = std::min(n, kMaxCasePoints / 2);
      const std::size_t w = 4 + param % 29;
      detail::height_field(d, m, w, 0.0, points);
      detail::height_field(d, m, w, -static_cast<double>(1 + (param >> 5)) / 8.0, points);
      break;
    }
  }
  return points;
}

/// The case's options and, when asked for, sensor directions.
inline recon::ReconstructOptions case_options(std::uint8_t flags) {
  recon::ReconstructOptions opt;
  if ((flags & 4u) != 0) opt.cube_mode = recon::ReconstructOptions::CubeMode::kNone;
  if ((flags & 8u) != 0) opt.front.bulk = false;
  if ((flags & 16u) != 0) opt.fill.max_edges = 16;
  if ((flags & 64u) != 0) opt.sharpen = true;
  return opt;
}

namespace detail {

/// The promises of a final mesh (shared by both paths): empty when they hold.
inline std::string broken_promise(const recon::Mesh& mesh, std::size_t* triangles) {
  const recon::MeshReport rep = recon::analyze(mesh);
  if (triangles != nullptr) *triangles = rep.triangles;
  if (rep.non_manifold_edges != 0) return "non-manifold edges";
  if (rep.non_manifold_vertices != 0) return "non-manifold vertices";
  if (!rep.orientation_consistent) return "inconsistent orientation";
  if (rep.degenerate_triangles != 0) return "degenerate triangles";
  if (rep.duplicate_triangles != 0) return "duplicate triangles";
  if (rep.referenced_vertices != rep.vertices) return "unused vertices in the output";
  if (recon::find_self_intersections(mesh, 0).pairs != 0) return "crossing triangles";
  return {};
}

/// The incremental case (option bit 128).
inline std::string run_incremental_case(const std::uint8_t* data, std::size_t size,
                                        const std::vector<recon::Vec3>& points,
                                        std::size_t* triangles) {
  recon::IncrementalOptions opt;
  opt.reconstruct = case_options(data[0]);
  opt.reconstruct.cube_mode = recon::ReconstructOptions::CubeMode::kAuto;
  opt.reconstruct.fill.max_edges = 0;
  opt.reconstruct.sharpen = false;
  opt.spacing_points = 200;
  opt.settle_interval_points = 64;
  opt.settle_delay_points = 128;
  const bool sensors = (data[0] & 32u) != 0;
  recon::IncrementalReconstructor rec(opt);
  // Replay of the deltas, by id.
  std::vector<recon::Vec3> vertices;
  std::vector<std::pair<std::uint32_t, recon::Triangle>> live;  // sorted by id
  auto apply = [&](const recon::MeshDelta& d) -> std::string {
    if (d.first_vertex != vertices.size()) return "delta vertex ids not consecutive";
    vertices.insert(vertices.end(), d.vertices.begin(), d.vertices.end());
    for (std::size_t i = 0; i < d.added.size(); ++i) {
      if (!live.empty() && d.added_ids[i] <= live.back().first) return "delta triangle ids reused";
      live.emplace_back(d.added_ids[i], d.added[i]);
    }
    for (const std::uint32_t id : d.removed) {
      const auto it = std::lower_bound(live.begin(), live.end(), std::make_pair(id, recon::Triangle{}),
                                       [](const auto& a, const auto& b) { return a.first < b.first; });
      if (it == live.end() || it->first != id) return "delta removes an unknown triangle";
      live.erase(it);
    }
    return {};
  };
  auto check_snapshot = [&]() -> std::string {
    const recon::MeshSnapshot snap = rec.snapshot();
    if (snap.triangle_count() != live.size()) return "snapshot and deltas differ";
    if (snap.triangle_count() == 0) return {};
    const recon::MeshReport r = recon::analyze(snap.to_mesh());
    if (r.non_manifold_edges != 0 || r.non_manifold_vertices != 0) return "non-manifold snapshot";
    if (!r.orientation_consistent) return "inconsistent snapshot";
    return {};
  };
  // Batch cuts: the bytes after the points, cycled (1-64 points a batch).
  const std::uint8_t* cuts = data + 2;
  const std::size_t ncuts = size - 2;
  std::size_t next_cut = 0;
  auto feed = [&](const std::vector<recon::Vec3>& pts) -> std::string {
    for (std::size_t i = 0; i < pts.size();) {
      const std::size_t n = std::min<std::size_t>(1 + cuts[next_cut++ % ncuts] % 64, pts.size() - i);
      const std::span<const recon::Vec3> batch(pts.data() + i, n);
      if (sensors) {
        const std::vector<recon::Vec3> up(n, recon::Vec3::UnitZ());
        rec.add(batch, up, recon::SensorData::kDirection);
      } else {
        rec.add(batch);
      }
      i += n;
      if (auto e = apply(rec.take_delta()); !e.empty()) return e;
      if (auto e = check_snapshot(); !e.empty()) return e;
    }
    return {};
  };
  try {
    if (auto e = feed(points); !e.empty()) return e;
    // A second pass over part of the cloud, shifted by a fraction of a unit: re-opening.
    if ((data[1] & 1u) != 0 && points.size() > 8) {
      rec.settle_all();
      if (auto e = apply(rec.take_delta()); !e.empty()) return e;
      std::vector<recon::Vec3> again(points.begin(), points.begin() + static_cast<std::ptrdiff_t>(points.size() / 2));
      for (recon::Vec3& p : again) p += recon::Vec3(0.31, 0.17, 0.0) * (1.0 + (data[1] >> 4) / 16.0);
      if (auto e = feed(again); !e.empty()) return e;
    }
    const recon::IncrementalResult r = rec.finish();
    if (auto e = apply(rec.take_delta()); !e.empty()) return e;
    if (auto e = broken_promise(r.mesh, triangles); !e.empty()) return e;
    if (live.size() != r.mesh.triangles.size()) return "deltas do not rebuild the final mesh";
    for (std::size_t i = 0; i < live.size(); ++i)
      for (int k = 0; k < 3; ++k)
        if (vertices[live[i].second[k]] != r.mesh.vertices[r.mesh.triangles[i][k]])
          return "deltas do not rebuild the final mesh";
  } catch (const Error&) {
    // a cloud that cannot make a surface
  }
  return {};
}

}  // namespace detail

/// Runs the case: empty when the promises hold (or the cloud was rejected with an Error),
/// otherwise the first promise broken. `triangles`, when given, receives the output's
/// triangle count (0 when rejected).
inline std::string run_reconstruct_case(const std::uint8_t* data, std::size_t size,
                                        std::size_t* triangles = nullptr) {
  if (triangles != nullptr) *triangles = 0;
  if (size < 2) return {};
  const std::vector<recon::Vec3> points = case_points(data, size);
  if ((data[0] & 128u) != 0) return detail::run_incremental_case(data, size, points, triangles);
  std::vector<recon::Vec3> towards;
  if ((data[0] & 32u) != 0) towards.assign(points.size(), recon::Vec3::UnitZ());
  try {
    const recon::ReconstructResult r = recon::reconstruct(points, case_options(data[0]), {}, towards);
    const recon::MeshReport rep = recon::analyze(r.mesh);
    if (triangles != nullptr) *triangles = rep.triangles;
    if (rep.non_manifold_edges != 0) return "non-manifold edges";
    if (rep.non_manifold_vertices != 0) return "non-manifold vertices";
    if (!rep.orientation_consistent) return "inconsistent orientation";
    if (rep.degenerate_triangles != 0) return "degenerate triangles";
    if (rep.duplicate_triangles != 0) return "duplicate triangles";
    if (rep.referenced_vertices != rep.vertices) return "unused vertices in the output";
    if (r.reduced_points > points.size()) return "more reduced points than input points";
    if (r.far_points > r.outliers.size()) return "more far points than outliers";
    // Holes filled and edges sharpened on request add vertices; every other vertex is a
    // reduced point.
    if (r.mesh.vertices.size() - r.fill.vertices - r.sharpen.edge_vertices -
            r.sharpen.corner_vertices + r.outliers.size() - r.far_points !=
        r.reduced_points)
      return "reduced points neither vertices nor outliers";
    if (recon::find_self_intersections(r.mesh, 0).pairs != 0) return "crossing triangles";
  } catch (const Error&) {
    // a cloud that cannot make a surface: the expected way to reject it
  }
  return {};
}

}  // namespace scanmesh::fuzz
