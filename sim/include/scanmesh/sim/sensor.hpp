// The sensor models the simulator casts rays with (point sensor, line profiler, touch probe) and
// the machine geometry they sit in: acquisition's own types (acquisition/sensor_model.hpp), so the
// simulation and the real mapping can never disagree.
// SPDX-License-Identifier: MIT
#pragma once

#include "scanmesh/acquisition/sensor_model.hpp"
#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::sim {

using recon::Vec3;

using acq::Calibration;
using acq::default_sensor;
using acq::measured_point;
using acq::measured_probe_point;
using acq::part_from_sensor;
using acq::SensorConfig;
using acq::SensorKind;
using acq::SensorOptics;
using acq::sensor_kind_from_string;
using acq::StagePose;
using acq::to_string;

}  // namespace scanmesh::sim
