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
#include "scanmesh/reconstruction/reconstruction.hpp"
#include "scanmesh/reconstruction/result_json.hpp"

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

/// The job as the library takes it (the options already validated).
reconstruction::Request make_request(const ReconstructArgs& args,
                                     const recon::ReconstructOptions& opt) {
  reconstruction::Request r;
  r.inputs = args.inputs;
  r.conf = args.conf;
  if (args.sensor.size() == 3) r.sensor = recon::Vec3(args.sensor[0], args.sensor[1], args.sensor[2]);
  r.options = opt;
  r.stream = args.stream;
  return r;
}

/// Warnings and notes on stderr as they come.
reconstruction::Observer stderr_observer() {
  reconstruction::Observer o;
  o.warning = [](const std::string& w) { std::fprintf(stderr, "scanmesh: warning: %s\n", w.c_str()); };
  o.note = [](const std::string& n) { std::fprintf(stderr, "scanmesh: note: %s\n", n.c_str()); };
  return o;
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
  // --progress: one line on stderr as each stage starts (stdout stays the summary or the JSON).
  auto report = [&](std::string_view what) {
    if (!args.progress) return;
    std::fprintf(stderr, "scanmesh: %8.3f s  %.*s\n",
                 std::chrono::duration<double>(Clock::now() - t0).count(),
                 static_cast<int>(what.size()), what.data());
    std::fflush(stderr);
  };
  reconstruction::Observer observer = stderr_observer();
  observer.stage = report;
  reconstruction::BatchOutcome outcome =
      reconstruction::run_batch(make_request(args, opt), observer);
  recon::ReconstructResult& res = outcome.result;
  std::map<std::string, double>& seconds = outcome.seconds;

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
    nlohmann::json j = reconstruction::to_json(outcome, opt, rep);
    j["output"] = args.output;
    if (!args.preview.empty()) j["preview"] = args.preview;
    j["seconds_total"] = total;
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
  reconstruction::Observer observer = stderr_observer();
  std::unique_ptr<ProgressBar> bar;
  observer.batch = [&](std::size_t fed, std::size_t total, const recon::IncrementalStats& st) {
    if (!bar) bar = std::make_unique<ProgressBar>(args.progress, total);
    bar->update(fed, st);
  };
  reconstruction::StreamOutcome outcome =
      reconstruction::run_stream(make_request(args, opt), observer);
  recon::IncrementalResult& res = outcome.result;
  if (bar) {
    bar->update(res.stats.points_in, res.stats, true);
    bar->end();
  }
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
    nlohmann::json j = reconstruction::to_json(outcome, opt, rep);
    j["seconds"]["write"] = write_seconds;
    j["output"] = args.output;
    if (!args.preview.empty()) j["preview"] = args.preview;
    j["seconds_total"] = total_seconds;
    std::cout << j.dump() << "\n";
  } else {
    std::cout << std::fixed << std::setprecision(3);
    std::cout << "input points     " << st.points_in << "  (streamed: " << outcome.batches
              << " batches, the largest " << outcome.max_batch_seconds << " s)\n"
              << "cube             " << st.cube_mm << "\n"
              << "vertices         " << res.mesh.vertices.size() << "\n"
              << "triangles        " << res.mesh.triangles.size() << "\n"
              << "boundary loops   " << rep.boundary_loops << "\n"
              << "components       " << rep.components << "\n"
              << "genus            " << rep.genus << "\n"
              << "outliers         " << res.outliers.size() << "\n"
              << "deltas           " << outcome.deltas << " (" << st.meshing_steps << " meshing steps, "
              << st.reopened_blocks << " blocks re-opened)\n"
              << "manifold         "
              << (rep.non_manifold_edges == 0 && rep.non_manifold_vertices == 0 ? "yes" : "NO")
              << ", orientation " << (rep.orientation_consistent ? "consistent" : "INCONSISTENT")
              << "\n"
              << "written          " << args.output << "\n"
              << "seconds          " << total_seconds << " (finish " << outcome.finish_seconds << ")\n";
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
