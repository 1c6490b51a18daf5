// scanmeshd: the scanner daemon (daemon/README.md). Runs in the foreground under systemd
// (Type=notify) or in a terminal.
// SPDX-License-Identifier: MIT
#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>

#include "scanmesh/common/error.hpp"
#include "scanmesh/daemon/config.hpp"
#include "scanmesh/daemon/daemon.hpp"
#include "scanmesh/daemon/engine_factory.hpp"
#include "scanmesh/daemon/log.hpp"

namespace {

struct Overrides {
  std::string socket;
  std::string state_dir;
};

scanmesh::daemon::DaemonConfig load(const std::string& file, const Overrides& o) {
  using scanmesh::daemon::DaemonConfig;
  DaemonConfig c = scanmesh::daemon::load_config(file);
  if (!o.socket.empty()) {
    c.socket_path = std::filesystem::absolute(o.socket);
    if (c.socket_path.string().size() > 107)
      throw scanmesh::ConfigError("--socket: longer than a Unix socket path may be (107 bytes)");
  }
  if (!o.state_dir.empty()) {
    const auto dir = std::filesystem::absolute(o.state_dir);
    // Export folders that defaulted to the state folder follow it.
    for (auto& d : c.export_dirs)
      if (d == c.state_dir / "exports") d = dir / "exports";
    c.state_dir = dir;
  }
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"scanmeshd: the scanmesh daemon (control socket, scans, meshes)"};
  std::string config_file = "/etc/scanmesh/scanmesh.toml";
  Overrides overrides;
  bool check_only = false;
  bool version = false;
  app.add_option("--config", config_file, "configuration file (TOML)")->capture_default_str();
  app.add_option("--socket", overrides.socket, "control socket path (overrides daemon.socket)");
  app.add_option("--state-dir", overrides.state_dir,
                 "folder for journals and the scan catalog (overrides daemon.state_dir)");
  bool foreground = true;
  app.add_flag("--foreground", foreground,
               "run in the foreground (always: systemd supervises the process)");
  app.add_flag("--check-config", check_only, "validate the configuration, print it and exit");
  app.add_flag("--version", version, "print the version and exit");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (version) {
    std::printf("scanmeshd %s (protocol %d.%d)\n", SCANMESH_VERSION, 1, 0);
    return 0;
  }
  // A client that goes away mid-write must not kill the daemon.
  std::signal(SIGPIPE, SIG_IGN);
  scanmesh::daemon::Log log;
  scanmesh::daemon::DaemonConfig config;
  try {
    config = load(config_file, overrides);
  } catch (const scanmesh::Error& e) {
    log.error(std::string("configuration errors:\n") + e.what());
    return 1;
  }
  log.set_level(config.log_level);
  if (check_only) {
    std::printf("%s: ok (backend %s, socket %s)\n", config_file.c_str(), config.backend.c_str(),
                config.socket_path.c_str());
    return 0;
  }
  std::unique_ptr<scanmesh::daemon::ScanEngine> engine;
  try {
    engine = scanmesh::daemon::make_engine(config, log);
  } catch (const scanmesh::Error& e) {
    log.error(std::string("cannot build the backend: ") + e.what());
    return 1;
  }
  scanmesh::daemon::Daemon daemon(config, *engine, log, SCANMESH_VERSION, [config_file, overrides] {
    return load(config_file, overrides);
  });
  return daemon.run();
}
