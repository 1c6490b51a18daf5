// The simulator's ground truth for each sensor sample, beside the drivers' sample types it
// produces.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <compare>
#include <cstdint>
#include <optional>
#include <string_view>

#include "scanmesh/drivers/samples.hpp"
#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::sim {

// The sample types are the drivers' own (drivers/include/scanmesh/drivers/samples.hpp): the
// simulator delivers exactly what a real driver delivers.
using drivers::ProbeTrigger;
using drivers::SensorSample;
using drivers::SensorStatus;
using drivers::StageSample;
using drivers::Timestamp;
using drivers::to_string;

/// Why a sensor sample has the value it has. Simulation only.
enum class SampleCause : std::uint8_t {
  kOk,          ///< a genuine reading of the surface (plus range noise)
  kNoHit,       ///< the ray met nothing
  kOutOfRange,  ///< the surface was nearer or farther than the measuring range
  kGrazing,     ///< incidence angle beyond the sensor's limit
  kShadowed,    ///< the receiver could not see the lit spot (triangulation shadow)
  kDropout,     ///< a random dropout of a valid reading
  kSpike,       ///< a random outlier value reported as kOk
};

std::string_view to_string(SampleCause cause);

/// Ground truth of one sensor sample.
struct SampleTruth {
  Timestamp t_true;  ///< instant the measurement was really taken (host clock)
  SampleCause cause = SampleCause::kNoHit;
  recon::Vec3 surface_point_mm{};  ///< the lit surface point in the part frame; NaN if none
  double true_value_mm = 0;        ///< noise-free reading; NaN if no surface point
};

}  // namespace scanmesh::sim
