// Internal to recon: each vertex's triangles as compressed lists, shared by the front's repairs
// and the gap untangling.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon::detail {

/// The triangles around every vertex, as compressed lists: those of vertex v are
/// list[start[v]] .. list[start[v + 1] - 1], in triangle order. 4 bytes per corner; used by
/// the passes that need adjacency once (fan repair, front rebuild, orientation, gap
/// untangling) instead of an array of every half-edge. With `slot`, the lists are indexed by
/// slot(v) (below n) instead.
struct VertexTriangles {
  std::vector<std::uint32_t> start, list;

  VertexTriangles(std::size_t n, const std::vector<Triangle>& tris)
      : VertexTriangles(n, tris, [](std::uint32_t v) { return v; }) {}
  /// slot(v) may be 0xffffffff for a vertex left out.
  template <class Slot>
  VertexTriangles(std::size_t n, const std::vector<Triangle>& tris, Slot slot) : start(n + 1, 0) {
    constexpr std::uint32_t kOut = 0xffffffffu;
    for (const Triangle& t : tris)
      for (std::uint32_t v : t)
        if (const std::uint32_t s = slot(v); s != kOut) ++start[s + 1];
    for (std::size_t i = 0; i < n; ++i) start[i + 1] += start[i];
    list.resize(start[n]);
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::uint32_t t = 0; t < tris.size(); ++t)
      for (std::uint32_t v : tris[t])
        if (const std::uint32_t s = slot(v); s != kOut) list[fill[s]++] = t;
  }
  /// The triangles of vertex (or slot) v.
  [[nodiscard]] std::span<const std::uint32_t> of(std::size_t v) const {
    return {list.data() + start[v], list.data() + start[v + 1]};
  }
};

}  // namespace scanmesh::recon::detail
