// Mesh and point writers (.stl binary/ascii, .ply binary little endian, .obj, .xyz). Every file is
// written to `<target>.tmp.<pid>` beside the target, synced, and renamed into place.
// SPDX-License-Identifier: MIT
#include <fcntl.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "detail.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"

namespace scanmesh::meshio {
namespace {

[[noreturn]] void fail_write(const std::filesystem::path& target, std::string_view why) {
  throw OutputError("cannot write " + target.string() + ": " + std::string(why));
}

/// A buffered output file that only appears under its final name after commit(). Until then the
/// data lives in `<target>.tmp.<pid>`, which the destructor removes if commit() was not reached.
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path target)
      : target_(std::move(target)), temp_(target_.string() + ".tmp." + std::to_string(::getpid())) {
    fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd_ < 0) fail_write(target_, std::strerror(errno));
    buffer_.reserve(kBufferSize);
  }
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile() {
    if (fd_ >= 0) ::close(fd_);
    if (!committed_) ::unlink(temp_.c_str());
  }

  void append(std::string_view s) {
    buffer_.append(s);
    if (buffer_.size() >= kBufferSize) flush();
  }
  void append_bytes(const void* p, std::size_t n) {
    append(std::string_view(static_cast<const char*>(p), n));
  }

  /// Writes the rest, syncs, closes and renames; throws OutputError on any failure.
  void commit() {
    flush();
    if (::fsync(fd_) != 0) fail_errno();
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) fail_errno();
    std::error_code ec;
    std::filesystem::rename(temp_, target_, ec);
    if (ec) fail_write(target_, ec.message());
    committed_ = true;
    // Make the rename itself durable; failing to sync the directory does not undo the write.
    const std::filesystem::path dir = target_.has_parent_path() ? target_.parent_path() : ".";
    const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd >= 0) {
      ::fsync(dfd);
      ::close(dfd);
    }
  }

 private:
  static constexpr std::size_t kBufferSize = 1 << 20;

  [[noreturn]] void fail_errno() { fail_write(target_, std::strerror(errno)); }

  void flush() {
    std::size_t done = 0;
    while (done < buffer_.size()) {
      const ssize_t n = ::write(fd_, buffer_.data() + done, buffer_.size() - done);
      if (n < 0) {
        if (errno == EINTR) continue;
        fail_errno();
      }
      if (n == 0) fail_write(target_, "write returned 0");
      done += static_cast<std::size_t>(n);
    }
    buffer_.clear();
  }

  std::filesystem::path target_;
  std::filesystem::path temp_;
  int fd_ = -1;
  bool committed_ = false;
  std::string buffer_;
};

/// Appends `v` as %.9g would print it (9 significant digits round-trip a float), or with 17
/// (round-trip a double) when `digits` says so.
void append_number(std::string& out, double v, int digits = 9) {
  char buf[40];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, digits);
  out.append(buf, r.ptr);
}

void append_u32_le(std::string& out, std::uint32_t v) {
  if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap32(v);
  out.append(reinterpret_cast<const char*>(&v), 4);
}

void append_f32_le(std::string& out, double v) {
  append_u32_le(out, std::bit_cast<std::uint32_t>(static_cast<float>(v)));
}

void append_f64_le(std::string& out, double v) {
  auto u = std::bit_cast<std::uint64_t>(v);
  if constexpr (std::endian::native == std::endian::big) u = __builtin_bswap64(u);
  out.append(reinterpret_cast<const char*>(&u), 8);
}

Eigen::Vector3d facet_normal(const recon::Mesh& mesh, const recon::Triangle& t) {
  const Eigen::Vector3d& a = mesh.vertices[t[0]];
  const Eigen::Vector3d n = (mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a);
  const double len = n.norm();
  return len > 0.0 && std::isfinite(len) ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

void check_mesh(const recon::Mesh& mesh, const std::filesystem::path& file) {
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    for (const std::uint32_t v : mesh.triangles[i]) {
      if (v >= mesh.vertices.size()) {
        fail_write(file, "triangle " + std::to_string(i) + " uses vertex " + std::to_string(v) +
                             " but the mesh has " + std::to_string(mesh.vertices.size()) +
                             " vertices");
      }
    }
  }
}

// Small records are collected in `chunk` and handed to the file in blocks.
constexpr std::size_t kChunk = 1 << 16;

void write_stl_binary(const recon::Mesh& mesh, AtomicFile& out, const std::filesystem::path& file) {
  if (mesh.triangles.size() > std::numeric_limits<std::uint32_t>::max()) {
    fail_write(file, "binary STL holds at most 2^32-1 triangles");
  }
  std::string chunk;
  // The header must not start with "solid", or readers may take the file for ascii STL.
  std::string header = "binary STL written by scanmesh";
  header.resize(80, ' ');
  chunk.append(header);
  append_u32_le(chunk, static_cast<std::uint32_t>(mesh.triangles.size()));
  for (const recon::Triangle& t : mesh.triangles) {
    const Eigen::Vector3d n = facet_normal(mesh, t);
    for (int k = 0; k < 3; ++k) append_f32_le(chunk, n[k]);
    for (const std::uint32_t v : t) {
      for (int k = 0; k < 3; ++k) append_f32_le(chunk, mesh.vertices[v][k]);
    }
    chunk.append(2, '\0');  // attribute byte count
    if (chunk.size() >= kChunk) {
      out.append(chunk);
      chunk.clear();
    }
  }
  out.append(chunk);
}

void write_stl_ascii(const recon::Mesh& mesh, AtomicFile& out, bool as_double) {
  std::string chunk = "solid scanmesh\n";
  auto vec = [&chunk, as_double](const Eigen::Vector3d& v) {
    for (int k = 0; k < 3; ++k) {
      chunk.push_back(' ');
      append_number(chunk, v[k], as_double ? 17 : 9);
    }
    chunk.push_back('\n');
  };
  for (const recon::Triangle& t : mesh.triangles) {
    chunk.append("  facet normal");
    vec(facet_normal(mesh, t));
    chunk.append("    outer loop\n");
    for (const std::uint32_t v : t) {
      chunk.append("      vertex");
      vec(mesh.vertices[v]);
    }
    chunk.append("    endloop\n  endfacet\n");
    if (chunk.size() >= kChunk) {
      out.append(chunk);
      chunk.clear();
    }
  }
  chunk.append("endsolid scanmesh\n");
  out.append(chunk);
}

void write_ply(const recon::Mesh& mesh, AtomicFile& out, const std::filesystem::path& file,
               bool as_double) {
  if (mesh.vertices.size() > std::numeric_limits<std::uint32_t>::max() ||
      mesh.triangles.size() > std::numeric_limits<std::uint32_t>::max()) {
    fail_write(file, "too many vertices or triangles for this writer");
  }
  const std::string type = as_double ? "double" : "float";
  std::string chunk =
      "ply\nformat binary_little_endian 1.0\ncomment written by scanmesh\nelement vertex " +
      std::to_string(mesh.vertices.size()) + "\nproperty " + type + " x\nproperty " + type +
      " y\nproperty " + type + " z\nelement face " + std::to_string(mesh.triangles.size()) +
      "\nproperty list uchar " +
      (mesh.vertices.size() > std::numeric_limits<std::int32_t>::max() ? "uint" : "int") +
      " vertex_indices\nend_header\n";
  for (const Eigen::Vector3d& v : mesh.vertices) {
    for (int k = 0; k < 3; ++k) {
      if (as_double) {
        append_f64_le(chunk, v[k]);
      } else {
        append_f32_le(chunk, v[k]);
      }
    }
    if (chunk.size() >= kChunk) {
      out.append(chunk);
      chunk.clear();
    }
  }
  for (const recon::Triangle& t : mesh.triangles) {
    chunk.push_back('\3');
    for (const std::uint32_t v : t) append_u32_le(chunk, v);
    if (chunk.size() >= kChunk) {
      out.append(chunk);
      chunk.clear();
    }
  }
  out.append(chunk);
}

void write_obj(const recon::Mesh& mesh, AtomicFile& out, bool as_double) {
  std::string chunk = "# written by scanmesh\n";
  for (const Eigen::Vector3d& v : mesh.vertices) {
    chunk.push_back('v');
    for (int k = 0; k < 3; ++k) {
      chunk.push_back(' ');
      append_number(chunk, v[k], as_double ? 17 : 9);
    }
    chunk.push_back('\n');
    if (chunk.size() >= kChunk) {
      out.append(chunk);
      chunk.clear();
    }
  }
  for (const recon::Triangle& t : mesh.triangles) {
    chunk.push_back('f');
    for (const std::uint32_t v : t) {
      chunk.push_back(' ');
      chunk.append(std::to_string(std::uint64_t{v} + 1));
    }
    chunk.push_back('\n');
    if (chunk.size() >= kChunk) {
      out.append(chunk);
      chunk.clear();
    }
  }
  out.append(chunk);
}

}  // namespace

bool float_holds(const recon::Mesh& mesh) {
  double extent = 0, edges = 0;
  for (const Eigen::Vector3d& v : mesh.vertices) extent = std::max(extent, v.cwiseAbs().maxCoeff());
  std::size_t counted = 0;
  for (const recon::Triangle& t : mesh.triangles) {
    if (t[0] >= mesh.vertices.size() || t[1] >= mesh.vertices.size()) continue;
    edges += (mesh.vertices[t[1]] - mesh.vertices[t[0]]).norm();
    ++counted;
  }
  if (counted == 0 || !(edges > 0)) return true;
  return 0x1.0p-24 * extent <= 1e-4 * edges / static_cast<double>(counted);
}

bool writes_mesh_extension(const std::filesystem::path& file) {
  const std::string ext = detail::lower_extension(file);
  return ext == ".stl" || ext == ".ply" || ext == ".obj";
}

WriteReport write_mesh(const recon::Mesh& mesh, const std::filesystem::path& file,
                       const WriteOptions& options) {
  const std::string ext = detail::lower_extension(file);
  if (!writes_mesh_extension(file)) {
    fail_write(file, "unknown mesh extension '" + ext + "' (use .stl, .ply or .obj)");
  }
  check_mesh(mesh, file);
  const bool as_double = !float_holds(mesh);
  WriteReport report;
  AtomicFile out(file);
  if (ext == ".stl") {
    if (options.ascii_stl) {
      write_stl_ascii(mesh, out, as_double);
    } else {
      write_stl_binary(mesh, out, file);
      report.float_rounds_mesh = as_double;
    }
  } else if (ext == ".ply") {
    write_ply(mesh, out, file, as_double);
  } else {
    write_obj(mesh, out, as_double);
  }
  out.commit();
  return report;
}

bool writes_points_extension(const std::filesystem::path& file) {
  const std::string ext = detail::lower_extension(file);
  return ext == ".xyz" || ext == ".txt" || ext == ".asc";
}

void write_points_xyz(const std::vector<recon::Vec3>& points, const std::filesystem::path& file) {
  if (!writes_points_extension(file)) {
    fail_write(file, "unknown point file extension '" + detail::lower_extension(file) +
                         "' (use .xyz, .txt or .asc)");
  }
  AtomicFile out(file);
  std::string chunk;
  for (const recon::Vec3& p : points) {
    for (int k = 0; k < 3; ++k) {
      if (k > 0) chunk.push_back(' ');
      append_number(chunk, p[k]);
    }
    chunk.push_back('\n');
    if (chunk.size() >= kChunk) {
      out.append(chunk);
      chunk.clear();
    }
  }
  out.append(chunk);
  out.commit();
}

}  // namespace scanmesh::meshio
