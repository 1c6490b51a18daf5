// scanmeshd's configuration: every example in config/ loads; a bad file reports every problem at
// once with the file and the key; reloads say which changes need a restart.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include "scanmesh/common/error.hpp"
#include "scanmesh/daemon/config.hpp"
#include "support/process.hpp"
#include "support/temp_dir.hpp"

using namespace scanmesh;
using namespace scanmesh::daemon;

namespace {
std::string error_of(std::string_view text,
                     const std::filesystem::path& source = "/etc/scanmesh/x.toml") {
  try {
    parse_config(text, source);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST_CASE("every daemon configuration in config/ loads", "[daemon][config]") {
  std::size_t loaded = 0;
  for (const auto& e : std::filesystem::directory_iterator(SCANMESH_SOURCE_DIR "/config")) {
    if (e.path().extension() != ".toml") continue;
    INFO(e.path());
    const DaemonConfig c = load_config(e.path());
    CHECK(c.source == e.path());
    ++loaded;
  }
  CHECK(loaded >= 1);
  const DaemonConfig sim = load_config(SCANMESH_SOURCE_DIR "/config/scanmesh-sim.toml");
  CHECK(sim.backend == "sim");
  CHECK(sim.sim.part == "container");
  CHECK(sim.sim.sensor == "point");
  CHECK(sim.sim.transport == "emulators");
  CHECK(sim.socket_path == "/run/scanmesh/control.sock");
  CHECK(sim.export_dirs == std::vector<std::filesystem::path>{"/var/lib/scanmesh/exports"});
  CHECK(std::get<std::string>(sim.scan_defaults.at("mesher")) == "incremental");
}

TEST_CASE("defaults hold when the file is empty", "[daemon][config]") {
  const DaemonConfig c = parse_config("", "/etc/scanmesh/empty.toml");
  CHECK(c.max_clients == 32);
  CHECK(c.client_output_limit_bytes == 1u << 20);
  CHECK(c.progress_interval == std::chrono::milliseconds(250));
  CHECK(c.backend == "sim");
  CHECK(c.log_level == LogLevel::kInfo);
}

TEST_CASE("every problem of a bad configuration is reported at once, with file and key",
          "[daemon][config]") {
  const std::string err = error_of(R"(
[daemon]
socket = "relative.sock"
max_clients = 0
client_output_limit_bytes = "big"
progress_interval_ms = 5
control_users = ["no-such-user-xyz"]
socket_group = "no-such-group-xyz"
log_level = "loud"
typo_key = 1

[backend]
kind = "magic"

[sim]
part = "teapot"
sensor = "sonar"
spacing_mm = -1

[colour]
x = 1
)");
  INFO(err);
  for (const char* expected : {
           "/etc/scanmesh/x.toml: daemon.socket: must be an absolute path, got 'relative.sock'",
           "/etc/scanmesh/x.toml: daemon.max_clients: must be in [1, 4096], got 0",
           "/etc/scanmesh/x.toml: daemon.client_output_limit_bytes: must be an integer",
           "/etc/scanmesh/x.toml: daemon.progress_interval_ms: must be in [10, 60000], got 5",
           "/etc/scanmesh/x.toml: daemon.control_users: no such user 'no-such-user-xyz'",
           "/etc/scanmesh/x.toml: daemon.socket_group: no such group 'no-such-group-xyz'",
           "/etc/scanmesh/x.toml: daemon.log_level: must be one of error, warning, notice, info, "
           "debug, got 'loud'",
           "/etc/scanmesh/x.toml: daemon.typo_key: unknown key",
           "/etc/scanmesh/x.toml: backend.kind: must be one of sim, replay, devices, got 'magic'",
           "/etc/scanmesh/x.toml: sim.part: unknown part 'teapot' (built-in parts: container, "
           "sphere, cylinder, steps)",
           "/etc/scanmesh/x.toml: sim.sensor: must be one of point, line, probe, got 'sonar'",
           "/etc/scanmesh/x.toml: sim.spacing_mm: must be in [0.001, 50], got -1",
           "/etc/scanmesh/x.toml: colour: unknown table",
       })
    CHECK_THAT(err, Catch::Contains(expected));
}

TEST_CASE("TOML syntax errors name the file, line and column", "[daemon][config]") {
  const std::string err = error_of("[daemon]\nmax_clients = = 3\n");
  CHECK_THAT(err, Catch::StartsWith("/etc/scanmesh/x.toml:2:"));
}

TEST_CASE("the replay and devices backends check their files before anything opens",
          "[daemon][config]") {
  test::TempDir dir;
  const std::string replay = error_of(
      "[backend]\nkind = \"replay\"\n[replay]\njournal = \"gone.mcap\"\n", dir / "d.toml");
  CHECK_THAT(replay, Catch::Contains("replay.journal: cannot read '" +
                                     (dir / "gone.mcap").string() + "': no such file"));
  CHECK_THAT(error_of("[backend]\nkind = \"replay\"\n"),
             Catch::Contains("replay.journal: is required"));
  test::spit(dir / "lkg.toml", "[sensor]\ndriver = \"no-such-driver\"\nbaud = 3\n");
  const std::string devices = error_of(
      "[backend]\nkind = \"devices\"\n[[devices]]\nrole = \"sensor\"\nconfig = \"lkg.toml\"\n",
      dir / "d.toml");
  INFO(devices);
  // The sensor file's own problems, each under the entry that names it.
  CHECK_THAT(devices, Catch::Contains("d.toml: devices[0].config: "));
  CHECK_THAT(devices, Catch::Contains("no-such-driver"));
  CHECK_THAT(devices, Catch::Contains("baud"));
}

TEST_CASE("reloads say which changes need a restart", "[daemon][config]") {
  const DaemonConfig a = parse_config("", "a.toml");
  DaemonConfig b = a;
  b.max_clients = 4;
  b.log_level = LogLevel::kDebug;
  b.export_dirs = {"/srv/out"};
  CHECK(restart_needed(a, b).empty());
  b.socket_path = "/run/other.sock";
  b.sim.part = "sphere";
  b.backend = "replay";
  CHECK(restart_needed(a, b) == std::vector<std::string>{"daemon.socket", "backend.kind", "sim"});
}
