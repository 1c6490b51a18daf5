// `scanmesh simulate`: the simulated scanner. Scans a reference mesh (or a built-in part) with a
// virtual sensor on a virtual stage, writes the measured points (computed from the timestamped
// sample stream exactly as acquisition will), optionally the ground truth and the raw stream;
// or replays a recorded stream into points.
// SPDX-License-Identifier: MIT
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/replay.hpp"
#include "scanmesh/sim/simulator.hpp"
#include "scanmesh/sim/stream.hpp"

namespace scanmesh::cli {
namespace {

struct SimulateArgs {
  std::string mesh;
  std::string part;
  std::string replay;
  std::string sensor = "point";
  std::string path = "serpentine";
  double spacing_mm = 0;       ///< 0: 0.2 (optical) or 5 (probe)
  double line_spacing_mm = 0;  ///< 0: the path's default
  double noise_mm = 0;
  double dropout = 0;
  double spike = 0;
  double missing = 0;
  double stage_noise_mm = 0;
  double latency_us = 0;
  double speed_mm_s = 20;
  double accel_mm_s2 = 1000;
  std::uint32_t views = 4;
  std::uint32_t profile_points = 200;
  std::uint32_t threads = 0;
  std::uint64_t seed = 1;
  std::string output;
  std::string truth;
  std::string stream;
  bool realtime = false;
  bool json = false;
};

/// Samples to the stream file and into memory at once.
class Tee : public sim::SampleSink, public sim::TruthSink {
 public:
  Tee(sim::ScanRecorder& rec, sim::StreamWriter* writer) : rec_(rec), writer_(writer) {}
  void on_sensor(std::span<const sim::SensorSample> s) override {
    rec_.on_sensor(s);
    if (writer_) writer_->on_sensor(s);
  }
  void on_stage(const sim::StageSample& s) override {
    rec_.on_stage(s);
    if (writer_) writer_->on_stage(s);
  }
  void on_probe(const sim::ProbeTrigger& g) override {
    rec_.on_probe(g);
    if (writer_) writer_->on_probe(g);
  }
  void on_truth(std::span<const sim::SampleTruth> t) override { rec_.on_truth(t); }

 private:
  sim::ScanRecorder& rec_;
  sim::StreamWriter* writer_;
};

std::vector<recon::Vec3> coordinates(const std::vector<sim::MeasuredPoint>& points) {
  std::vector<recon::Vec3> out;
  out.reserve(points.size());
  for (const auto& p : points) out.push_back(p.point_mm);
  return out;
}

int run_replay(const SimulateArgs& args) {
  const auto t0 = std::chrono::steady_clock::now();
  const sim::RecordedStream rec = sim::read_stream(args.replay, {true});
  // Deliver through the replayer (paced by the steady clock with --realtime) into memory, as a
  // live consumer would receive it.
  sim::ScanRecorder out;
  sim::SteadyClock clock;
  sim::Replayer replayer(rec, clock);
  if (args.realtime) {
    while (!replayer.done()) {
      replayer.poll(out);
      if (const auto due = replayer.next_due()) {
        const auto wait = *due - clock.now();
        if (wait.count() > 0) std::this_thread::sleep_for(wait);
      }
    }
  } else {
    replayer.run_all(out);
  }
  const sim::SensorOptics optics(rec.header.sensor);
  sim::PointStats st;
  const auto points = sim::points_from_samples(optics, rec.header.calibration, out.scan().stage,
                                               out.scan().sensor, out.scan().probe, &st);
  meshio::write_points_xyz(coordinates(points), args.output);
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (args.json) {
    nlohmann::json j;
    j["replay"] = args.replay;
    j["complete"] = rec.complete;
    j["sensor"] = std::string(sim::to_string(rec.header.sensor.kind));
    j["sensor_samples"] = rec.sensor.size();
    j["stage_samples"] = rec.stage.size();
    j["probe_triggers"] = rec.probe.size();
    j["points"] = points.size();
    j["invalid"] = st.invalid;
    j["no_pose"] = st.no_pose;
    j["output"] = args.output;
    j["realtime"] = args.realtime;
    j["elapsed_s"] = elapsed;
    std::cout << j.dump() << "\n";
  } else {
    std::cout << "replayed " << args.replay << (rec.complete ? "" : " (truncated)") << ": "
              << rec.sensor.size() << " sensor samples, " << rec.stage.size()
              << " stage samples -> " << points.size() << " points -> " << args.output << "\n";
  }
  return kExitOk;
}

int run_simulate(const SimulateArgs& args) {
  if (!args.replay.empty()) return run_replay(args);
  if (args.part.empty() && args.mesh.empty())
    throw ConfigError("give --mesh FILE, --part NAME or --replay STREAM");
  const auto t0 = std::chrono::steady_clock::now();
  recon::Mesh mesh;
  if (!args.part.empty()) {
    mesh = sim::make_part(args.part);
  } else {
    mesh = meshio::read_mesh(args.mesh);
    if (mesh.triangles.empty())
      throw InputError(args.mesh + ": no triangles to scan (a point cloud?)");
  }
  const sim::Scene scene(std::move(mesh));

  sim::SimConfig cfg;
  const sim::SensorKind kind = sim::sensor_kind_from_string(args.sensor);
  cfg.sensor = sim::default_sensor(kind);
  if (kind == sim::SensorKind::kLine) cfg.sensor.profile_points = args.profile_points;
  cfg.path.kind = sim::path_kind_from_string(args.path);
  cfg.path.spacing_mm = args.spacing_mm > 0               ? args.spacing_mm
                        : kind == sim::SensorKind::kProbe ? 5.0
                                                          : 0.2;
  cfg.path.line_spacing_mm = args.line_spacing_mm;
  cfg.path.views = args.views;
  cfg.path.limits.linear_accel_mm_s2 = args.accel_mm_s2;
  if (kind == sim::SensorKind::kProbe) {
    cfg.sensor.probe_speed_mm_s = args.speed_mm_s;
  } else {
    // The line speed and the spacing set the sampling rate.
    cfg.sensor.rate_hz = args.speed_mm_s / cfg.path.spacing_mm;
  }
  cfg.imperfections.seed = args.seed;
  cfg.imperfections.range_noise_mm = args.noise_mm;
  cfg.imperfections.dropout_probability = args.dropout;
  cfg.imperfections.spike_probability = args.spike;
  cfg.imperfections.missing_probability = args.missing;
  cfg.imperfections.stage_noise_mm = args.stage_noise_mm;
  cfg.imperfections.sensor_latency =
      std::chrono::nanoseconds(std::llround(args.latency_us * 1000.0));
  cfg.threads = args.threads;
  const sim::Simulator simulator(scene, cfg);

  const std::string source = args.part.empty() ? args.mesh : "part:" + args.part;
  sim::ScanRecorder rec;
  std::unique_ptr<std::ofstream> stream_file;
  std::unique_ptr<sim::StreamWriter> writer;
  std::filesystem::path stream_tmp;
  if (!args.stream.empty()) {
    stream_tmp = args.stream + ".tmp";
    stream_file = std::make_unique<std::ofstream>(stream_tmp, std::ios::binary | std::ios::trunc);
    if (!*stream_file) throw OutputError(args.stream + ": cannot create");
    writer = std::make_unique<sim::StreamWriter>(
        *stream_file, sim::stream_header(simulator, {{"source", source},
                                                     {"path", args.path},
                                                     {"seed", std::to_string(args.seed)},
                                                     {"recorder", "scanmesh simulate"}}));
  }
  Tee tee(rec, writer.get());
  const sim::SimStats stats = simulator.run(tee, &tee);
  if (writer) {
    writer->finish();
    stream_file->close();
    if (!*stream_file) throw OutputError(args.stream + ": write failed");
    std::error_code ec;
    std::filesystem::rename(stream_tmp, args.stream, ec);
    if (ec) throw OutputError(args.stream + ": cannot rename into place: " + ec.message());
  }

  // The cloud is what acquisition computes from the stream: pose at each sample's host time,
  // mapped through the calibration.
  const sim::SimulatedScan& scan = rec.scan();
  sim::PointStats pst;
  const auto points = sim::points_from_samples(simulator.optics(), simulator.calibration(),
                                               scan.stage, scan.sensor, scan.probe, &pst);
  if (points.empty()) throw GeometryError("the scan measured no points (is the part in range?)");
  meshio::write_points_xyz(coordinates(points), args.output);
  if (!args.truth.empty()) {
    // The true surface point of each measured point, line for line.
    std::vector<recon::Vec3> truth;
    truth.reserve(points.size());
    std::size_t j = 0;
    for (std::size_t i = 0; i < scan.sensor.size() && j < points.size(); ++i) {
      const auto& p = points[j];
      if (!p.probe && scan.sensor[i].seq == p.seq && scan.sensor[i].index == p.index) {
        truth.push_back(scan.truth[i].surface_point_mm);
        ++j;
      }
    }
    for (; j < points.size(); ++j)
      truth.push_back(scan.probe_truth[points[j].seq].surface_point_mm);
    meshio::write_points_xyz(truth, args.truth);
  }
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double duration_s = static_cast<double>((stats.end - stats.start).count()) * 1e-9;

  if (args.json) {
    nlohmann::json j;
    j["source"] = source;
    j["triangles"] = scene.mesh().triangles.size();
    j["sensor"] = args.sensor;
    j["path"] = args.path;
    j["spacing_mm"] = cfg.path.spacing_mm;
    j["line_spacing_mm"] = args.line_spacing_mm;
    j["lines"] = simulator.plan().lines;
    j["rate_hz"] = cfg.sensor.rate_hz;
    j["noise_mm"] = args.noise_mm;
    j["dropout"] = args.dropout;
    j["seed"] = args.seed;
    j["measurements"] = stats.measurements;
    j["samples"] = stats.samples;
    j["missing"] = stats.missing;
    j["stage_samples"] = stats.stage_samples;
    j["rays"] = stats.rays;
    nlohmann::json causes;
    for (std::size_t c = 0; c < stats.causes.size(); ++c)
      causes[std::string(sim::to_string(static_cast<sim::SampleCause>(c)))] = stats.causes[c];
    j["causes"] = causes;
    j["points"] = points.size();
    j["scan_duration_s"] = duration_s;
    j["output"] = args.output;
    j["truth"] = args.truth.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.truth);
    j["stream"] = args.stream.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.stream);
    j["elapsed_s"] = elapsed;
    std::cout << j.dump() << "\n";
  } else {
    std::cout << "simulated " << args.sensor << " sensor, " << args.path << " path over " << source
              << ": " << stats.measurements << " measurements, " << stats.samples << " samples ("
              << stats.cause(sim::SampleCause::kOk) << " ok, "
              << stats.cause(sim::SampleCause::kShadowed) << " shadowed, "
              << stats.cause(sim::SampleCause::kGrazing) << " grazing, "
              << stats.cause(sim::SampleCause::kOutOfRange) << " out of range, "
              << stats.cause(sim::SampleCause::kNoHit) << " no target), " << duration_s
              << " s of scanning -> " << points.size() << " points -> " << args.output;
    if (!args.truth.empty()) std::cout << ", truth -> " << args.truth;
    if (!args.stream.empty()) std::cout << ", stream -> " << args.stream;
    std::cout << "\n";
  }
  return kExitOk;
}

}  // namespace

void add_simulate_command(CLI::App& app, Runner& run) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "simulate",
      "Scan a mesh or built-in part with a simulated sensor and stage (or replay a stream)");
  cmd->footer(
      "The points are computed from the timestamped sample stream (stage pose interpolated at "
      "each sample's time, then the sensor calibration), exactly as acquisition does. The "
      "stream format is described in sim/README.md.");
  auto* mesh = cmd->add_option("--mesh", args->mesh, "reference mesh to scan (.stl .ply .obj)");
  auto* part = cmd->add_option("--part", args->part, "built-in part to scan")
                   ->check(CLI::IsMember(sim::part_names()));
  auto* replay =
      cmd->add_option("--replay", args->replay, "replay a recorded stream file into points");
  mesh->excludes(part)->excludes(replay);
  part->excludes(mesh)->excludes(replay);
  replay->excludes(mesh)->excludes(part);
  cmd->add_option("--sensor", args->sensor, "sensor model")
      ->capture_default_str()
      ->check(CLI::IsMember({"point", "line", "probe"}));
  cmd->add_option("--path", args->path, "scan path")
      ->capture_default_str()
      ->check(CLI::IsMember({"raster", "serpentine", "rotary", "views"}));
  cmd->add_option("--spacing", args->spacing_mm,
                  "sample spacing along the lines at cruise speed, mm (default 0.2; probe: "
                  "touch spacing, default 5)")
      ->check(kPositive);
  cmd->add_option("--line-spacing", args->line_spacing_mm,
                  "distance between scan lines, mm (default: 5 x spacing; line profiler: 0.8 "
                  "profile widths)")
      ->check(kPositive);
  cmd->add_option("--noise", args->noise_mm, "Gaussian range noise (sigma), mm")
      ->capture_default_str()
      ->check(kNonNegative);
  cmd->add_option("--dropout", args->dropout, "probability that a valid reading drops out")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--spike", args->spike, "probability that a valid reading is a random spike")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--missing", args->missing, "probability that a measurement never arrives")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.99));
  cmd->add_option("--stage-noise", args->stage_noise_mm,
                  "Gaussian noise on reported stage positions (sigma), mm")
      ->capture_default_str()
      ->check(kNonNegative);
  cmd->add_option("--latency-us", args->latency_us,
                  "sensor latency relative to the stage clock, microseconds")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e6));
  cmd->add_option("--speed", args->speed_mm_s,
                  "line speed, mm/s (sets the sample rate: speed / spacing); probe: approach "
                  "speed")
      ->capture_default_str()
      ->check(kPositive);
  cmd->add_option("--accel", args->accel_mm_s2, "axis acceleration limit, mm/s^2")
      ->capture_default_str()
      ->check(kPositive);
  cmd->add_option("--views", args->views, "number of table angles for --path views")
      ->capture_default_str()
      ->check(CLI::Range(1, 360));
  cmd->add_option("--profile-points", args->profile_points, "points per profile (line sensor)")
      ->capture_default_str()
      ->check(CLI::Range(1, 65536));
  cmd->add_option("--threads", args->threads, "ray-casting threads (0: all cores)")
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "random seed (same seed, same bytes)")
      ->capture_default_str();
  cmd->add_option("-o,--output", args->output, "measured points to write (.xyz)")
      ->required()
      ->check(points_output());
  cmd->add_option("--truth", args->truth,
                  "also write the true surface point of each measured point (.xyz)")
      ->check(points_output());
  cmd->add_option("--stream", args->stream,
                  "also write the raw timestamped sample stream (scanmesh-stream v1)");
  cmd->add_flag("--realtime", args->realtime,
                "with --replay: deliver at the recorded speed (manual runs only)");
  cmd->add_flag("--json", args->json, "print one JSON object instead of the summary line");
  cmd->callback([args, &run] { run = [args] { return run_simulate(*args); }; });
}

}  // namespace scanmesh::cli
