// Wavefront OBJ reader: 'v' and 'f' statements (v, v/t, v//n, v/t/n, negative relative
// indices, polygons as fans); every other statement is ignored.
// SPDX-License-Identifier: MIT
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "detail.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"

namespace scanmesh::meshio {
namespace detail {

recon::Mesh parse_obj(std::string_view text, std::string_view name, bool vertices_only) {
  recon::Mesh mesh;
  LineReader lines(text);
  std::string_view line;
  std::vector<std::uint32_t> face;
  // Positive indices may refer to vertices defined further down, so they are checked at the end;
  // the largest one and its line are enough for the error message.
  std::uint64_t max_index = 0;
  std::size_t max_index_line = 0;

  while (lines.next(line)) {
    Tokenizer tok(line);
    const std::string_view key = tok.next();
    if (key == "v") {
      double xyz[3];
      for (int i = 0; i < 3; ++i) {
        const std::string_view t = tok.next();
        if (t.empty() || t.front() == '#') {
          fail_line(name, lines.line_number(),
                    "expected 3 numbers (x y z) after 'v', found " + std::to_string(i));
        }
        const NumberStatus s = parse_double_token(t, xyz[i]);
        if (s != NumberStatus::kOk) fail_line(name, lines.line_number(), describe(s, t));
      }
      if (mesh.vertices.size() >= std::numeric_limits<std::uint32_t>::max()) {
        fail_line(name, lines.line_number(), "more than 2^32-1 vertices are not supported");
      }
      mesh.vertices.emplace_back(xyz[0], xyz[1], xyz[2]);  // w and colour columns are ignored
    } else if (key == "f" && !vertices_only) {
      face.clear();
      for (std::string_view t = tok.next(); !t.empty() && t.front() != '#'; t = tok.next()) {
        // Only the vertex index (before the first '/') matters; texture and normal indices
        // are not used.
        const std::string_view v = t.substr(0, t.find('/'));
        std::int64_t i = 0;
        if (!parse_int_token(v, i)) {
          fail_line(name, lines.line_number(), "bad face vertex " + quote(t));
        }
        std::int64_t resolved = 0;
        if (i > 0) {
          if (static_cast<std::uint64_t>(i) > std::numeric_limits<std::uint32_t>::max()) {
            fail_line(name, lines.line_number(),
                      "vertex index " + std::to_string(i) + " too large");
          }
          resolved = i - 1;
          if (static_cast<std::uint64_t>(i) > max_index) {
            max_index = static_cast<std::uint64_t>(i);
            max_index_line = lines.line_number();
          }
        } else if (i < 0) {
          // Relative: -1 is the last vertex defined so far.
          resolved = static_cast<std::int64_t>(mesh.vertices.size()) + i;
          if (resolved < 0) {
            fail_line(name, lines.line_number(),
                      "relative vertex index " + std::to_string(i) +
                          " reaches before the first vertex (" +
                          std::to_string(mesh.vertices.size()) + " defined so far)");
          }
        } else {
          fail_line(name, lines.line_number(), "vertex index 0 (OBJ indices start at 1)");
        }
        face.push_back(static_cast<std::uint32_t>(resolved));
      }
      if (face.size() < 3) {
        fail_line(name, lines.line_number(),
                  "face needs at least 3 vertices, found " + std::to_string(face.size()));
      }
      for (std::size_t k = 1; k + 1 < face.size(); ++k) {
        mesh.triangles.push_back({face[0], face[k], face[k + 1]});
      }
    }
  }
  if (max_index > mesh.vertices.size()) {
    fail_line(name, max_index_line,
              "vertex index " + std::to_string(max_index) + " out of range (" +
                  std::to_string(mesh.vertices.size()) + " vertices)");
  }
  return mesh;
}

}  // namespace detail

recon::Mesh parse_obj(std::string_view text, std::string_view name) {
  return detail::parse_obj(text, name, false);
}

}  // namespace scanmesh::meshio
