// The daemon process around the server: opens the engine, adopts or binds the control socket,
// tells systemd READY / STATUS / RELOADING / STOPPING, pings the watchdog from the io loop,
// reloads on SIGHUP and shuts down cleanly on SIGTERM / SIGINT (STYLE §9).
// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>

#include "scanmesh/daemon/config.hpp"
#include "scanmesh/daemon/engine.hpp"
#include "scanmesh/daemon/log.hpp"

namespace scanmesh::daemon {

class Daemon {
 public:
  /// `reload` re-reads the configuration for SIGHUP (throws ConfigError when the file is bad;
  /// the running configuration then stays). `engine` is not opened yet.
  Daemon(DaemonConfig config, ScanEngine& engine, Log& log, std::string version,
         std::function<DaemonConfig()> reload);
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  /// Runs until SIGTERM / SIGINT (or request_stop). Returns the exit status: 0 after a clean
  /// shutdown, 1 when startup failed (logged).
  int run();
  /// Starts the same shutdown as SIGTERM, from any thread.
  void request_stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace scanmesh::daemon
