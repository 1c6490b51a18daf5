// Simulated scans for the quality benchmarks: a built-in part scanned in one of the simulator's
// modes, with noise and dropouts, returned as the measured points.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <vector>

#include "scanmesh/recon/mesh.hpp"
#include "scanmesh/sim/simulator.hpp"
#include "scanmesh/sim/stream.hpp"

namespace scanmesh::bench {

namespace sim = scanmesh::sim;
using recon::Vec3;

/// A scanning mode: sensor, path and their sampling.
struct Mode {
  const char* name;
  sim::SensorKind sensor;
  const char* path;
  double spacing_mm;
  std::uint32_t profile_points;  // line profiler only
  std::uint32_t views;           // table angles, path "views" only
};

/// Sensor imperfections of every scan (--noise, --dropout).
struct Imperfections {
  double noise_mm = 0.02, dropout = 0.05, spike = 0;
};

/// The measured points of one scan of `scene` in mode m (same seed, same points).
inline std::vector<Vec3> scan(const sim::Scene& scene, const Mode& m, const Imperfections& imp,
                              std::uint64_t seed) {
  sim::SimConfig cfg;
  cfg.sensor = sim::default_sensor(m.sensor);
  if (m.sensor == sim::SensorKind::kLine) cfg.sensor.profile_points = m.profile_points;
  cfg.path.kind = sim::path_kind_from_string(m.path);
  cfg.path.spacing_mm = m.spacing_mm;
  if (m.views > 0) cfg.path.views = m.views;
  cfg.sensor.rate_hz = 20.0 / m.spacing_mm;  // 20 mm/s, as the CLI's default speed
  cfg.imperfections.seed = seed;
  cfg.imperfections.range_noise_mm = imp.noise_mm;
  cfg.imperfections.dropout_probability = imp.dropout;
  cfg.imperfections.spike_probability = imp.spike;
  const sim::Simulator simulator(scene, cfg);
  sim::ScanRecorder rec;
  simulator.run(rec, &rec);
  const sim::SimulatedScan& s = rec.scan();
  const auto measured = sim::points_from_samples(simulator.optics(), simulator.calibration(),
                                                 s.stage, s.sensor, s.probe);
  std::vector<Vec3> points;
  points.reserve(measured.size());
  for (const auto& p : measured) points.push_back(p.point_mm);
  return points;
}

}  // namespace scanmesh::bench
