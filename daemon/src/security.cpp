// Peer credentials and confined output paths (security.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/daemon/security.hpp"

#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <system_error>

#include "scanmesh/common/error.hpp"
#include "scanmesh/daemon/protocol.hpp"

namespace scanmesh::daemon {

PeerCredentials peer_credentials(int fd) {
  ucred cred{};
  socklen_t len = sizeof cred;
  if (::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0)
    throw Error(std::string("SO_PEERCRED: ") + std::strerror(errno));
  return {cred.pid, cred.uid, cred.gid};
}

bool may_control(const PeerCredentials& peer, const std::vector<uid_t>& control_uids) {
  if (peer.uid == 0 || peer.uid == ::geteuid()) return true;
  return std::find(control_uids.begin(), control_uids.end(), peer.uid) != control_uids.end();
}

ConfinedPath::ConfinedPath(int dir_fd, std::string name, std::filesystem::path shown)
    : dir_fd_(dir_fd), name_(std::move(name)), shown_(std::move(shown)) {}
ConfinedPath::~ConfinedPath() {
  if (dir_fd_ >= 0) ::close(dir_fd_);
}
ConfinedPath::ConfinedPath(ConfinedPath&& o) noexcept
    : dir_fd_(o.dir_fd_), name_(std::move(o.name_)), shown_(std::move(o.shown_)) {
  o.dir_fd_ = -1;
}
std::filesystem::path ConfinedPath::path() const {
  return std::filesystem::path("/proc/self/fd") / std::to_string(dir_fd_) / name_;
}

namespace {

[[noreturn]] void refuse(const std::filesystem::path& p, const std::string& why) {
  throw proto::ProtocolError(proto::errc::kPathRefused, p.string() + ": " + why);
}

/// `inner` is `outer` or below it (both canonical).
bool inside(const std::filesystem::path& inner, const std::filesystem::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i) {
    if (o->empty()) continue;  // trailing separator
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

}  // namespace

ConfinedPath confine_output(const std::filesystem::path& requested,
                            const std::vector<std::filesystem::path>& allowed) {
  if (!requested.is_absolute()) refuse(requested, "must be an absolute path");
  for (const auto& part : requested)
    if (part == "..") refuse(requested, "must not contain '..'");
  const std::string name = requested.filename().string();
  if (name.empty() || name == ".") refuse(requested, "names a folder, not a file");
  // O_PATH: no read permission needed; the folder's symlinks are resolved here, once.
  const int dir = ::open(requested.parent_path().c_str(), O_PATH | O_DIRECTORY | O_CLOEXEC);
  if (dir < 0) refuse(requested, std::string("cannot open its folder: ") + std::strerror(errno));
  struct DirGuard {
    int fd;
    ~DirGuard() {
      if (fd >= 0) ::close(fd);
    }
  } guard{dir};
  std::error_code ec;
  const std::filesystem::path real_dir =
      std::filesystem::read_symlink("/proc/self/fd/" + std::to_string(dir), ec);
  if (ec) refuse(requested, "cannot resolve its folder: " + ec.message());
  bool ok = false;
  for (const auto& a : allowed) {
    const std::filesystem::path real_allowed = std::filesystem::weakly_canonical(a, ec);
    if (!ec && inside(real_dir, real_allowed)) {
      ok = true;
      break;
    }
  }
  if (!ok) {
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a.string();
    refuse(requested, "is outside the folders the daemon may write (" + list + ")" +
                          (real_dir != requested.parent_path()
                               ? "; its folder resolves to " + real_dir.string()
                               : std::string()));
  }
  struct stat st {};
  if (::fstatat(dir, name.c_str(), &st, AT_SYMLINK_NOFOLLOW) == 0) {
    if (S_ISLNK(st.st_mode)) refuse(requested, "is a symbolic link");
    if (!S_ISREG(st.st_mode)) refuse(requested, "exists and is not a regular file");
  }
  guard.fd = -1;
  return ConfinedPath(dir, name, real_dir / name);
}

}  // namespace scanmesh::daemon
