// libsystemd glue: sd_notify, sd_watchdog_enabled, sd_listen_fds + sd_is_socket_unix.
// SPDX-License-Identifier: MIT
#include "scanmesh/daemon/systemd.hpp"

#include <fcntl.h>
#include <systemd/sd-daemon.h>
#include <time.h>
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <string>

#include "scanmesh/common/error.hpp"
#include "scanmesh/daemon/log.hpp"

namespace scanmesh::daemon {

namespace {
/// STATUS= is one line: newlines would end it early.
std::string one_line(std::string_view s) {
  std::string out(s);
  for (char& c : out)
    if (c == '\n') c = ' ';
  return out;
}
}  // namespace

void Notifier::send(std::string_view text) const {
  const std::string s(text);
  ::sd_notify(0, s.c_str());
}

void Notifier::ready(std::string_view status) const { send("READY=1\nSTATUS=" + one_line(status)); }

void Notifier::reloading() const {
  // systemd 253+ wants MONOTONIC_USEC with RELOADING=1 (Type=notify-reload); older ones ignore it.
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  const std::uint64_t usec = static_cast<std::uint64_t>(ts.tv_sec) * 1000000u +
                             static_cast<std::uint64_t>(ts.tv_nsec) / 1000u;
  send("RELOADING=1\nMONOTONIC_USEC=" + std::to_string(usec));
}

void Notifier::status(std::string_view status) const { send("STATUS=" + one_line(status)); }

void Notifier::stopping(std::string_view status) const {
  send("STOPPING=1\nSTATUS=" + one_line(status));
}

void Notifier::watchdog() const { send("WATCHDOG=1"); }

std::optional<std::chrono::microseconds> watchdog_interval() {
  std::uint64_t usec = 0;
  if (::sd_watchdog_enabled(0, &usec) > 0 && usec > 0) return std::chrono::microseconds(usec);
  return std::nullopt;
}

std::optional<int> take_activated_socket(const std::filesystem::path& path, const Log& log) {
  const int n = ::sd_listen_fds(1);
  if (n < 0)
    throw ConfigError(std::string("socket activation: sd_listen_fds failed: ") + std::strerror(-n));
  if (n == 0) return std::nullopt;
  std::optional<int> chosen;
  for (int fd = SD_LISTEN_FDS_START; fd < SD_LISTEN_FDS_START + n; ++fd) {
    const int r = ::sd_is_socket_unix(fd, SOCK_STREAM, 1, path.c_str(), 0);
    if (r > 0 && !chosen) {
      const int flags = ::fcntl(fd, F_GETFD);
      if (flags < 0 || ::fcntl(fd, F_SETFD, flags | FD_CLOEXEC) < 0)
        throw ConfigError("socket activation: cannot set FD_CLOEXEC on fd " + std::to_string(fd));
      chosen = fd;
      continue;
    }
    log.warning("socket activation: fd " + std::to_string(fd) +
                " is not a listening Unix stream socket at " + path.string() + ": closed");
    ::close(fd);
  }
  if (!chosen)
    throw ConfigError("socket activation: " + std::to_string(n) +
                      " socket(s) passed, none is a listening Unix stream socket at " +
                      path.string() + " (check ListenStream= against daemon.socket)");
  return chosen;
}

}  // namespace scanmesh::daemon
