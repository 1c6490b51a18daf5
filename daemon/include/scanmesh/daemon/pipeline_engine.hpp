// PipelineEngine: the ScanEngine over the acquisition pipeline. Each scan is a backend made by a
// BackendFactory (the simulated scanner, a journal replay, real devices), an acq::Pipeline with
// an MCAP JournalRecorder and the configured mesher, and a row in the SQLite scan catalog.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "scanmesh/acquisition/backend.hpp"
#include "scanmesh/daemon/config.hpp"
#include "scanmesh/daemon/engine.hpp"
#include "scanmesh/daemon/log.hpp"

namespace scanmesh::daemon {

/// What a backend factory is asked for: one scan's backend.
struct BackendRequest {
  /// The scan's parameters minus the engine's own (cube_mm, mesher). A factory refuses any it
  /// does not know with EngineError(bad_argument) naming "parameters.KEY".
  Parameters parameters;
  /// scan.resume_interrupted: the new journal segment's samples must come after this host time
  /// (the last sample the earlier segments hold), so the segments replay as one scan. A backend
  /// that cannot continue a scan throws EngineError(bad_state).
  std::optional<drivers::Timestamp> continue_after;
};

/// One scan's source of samples.
struct ScanSource {
  std::unique_ptr<acq::ScanBackend> backend;
  std::string description;  ///< what is scanned ("part:container", "journal:/x.mcap")
  /// Sensor samples the scan is planned to deliver (progress); 0: unknown.
  std::uint64_t planned_sensor_samples = 0;
};

/// Called on the thread that starts a scan (and once at open() with the [scan] defaults, to
/// check the configuration and list the devices). Throws ConfigError / InputError / EngineError.
using BackendFactory = std::function<ScanSource(const BackendRequest&)>;

/// `kind` is what version and status report ("sim", "replay", "devices", ...). The catalog is
/// STATE_DIR/catalog.sqlite, the journals STATE_DIR/scans/scan-ID-NAME[.SEGMENT].mcap.
std::unique_ptr<ScanEngine> make_pipeline_engine(const DaemonConfig& config, const Log& log,
                                                 std::string kind, BackendFactory factory);

}  // namespace scanmesh::daemon
