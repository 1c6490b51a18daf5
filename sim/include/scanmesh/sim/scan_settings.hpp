// The simulated scanner's knobs as a user sets them (`scanmesh simulate`, `scanmesh scan --sim`,
// the daemon's [sim] table): sensor and path by name, line speed instead of a sample rate.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <string>

#include "scanmesh/sim/simulator.hpp"

namespace scanmesh::sim {

struct ScanSettings {
  std::string sensor = "point";      ///< "point", "line" or "probe"
  std::string path = "serpentine";   ///< "raster", "serpentine", "rotary" or "views"
  double spacing_mm = 0;             ///< along-line spacing; 0: 0.2 (optical) or 5 (probe)
  double line_spacing_mm = 0;        ///< 0: the path's default
  double noise_mm = 0;               ///< Gaussian range noise (sigma)
  double dropout = 0;                ///< probability of a dropout, [0, 1]
  double spike = 0;                  ///< probability of a spike, [0, 1]
  double missing = 0;                ///< probability of a missing measurement, [0, 0.99]
  double stage_noise_mm = 0;         ///< sigma on reported stage positions
  double latency_us = 0;             ///< sensor latency relative to the stage, us
  double speed_mm_s = 20;            ///< line speed (sets the rate: speed / spacing); probe: approach
  double accel_mm_s2 = 1000;         ///< axis acceleration limit
  std::uint32_t views = 4;           ///< table angles for "views"
  std::uint32_t profile_points = 200;  ///< points per profile (line sensor)
  std::uint32_t threads = 0;         ///< ray-casting threads (0: all cores)
  std::uint64_t seed = 1;

  /// The simulator's configuration (validated by Simulator; names checked here: ConfigError).
  SimConfig to_config() const;
};

}  // namespace scanmesh::sim
