// The journal's POSIX file wrapper (see file.hpp).
// SPDX-License-Identifier: MIT
#include "file.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <vector>

#include "scanmesh/acquisition/mcap.hpp"

namespace scanmesh::acq::detail {

std::string errno_text(int e) {
  char buf[256];
  // GNU strerror_r returns the message (possibly not in buf).
  return ::strerror_r(e, buf, sizeof buf);
}

namespace {

void sync_directory_of(const std::filesystem::path& path) {
  std::filesystem::path dir = path.parent_path();
  if (dir.empty()) dir = ".";
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;  // best effort: the file itself is fine
  (void)::fsync(fd);
  ::close(fd);
}

}  // namespace

File File::create_new(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int e = errno;
    throw JournalWriteError("journal " + path.string() + ": cannot create: " + errno_text(e) +
                                (e == EEXIST ? " (a journal is never overwritten)" : ""),
                            e);
  }
  File f(fd, path.string(), true);
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    throw JournalWriteError("journal " + path.string() + ": cannot lock: " + errno_text(e), e);
  }
  sync_directory_of(path);
  return f;
}

File File::open_read(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    throw InputError("journal " + path.string() + ": cannot open: " + errno_text(errno));
  }
  File f(fd, path.string(), true);
  struct stat st {};
  if (::fstat(fd, &st) == 0 && !S_ISREG(st.st_mode)) {
    throw InputError("journal " + path.string() + ": not a regular file");
  }
  return f;
}

File File::open_update(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) {
    throw InputError("journal " + path.string() +
                     ": cannot open for writing: " + errno_text(errno));
  }
  File f(fd, path.string(), true);
  struct stat st {};
  if (::fstat(fd, &st) == 0 && !S_ISREG(st.st_mode)) {
    throw InputError("journal " + path.string() + ": not a regular file");
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    if (e == EWOULDBLOCK) {
      throw InputError("journal " + path.string() +
                       ": another process is writing it (it holds the journal's lock); stop "
                       "that scan first");
    }
    throw InputError("journal " + path.string() + ": cannot lock: " + errno_text(e));
  }
  return f;
}

File File::borrow(int fd, std::string name) { return File(fd, std::move(name), false); }

File::File(File&& o) noexcept : fd_(o.fd_), name_(std::move(o.name_)), owned_(o.owned_) {
  o.fd_ = -1;
  o.owned_ = false;
}

File& File::operator=(File&& o) noexcept {
  if (this != &o) {
    close();
    fd_ = o.fd_;
    name_ = std::move(o.name_);
    owned_ = o.owned_;
    o.fd_ = -1;
    o.owned_ = false;
  }
  return *this;
}

File::~File() { close(); }

void File::close() noexcept {
  if (owned_ && fd_ >= 0) ::close(fd_);
  fd_ = -1;
  owned_ = false;
}

std::uint64_t File::size() const {
  struct stat st {};
  if (::fstat(fd_, &st) != 0) {
    throw InputError("journal " + name_ + ": cannot stat: " + errno_text(errno));
  }
  return static_cast<std::uint64_t>(st.st_size);
}

std::size_t File::read_at(std::uint64_t offset, std::byte* dst, std::size_t n) const {
  std::size_t done = 0;
  while (done < n) {
    const ssize_t r = ::pread(fd_, dst + done, n - done, static_cast<off_t>(offset + done));
    if (r < 0) {
      if (errno == EINTR) continue;
      throw InputError("journal " + name_ + ": read of " + std::to_string(n) + " bytes at byte " +
                       std::to_string(offset) + " failed: " + errno_text(errno));
    }
    if (r == 0) break;  // end of file
    done += static_cast<std::size_t>(r);
  }
  return done;
}

int File::write_all(std::span<const std::span<const std::byte>> parts) noexcept {
  std::array<iovec, 8> iov{};
  std::size_t count = 0;
  for (const auto& p : parts) {
    if (p.empty()) continue;
    if (count == iov.size()) return EINVAL;
    iov[count++] = iovec{const_cast<std::byte*>(p.data()), p.size()};
  }
  std::size_t first = 0;
  while (first < count) {
    const ssize_t w = ::writev(fd_, iov.data() + first, static_cast<int>(count - first));
    if (w < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    if (w == 0) return EIO;
    auto left = static_cast<std::size_t>(w);
    while (first < count && left >= iov[first].iov_len) {
      left -= iov[first].iov_len;
      ++first;
    }
    if (first < count) {
      iov[first].iov_base = static_cast<char*>(iov[first].iov_base) + left;
      iov[first].iov_len -= left;
    }
  }
  return 0;
}

int File::write_at(std::uint64_t offset, std::span<const std::byte> bytes) noexcept {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t w =
        ::pwrite(fd_, bytes.data() + done, bytes.size() - done, static_cast<off_t>(offset + done));
    if (w < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    if (w == 0) return EIO;
    done += static_cast<std::size_t>(w);
  }
  return 0;
}

int File::seek(std::uint64_t offset) noexcept {
  return ::lseek(fd_, static_cast<off_t>(offset), SEEK_SET) < 0 ? errno : 0;
}

int File::truncate(std::uint64_t size) noexcept {
  while (::ftruncate(fd_, static_cast<off_t>(size)) != 0) {
    if (errno != EINTR) return errno;
  }
  return 0;
}

int File::datasync() noexcept {
  while (::fdatasync(fd_) != 0) {
    if (errno != EINTR) return errno;
  }
  return 0;
}

bool File::locked_elsewhere() const noexcept {
  if (::flock(fd_, LOCK_SH | LOCK_NB) != 0) return errno == EWOULDBLOCK;
  ::flock(fd_, LOCK_UN);
  return false;
}

}  // namespace scanmesh::acq::detail
