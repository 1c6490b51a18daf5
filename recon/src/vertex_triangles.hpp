// Internal to recon: each vertex's triangles as compressed lists and the fans they form, shared
// by the front's repairs and the gap untangling.
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

/// Number of fans that v's m triangles tris[ids[0..m)] form: triangles sharing a corner other
/// than v (an edge at v) are joined (union-find in `fan`: a root's entry is negative; the size
/// of each root's fan in `size`).
inline std::size_t fans_of(const std::vector<Triangle>& tris, std::uint32_t v,
                           const std::uint32_t* ids, std::uint32_t m, std::vector<int>& fan,
                           std::vector<std::uint32_t>& size) {
  fan.assign(m, -1);
  auto find = [&](int i) {
    while (fan[static_cast<std::size_t>(i)] >= 0) i = fan[static_cast<std::size_t>(i)];
    return i;
  };
  for (std::uint32_t i = 0; i < m; ++i)
    for (std::uint32_t j = i + 1; j < m; ++j) {
      const Triangle &ti = tris[ids[i]], &tj = tris[ids[j]];
      int shared = 0;
      for (std::uint32_t x : ti)
        if (x != v && (x == tj[0] || x == tj[1] || x == tj[2])) ++shared;
      if (shared == 0) continue;
      const int ri = find(static_cast<int>(i)), rj = find(static_cast<int>(j));
      if (ri != rj) fan[static_cast<std::size_t>(rj)] = ri;
    }
  size.assign(m, 0);
  std::size_t roots = 0;
  for (std::uint32_t i = 0; i < m; ++i) {
    const auto r = static_cast<std::size_t>(find(static_cast<int>(i)));
    if (size[r]++ == 0) ++roots;
  }
  return roots;
}

}  // namespace scanmesh::recon::detail
