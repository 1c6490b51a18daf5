// The values the control protocol carries (devices, scan state and counters, scan records):
// plain structs shared by the engine interface, the server and the clients.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace scanmesh::daemon {

/// A scan parameter value as a request carries it (a JSON scalar).
using Scalar = std::variant<bool, std::int64_t, double, std::string>;
/// Named scan parameters ("part", "spacing_mm", ...), in key order.
using Parameters = std::map<std::string, Scalar, std::less<>>;

/// Wire strings: "closed", "opening", "ok", "lost", "failed".
enum class DeviceState : std::uint8_t { kClosed, kOpening, kOk, kLost, kFailed };
std::string_view to_string(DeviceState state);
std::optional<DeviceState> device_state_from_string(std::string_view word);

struct DeviceInfo {
  std::string name;    ///< the device name used in every log line
  std::string role;    ///< "sensor", "stage", "probe"
  std::string driver;  ///< registered driver name ("sim" for the simulated scanner)
  std::string port;    ///< serial path, usb:VID:PID, HOST:PORT, or "" when none
  DeviceState state = DeviceState::kClosed;
  std::string detail;         ///< why it is lost or failed; empty when ok
  std::uint64_t samples = 0;  ///< samples delivered since the daemon started
  std::uint64_t errors = 0;   ///< malformed frames, timeouts, sequence gaps
};

/// Wire strings: "idle", "running", "paused", "stopping".
enum class ScanState : std::uint8_t { kIdle, kRunning, kPaused, kStopping };
std::string_view to_string(ScanState state);
std::optional<ScanState> scan_state_from_string(std::string_view word);

/// What the running (or last) scan has done so far.
struct ScanCounters {
  std::uint64_t samples = 0;             ///< sensor samples recorded in the journal (acknowledged)
  std::uint64_t points = 0;              ///< 3D points mapped from them
  std::uint64_t triangles = 0;           ///< triangles of the current mesh
  std::uint64_t vertices = 0;            ///< vertices of the current mesh
  std::uint64_t meshing_lag_points = 0;  ///< points recorded but not yet in the mesh
  double meshing_lag_s = 0;              ///< that lag in seconds of scanning at the current rate
  std::uint64_t journal_bytes = 0;       ///< size of the scan's journal
  double rate_hz = 0;                    ///< samples per second over the last second
  std::uint64_t errors = 0;              ///< invalid samples, sequence gaps, device errors
};

struct ScanStatus {
  ScanState state = ScanState::kIdle;
  std::string reason;    ///< why paused/stopped ("operator", "device_lost: NAME", ...)
  std::int64_t id = 0;   ///< the running or last scan's catalog id, 0 when none
  std::string name;      ///< its name
  double elapsed_s = 0;  ///< scanning time so far (pauses excluded)
  double progress = -1;  ///< fraction of the planned scan done, 0..1; -1 when unknown
  ScanCounters counters;
};

/// One catalog row.
struct ScanRecord {
  std::int64_t id = 0;
  std::string name;
  /// "running", "paused", "finished", "stopped", "failed", "interrupted", "closed".
  std::string state;
  std::string started_utc;  ///< ISO 8601, e.g. "2024-05-01T10:00:00Z"
  std::string stopped_utc;  ///< empty while running
  std::string reason;       ///< why it stopped or failed
  std::uint64_t samples = 0, points = 0, triangles = 0, journal_bytes = 0;
  std::string journal;    ///< journal file path
  Parameters parameters;  ///< what it was started with (defaults merged in)
};

/// A mesh update, as counts (the mesh itself is fetched with mesh.export).
struct MeshCounts {
  std::int64_t scan = 0;
  std::uint64_t vertices = 0, triangles = 0;
  std::uint64_t added = 0, removed = 0;  ///< triangles since the previous update
};

struct VersionInfo {
  std::string daemon;  ///< scanmeshd version
  int proto_major = 0, proto_minor = 0;
  std::string backend;  ///< "sim", "devices", "replay"
};

struct StatusInfo {
  std::string daemon_state;  ///< "ready", "reloading", "stopping"
  std::string backend;
  double uptime_s = 0;
  std::uint64_t clients = 0;
  std::uint64_t protocol_errors = 0;  ///< malformed or refused requests since start
  std::vector<DeviceInfo> devices;
  ScanStatus scan;
};

struct ExportInfo {
  std::int64_t scan = 0;
  std::string path, format;
  std::uint64_t vertices = 0, triangles = 0, bytes = 0;
};

struct PreviewInfo {
  std::int64_t scan = 0;
  std::string path;
  int width_px = 0, height_px = 0;
  std::uint64_t bytes = 0;
};

}  // namespace scanmesh::daemon
