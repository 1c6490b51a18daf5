// Back-end selection by configuration alone (engine_factory.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/daemon/engine_factory.hpp"

#include "scanmesh/common/error.hpp"
#include "sim_engine.hpp"

namespace scanmesh::daemon {

std::unique_ptr<ScanEngine> make_engine(const DaemonConfig& config, const Log& log) {
  if (config.backend == "sim" || config.backend == "replay")
    return make_playback_engine(config, log);
  if (config.backend == "devices")
    throw ConfigError(config.source.string() +
                      ": backend.kind: \"devices\" needs the acquisition pipeline (issue 54), "
                      "which this build does not have yet; use \"sim\" or \"replay\"");
  throw ConfigError(config.source.string() + ": backend.kind: unknown backend '" + config.backend +
                    "'");
}

}  // namespace scanmesh::daemon
