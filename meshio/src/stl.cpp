// STL reader (binary and ascii). STL stores every facet with its own three corners, so exactly
// coincident corners are merged into shared vertices to give an indexed mesh.
// SPDX-License-Identifier: MIT
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <string>
#include <unordered_map>

#include "detail.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"

namespace scanmesh::meshio {
namespace {

using detail::fail_byte;
using detail::fail_line;

constexpr std::size_t kBinaryHeader = 84;  ///< 80-byte header + u32 triangle count
constexpr std::size_t kBinaryRecord = 50;  ///< normal, 3 corners (12 floats), u16 attribute

/// Exact bit pattern of a corner; -0 is folded into +0 because they are the same position.
struct CornerKey {
  std::array<std::uint64_t, 3> bits;
  bool operator==(const CornerKey&) const = default;
};

struct CornerHash {
  std::size_t operator()(const CornerKey& k) const {
    std::uint64_t h = 0x9e3779b97f4a7c15ULL;
    for (const std::uint64_t b : k.bits) {
      h ^= b + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
      h *= 0xff51afd7ed558ccdULL;
      h ^= h >> 33;
    }
    return static_cast<std::size_t>(h);
  }
};

/// Collects corners into unique vertices, keyed on their exact bits.
class VertexMerger {
 public:
  VertexMerger(recon::Mesh& mesh, std::size_t expected_corners) : mesh_(mesh) {
    index_.reserve(expected_corners / 2 + 16);
    mesh_.vertices.reserve(expected_corners / 4 + 16);
  }

  std::uint32_t add(double x, double y, double z) {
    // Adding +0.0 turns -0.0 into +0.0 and leaves every other value unchanged.
    const CornerKey key{{std::bit_cast<std::uint64_t>(x + 0.0),
                         std::bit_cast<std::uint64_t>(y + 0.0),
                         std::bit_cast<std::uint64_t>(z + 0.0)}};
    const auto next = static_cast<std::uint32_t>(mesh_.vertices.size());
    const auto [it, inserted] = index_.try_emplace(key, next);
    if (inserted) mesh_.vertices.emplace_back(x, y, z);
    return it->second;
  }

 private:
  recon::Mesh& mesh_;
  std::unordered_map<CornerKey, std::uint32_t, CornerHash> index_;
};

float read_f32_le(const unsigned char* p) {
  std::uint32_t u;
  std::memcpy(&u, p, 4);
  if constexpr (std::endian::native == std::endian::big) u = __builtin_bswap32(u);
  return std::bit_cast<float>(u);
}

recon::Mesh parse_binary(std::string_view bytes, std::string_view name, std::size_t count) {
  recon::Mesh mesh;
  mesh.triangles.reserve(count);
  VertexMerger merger(mesh, 3 * count);
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  for (std::size_t t = 0; t < count; ++t) {
    const std::size_t at = kBinaryHeader + t * kBinaryRecord;
    recon::Triangle tri{};
    for (std::size_t c = 0; c < 3; ++c) {
      const unsigned char* p = data + at + 12 + 12 * c;  // the stored normal is recomputed later
      const float x = read_f32_le(p);
      const float y = read_f32_le(p + 4);
      const float z = read_f32_le(p + 8);
      if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
        fail_byte(name, at + 12 + 12 * c,
                  "facet " + std::to_string(t) + " has a non-finite coordinate");
      }
      tri[c] = merger.add(x, y, z);
    }
    mesh.triangles.push_back(tri);
  }
  return mesh;
}

bool starts_with_solid(std::string_view bytes) {
  std::size_t i = 0;
  while (i < bytes.size() && (detail::is_blank(bytes[i]) || bytes[i] == '\n')) ++i;
  return bytes.size() - i >= 5 && detail::iequals(bytes.substr(i, 5), "solid") &&
         (bytes.size() - i == 5 || detail::is_blank(bytes[i + 5]) || bytes[i + 5] == '\n');
}

recon::Mesh parse_ascii(std::string_view text, std::string_view name) {
  enum class State { kOutside, kSolid, kFacet, kLoop, kLoopDone };
  recon::Mesh mesh;
  VertexMerger merger(mesh, text.size() / 64);
  State state = State::kOutside;
  std::vector<std::uint32_t> loop;
  detail::LineReader lines(text);
  std::string_view line;
  auto expect = [&](std::string_view wanted, std::string_view found) {
    fail_line(name, lines.line_number(),
              "expected " + std::string(wanted) + ", found " +
                  (found.empty() ? std::string("end of line") : detail::quote(found)));
  };
  while (lines.next(line)) {
    detail::Tokenizer tok(line);
    const std::string_view key = tok.next();
    if (key.empty()) continue;
    switch (state) {
      case State::kOutside:
        if (!detail::iequals(key, "solid")) expect("'solid'", key);
        state = State::kSolid;
        break;
      case State::kSolid:
        if (detail::iequals(key, "facet")) {
          state = State::kFacet;
        } else if (detail::iequals(key, "endsolid")) {
          state = State::kOutside;
        } else {
          expect("'facet' or 'endsolid'", key);
        }
        break;
      case State::kFacet: {
        if (!detail::iequals(key, "outer")) expect("'outer loop'", key);
        const std::string_view loop_word = tok.next();
        if (!detail::iequals(loop_word, "loop")) expect("'outer loop'", loop_word);
        loop.clear();
        state = State::kLoop;
        break;
      }
      case State::kLoop:
        if (detail::iequals(key, "vertex")) {
          double v[3];
          for (int i = 0; i < 3; ++i) {
            const std::string_view t = tok.next();
            if (t.empty()) {
              fail_line(name, lines.line_number(),
                        "expected 3 numbers after 'vertex', found " + std::to_string(i));
            }
            const detail::NumberStatus s = detail::parse_double_token(t, v[i]);
            if (s != detail::NumberStatus::kOk) {
              fail_line(name, lines.line_number(), detail::describe(s, t));
            }
          }
          loop.push_back(merger.add(v[0], v[1], v[2]));
        } else if (detail::iequals(key, "endloop")) {
          if (loop.size() < 3) {
            fail_line(name, lines.line_number(),
                      "facet has " + std::to_string(loop.size()) + " vertices, expected 3");
          }
          // Polygons with more than three corners (seen in some exporters) become fans.
          for (std::size_t i = 1; i + 1 < loop.size(); ++i) {
            mesh.triangles.push_back({loop[0], loop[i], loop[i + 1]});
          }
          state = State::kLoopDone;
        } else {
          expect("'vertex' or 'endloop'", key);
        }
        break;
      case State::kLoopDone:
        if (!detail::iequals(key, "endfacet")) expect("'endfacet'", key);
        state = State::kSolid;
        break;
    }
  }
  if (state == State::kFacet || state == State::kLoop || state == State::kLoopDone) {
    fail_line(name, lines.line_number(), "unexpected end of file inside a facet");
  }
  return mesh;
}

}  // namespace

recon::Mesh parse_stl(std::string_view bytes, std::string_view name) {
  if (bytes.size() >= kBinaryHeader) {
    std::uint32_t count = 0;
    std::memcpy(&count, bytes.data() + 80, 4);
    if constexpr (std::endian::native == std::endian::big) count = __builtin_bswap32(count);
    const std::uint64_t expected = kBinaryHeader + std::uint64_t{kBinaryRecord} * count;
    if (expected == bytes.size()) return parse_binary(bytes, name, count);
    // Binary files whose size does not match are only parsed as text when they look like text:
    // many binary exporters also start their header with "solid".
    if (!starts_with_solid(bytes) || std::memchr(bytes.data(), '\0', bytes.size()) != nullptr) {
      fail_byte(name, 80,
                "binary STL declares " + std::to_string(count) + " triangles (" +
                    std::to_string(expected) + " bytes) but the file has " +
                    std::to_string(bytes.size()) + " bytes");
    }
    return parse_ascii(bytes, name);
  }
  if (starts_with_solid(bytes) && std::memchr(bytes.data(), '\0', bytes.size()) == nullptr) {
    return parse_ascii(bytes, name);
  }
  detail::fail(name, "not an STL file (" + std::to_string(bytes.size()) +
                         " bytes: too short for binary STL and no 'solid' line)");
}

}  // namespace scanmesh::meshio
