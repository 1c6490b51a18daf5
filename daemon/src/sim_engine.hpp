// The stream-playback engine behind the "sim" and "replay" back ends until the acquisition
// pipeline lands: a simulated scan (sim::Simulator over a reference part) or a recorded sample
// stream is delivered at its own pace on a worker thread, journalled as a sim stream file,
// mapped to points (sim::points_from_samples' mapping) and meshed in batches on a meshing
// thread (recon::reconstruct). Scans are catalogued by their journal files in STATE_DIR/scans.
// SPDX-License-Identifier: MIT
#pragma once

#include <memory>

#include "scanmesh/daemon/config.hpp"
#include "scanmesh/daemon/engine.hpp"
#include "scanmesh/daemon/log.hpp"

namespace scanmesh::daemon {

std::unique_ptr<ScanEngine> make_playback_engine(const DaemonConfig& config, const Log& log);

}  // namespace scanmesh::daemon
