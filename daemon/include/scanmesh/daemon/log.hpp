// The daemon's logger: one line per event on stderr with a syslog priority prefix ("<4>..."),
// which journald turns into the entry's priority. One object, passed by reference (no global).
// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <string_view>

#include "scanmesh/daemon/config.hpp"

namespace scanmesh::daemon {

class Log {
 public:
  /// Writes to `fd` (stderr by default). Thread-safe: each line is one write(2).
  explicit Log(LogLevel level = LogLevel::kInfo, int fd = 2) : level_(level), fd_(fd) {}

  void set_level(LogLevel level) { level_ = level; }
  bool enabled(LogLevel level) const {
    return static_cast<int>(level) <= static_cast<int>(level_.load());
  }

  void write(LogLevel level, std::string_view message) const;
  /// A device line: "<N>device NAME: message" (STYLE §9.1: the device name in every device line).
  void device(LogLevel level, std::string_view device, std::string_view message) const;

  void error(std::string_view m) const { write(LogLevel::kError, m); }
  void warning(std::string_view m) const { write(LogLevel::kWarning, m); }
  void notice(std::string_view m) const { write(LogLevel::kNotice, m); }
  void info(std::string_view m) const { write(LogLevel::kInfo, m); }
  void debug(std::string_view m) const { write(LogLevel::kDebug, m); }

 private:
  std::atomic<LogLevel> level_;
  int fd_;
};

}  // namespace scanmesh::daemon
