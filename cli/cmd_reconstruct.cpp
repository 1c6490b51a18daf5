// `scanmesh reconstruct`: read point files, reconstruct a manifold mesh, write it.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/preview/render.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/incremental.hpp"
#include "scanmesh/recon/reconstruct.hpp"

namespace scanmesh::cli {
namespace {

struct ReconstructArgs {
  std::vector<std::string> inputs;
  std::string output;
  std::string cube = "auto";
  double min_angle_deg = 20;
  std::string conf;
  std::vector<double> sensor;  ///< --sensor X,Y,Z: one sensor position for every input point
  bool json = false;
  bool ascii = false;
  std::string outliers_file;
  bool no_insert = false;
  bool zip_holes = false;
  bool no_bulk = false;
  bool progress = false;
  std::size_t fill_holes = 0;
  double fill_width = 0;
  bool fill_flat = false;
  bool denoise = false;
  recon::DenoiseOptions denoise_options;
  bool sharpen = false;
  recon::SharpenOptions sharpen_options;
  std::string preview;
  std::string up = "z";
  std::size_t stream = 0;  ///< --stream N: the incremental path, N points a batch (0: batch path)
};

/// One scan as read: its points in file order, each one's direction towards its sensor (when
/// known) and, for a range scan, its rows (vertex indices a row: fed row by row with --stream).
struct Scan {
  std::vector<recon::Vec3> points, towards;
  std::vector<std::vector<std::uint32_t>> rows;
};

/// Parses --cube: "auto", "none" or a positive size in input units.
void apply_cube(const std::string& text, recon::ReconstructOptions& o) {
  if (text == "auto") {
    o.cube_mode = recon::ReconstructOptions::CubeMode::kAuto;
  } else if (text == "none") {
    o.cube_mode = recon::ReconstructOptions::CubeMode::kNone;
  } else {
    std::size_t used = 0;
    double v = 0;
    try {
      v = std::stod(text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != text.size() || !(v > 0) || !std::isfinite(v))
      throw ConfigError("--cube must be 'auto', 'none' or a positive size, got '" + text + "'");
    o.cube_mode = recon::ReconstructOptions::CubeMode::kFixed;
    o.cube_mm = v;
  }
}

/// meshio::read_points_and_faces, and for a .ply its extras: each header line skipped is warned
/// about on stderr (naming it), and a range scan's rows go to `rows` when given.
recon::Mesh read_with_extras(const std::filesystem::path& in,
                             std::vector<std::vector<std::uint32_t>>* rows) {
  std::string ext = in.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".ply") {
    meshio::PlyExtras extras;
    try {
      recon::Mesh mesh = meshio::read_ply(in, extras);
      for (const auto& w : extras.warnings) std::fprintf(stderr, "scanmesh: warning: %s\n", w.c_str());
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
                             std::vector<std::vector<std::uint32_t>>* rows = nullptr) {
  recon::Mesh mesh = read_with_extras(in, rows);
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

/// Loads and merges every input (registered through the .conf when one is given). With a .conf,
/// `towards_sensor` gets, for each point, its scan's +z axis in world coordinates: a range scan
/// looks at the part along -z of its own frame (the Stanford scans: 99 % of bun000's surface
/// faces +z). `notes` gets read_input's notes on the inputs.
std::vector<Scan> load_scans(const ReconstructArgs& args, std::vector<std::string>& notes) {
  std::vector<Scan> scans;
  if (!args.conf.empty()) {
    const auto entries = meshio::read_conf(args.conf);
    std::map<std::string, const meshio::ConfEntry*> by_name;
    for (const auto& e : entries) by_name[e.file.filename().string()] = &e;
    std::vector<std::pair<std::filesystem::path, const meshio::ConfEntry*>> jobs;
    if (args.inputs.empty()) {
      for (const auto& e : entries) jobs.emplace_back(e.file, &e);
    } else {
      for (const auto& in : args.inputs) {
        const std::filesystem::path p(in);
        auto it = by_name.find(p.filename().string());
        if (it == by_name.end())
          throw ConfigError("input '" + in + "' is not listed in the registration file '" +
                            args.conf + "'");
        jobs.emplace_back(p, it->second);
      }
    }
    for (const auto& [path, entry] : jobs) {
      Scan scan;
      recon::PointCloud c;
      try {
        c.points = read_with_extras(path, &scan.rows).vertices;
      } catch (const InputError& e) {
        if (!args.inputs.empty()) throw;
        // The path came from the registration file, resolved against its folder: say so.
        throw InputError(std::string(e.what()) + " (a scan listed in " + args.conf + ")");
      }
      const recon::Vec3 sensor =
          entry->to_world(recon::Vec3::UnitZ()) - entry->to_world(recon::Vec3::Zero());
      for (const auto& p : c.points) {
        scan.points.push_back(entry->to_world(p));
        scan.towards.push_back(sensor);
      }
      scans.push_back(std::move(scan));
    }
  } else {
    for (const auto& in : args.inputs) {
      Scan scan;
      scan.points = read_input(in, notes, &scan.rows).points;
      scans.push_back(std::move(scan));
    }
  }
  return scans;
}

/// Every scan merged (the batch path's input).
std::vector<recon::Vec3> load_inputs(const ReconstructArgs& args,
                                     std::vector<recon::Vec3>& towards_sensor,
                                     std::vector<std::string>& notes) {
  std::vector<recon::Vec3> all;
  for (const Scan& s : load_scans(args, notes)) {
    all.insert(all.end(), s.points.begin(), s.points.end());
    towards_sensor.insert(towards_sensor.end(), s.towards.begin(), s.towards.end());
  }
  return all;
}

int run_stream(const ReconstructArgs& args, const recon::ReconstructOptions& opt);

int run_reconstruct(const ReconstructArgs& args) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  recon::ReconstructOptions opt;
  apply_cube(args.cube, opt);
  opt.front.min_angle_deg = args.min_angle_deg;
  opt.front.relaxed_min_angle_deg = std::min(opt.front.relaxed_min_angle_deg, args.min_angle_deg);
  opt.refine.enabled = !args.no_insert;
  opt.front.keep_holes = !args.zip_holes;
  opt.front.bulk = !args.no_bulk;
  opt.fill.max_edges = args.fill_holes;
  opt.fill.max_width = args.fill_width;
  // A width alone closes every loop under it, whatever its edge count (up to the limit).
  if (args.fill_width > 0 && args.fill_holes == 0) opt.fill.max_edges = recon::FillOptions::kLimit;
  opt.fill.refine = !args.fill_flat;
  opt.denoise = args.denoise;
  opt.denoise_options = args.denoise_options;
  opt.sharpen = args.sharpen;
  opt.sharpen_options = args.sharpen_options;
  if (args.inputs.empty() && args.conf.empty())
    throw ConfigError("no INPUT given (and no --conf to take the scans from)");
  if (const auto errors = opt.validate(); !errors.empty()) throw ConfigError(errors.front());

  if (!args.sensor.empty() && !args.conf.empty())
    throw ConfigError("--sensor and --conf both say where the sensor was: give one");
  if (args.stream > 0) return run_stream(args, opt);
  std::vector<recon::Vec3> towards_sensor;
  std::vector<std::string> notes;  // about the inputs and the result: on stderr, and in the JSON
  const std::vector<recon::Vec3> points = load_inputs(args, towards_sensor, notes);
  for (const auto& note : notes) std::fprintf(stderr, "scanmesh: note: %s\n", note.c_str());
  if (args.sensor.size() == 3) {
    const recon::Vec3 at(args.sensor[0], args.sensor[1], args.sensor[2]);
    towards_sensor.resize(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) towards_sensor[i] = at - points[i];
  }
  if (points.empty()) {
    std::string names;
    for (const auto& in : args.inputs) names += (names.empty() ? "" : ", ") + in;
    throw InputError(names + ": no points in the input");
  }
  auto last = Clock::now();
  // --progress: one line on stderr as each stage starts (stdout stays the summary or the JSON).
  auto report = [&](std::string_view what) {
    if (!args.progress) return;
    std::fprintf(stderr, "scanmesh: %8.3f s  %.*s\n",
                 std::chrono::duration<double>(Clock::now() - t0).count(),
                 static_cast<int>(what.size()), what.data());
    std::fflush(stderr);
  };
  report("read " + std::to_string(points.size()) + " points");
  std::map<std::string, double> seconds;
  seconds["read"] = std::chrono::duration<double>(last - t0).count();
  // Steps within a stage ("front/growth") are timed on their own and count into their stage.
  std::map<std::string, double> step_seconds;
  std::string current, current_step;
  auto step_start = last;
  auto observer = [&](std::string_view stage) {
    const auto now = Clock::now();
    if (!current_step.empty())
      step_seconds[current_step] += std::chrono::duration<double>(now - step_start).count();
    current_step.clear();
    step_start = now;
    if (stage.find('/') != std::string_view::npos) {  // --progress shows the stages only
      current_step = stage;
      return;
    }
    if (!current.empty()) seconds[current] += std::chrono::duration<double>(now - last).count();
    last = now;
    current = stage == "done" ? "" : std::string(stage);
    if (stage != "done") report(stage);
  };
  recon::ReconstructResult res = recon::reconstruct(points, opt, observer, towards_sensor);
  if (res.untangle.skipped > 0) {
    notes.push_back(std::to_string(res.untangle.skipped) +
                    " more gaps whose patch would cross the mesh stay open: untangling stops after " +
                    std::to_string(recon::kMaxUntangledGaps) +
                    " (so many usually means noise thicker than the spacing, or points that are "
                    "not a surface)");
    std::fprintf(stderr, "scanmesh: note: %s\n", notes.back().c_str());
  }

  auto t = Clock::now();
  report("write " + args.output);
  write_mesh_file(res.mesh, args.output, args.ascii);
  if (!args.outliers_file.empty()) meshio::write_points_xyz(res.outliers, args.outliers_file);
  seconds["write"] = std::chrono::duration<double>(Clock::now() - t).count();
  const recon::MeshReport rep = recon::analyze(res.mesh);
  if (!args.preview.empty()) {
    report("preview " + args.preview);
    t = Clock::now();
    preview::RenderOptions options;
    options.up = axis_of(args.up);
    options.title = std::filesystem::path(args.output).filename().string() + ": " +
                    std::to_string(res.mesh.triangles.size()) + " triangles, " +
                    std::to_string(rep.boundary_loops) + " boundary loops, genus " +
                    std::to_string(rep.genus);
    if (res.fill.triangles > 0) {
      options.highlight_from = res.mesh.triangles.size() - res.fill.triangles;
      options.title += ", " + std::to_string(res.fill.filled) + " holes filled (amber)";
    }
    preview::render_mesh_png(res.mesh, args.preview, options);
    seconds["preview"] = std::chrono::duration<double>(Clock::now() - t).count();
  }
  const double total = std::chrono::duration<double>(Clock::now() - t0).count();
  report("done");

  if (args.json) {
    nlohmann::json j;
    j["input_points"] = res.input_points;
    j["reduced_points"] = res.reduced_points;
    j["vertices"] = res.mesh.vertices.size();
    j["triangles"] = res.mesh.triangles.size();
    put_topology(j, rep);
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
    if (opt.denoise) put_denoise(j, res.denoise);
    if (opt.sharpen) put_sharpen(j, res.sharpen);
    j["edge_evaluations"] = res.edge_evaluations;
    j["points_scanned"] = res.points_scanned;
    j["skipped_evaluations"] = res.skipped_evaluations;
    j["turning_points"] = res.turning_points;
    j["bulk_patches"] = res.bulk_patches;
    j["bulk_triangles"] = res.bulk_triangles;
    j["dropped_components"] = res.dropped_components;
    j["dropped_specks"] = res.dropped_specks;
    // Representatives whose projection cut across a sharp edge, a corner or a step, and of
    // those the vertices the mesh has at the measured point.
    j["feature_points"] = res.features;
    j["feature_points_measured"] = res.restored;
    j["peeled_chords"] = res.peeled_chords;
    j["output"] = args.output;
    j["notes"] = notes;
    if (!args.preview.empty()) j["preview"] = args.preview;
    j["seconds_total"] = total;
    j["seconds"] = seconds;
    j["step_seconds"] = step_seconds;
    std::cout << j.dump() << "\n";
  } else {
    std::cout << std::fixed << std::setprecision(3);
    std::cout << "input points     " << res.input_points << "\n"
              << "cube             " << (res.cube_mm > 0 ? std::to_string(res.cube_mm) : "none")
              << "\n"
              << "reduced points   " << res.reduced_points << "\n"
              << "vertices         " << res.mesh.vertices.size() << "\n"
              << "triangles        " << res.mesh.triangles.size() << "\n"
              << "boundary loops   " << rep.boundary_loops << "\n"
              << "components       " << rep.components << "\n"
              << "genus            " << rep.genus << "\n"
              << "inserted points  " << res.refine.inserted << " (left out by the front)\n";
    if (res.zip.zipped > 0)
      std::cout << "zipped slits     " << res.zip.zipped << " (" << res.zip.split_points
                << " border points a long edge ran along, joined to it)\n";
    if (res.gaps.filled > 0)
      std::cout << "closed gaps      " << res.gaps.filled
                << " (small loops the front left, closed with their own vertices)\n";
    if (res.untangle.closed > 0)
      std::cout << "untangled gaps   " << res.untangle.closed << " (" << res.untangle.removed
                << " triangles reaching through them removed and closed again, "
                << res.untangle.reinserted
                << (res.untangle.reinserted == 1 ? " point put back" : " points put back")
                << (res.untangle.dropped.empty()
                        ? std::string()
                        : ", " + std::to_string(res.untangle.dropped.size()) +
                              " of a removed fold on no patch: outliers")
                << ")\n";
    if (opt.fill.max_edges > 0)
      std::cout << "filled holes     " << res.fill.filled << " (" << res.fill.triangles
                << " triangles, " << res.fill.vertices << " new vertices; " << res.fill.kept
                << " loops kept, " << res.fill.crossing
                << " of them because a patch would cross the mesh)\n";
    if (opt.denoise)
      std::cout << "denoised         " << res.denoise.moved << " vertices moved, "
                << res.denoise.mean_move << " on average (noise " << res.denoise.noise_mm
                << ", normals' scatter " << res.denoise.noise_deg << " deg; " << res.denoise.refused
                << " left: a move would fold or cross)\n";
    if (opt.sharpen)
      std::cout << "sharpened        " << res.sharpen.edge_vertices << " vertices on edges, "
                << res.sharpen.corner_vertices << " at corners (" << res.sharpen.bevel_triangles
                << " bevel triangles, " << res.sharpen.refused
                << " left as they were: a new vertex would cross or fold; "
                << res.sharpen.rounded << " on fillets, left round)\n";
    std::cout
              << "outliers         " << res.outliers.size()
              << (res.far_points > 0 ? " (" + std::to_string(res.far_points) +
                                           " far outside the cloud: stray readings, not meshed)"
                                     : std::string())
              << "\n"
              << "manifold         "
              << (rep.non_manifold_edges == 0 && rep.non_manifold_vertices == 0 ? "yes" : "NO")
              << ", orientation " << (rep.orientation_consistent ? "consistent" : "INCONSISTENT")
              << "\n"
              << "written          " << args.output
              << (args.preview.empty() ? std::string() : ", preview " + args.preview) << "\n"
              << "seconds          " << total << " (";
    bool first = true;
    for (const auto& [k, v] : seconds) {
      std::cout << (first ? "" : ", ") << k << " " << v;
      first = false;
    }
    std::cout << ")\n";
  }
  return kExitOk;
}

/// --progress with --stream: a bar on stderr, redrawn at most ten times a second.
class ProgressBar {
 public:
  explicit ProgressBar(bool on, std::size_t total) : on_(on), total_(total) {}
  void update(std::size_t done, const recon::IncrementalStats& st, bool force = false) {
    if (!on_) return;
    const auto now = std::chrono::steady_clock::now();
    if (!force && now - last_ < std::chrono::milliseconds(100)) return;
    last_ = now;
    const double f = total_ > 0 ? static_cast<double>(done) / static_cast<double>(total_) : 1.0;
    const int width = 30, full = static_cast<int>(f * width + 0.5);
    std::fprintf(stderr, "\rscanmesh: [%s%s] %3.0f %%  %zu/%zu points, %zu triangles, %zu cubes unmeshed",
                 std::string(static_cast<std::size_t>(full), '#').c_str(),
                 std::string(static_cast<std::size_t>(width - full), '.').c_str(), 100.0 * f, done,
                 total_, st.triangles, st.unmeshed_cubes);
    std::fflush(stderr);
  }
  void end() {
    if (on_) std::fprintf(stderr, "\n");
  }

 private:
  bool on_;
  std::size_t total_;
  std::chrono::steady_clock::time_point last_{};
};

/// --stream N: the incremental path. Each scan in turn (a turntable delivers them one after
/// another), fed N points a batch in file order, or row by row for a range scan with a
/// range_grid; a consumer takes the delta after every batch, as the daemon will.
int run_stream(const ReconstructArgs& args, const recon::ReconstructOptions& opt) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  auto secs = [](Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double>(b - a).count();
  };
  recon::IncrementalOptions io;
  io.reconstruct = opt;
  // The on-request passes run on the finished mesh (below), as the batch path runs them last.
  io.reconstruct.fill.max_edges = 0;
  io.reconstruct.denoise = false;
  io.reconstruct.sharpen = false;
  std::vector<std::string> notes;
  std::vector<Scan> scans = load_scans(args, notes);
  for (const auto& note : notes) std::fprintf(stderr, "scanmesh: note: %s\n", note.c_str());
  std::size_t total = 0;
  for (Scan& sc : scans) {
    total += sc.points.size();
    if (args.sensor.size() == 3) {
      const recon::Vec3 at(args.sensor[0], args.sensor[1], args.sensor[2]);
      sc.towards.resize(sc.points.size());
      for (std::size_t i = 0; i < sc.points.size(); ++i) sc.towards[i] = at - sc.points[i];
    }
  }
  if (total == 0) {
    std::string names;
    for (const auto& in : args.inputs) names += (names.empty() ? "" : ", ") + in;
    throw InputError(names + ": no points in the input");
  }
  const double read_seconds = secs(t0, Clock::now());
  const auto clock_start = Clock::now();
  recon::IncrementalReconstructor rec(io, [clock_start] {
    return std::chrono::duration<double>(Clock::now() - clock_start).count();
  });
  ProgressBar bar(args.progress, total);
  std::size_t batches = 0, deltas = 0, fed = 0;
  double max_batch = 0, delta_seconds = 0;
  std::vector<recon::Vec3> pts, dirs;
  auto feed = [&](std::span<const recon::Vec3> p, std::span<const recon::Vec3> d) {
    const auto a = Clock::now();
    if (d.empty()) {
      rec.add(p);
    } else {
      rec.add(p, d, recon::SensorData::kDirection);
    }
    const auto b = Clock::now();
    max_batch = std::max(max_batch, secs(a, b));
    ++batches;
    fed += p.size();
    if (!rec.take_delta().empty()) ++deltas;
    delta_seconds += secs(b, Clock::now());
    bar.update(fed, rec.stats());
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
    for (std::size_t i = 0; i < sc.points.size(); i += args.stream) {
      const std::size_t n = std::min(args.stream, sc.points.size() - i);
      feed(std::span<const recon::Vec3>(sc.points.data() + i, n),
           dir ? std::span<const recon::Vec3>(sc.towards.data() + i, n) : std::span<const recon::Vec3>());
    }
  }
  const auto f0 = Clock::now();
  recon::IncrementalResult res = rec.finish();
  if (!rec.take_delta().empty()) ++deltas;
  const double finish_seconds = secs(f0, Clock::now());
  bar.update(fed, res.stats, true);
  bar.end();
  recon::DenoiseStats denoise;
  recon::SharpenStats sharpen;
  recon::FillStats fill;
  if (opt.denoise) denoise = recon::denoise_mesh(res.mesh, opt.denoise_options);
  if (opt.sharpen) sharpen = recon::sharpen_edges(res.mesh, opt.sharpen_options);
  if (opt.fill.max_edges > 0) fill = recon::fill_holes(res.mesh, opt.fill);
  auto t = Clock::now();
  write_mesh_file(res.mesh, args.output, args.ascii);
  if (!args.outliers_file.empty()) meshio::write_points_xyz(res.outliers, args.outliers_file);
  const double write_seconds = secs(t, Clock::now());
  const recon::MeshReport rep = recon::analyze(res.mesh);
  if (!args.preview.empty()) {
    preview::RenderOptions options;
    options.up = axis_of(args.up);
    options.title = std::filesystem::path(args.output).filename().string() + ": " +
                    std::to_string(res.mesh.triangles.size()) + " triangles, streamed";
    preview::render_mesh_png(res.mesh, args.preview, options);
  }
  const double total_seconds = secs(t0, Clock::now());
  const recon::IncrementalStats& st = res.stats;
  if (args.json) {
    nlohmann::json j;
    j["input_points"] = st.points_in;
    j["reduced_points"] = res.mesh.vertices.size() + res.outliers.size() - res.far_points;
    j["vertices"] = res.mesh.vertices.size();
    j["triangles"] = res.mesh.triangles.size();
    put_topology(j, rep);
    j["outliers"] = res.outliers.size();
    j["far_points"] = res.far_points;
    j["cube"] = st.cube_mm;
    j["stream"] = args.stream;
    j["batches"] = batches;
    j["max_batch_seconds"] = max_batch;
    j["finish_seconds"] = finish_seconds;
    j["deltas"] = deltas;
    j["reopened_blocks"] = st.reopened_blocks;
    j["meshing_steps"] = st.meshing_steps;
    j["meshed_blocks"] = st.meshed_blocks_total;
    j["settle_to_mesh_p99_seconds"] = st.settle_to_mesh_p99_seconds;
    j["take_delta_seconds"] = delta_seconds;
    if (opt.fill.max_edges > 0) put_fill(j, fill);
    if (opt.denoise) put_denoise(j, denoise);
    if (opt.sharpen) put_sharpen(j, sharpen);
    j["output"] = args.output;
    j["notes"] = notes;
    if (!args.preview.empty()) j["preview"] = args.preview;
    j["seconds_total"] = total_seconds;
    nlohmann::json seconds = {{"read", read_seconds}, {"write", write_seconds}};
    for (const auto& [k, v] : st.seconds) seconds[k] = v;
    j["seconds"] = seconds;
    std::cout << j.dump() << "\n";
  } else {
    std::cout << std::fixed << std::setprecision(3);
    std::cout << "input points     " << st.points_in << "  (streamed: " << batches
              << " batches, the largest " << max_batch << " s)\n"
              << "cube             " << st.cube_mm << "\n"
              << "vertices         " << res.mesh.vertices.size() << "\n"
              << "triangles        " << res.mesh.triangles.size() << "\n"
              << "boundary loops   " << rep.boundary_loops << "\n"
              << "components       " << rep.components << "\n"
              << "genus            " << rep.genus << "\n"
              << "outliers         " << res.outliers.size() << "\n"
              << "deltas           " << deltas << " (" << st.meshing_steps << " meshing steps, "
              << st.reopened_blocks << " blocks re-opened)\n"
              << "manifold         "
              << (rep.non_manifold_edges == 0 && rep.non_manifold_vertices == 0 ? "yes" : "NO")
              << ", orientation " << (rep.orientation_consistent ? "consistent" : "INCONSISTENT")
              << "\n"
              << "written          " << args.output << "\n"
              << "seconds          " << total_seconds << " (finish " << finish_seconds << ")\n";
  }
  return kExitOk;
}

}  // namespace

void add_reconstruct_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<ReconstructArgs>();
  CLI::App* cmd = app.add_subcommand("reconstruct", "Reconstruct a triangle mesh from points");
  cmd->add_option("INPUT", args->inputs,
                  "point files: .xyz .txt .csv .asc .ply .stl .obj (merged)");
  add_mesh_output_option(*cmd, args->output);
  cmd->add_option("--cube", args->cube,
                  "cube reduction edge in input units, 'auto' (from the measured spacing) or "
                  "'none'")
      ->capture_default_str();
  cmd->add_option("--min-angle", args->min_angle_deg, "smallest interior angle, degrees")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 59.0));
  cmd->add_option("--conf", args->conf,
                  "scanalyze registration file (bmesh FILE tx ty tz qx qy qz qw); without INPUT "
                  "every listed scan is used");
  cmd->add_option("--sensor", args->sensor,
                  "X,Y,Z: where the sensor was (a single-view scan); an open surface then faces "
                  "it (with --conf, each scan's own sensor is used instead)")
      ->delimiter(',')
      ->expected(3);
  cmd->add_flag("--json", args->json, "print one JSON object with the figures");
  cmd->add_flag("--ascii", args->ascii, "write ASCII STL instead of binary");
  cmd->add_option("--outliers", args->outliers_file, "write the unreached points here (.xyz)")
      ->check(points_output());
  cmd->add_flag("--no-insert", args->no_insert,
                "leave the points the front did not reach out (no insertion afterwards)");
  cmd->add_flag("--zip-holes", args->zip_holes,
                "let the front's relaxed pass close wide loops the mesh surrounds with long "
                "edges too (by default they stay open: real holes whose rims noise or sparse "
                "sampling made ragged)");
  cmd->add_flag("--no-bulk", args->no_bulk,
                "grow the whole mesh with the front from seed triangles (no planar Delaunay "
                "patches first; slower, for comparison)");
  cmd->add_option("--fill-holes", args->fill_holes,
                  "close the boundary loops of at most N edges (minimum-weight patch of the "
                  "loop, refined to the density around it and faired to continue the surface); "
                  "default 0: every hole is kept")
      ->check(CLI::Range(std::size_t{0}, recon::FillOptions::kLimit));
  cmd->add_option("--fill-width", args->fill_width,
                  "close the boundary loops at most SIZE across, in input units (the largest "
                  "distance between two of a loop's vertices: a round hole's diameter); with "
                  "--fill-holes N both limits hold, alone it takes loops of up to 1000 edges")
      ->check(kNonNegative);
  cmd->add_flag("--fill-flat", args->fill_flat,
                "with --fill-holes or --fill-width: patch each hole with triangles of its "
                "rim's vertices only (no new vertex, no fairing)");
  cmd->add_flag("--denoise", args->denoise,
                "remove the scan's noise, keeping the sharp edges: filtered triangle normals, "
                "the vertices fitted to them (as `scanmesh denoise`; before --sharpen)");
  add_denoise_options(*cmd, args->denoise_options, "with --denoise: ");
  cmd->add_flag("--sharpen", args->sharpen,
                "recover the sharp edges and corners the scan bevelled: new vertices where the "
                "faces meet (as `scanmesh sharpen`)");
  add_sharpen_options(*cmd, args->sharpen_options, "with --sharpen: ");
  cmd->add_option("--preview", args->preview,
                  "also write a shaded picture of the mesh (.png; back faces tinted, so holes "
                  "and flipped triangles show; filled holes amber)")
      ->check(png_output());
  cmd->add_option("--up", args->up, "world axis shown upwards in the preview (x, y or z)")
      ->capture_default_str()
      ->check(CLI::IsMember({"x", "y", "z"}));
  cmd->add_flag("--progress", args->progress,
                "print each stage on stderr as it starts, with the seconds elapsed (with "
                "--stream: a live bar)");
  cmd->add_option("--stream", args->stream,
                  "feed the points to the incremental reconstruction N at a time, in file order "
                  "(a .ply range scan with a range_grid row by row; several inputs, or a --conf "
                  "list, one scan after another)")
      ->check(CLI::Range(std::size_t{1}, std::size_t{1} << 30));
  cmd->callback([args, &run] { run = [args] { return run_reconstruct(*args); }; });
}

}  // namespace scanmesh::cli
