// The scan motion as a host sends it to a stage: absolute moves with feeds (the DevicesBackend
// runs it; the simulated scanner's plan converts to it).
// SPDX-License-Identifier: MIT
#pragma once

#include <string>
#include <vector>

#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::acq {

/// One absolute move of the scan motion.
struct ScanMove {
  drivers::StagePose to;   ///< machine coordinates (mm; the table A in rad)
  double feed_mm_min = 0;  ///< > 0: the controller's feed (a table-only move: deg/min)
  bool sensing = false;    ///< a scan line: after a pause it is run again from its start
};

/// The scan motion: moves run in order, each from where the previous one ended. A serpentine
/// raster is its lines with the steps between them; a rotary scan adds table moves.
struct ScanProgram {
  std::vector<ScanMove> moves;
  bool uses_table = false;  ///< some move turns the table (the stage needs an A axis)
  std::vector<std::string> problems() const;  ///< empty: valid
  double nominal_seconds() const;             ///< at the feeds, without acceleration
};

}  // namespace scanmesh::acq
