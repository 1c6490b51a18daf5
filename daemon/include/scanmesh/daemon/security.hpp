// Who may do what on the control socket (SO_PEERCRED), and where files may be written
// (export paths confined to configured folders, no ".." and no symlink escape).
// SPDX-License-Identifier: MIT
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

namespace scanmesh::daemon {

/// The connecting process, from SO_PEERCRED at accept time.
struct PeerCredentials {
  pid_t pid = 0;
  uid_t uid = static_cast<uid_t>(-1);
  gid_t gid = static_cast<gid_t>(-1);
};

/// SO_PEERCRED of a connected Unix socket. Throws Error when the kernel refuses.
PeerCredentials peer_credentials(int fd);

/// Commands that change state or write files: root, the daemon's own user, and `control_uids`.
bool may_control(const PeerCredentials& peer, const std::vector<uid_t>& control_uids);

/// An output file name resolved inside an allowed folder, with that folder held open: writing
/// through path() goes to the folder that was checked even if a directory on the way is swapped
/// for a symlink afterwards (/proc/self/fd/N/NAME).
class ConfinedPath {
 public:
  ConfinedPath(int dir_fd, std::string name, std::filesystem::path shown);
  ~ConfinedPath();
  ConfinedPath(const ConfinedPath&) = delete;
  ConfinedPath& operator=(const ConfinedPath&) = delete;
  ConfinedPath(ConfinedPath&& o) noexcept;
  ConfinedPath& operator=(ConfinedPath&&) = delete;

  /// The path to open for writing (through the held directory descriptor).
  std::filesystem::path path() const;
  /// The real path, for replies and logs.
  const std::filesystem::path& shown() const { return shown_; }

 private:
  int dir_fd_;
  std::string name_;
  std::filesystem::path shown_;
};

/// Checks `requested` (absolute; no ".." component; its folder, symlinks resolved, inside one of
/// `allowed` after resolving theirs; the file itself not a symlink or a folder) and opens its
/// folder. Throws ProtocolError(path_refused) saying why.
ConfinedPath confine_output(const std::filesystem::path& requested,
                            const std::vector<std::filesystem::path>& allowed);

}  // namespace scanmesh::daemon
