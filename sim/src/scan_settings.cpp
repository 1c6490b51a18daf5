// ScanSettings -> SimConfig.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/scan_settings.hpp"

#include <cmath>

namespace scanmesh::sim {

SimConfig ScanSettings::to_config() const {
  SimConfig cfg;
  const SensorKind kind = sensor_kind_from_string(sensor);
  cfg.sensor = default_sensor(kind);
  if (kind == SensorKind::kLine) cfg.sensor.profile_points = profile_points;
  cfg.path.kind = path_kind_from_string(path);
  cfg.path.spacing_mm = spacing_mm > 0 ? spacing_mm : kind == SensorKind::kProbe ? 5.0 : 0.2;
  cfg.path.line_spacing_mm = line_spacing_mm;
  cfg.path.views = views;
  cfg.path.limits.linear_accel_mm_s2 = accel_mm_s2;
  if (kind == SensorKind::kProbe) {
    cfg.sensor.probe_speed_mm_s = speed_mm_s;
  } else {
    // The line speed and the spacing set the sampling rate.
    cfg.sensor.rate_hz = speed_mm_s / cfg.path.spacing_mm;
  }
  cfg.imperfections.seed = seed;
  cfg.imperfections.range_noise_mm = noise_mm;
  cfg.imperfections.dropout_probability = dropout;
  cfg.imperfections.spike_probability = spike;
  cfg.imperfections.missing_probability = missing;
  cfg.imperfections.stage_noise_mm = stage_noise_mm;
  cfg.imperfections.sensor_latency = std::chrono::nanoseconds(std::llround(latency_us * 1000.0));
  cfg.threads = threads;
  return cfg;
}

}  // namespace scanmesh::sim
