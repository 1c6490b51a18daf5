// scanmeshd's configuration: one TOML file (config/scanmesh-sim.toml is the example), parsed
// into plain structs and validated whole before any device opens.
// SPDX-License-Identifier: MIT
#pragma once

#include <sys/types.h>

#include <chrono>
#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/daemon/messages.hpp"

namespace scanmesh::daemon {

/// syslog priorities used by the logger (<N> prefixes on stderr).
enum class LogLevel : int { kError = 3, kWarning = 4, kNotice = 5, kInfo = 6, kDebug = 7 };

/// [sim]: the simulated scanner scanning a reference part (backend = "sim").
struct SimBackendConfig {
  std::string part = "container";   ///< built-in part (sim::part_names()); or:
  std::filesystem::path mesh;       ///< an STL/PLY/OBJ to scan instead (relative: to the file)
  std::string sensor = "point";     ///< "point", "line" or "probe"
  std::string path = "serpentine";  ///< "raster", "serpentine", "rotary", "views"
  double spacing_mm = 0.5;          ///< along-line sample spacing, mm, (0, 50]
  double line_spacing_mm = 0;       ///< between lines, mm, >= 0 (0: the path's default)
  double speed_mm_s = 20;           ///< line speed, mm/s, (0, 5000]: rate = speed / spacing
  double noise_mm = 0.01;           ///< Gaussian range noise, mm, [0, 5]
  std::int64_t seed = 1;            ///< noise seed, >= 0
  std::int64_t views = 4;           ///< table angles of the "views" path, 1..360
  std::int64_t profile_points = 200;  ///< points per profile (line sensor), 1..65536
  /// Playback speed relative to the scan's own time, [0, 10000]: 1 live, 0 as fast as possible.
  double playback = 1;
  /// A simulated fault: the sensor drops off this far into each scan (scan time, s; 0: never,
  /// [0, 86400]) for `sensor_loss_s` (s, (0, 60], default 0.3), then comes back.
  double sensor_loss_at_s = 0;
  double sensor_loss_s = 0.3;
  /// "in-process" (default): the simulator delivers its samples straight into the pipeline
  /// (deterministic). "emulators": the simulated scanner drives the GRBL and ILD1420 protocol
  /// emulators on ptys and the real drivers read them (a point sensor only; live pace, so
  /// `playback` and the sensor_loss fault do not apply).
  std::string transport = "in-process";
};

/// [replay]: a recorded scan journal played back as if live (backend = "replay").
struct ReplayBackendConfig {
  std::filesystem::path journal;  ///< MCAP scan journal (relative: to the config file)
  double playback = 1;            ///< as in [sim]
};

/// One [[devices]] entry (backend = "devices"): a sensor configuration file (drivers/).
struct DeviceEntry {
  std::string role = "sensor";   ///< "sensor" or "stage"
  std::filesystem::path config;  ///< config/sensors/*.toml style file (relative: to this file)
};

struct DaemonConfig {
  std::filesystem::path source;  ///< the file it came from ("" for defaults)

  // [daemon]: what needs a restart to change is marked (restart).
  std::filesystem::path socket_path = "/run/scanmesh/control.sock";  ///< (restart)
  std::string socket_group;  ///< group of a socket the daemon binds; "" keep (restart)
  std::filesystem::path state_dir = "/var/lib/scanmesh";  ///< journals, scans (restart)
  std::size_t max_clients = 32;                           ///< connected clients at once, 1..4096
  /// Unsent output one client may hold before it is dropped, bytes, 64 KiB..1 GiB; default 1 MiB.
  std::size_t client_output_limit_bytes = 1u << 20;
  std::chrono::milliseconds progress_interval{250};  ///< progress events, 10..60000 ms
  std::vector<std::string> control_users;  ///< may change state and write files (root always)
  std::vector<uid_t> control_uids;         ///< control_users resolved at load
  /// Folders mesh.export and mesh.preview may write into (default: STATE_DIR/exports).
  std::vector<std::filesystem::path> export_dirs;
  LogLevel log_level = LogLevel::kInfo;  ///< "error", "warning", "notice", "info", "debug"

  std::string backend = "sim";       ///< "sim", "replay" or "devices" (restart)
  SimBackendConfig sim;              ///< (restart)
  ReplayBackendConfig replay;        ///< (restart)
  std::vector<DeviceEntry> devices;  ///< (restart)

  /// [scan]: defaults merged under every scan.start's parameters.
  Parameters scan_defaults;
};

/// Parses TOML text. Reports every problem at once: throws ConfigError whose message has one
/// line per problem, each "<source>: <table.key>: what is wrong" (or "<source>:LINE:COL: ..."
/// for TOML syntax), unknown keys included.
DaemonConfig parse_config(std::string_view toml_text, const std::filesystem::path& source);
DaemonConfig load_config(const std::filesystem::path& file);

/// The keys whose change needs a restart, as "table.key", comparing a reload with the running
/// configuration.
std::vector<std::string> restart_needed(const DaemonConfig& running, const DaemonConfig& loaded);

std::string_view to_string(LogLevel level);

}  // namespace scanmesh::daemon
