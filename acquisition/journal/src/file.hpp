// A POSIX file descriptor owned by one object: the journal's only system calls (open, pwrite-free
// sequential writes, pread, ftruncate, fdatasync, flock), each failure turned into an error that
// names the file, the operation and errno's words.
// SPDX-License-Identifier: MIT
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>

namespace scanmesh::acq::detail {

/// The system's words for errno value `e` ("No space left on device").
std::string errno_text(int e);

class File {
 public:
  enum class Lock { kNone, kExclusive };

  File() = default;
  /// Creates a new file (O_EXCL: an existing one is refused), takes an exclusive flock and syncs
  /// the directory so the name survives a power cut. Throws JournalWriteError.
  static File create_new(const std::filesystem::path& path);
  /// Opens for reading. Throws InputError.
  static File open_read(const std::filesystem::path& path);
  /// Opens for reading and writing with an exclusive flock; throws InputError when another
  /// process holds the lock (a writer still at work) or the file cannot be opened.
  static File open_update(const std::filesystem::path& path);
  /// Adopts a descriptor (not closed on destruction).
  static File borrow(int fd, std::string name);

  File(File&& o) noexcept;
  File& operator=(File&& o) noexcept;
  File(const File&) = delete;
  File& operator=(const File&) = delete;
  ~File();

  [[nodiscard]] int fd() const noexcept { return fd_; }
  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  /// Size from fstat. Throws InputError.
  [[nodiscard]] std::uint64_t size() const;
  /// Reads exactly n bytes at offset (fewer only at the end of the file: returns the count).
  /// Throws InputError on a read error.
  std::size_t read_at(std::uint64_t offset, std::byte* dst, std::size_t n) const;
  /// Writes all of the buffers at the current position (writev, retried on short writes and
  /// EINTR). Returns 0 on success or the errno of the failure.
  [[nodiscard]] int write_all(std::span<const std::span<const std::byte>> parts) noexcept;
  /// Writes all of `bytes` at `offset` (pwrite), not moving the position. Returns 0 or errno.
  [[nodiscard]] int write_at(std::uint64_t offset, std::span<const std::byte> bytes) noexcept;
  /// Moves the write position (lseek). Returns 0 or errno.
  [[nodiscard]] int seek(std::uint64_t offset) noexcept;
  /// ftruncate; returns 0 or errno.
  [[nodiscard]] int truncate(std::uint64_t size) noexcept;
  /// fdatasync; returns 0 or errno.
  [[nodiscard]] int datasync() noexcept;
  /// Whether another open file description holds an flock on the file (a writer at work).
  [[nodiscard]] bool locked_elsewhere() const noexcept;

 private:
  File(int fd, std::string name, bool owned) : fd_(fd), name_(std::move(name)), owned_(owned) {}
  void close() noexcept;
  int fd_ = -1;
  std::string name_;
  bool owned_ = false;
};

}  // namespace scanmesh::acq::detail
