// Internal to recon: the connected components of a triangle set (triangles joined through shared
// vertices), shared by the front's orientation pass and remove_crossing_components.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon::detail {

/// Union-find over vertex indices, joined through triangles (path halving). One word a vertex.
class VertexSets {
 public:
  /// Every vertex below `vertices` in a set of its own.
  void reset(std::size_t vertices) {
    parent_.resize(vertices);
    for (std::size_t i = 0; i < vertices; ++i) parent_[i] = static_cast<std::uint32_t>(i);
  }
  /// Joins the sets of t's three corners. The lower root becomes the root of both: a set
  /// growing over triangles in storage order then keeps its root instead of passing it to each
  /// new corner (which made the paths, and their cache misses, long).
  void join(const Triangle& t) {
    std::uint32_t r0 = find(t[0]);
    for (int k = 1; k < 3; ++k) {
      std::uint32_t r = find(t[static_cast<std::size_t>(k)]);
      if (r == r0) continue;
      if (r < r0) std::swap(r, r0);
      parent_[r] = r0;
    }
  }
  [[nodiscard]] std::uint32_t find(std::uint32_t i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }

 private:
  std::vector<std::uint32_t> parent_;
};

/// Union-find over the vertices of `triangles` (indices below `vertices`), with compact
/// component ids numbered in order of first appearance in `triangles`. Memory: two words a
/// vertex and one a component (no per-triangle array: the front runs this at its peak).
class TriangleComponents {
 public:
  TriangleComponents(std::size_t vertices, std::span<const Triangle> triangles)
      : id_(vertices, kNone) {
    sets_.reset(vertices);
    for (const Triangle& t : triangles) sets_.join(t);
    for (const Triangle& t : triangles) {
      std::uint32_t& c = id_[sets_.find(t[0])];
      if (c == kNone) {
        c = static_cast<std::uint32_t>(sizes_.size());
        sizes_.push_back(0);
      }
      ++sizes_[c];
    }
  }
  /// The component of triangle t (one of those given).
  [[nodiscard]] std::uint32_t of(const Triangle& t) { return id_[sets_.find(t[0])]; }
  [[nodiscard]] std::size_t count() const { return sizes_.size(); }
  /// Triangles per component.
  [[nodiscard]] const std::vector<std::uint32_t>& sizes() const { return sizes_; }

 private:
  static constexpr std::uint32_t kNone = 0xffffffffu;
  VertexSets sets_;
  std::vector<std::uint32_t> id_, sizes_;
};

}  // namespace scanmesh::recon::detail
