// The real holes of a reference mesh, as sampled areas, and how much of each a mesh leaves
// open: for the tests and bench_holes (the bunny's five holes under perturbed sampling).
// SPDX-License-Identifier: MIT
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <vector>

#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/recon/fill.hpp"
#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::test {

/// Points on the area of one hole, each standing for `weight` of it.
struct Hole {
  std::vector<recon::Vec3> samples;
  std::vector<double> weight;
  double area = 0;
};

/// The reference's holes: each boundary loop closed by its flat patch (fill_holes without new
/// vertices), the patch triangles grouped by the vertices they share, and sampled on a
/// barycentric grid of about `step` spacing.
inline std::vector<Hole> reference_holes(const recon::Mesh& ref, double step) {
  recon::Mesh filled = ref;
  recon::FillOptions fo;
  fo.max_edges = recon::FillOptions::kLimit;
  fo.refine = false;
  recon::fill_holes(filled, fo);
  const std::size_t first = ref.triangles.size();
  std::vector<std::uint32_t> root(filled.vertices.size());
  std::iota(root.begin(), root.end(), 0u);
  auto find = [&](std::uint32_t v) {
    while (root[v] != v) v = root[v] = root[root[v]];
    return v;
  };
  for (std::size_t t = first; t < filled.triangles.size(); ++t) {
    const auto& tr = filled.triangles[t];
    for (int k = 1; k < 3; ++k) root[find(tr[k])] = find(tr[0]);
  }
  std::vector<std::uint32_t> hole_of_root(filled.vertices.size(), UINT32_MAX);
  std::vector<Hole> holes;
  for (std::size_t t = first; t < filled.triangles.size(); ++t) {
    const auto& tr = filled.triangles[t];
    std::uint32_t& h = hole_of_root[find(tr[0])];
    if (h == UINT32_MAX) {
      h = static_cast<std::uint32_t>(holes.size());
      holes.emplace_back();
    }
    Hole& hole = holes[h];
    const recon::Vec3 &a = filled.vertices[tr[0]], &b = filled.vertices[tr[1]],
                      &c = filled.vertices[tr[2]];
    const double area = 0.5 * (b - a).cross(c - a).norm();
    const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
    const int n = std::max(1, static_cast<int>(std::ceil(longest / step)));
    const std::size_t count = static_cast<std::size_t>(n + 1) * static_cast<std::size_t>(n + 2) / 2;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) {
        const double u = static_cast<double>(i) / n, v = static_cast<double>(j) / n;
        hole.samples.push_back(a + u * (b - a) + v * (c - a));
        hole.weight.push_back(area / static_cast<double>(count));
      }
    hole.area += area;
  }
  std::sort(holes.begin(), holes.end(),
            [](const Hole& l, const Hole& r) { return l.area > r.area; });
  return holes;
}

/// The share (0-100) of a hole's area farther than `reach` from `surface`.
inline double open_percent(const Hole& h, const recon::SurfaceDistance& surface, double reach) {
  double uncovered = 0, total = 0;
  for (std::size_t s = 0; s < h.samples.size(); ++s) {
    total += h.weight[s];
    if (surface.distance(h.samples[s]) > reach) uncovered += h.weight[s];
  }
  return total > 0 ? 100 * uncovered / total : 0;
}

}  // namespace scanmesh::test
