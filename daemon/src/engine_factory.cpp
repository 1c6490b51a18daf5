// Back-end selection by configuration alone (engine_factory.hpp): one BackendFactory per
// backend.kind, each a line in make_engine; the engine is the same PipelineEngine for all.
// SPDX-License-Identifier: MIT
#include "scanmesh/daemon/engine_factory.hpp"

#include <algorithm>
#include <chrono>

#include "scan_parameters.hpp"
#include "scanmesh/acquisition/journal.hpp"
#include "scanmesh/acquisition/journal_backend.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/daemon/pipeline_engine.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/scan_settings.hpp"
#include "scanmesh/sim/emulators/emulated_backend.hpp"
#include "scanmesh/sim/scanner_backend.hpp"

namespace scanmesh::daemon {

namespace {

/// Sensor samples a simulated scan's plan delivers: its sensing time at the sensor's rate (a
/// profile of profile_points samples per measurement), or one per probe approach. Missing
/// measurements make the real count a little lower: it is the progress bar's denominator.
std::uint64_t planned_samples(const sim::Simulator& s) {
  const auto& optics = s.optics().config();
  if (optics.kind == acq::SensorKind::kProbe) return s.plan().approaches.size();
  double seconds = 0;
  for (const auto& m : s.plan().trajectory.moves())
    if (m.sensing) seconds += std::chrono::duration<double>(m.end - m.start).count();
  const double per = optics.kind == acq::SensorKind::kLine ? optics.profile_points : 1.0;
  return static_cast<std::uint64_t>(seconds * optics.rate_hz * per);
}

/// [sim] with the request's parameters on top: the simulated scanner over a part or a mesh.
ScanSource make_sim(const SimBackendConfig& config, const BackendRequest& request) {
  SimBackendConfig s = config;
  for (const auto& [key, v] : request.parameters) {
    if (key == "part") {
      s.part = params::string(key, v);
      s.mesh.clear();
      const auto names = sim::part_names();
      if (std::find(names.begin(), names.end(), s.part) == names.end())
        params::bad(key, "unknown part '" + s.part + "'");
    } else if (key == "mesh") {
      s.mesh = params::string(key, v);
      s.part.clear();
      std::error_code ec;
      if (!s.mesh.is_absolute() || !std::filesystem::is_regular_file(s.mesh, ec))
        params::bad(key, "must be an absolute path to a mesh file the daemon can read");
    } else if (key == "sensor") {
      s.sensor = params::string(key, v);
      if (s.sensor != "point" && s.sensor != "line" && s.sensor != "probe")
        params::bad(key, "must be point, line or probe");
    } else if (key == "path") {
      s.path = params::string(key, v);
      if (s.path != "raster" && s.path != "serpentine" && s.path != "rotary" && s.path != "views")
        params::bad(key, "must be raster, serpentine, rotary or views");
    } else if (key == "spacing_mm") {
      s.spacing_mm = params::number(key, v, 1e-3, 50);
    } else if (key == "line_spacing_mm") {
      s.line_spacing_mm = params::number(key, v, 0, 500);
    } else if (key == "speed_mm_s") {
      s.speed_mm_s = params::number(key, v, 1e-3, 5000);
    } else if (key == "noise_mm") {
      s.noise_mm = params::number(key, v, 0, 5);
    } else if (key == "seed") {
      s.seed = static_cast<std::int64_t>(params::number(key, v, 0, 9e15));
    } else if (key == "views") {
      s.views = static_cast<std::int64_t>(params::number(key, v, 1, 360));
    } else if (key == "profile_points") {
      s.profile_points = static_cast<std::int64_t>(params::number(key, v, 1, 65536));
    } else if (key == "playback") {
      s.playback = params::number(key, v, 0, 10000);
    } else if (key == "transport") {
      s.transport = params::string(key, v);
      if (s.transport != "in-process" && s.transport != "emulators")
        params::bad(key, "must be in-process or emulators");
    } else {
      params::bad(key,
                  "unknown parameter (the sim backend takes part, mesh, sensor, path, spacing_mm, "
                  "line_spacing_mm, speed_mm_s, noise_mm, seed, views, profile_points, playback, "
                  "transport; "
                  "every backend cube_mm and mesher)");
    }
  }
  sim::ScanSettings settings;
  settings.sensor = s.sensor;
  settings.path = s.path;
  settings.spacing_mm = s.spacing_mm;
  settings.line_spacing_mm = s.line_spacing_mm;
  settings.speed_mm_s = s.speed_mm_s;
  settings.noise_mm = s.noise_mm;
  settings.seed = static_cast<std::uint64_t>(s.seed);
  settings.views = static_cast<std::uint32_t>(s.views);
  settings.profile_points = static_cast<std::uint32_t>(s.profile_points);
  sim::SimConfig cfg = settings.to_config();
  // A resumed scan is a new simulated pass over the part whose clock starts after the
  // interrupted segments' last sample, so that the segments replay as one scan.
  if (request.continue_after)
    cfg.path.start = std::max(cfg.path.start, *request.continue_after + std::chrono::seconds(1));
  recon::Mesh part;
  ScanSource out;
  if (!s.mesh.empty()) {
    part = meshio::read_mesh(s.mesh);
    if (part.triangles.empty())
      throw InputError(s.mesh.string() + ": no triangles to scan (a point cloud?)");
    out.description = "mesh:" + s.mesh.string();
  } else {
    part = sim::make_part(s.part);
    out.description = "part:" + s.part;
  }
  if (s.transport == "emulators") {
    if (s.sensor != "point")
      params::bad("sensor", "the emulators are a point sensor (ILD1420): sensor must be point");
    auto emulated = std::make_unique<sim::EmulatedScanBackend>(std::move(part), settings);
    // Sensing time at the ILD1420's rate: the progress bar's denominator.
    double seconds = 0;
    for (const auto& m : emulated->scanner().planner().plan().trajectory.moves())
      if (m.sensing) seconds += std::chrono::duration<double>(m.end - m.start).count();
    out.planned_sensor_samples =
        static_cast<std::uint64_t>(seconds * emulated->scanner().sensor_rate_hz());
    out.description += " (emulators)";
    out.backend = std::move(emulated);
    return out;
  }
  sim::SimulatedScannerOptions options;
  options.speed = s.playback;
  if (s.sensor_loss_at_s > 0) {
    options.sensor_loss_at =
        std::chrono::nanoseconds(static_cast<std::int64_t>(s.sensor_loss_at_s * 1e9));
    options.loss_duration =
        std::chrono::nanoseconds(static_cast<std::int64_t>(s.sensor_loss_s * 1e9));
  }
  auto scanner = std::make_unique<sim::SimulatedScanner>(std::move(part), cfg, options);
  out.planned_sensor_samples = planned_samples(scanner->simulator());
  out.backend = std::move(scanner);
  return out;
}

/// [replay]: the configured journal played back through the pipeline as if live.
ScanSource make_replay(const ReplayBackendConfig& config, const BackendRequest& request) {
  acq::ReplayOptions options;
  options.speed = config.playback;
  for (const auto& [key, v] : request.parameters) {
    if (key == "playback")
      options.speed = params::number(key, v, 0, 10000);
    else
      params::bad(key,
                  "unknown parameter (the replay backend takes playback; every backend cube_mm "
                  "and mesher)");
  }
  if (request.continue_after)
    throw EngineError(proto::errc::kBadState,
                      "the replay backend cannot continue a scan: it plays " +
                          config.journal.string() + " from its start (close the scan instead)");
  ScanSource out;
  out.description = "journal:" + config.journal.string();
  for (const auto& c : acq::check_journal(config.journal).channels)
    if (c.channel.kind == acq::ChannelKind::kSensor) out.planned_sensor_samples += c.samples;
  out.backend = std::make_unique<acq::ReplayBackend>(
      std::vector<std::filesystem::path>{config.journal}, options);
  return out;
}

}  // namespace

std::unique_ptr<ScanEngine> make_engine(const DaemonConfig& config, const Log& log) {
  if (config.backend == "sim")
    return make_pipeline_engine(
        config, log, "sim", [c = config.sim](const BackendRequest& r) { return make_sim(c, r); });
  if (config.backend == "replay")
    return make_pipeline_engine(
        config, log, "replay",
        [c = config.replay](const BackendRequest& r) { return make_replay(c, r); });
  if (config.backend == "devices")
    throw ConfigError(config.source.string() +
                      ": backend.kind: \"devices\" is not wired to the pipeline yet (a ScanBackend "
                      "over the drivers of [[devices]] is needed); use \"sim\" or \"replay\"");
  throw ConfigError(config.source.string() + ": backend.kind: unknown backend '" + config.backend +
                    "'");
}

}  // namespace scanmesh::daemon
