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
#include "sim_options.hpp"
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
  sim::ScanSettings scan;
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

  const sim::SimConfig cfg = args.scan.to_config();
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
                                                     {"path", args.scan.path},
                                                     {"seed", std::to_string(args.scan.seed)},
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
    j["sensor"] = args.scan.sensor;
    j["path"] = args.scan.path;
    j["spacing_mm"] = cfg.path.spacing_mm;
    j["line_spacing_mm"] = args.scan.line_spacing_mm;
    j["lines"] = simulator.plan().lines;
    j["rate_hz"] = cfg.sensor.rate_hz;
    j["noise_mm"] = args.scan.noise_mm;
    j["dropout"] = args.scan.dropout;
    j["seed"] = args.scan.seed;
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
    std::cout << "simulated " << args.scan.sensor << " sensor, " << args.scan.path << " path over " << source
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
  add_sim_scan_options(cmd, args->scan);
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
