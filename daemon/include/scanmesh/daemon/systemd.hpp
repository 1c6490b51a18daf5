// systemd integration through libsystemd: sd_notify messages, the watchdog interval, and
// adopting a socket passed by socket activation (STYLE §9.3). With no NOTIFY_SOCKET, no
// WATCHDOG_USEC and no LISTEN_FDS everything is a no-op, so the same binary runs in a terminal.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <filesystem>
#include <optional>
#include <string_view>

namespace scanmesh::daemon {

class Log;

/// sd_notify(3) wrapper. Messages are sent as given; failures are ignored (systemd may be gone).
class Notifier {
 public:
  void ready(std::string_view status) const;     ///< READY=1 + STATUS=
  void reloading() const;                        ///< RELOADING=1 + MONOTONIC_USEC=
  void status(std::string_view status) const;    ///< STATUS=
  void stopping(std::string_view status) const;  ///< STOPPING=1 + STATUS=
  void watchdog() const;                         ///< WATCHDOG=1
  void send(std::string_view text) const;
};

/// The watchdog interval when systemd asked for pings (WATCHDOG_USEC set and WATCHDOG_PID absent
/// or ours; sd_watchdog_enabled), otherwise nullopt.
std::optional<std::chrono::microseconds> watchdog_interval();

/// Socket activation: when LISTEN_PID is ours, takes the passed descriptors (sd_listen_fds,
/// which unsets LISTEN_*), keeps the one that is a listening AF_UNIX stream socket bound to
/// `path` (sd_is_socket_unix: type, SO_ACCEPTCONN, family and path; never trusting the order),
/// sets FD_CLOEXEC on it and closes the others with a warning. Returns its descriptor, or
/// nullopt when the process was not socket-activated. Throws ConfigError when descriptors were
/// passed but none matches.
std::optional<int> take_activated_socket(const std::filesystem::path& path, const Log& log);

}  // namespace scanmesh::daemon
