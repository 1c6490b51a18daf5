// The stderr logger with syslog priority prefixes (log.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/daemon/log.hpp"

#include <unistd.h>

#include <cerrno>
#include <string>

namespace scanmesh::daemon {

void Log::write(LogLevel level, std::string_view message) const {
  if (!enabled(level)) return;
  std::string line;
  line.reserve(message.size() + 5);
  line += '<';
  line += static_cast<char>('0' + static_cast<int>(level));
  line += '>';
  // One event, one line: embedded newlines (multi-line config errors) become separate entries
  // with the same priority.
  for (char c : message) {
    line += c;
    if (c == '\n') {
      line += '<';
      line += static_cast<char>('0' + static_cast<int>(level));
      line += '>';
    }
  }
  line += '\n';
  const char* p = line.data();
  std::size_t left = line.size();
  while (left > 0) {
    const ssize_t n = ::write(fd_, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;  // nowhere to log to: nothing sensible left to do
    p += n;
    left -= static_cast<std::size_t>(n);
  }
}

void Log::device(LogLevel level, std::string_view device, std::string_view message) const {
  if (!enabled(level)) return;
  std::string m = "device ";
  m += device;
  m += ": ";
  m += message;
  write(level, m);
}

}  // namespace scanmesh::daemon
