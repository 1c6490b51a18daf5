// Builds the configured ScanEngine (backend.kind): the simulated scanner ("sim"), a recorded
// stream played back as if live ("replay"), or real devices ("devices").
// SPDX-License-Identifier: MIT
#pragma once

#include <memory>

#include "scanmesh/daemon/config.hpp"
#include "scanmesh/daemon/engine.hpp"
#include "scanmesh/daemon/log.hpp"

namespace scanmesh::daemon {

/// Throws ConfigError when the backend cannot be built from this configuration.
std::unique_ptr<ScanEngine> make_engine(const DaemonConfig& config, const Log& log);

}  // namespace scanmesh::daemon
