// The reconstruction job (reconstruction.hpp): reading and merging the inputs, the batch and
// the streamed paths.
// SPDX-License-Identifier: MIT
#include "scanmesh/reconstruction/reconstruction.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <span>

#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"

namespace scanmesh::reconstruction {

namespace {

using Clock = std::chrono::steady_clock;

double secs(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

void tell(const std::function<void(const std::string&)>& f, const std::string& what) {
  if (f) f(what);
}

/// meshio::read_points_and_faces, and for a .ply its extras: each header line skipped is a
/// warning (naming it), and a range scan's rows go to `rows` when given.
recon::Mesh read_with_extras(const std::filesystem::path& in,
                             std::vector<std::vector<std::uint32_t>>* rows,
                             const Observer& observer) {
  std::string ext = in.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".ply") {
    meshio::PlyExtras extras;
    try {
      recon::Mesh mesh = meshio::read_ply(in, extras);
      for (const auto& w : extras.warnings) tell(observer.warning, w);
      if (rows != nullptr) *rows = std::move(extras.range_rows);
      return mesh;
    } catch (const InputError&) {
      // Faces (or a range grid) that do not parse do not spoil the points: as below.
    }
  }
  return meshio::read_points_and_faces(in);
}

/// One INPUT's points. A mesh file's vertices are its points; when they do not sample its
/// surface as a scan does (a CAD export: few vertices, long edges across flat faces, slivers),
/// `notes` gets a note saying so and how to sample the surface instead: the flat faces have no
/// points, and the front leaves loops and wrong handles there (the casting's mesh: genus 8 and
/// 5 loops, against exactly 9 and none from a sample of its surface).
recon::PointCloud read_input(const std::string& in, std::vector<std::string>& notes,
                             std::vector<std::vector<std::uint32_t>>* rows,
                             const Observer& observer) {
  recon::Mesh mesh = read_with_extras(in, rows, observer);
  if (!mesh.triangles.empty()) {  // not a range scan or a bare vertex list
    const recon::MeshReport r = recon::analyze(mesh);
    if (!recon::scan_like_vertices(r)) {
      char figures[160];
      std::snprintf(figures, sizeof figures,
                    " (%zu vertices, %.0f %% of the triangles under 20 degrees, longest edge "
                    "%.1f mean edges)",
                    r.referenced_vertices, 100.0 * r.frac_min_angle_below_20,
                    r.mean_edge_length > 0 ? r.max_edge_length / r.mean_edge_length : 0.0);
      notes.push_back(in +
                      ": its vertices are too few or too uneven to sample the surface as a "
                      "scan does" +
                      figures +
                      "; they are used as the points, but for a faithful mesh sample its "
                      "surface: scanmesh generate --mesh-in " +
                      in + " --points 100000 -o points.xyz");
    }
  }
  return recon::PointCloud{std::move(mesh.vertices)};
}

[[noreturn]] void no_points(const Request& request) {
  std::string names;
  for (const auto& in : request.inputs) names += (names.empty() ? "" : ", ") + in;
  throw InputError(names + ": no points in the input");
}

}  // namespace

std::vector<Scan> load_scans(const Request& request, std::vector<std::string>& notes,
                             const Observer& observer) {
  std::vector<Scan> scans;
  if (!request.conf.empty()) {
    const auto entries = meshio::read_conf(request.conf);
    std::map<std::string, const meshio::ConfEntry*> by_name;
    for (const auto& e : entries) by_name[e.file.filename().string()] = &e;
    std::vector<std::pair<std::filesystem::path, const meshio::ConfEntry*>> jobs;
    if (request.inputs.empty()) {
      for (const auto& e : entries) jobs.emplace_back(e.file, &e);
    } else {
      for (const auto& in : request.inputs) {
        const std::filesystem::path p(in);
        auto it = by_name.find(p.filename().string());
        if (it == by_name.end())
          throw ConfigError("input '" + in + "' is not listed in the registration file '" +
                            request.conf + "'");
        jobs.emplace_back(p, it->second);
      }
    }
    for (const auto& [path, entry] : jobs) {
      Scan scan;
      recon::PointCloud c;
      try {
        c.points = read_with_extras(path, &scan.rows, observer).vertices;
      } catch (const InputError& e) {
        if (!request.inputs.empty()) throw;
        // The path came from the registration file, resolved against its folder: say so.
        throw InputError(std::string(e.what()) + " (a scan listed in " + request.conf + ")");
      }
      // A range scan looks at the part along -z of its own frame (the Stanford scans: 99 % of
      // bun000's surface faces +z): each point's direction towards its sensor is the scan's +z
      // axis in world coordinates.
      const recon::Vec3 sensor =
          entry->to_world(recon::Vec3::UnitZ()) - entry->to_world(recon::Vec3::Zero());
      for (const auto& p : c.points) {
        scan.points.push_back(entry->to_world(p));
        scan.towards.push_back(sensor);
      }
      scans.push_back(std::move(scan));
    }
  } else {
    for (const auto& in : request.inputs) {
      Scan scan;
      scan.points = read_input(in, notes, &scan.rows, observer).points;
      scans.push_back(std::move(scan));
    }
  }
  if (request.sensor) {
    const recon::Vec3 at = *request.sensor;
    for (Scan& sc : scans) {
      sc.towards.resize(sc.points.size());
      for (std::size_t i = 0; i < sc.points.size(); ++i) sc.towards[i] = at - sc.points[i];
    }
  }
  return scans;
}

BatchOutcome run_batch(const Request& request, const Observer& observer) {
  const auto t0 = Clock::now();
  BatchOutcome out;
  std::vector<recon::Vec3> points, towards_sensor;
  for (Scan& s : load_scans(request, out.notes, observer)) {
    points.insert(points.end(), s.points.begin(), s.points.end());
    towards_sensor.insert(towards_sensor.end(), s.towards.begin(), s.towards.end());
  }
  for (const auto& note : out.notes) tell(observer.note, note);
  if (points.empty()) no_points(request);
  out.points = points.size();
  auto last = Clock::now();
  if (observer.stage) observer.stage("read " + std::to_string(points.size()) + " points");
  out.seconds["read"] = secs(t0, last);
  // Steps within a stage ("front/growth") are timed on their own and count into their stage.
  std::string current, current_step;
  auto step_start = last;
  auto on_stage = [&](std::string_view stage) {
    const auto now = Clock::now();
    if (!current_step.empty()) out.step_seconds[current_step] += secs(step_start, now);
    current_step.clear();
    step_start = now;
    if (stage.find('/') != std::string_view::npos) {  // steps are timed, not announced
      current_step = stage;
      return;
    }
    if (!current.empty()) out.seconds[current] += secs(last, now);
    last = now;
    current = stage == "done" ? "" : std::string(stage);
    if (stage != "done" && observer.stage) observer.stage(stage);
  };
  out.result = recon::reconstruct(points, request.options, on_stage, towards_sensor);
  if (out.result.untangle.skipped > 0) {
    out.notes.push_back(
        std::to_string(out.result.untangle.skipped) +
        " more gaps whose patch would cross the mesh stay open: untangling stops after " +
        std::to_string(recon::kMaxUntangledGaps) +
        " (so many usually means noise thicker than the spacing, or points that are not a "
        "surface)");
    tell(observer.note, out.notes.back());
  }
  return out;
}

StreamOutcome run_stream(const Request& request, const Observer& observer) {
  const auto t0 = Clock::now();
  StreamOutcome out;
  out.stream = request.stream;
  const recon::ReconstructOptions& opt = request.options;
  recon::IncrementalOptions io;
  io.reconstruct = opt;
  // The on-request passes run on the finished mesh (below), as the batch path runs them last.
  io.reconstruct.fill.max_edges = 0;
  io.reconstruct.denoise = false;
  io.reconstruct.sharpen = false;
  const std::vector<Scan> scans = load_scans(request, out.notes, observer);
  for (const auto& note : out.notes) tell(observer.note, note);
  std::size_t total = 0;
  for (const Scan& sc : scans) total += sc.points.size();
  if (total == 0) no_points(request);
  out.read_seconds = secs(t0, Clock::now());
  const auto clock_start = Clock::now();
  recon::IncrementalReconstructor rec(io,
                                      [clock_start] { return secs(clock_start, Clock::now()); });
  std::size_t fed = 0;
  std::vector<recon::Vec3> pts, dirs;
  auto feed = [&](std::span<const recon::Vec3> p, std::span<const recon::Vec3> d) {
    const auto a = Clock::now();
    if (d.empty()) {
      rec.add(p);
    } else {
      rec.add(p, d, recon::SensorData::kDirection);
    }
    const auto b = Clock::now();
    out.max_batch_seconds = std::max(out.max_batch_seconds, secs(a, b));
    ++out.batches;
    fed += p.size();
    if (!rec.take_delta().empty()) ++out.deltas;
    out.take_delta_seconds += secs(b, Clock::now());
    if (observer.batch) observer.batch(fed, total, rec.stats());
  };
  for (const Scan& sc : scans) {
    const bool dir = !sc.towards.empty();
    if (!sc.rows.empty()) {
      for (const auto& row : sc.rows) {
        if (row.empty()) continue;
        pts.clear();
        dirs.clear();
        for (std::uint32_t v : row) {
          pts.push_back(sc.points[v]);
          if (dir) dirs.push_back(sc.towards[v]);
        }
        feed(pts, dirs);
      }
      continue;
    }
    for (std::size_t i = 0; i < sc.points.size(); i += request.stream) {
      const std::size_t n = std::min(request.stream, sc.points.size() - i);
      feed(std::span<const recon::Vec3>(sc.points.data() + i, n),
           dir ? std::span<const recon::Vec3>(sc.towards.data() + i, n)
               : std::span<const recon::Vec3>());
    }
  }
  const auto f0 = Clock::now();
  out.result = rec.finish();
  if (!rec.take_delta().empty()) ++out.deltas;
  out.finish_seconds = secs(f0, Clock::now());
  if (opt.denoise) out.denoise = recon::denoise_mesh(out.result.mesh, opt.denoise_options);
  if (opt.sharpen) out.sharpen = recon::sharpen_edges(out.result.mesh, opt.sharpen_options);
  if (opt.fill.max_edges > 0) out.fill = recon::fill_holes(out.result.mesh, opt.fill);
  return out;
}

}  // namespace scanmesh::reconstruction
