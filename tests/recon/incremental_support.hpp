// Helpers of the incremental reconstruction's tests: a synthetic serpentine raster scan over a
// known height field, and a replay of mesh deltas (what a viewer does with them).
// SPDX-License-Identifier: MIT
#pragma once

#include <cmath>
#include <cstdint>
#include <algorithm>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/incremental.hpp"
#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::test {

using recon::Vec3;

/// The surface the raster scans: gentle bumps, about 1 mm high over 20 mm.
inline double raster_height(double x, double y) {
  return 0.8 * std::sin(x * 0.3) * std::cos(y * 0.25) + 0.05 * x;
}

/// A serpentine raster scan of raster_height: `lines` lines `line_mm` apart along y, each of
/// `per_line` samples `along_mm` apart along x (alternating direction), Gaussian noise of
/// `noise_mm` along z (seeded).
inline std::vector<Vec3> raster_scan(int per_line, int lines, double along_mm, double line_mm,
                                     double noise_mm, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<Vec3> pts;
  pts.reserve(static_cast<std::size_t>(per_line) * static_cast<std::size_t>(lines));
  for (int l = 0; l < lines; ++l)
    for (int i = 0; i < per_line; ++i) {
      const int k = l % 2 == 0 ? i : per_line - 1 - i;
      const double x = k * along_mm, y = l * line_mm;
      pts.emplace_back(x, y, raster_height(x, y) + noise_mm * noise(rng));
    }
  return pts;
}

/// Mean vertical distance of the mesh's vertices and triangle centroids from raster_height.
inline double mean_height_error(const recon::Mesh& m) {
  double sum = 0;
  std::size_t n = 0;
  for (const Vec3& v : m.vertices) {
    sum += std::abs(v.z() - raster_height(v.x(), v.y()));
    ++n;
  }
  for (const auto& t : m.triangles) {
    const Vec3 c = (m.vertices[t[0]] + m.vertices[t[1]] + m.vertices[t[2]]) / 3.0;
    sum += std::abs(c.z() - raster_height(c.x(), c.y()));
    ++n;
  }
  return n > 0 ? sum / static_cast<double>(n) : 0.0;
}

/// Vertices lying over or under a triangle they are not part of, less than `height` from its
/// plane (their projection inside it, a margin of 1 % of its size in): a second layer.
/// `only`, when not empty, flags the vertices to test.
inline std::size_t layered_vertices(const recon::Mesh& m, double height,
                                    const std::vector<std::uint8_t>& only = {}) {
  double mean_edge = 0;
  for (const auto& t : m.triangles) mean_edge += (m.vertices[t[0]] - m.vertices[t[1]]).norm();
  mean_edge /= static_cast<double>(std::max<std::size_t>(1, m.triangles.size()));
  std::vector<Vec3> centroids;
  for (const auto& t : m.triangles)
    centroids.push_back((m.vertices[t[0]] + m.vertices[t[1]] + m.vertices[t[2]]) / 3.0);
  recon::PointGrid grid;
  grid.build(centroids, 2.0 * mean_edge + height);
  std::size_t layered = 0;
  for (std::uint32_t v = 0; v < m.vertices.size(); ++v) {
    if (!only.empty() && only[v] == 0) continue;
    const Vec3& p = m.vertices[v];
    bool over = false;
    grid.for_each_near(p, 1, [&](std::uint32_t ti) {
      if (over) return;
      const auto& t = m.triangles[ti];
      if (t[0] == v || t[1] == v || t[2] == v) return;
      const Vec3 &a = m.vertices[t[0]], &b = m.vertices[t[1]], &c = m.vertices[t[2]];
      const Vec3 n = (b - a).cross(c - a);
      const double area2 = n.norm();
      if (!(area2 > 0)) return;
      const Vec3 u = n / area2;
      if (std::abs((p - a).dot(u)) >= height) return;
      // Barycentric coordinates of the projection, each at least 1 %.
      const double wa = (c - b).cross(p - b).dot(u) / area2, wb = (a - c).cross(p - c).dot(u) / area2;
      const double wc = 1.0 - wa - wb;
      over = wa > 0.01 && wb > 0.01 && wc > 0.01;
    });
    if (over) ++layered;
  }
  return layered;
}

/// A mesh rebuilt from deltas alone, by id, checking each delta's promises.
class DeltaReplay {
 public:
  /// Applies d; returns the first broken promise (empty when none).
  std::string apply(const recon::MeshDelta& d) {
    if (d.first_vertex != vertices_.size()) return "vertex ids not consecutive";
    vertices_.insert(vertices_.end(), d.vertices.begin(), d.vertices.end());
    if (d.added_ids.size() != d.added.size()) return "added ids and triangles differ in number";
    for (std::size_t i = 0; i < d.added.size(); ++i) {
      if (triangles_.count(d.added_ids[i]) != 0 || d.added_ids[i] < next_triangle_)
        return "triangle id reused";
      for (std::uint32_t v : d.added[i])
        if (v >= vertices_.size()) return "triangle with an unknown vertex";
      triangles_[d.added_ids[i]] = d.added[i];
    }
    for (std::uint32_t id : d.removed) {
      if (id >= next_triangle_) return "removed a triangle of the same delta";
      if (triangles_.erase(id) != 1) return "removed an unknown triangle";
    }
    if (!d.added_ids.empty()) next_triangle_ = d.added_ids.back() + 1;
    return {};
  }
  [[nodiscard]] std::size_t triangle_count() const { return triangles_.size(); }
  /// Empty when every loop is closed and each of its edges u -> v is a boundary edge of the
  /// mesh with its triangle on the left (u -> v in a triangle, v -> u in none).
  [[nodiscard]] std::string loops_are_boundary(
      const std::vector<std::vector<std::uint32_t>>& loops) const {
    std::vector<std::pair<std::uint32_t, std::uint32_t>> half;
    for (const auto& [id, t] : triangles_)
      for (int k = 0; k < 3; ++k) half.emplace_back(t[k], t[(k + 1) % 3]);
    std::sort(half.begin(), half.end());
    for (const auto& loop : loops) {
      if (loop.size() < 3) return "a loop of fewer than 3 vertices";
      for (std::size_t i = 0; i < loop.size(); ++i) {
        const std::uint32_t u = loop[i], v = loop[(i + 1) % loop.size()];
        if (!std::binary_search(half.begin(), half.end(), std::make_pair(u, v))) return "a loop edge in no triangle";
        if (std::binary_search(half.begin(), half.end(), std::make_pair(v, u))) return "a loop edge inside the mesh";
      }
    }
    return {};
  }
  /// Compact, as MeshSnapshot::to_mesh: used vertices and triangles in id order.
  [[nodiscard]] recon::Mesh mesh(std::vector<std::uint32_t>* ids = nullptr) const {
    recon::Mesh m;
    std::vector<std::uint32_t> remap(vertices_.size(), 0xffffffffu);
    for (const auto& [id, t] : triangles_)
      for (std::uint32_t v : t) remap[v] = 0;
    std::uint32_t used = 0;
    for (std::size_t v = 0; v < vertices_.size(); ++v) {
      if (remap[v] != 0) continue;
      remap[v] = used++;
      m.vertices.push_back(vertices_[v]);
      if (ids != nullptr) ids->push_back(static_cast<std::uint32_t>(v));
    }
    for (const auto& [id, t] : triangles_) m.triangles.push_back({remap[t[0]], remap[t[1]], remap[t[2]]});
    return m;
  }

 private:
  std::vector<Vec3> vertices_;
  std::map<std::uint32_t, recon::Triangle> triangles_;
  std::uint32_t next_triangle_ = 0;
};

}  // namespace scanmesh::test
