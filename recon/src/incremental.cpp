// IncrementalReconstructor: incremental cube reduction in a sparse block grid, settling per
// block, meshing of settled regions, deltas with stable ids, copy-on-write snapshots.
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/incremental.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <unordered_map>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/normals.hpp"
#include "incremental_grid.hpp"
#include "incremental_job.hpp"
#include "incremental_store.hpp"

namespace scanmesh::recon {

using detail::kNoId;

std::vector<std::string> IncrementalOptions::validate() const {
  std::vector<std::string> errors = reconstruct.validate();
  if (reconstruct.fill.max_edges > 0)
    errors.push_back("the incremental path does not fill holes on request (fill.max_edges must be 0)");
  if (reconstruct.cube_mode == ReconstructOptions::CubeMode::kNone)
    errors.push_back("the incremental path needs cubes (cube mode none is for the batch path only)");
  if (reconstruct.denoise) errors.push_back("the incremental path does not denoise (denoise must be off)");
  if (reconstruct.sharpen) errors.push_back("the incremental path does not sharpen (sharpen must be off)");
  if (spacing_points < 100 || spacing_points > 10000000)
    errors.push_back("spacing_points must be in [100, 10000000], got " + std::to_string(spacing_points));
  if (block_cubes < 8 || block_cubes > 64)
    errors.push_back("block_cubes must be in [8, 64], got " + std::to_string(block_cubes));
  if (settle_interval_points < 1 || settle_interval_points > 1000000)
    errors.push_back("settle_interval_points must be in [1, 1000000], got " +
                     std::to_string(settle_interval_points));
  if (settle_delay_points > 1000000000)
    errors.push_back("settle_delay_points must be in [0, 1e9], got " + std::to_string(settle_delay_points));
  if (!(settle_margin_cubes >= 0 && settle_margin_cubes <= 1000))
    errors.push_back("settle_margin_cubes must be in [0, 1000]");
  if (max_blocks_per_step < 1 || max_blocks_per_step > 1000000)
    errors.push_back("max_blocks_per_step must be in [1, 1000000], got " +
                     std::to_string(max_blocks_per_step));
  return errors;
}

Mesh MeshSnapshot::to_mesh(std::vector<std::uint32_t>* vertex_ids) const {
  Mesh out;
  std::vector<std::uint32_t> remap(vertex_count_, kNoId);
  for (std::uint32_t t = 0; t < triangle_slots_; ++t) {
    const Triangle& tri = triangle(t);
    if (tri[0] == kRemoved) continue;
    for (std::uint32_t v : tri) remap[v] = 0;
  }
  std::uint32_t used = 0;
  if (vertex_ids != nullptr) vertex_ids->clear();
  for (std::uint32_t v = 0; v < vertex_count_; ++v) {
    if (remap[v] == kNoId) continue;
    remap[v] = used++;
    out.vertices.push_back(vertex(v));
    if (vertex_ids != nullptr) vertex_ids->push_back(v);
  }
  out.triangles.reserve(triangle_count_);
  for (std::uint32_t t = 0; t < triangle_slots_; ++t) {
    const Triangle& tri = triangle(t);
    if (tri[0] == kRemoved) continue;
    out.triangles.push_back({remap[tri[0]], remap[tri[1]], remap[tri[2]]});
  }
  return out;
}

// ------------------------------------------------------------------------------------------
struct IncrementalReconstructor::State {
  IncrementalOptions opt;
  SecondsClock clock;
  detail::StageTimes times;
  bool finished = false;

  // The first points, until the cube size is known.
  std::vector<Vec3> buffer, buffer_dir;  // buffer_dir: towards the sensor (empty: none given)
  bool any_sensor = false;
  std::size_t seq = 0;  // points taken so far (the sequence position)

  detail::CubeGrid grid;
  detail::PublishedMesh mesh;
  detail::JobMesher jobs{opt.reconstruct, grid, mesh};
  std::vector<Vec3> far;  // points beyond the grid's reach

  std::size_t meshing_steps = 0, meshed_blocks_total = 0, reopened = 0, deltas = 0;
  std::vector<double> settle_latency;  // seconds, per block meshed (clock given)

  double now() const { return clock ? clock() : 0.0; }

  // --- points ------------------------------------------------------------------------------
  void take(const Vec3& p, const Vec3* towards, const std::optional<Footprint>& footprint) {
    ++seq;
    if (!grid.ready()) {
      buffer.push_back(p);
      if (towards != nullptr) {
        buffer_dir.resize(buffer.size() - 1, Vec3::Zero());
        buffer_dir.push_back(*towards);
      }
      if (buffer.size() >= opt.spacing_points) start_grid();
      return;
    }
    insert(p, towards, seq - 1);
    if (seq % opt.settle_interval_points == 0) step(footprint);
  }

  void insert(const Vec3& p, const Vec3* towards, std::size_t index) {
    const detail::InsertOutcome out = grid.insert(p, towards, index);
    if (out == detail::InsertOutcome::kFar) far.push_back(p);
    if (out == detail::InsertOutcome::kReopened) ++reopened;
  }

  /// Decides the cube size from the buffered points and moves them into the grid.
  void start_grid() {
    double cube = 0;
    const ReconstructOptions& ro = opt.reconstruct;
    if (ro.cube_mode == ReconstructOptions::CubeMode::kFixed) {
      cube = ro.cube_mm;
    } else {
      const SpacingEstimate s = estimate_spacing(buffer);
      cube = ro.cube_mode == ReconstructOptions::CubeMode::kNone
                 ? std::max(s.nearest_mm * 1e-3, 1e-12)
                 : auto_cube_size(s);
      if (!(cube > 0) || !std::isfinite(cube)) cube = std::max(s.nearest_mm, 1e-9);
      if (!(cube > 0) || !std::isfinite(cube)) {
        // All buffered points coincide: any positive size (a later batch may still spread).
        cube = 1e-9;
      }
    }
    grid.start(buffer.front(), cube, opt.block_cubes);
    std::vector<Vec3> pts, dirs;
    pts.swap(buffer);
    dirs.swap(buffer_dir);
    if (!dirs.empty()) dirs.resize(pts.size(), Vec3::Zero());
    for (std::size_t i = 0; i < pts.size(); ++i) insert(pts[i], dirs.empty() ? nullptr : &dirs[i], i);
  }

  // --- settling and meshing ----------------------------------------------------------------
  /// A decision point: blocks settle, the ready ones are meshed.
  void step(const std::optional<Footprint>& footprint) {
    const double t0 = now();
    const std::vector<std::uint32_t> ready =
        grid.settle(seq, footprint, opt.settle_delay_points, opt.settle_margin_cubes, t0);
    times.add("settle", now() - t0);
    if (ready.empty()) return;
    const std::size_t take_n = std::min(ready.size(), opt.max_blocks_per_step);
    mesh_blocks(std::span<const std::uint32_t>(ready.data(), take_n), false);
  }

  /// Meshes `blocks` (ready, ascending) as one job, then marks them meshed. final: at finish()
  /// (then the caller runs the closing passes).
  void mesh_blocks(std::span<const std::uint32_t> blocks, bool final) {
    const double t0 = now();
    ++meshing_steps;
    meshed_blocks_total += blocks.size();
    jobs.run(blocks);
    for (std::uint32_t b : blocks) grid.mark_meshed(b);
    times.add(final ? "finish" : "mesh", now() - t0);
    if (clock && !final) {
      const double t1 = now();
      for (std::uint32_t b : blocks) settle_latency.push_back(std::max(0.0, t1 - grid.settled_at(b)));
    }
  }

  void settle_blocks(const Eigen::AlignedBox3d* box) {
    if (!grid.ready()) return;
    const double t = now();
    grid.force_settle(box, t);
  }

  /// Meshes every block ready now (explicit settling), in steps of max_blocks_per_step.
  void mesh_ready() {
    for (;;) {
      const double t0 = now();
      const std::vector<std::uint32_t> ready =
          grid.settle(seq, std::nullopt, opt.settle_delay_points, opt.settle_margin_cubes, t0);
      if (ready.empty()) return;
      mesh_blocks(ready, false);
    }
  }
};

// ------------------------------------------------------------------------------------------
IncrementalReconstructor::IncrementalReconstructor(const IncrementalOptions& options,
                                                   SecondsClock clock)
    : s_(std::make_unique<State>()) {
  if (const auto errors = options.validate(); !errors.empty()) {
    std::string msg = "invalid incremental reconstruction options:";
    for (const auto& e : errors) msg += " " + e + ";";
    throw ConfigError(msg);
  }
  s_->opt = options;
  s_->clock = std::move(clock);
}

IncrementalReconstructor::~IncrementalReconstructor() = default;
IncrementalReconstructor::IncrementalReconstructor(IncrementalReconstructor&&) noexcept = default;
IncrementalReconstructor& IncrementalReconstructor::operator=(IncrementalReconstructor&&) noexcept =
    default;

void IncrementalReconstructor::add(std::span<const Vec3> points,
                                   const std::optional<Footprint>& footprint) {
  add(points, {}, SensorData::kDirection, footprint);
}

void IncrementalReconstructor::add(std::span<const Vec3> points, std::span<const Vec3> sensor,
                                   SensorData kind, const std::optional<Footprint>& footprint) {
  State& s = *s_;
  if (s.finished) throw ConfigError("incremental reconstruction: add() after finish()");
  if (!sensor.empty() && sensor.size() != points.size())
    throw ConfigError("incremental reconstruction: " + std::to_string(sensor.size()) +
                      " sensor vectors for " + std::to_string(points.size()) +
                      " points (one per point, or none)");
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!points[i].allFinite() || (!sensor.empty() && !sensor[i].allFinite()))
      throw GeometryError("incremental reconstruction: point #" + std::to_string(i) +
                          " of the batch has a non-finite coordinate" +
                          (points[i].allFinite() ? " in its sensor vector" : "") +
                          "; the batch was not taken");
  if (footprint && !(footprint->centre.allFinite() && std::isfinite(footprint->radius_mm) &&
                     footprint->radius_mm >= 0))
    throw GeometryError("incremental reconstruction: the footprint must be finite with a radius >= 0");
  if (!sensor.empty()) s.any_sensor = true;
  const double t0 = s.now();
  const double mesh_before = s.times.get("mesh") + s.times.get("settle");
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (sensor.empty()) {
      s.take(points[i], nullptr, footprint);
    } else {
      const Vec3 towards = kind == SensorData::kPosition ? Vec3(sensor[i] - points[i]) : sensor[i];
      s.take(points[i], &towards, footprint);
    }
  }
  // The reduction's share: the whole call less what settling and meshing took inside it.
  const double spent = s.now() - t0 - (s.times.get("mesh") + s.times.get("settle") - mesh_before);
  s.times.add("reduce", std::max(0.0, spent));
}

void IncrementalReconstructor::settle_all() {
  s_->settle_blocks(nullptr);
  s_->mesh_ready();
}

void IncrementalReconstructor::settle(const Eigen::AlignedBox3d& box) {
  s_->settle_blocks(&box);
  s_->mesh_ready();
}

MeshDelta IncrementalReconstructor::take_delta() {
  const double t0 = s_->now();
  MeshDelta d = s_->mesh.take_delta(
      [&](std::span<const std::uint32_t> touched) { return s_->jobs.loops_through(touched); });
  if (!d.empty()) ++s_->deltas;
  s_->times.add("delta", s_->now() - t0);
  return d;
}

MeshSnapshot IncrementalReconstructor::snapshot() const { return s_->mesh.snapshot(); }

IncrementalResult IncrementalReconstructor::finish() {
  State& s = *s_;
  if (s.finished) throw ConfigError("incremental reconstruction: finish() called twice");
  const double t0 = s.now();
  if (!s.grid.ready()) {
    if (s.buffer.empty()) throw GeometryError("no points: the input is empty");
    s.start_grid();
  }
  s.finished = true;
  s.grid.force_settle(nullptr, t0);
  if (const std::vector<std::uint32_t> rest = s.grid.unmeshed_blocks(); !rest.empty())
    s.mesh_blocks(rest, true);
  s.jobs.close();
  s.times.add("finish", s.now() - t0);
  s.finished = true;
  IncrementalResult res;
  const MeshSnapshot snap = s.mesh.snapshot();
  res.mesh = snap.to_mesh(&res.vertex_ids);
  if (res.mesh.triangles.empty())
    throw GeometryError("the " + std::to_string(s.grid.cube_count()) +
                        " kept point(s) make no surface (too few, collinear or scattered)");
  // Outliers: kept points (thinned, vertices first) that are no vertex of the final mesh.
  std::vector<std::uint32_t> all(s.grid.block_count());
  for (std::uint32_t b = 0; b < all.size(); ++b) all[b] = b;
  for (std::uint32_t c : s.grid.thinned_cubes_of(all)) {
    const std::uint32_t id = s.grid.vertex_of(c);
    if (id != kNoId && s.jobs.used(id)) continue;
    res.outliers.push_back(id != kNoId ? s.mesh.vertex(id)
                                       : (s.opt.reconstruct.project ? s.grid.projected(c) : s.grid.rep(c)));
  }
  res.outliers.insert(res.outliers.end(), s.far.begin(), s.far.end());
  res.far_points = s.far.size();
  res.stats = stats();
  return res;
}

IncrementalStats IncrementalReconstructor::stats() const {
  const State& s = *s_;
  IncrementalStats st;
  st.points_in = s.seq;
  st.pending_points = s.buffer.size();
  st.far_points = s.far.size();
  st.cube_mm = s.grid.ready() ? s.grid.cube() : 0.0;
  st.cubes_kept = s.grid.cube_count();
  const detail::BlockCounts bc = s.grid.block_counts();
  st.blocks_open = bc.open;
  st.blocks_settled = bc.settled;
  st.blocks_meshed = bc.meshed;
  st.unmeshed_cubes = bc.unmeshed_cubes;
  st.vertices = s.mesh.vertex_count();
  st.triangles = s.mesh.triangle_count();
  st.meshing_steps = s.meshing_steps;
  st.meshed_blocks_total = s.meshed_blocks_total;
  st.reopened_blocks = s.reopened;
  st.deltas = s.deltas;
  st.seconds = s.times.all();
  if (!s.settle_latency.empty()) {
    std::vector<double> l = s.settle_latency;
    std::sort(l.begin(), l.end());
    st.settle_to_mesh_max_seconds = l.back();
    st.settle_to_mesh_p99_seconds = l[std::min(l.size() - 1, (l.size() * 99) / 100)];
  }
  return st;
}

}  // namespace scanmesh::recon
