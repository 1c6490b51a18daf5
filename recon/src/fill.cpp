// Hole filling: minimum-weight triangulation of each small boundary loop by dynamic programming
// over its vertices (Liepa, "Filling holes in meshes", 2003: the weight of a triangulation is its
// largest dihedral angle, ties broken by its area). Pure: no I/O, no globals.
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/fill.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <utility>

#include "scanmesh/recon/analysis.hpp"

namespace scanmesh::recon {
namespace {

std::uint64_t undirected_key(std::uint32_t u, std::uint32_t v) {
  return u < v ? (std::uint64_t{u} << 32) | v : (std::uint64_t{v} << 32) | u;
}

/// Weight of a partial triangulation, compared lexicographically.
struct Weight {
  double angle = 0;  // largest dihedral angle between adjacent triangles, radians
  double area = 0;
  bool operator<(const Weight& o) const {
    return angle != o.angle ? angle < o.angle : area < o.area;
  }
};

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr std::uint32_t kNone = 0xffffffffu;

/// Fills one loop (vertices q, traversed q[i] -> q[i+1] by the mesh's triangles; border[i] is the
/// unit normal of the triangle on edge i). Returns false, adding nothing, when every
/// triangulation would repeat an edge the mesh already has.
class LoopFiller {
 public:
  LoopFiller(const std::vector<Vec3>& vertices, const std::vector<std::uint32_t>& q,
             const std::vector<Vec3>& border, const std::vector<std::uint64_t>& edges)
      : p_(vertices), q_(q), border_(border), edges_(edges), n_(q.size()),
        weight_(n_ * n_), split_(n_ * n_, kNone) {}

  bool run(std::vector<Triangle>& out) {
    const std::size_t n = n_;
    for (std::size_t len = 2; len < n; ++len) {
      for (std::size_t i = 0; i + len < n; ++i) {
        const std::size_t j = i + len;
        Weight& best = weight_[i * n + j];
        best = {kInfinity, kInfinity};
        const bool outer = i == 0 && j == n - 1;  // its edge (j, i) is the loop's last edge
        if (!outer && chord_exists(i, j)) continue;
        for (std::size_t m = i + 1; m < j; ++m) {
          const Weight& left = weight_[i * n + m];
          const Weight& right = weight_[m * n + j];
          if (left.angle == kInfinity || right.angle == kInfinity) continue;
          const Vec3 normal = patch_normal(i, m, j);
          const double twice_area = normal.norm();
          double angle = std::max(left.angle, right.angle);
          if (twice_area == 0) {
            angle = std::numbers::pi;
          } else {
            const Vec3 unit = normal / twice_area;
            angle = std::max(angle, dihedral(unit, neighbour_normal(i, m)));
            angle = std::max(angle, dihedral(unit, neighbour_normal(m, j)));
            if (outer) angle = std::max(angle, dihedral(unit, border_[n - 1]));
          }
          const Weight w{angle, left.area + right.area + 0.5 * twice_area};
          if (w < best) {
            best = w;
            split_[i * n + j] = static_cast<std::uint32_t>(m);
          }
        }
      }
    }
    if (split_[n - 1] == kNone) return false;  // (0, n - 1) has no triangulation
    std::vector<std::pair<std::size_t, std::size_t>> stack{{0, n - 1}};
    while (!stack.empty()) {
      const auto [i, j] = stack.back();
      stack.pop_back();
      if (j - i < 2) continue;
      const std::size_t m = split_[i * n + j];
      out.push_back({q_[j], q_[m], q_[i]});
      stack.emplace_back(i, m);
      stack.emplace_back(m, j);
    }
    return true;
  }

 private:
  /// Normal of the patch triangle (q[j], q[m], q[i]) (twice its area long): reversed against the
  /// loop's direction, like the triangles across the loop's edges.
  [[nodiscard]] Vec3 patch_normal(std::size_t i, std::size_t m, std::size_t j) const {
    const Vec3& a = p_[q_[j]];
    return (p_[q_[m]] - a).cross(p_[q_[i]] - a);
  }
  /// Unit normal of the triangle across edge (i, k), k > i: the mesh's on a loop edge, else the
  /// one the sub-polygon (i, k) chose.
  [[nodiscard]] Vec3 neighbour_normal(std::size_t i, std::size_t k) const {
    if (k == i + 1) return border_[i];
    const Vec3 normal = patch_normal(i, split_[i * n_ + k], k);
    const double len = normal.norm();
    return len > 0 ? Vec3(normal / len) : Vec3::Zero();
  }
  static double dihedral(const Vec3& a, const Vec3& b) {
    if (b.squaredNorm() == 0) return std::numbers::pi;
    return std::acos(std::clamp(a.dot(b), -1.0, 1.0));
  }
  [[nodiscard]] bool chord_exists(std::size_t i, std::size_t j) const {
    return std::binary_search(edges_.begin(), edges_.end(), undirected_key(q_[i], q_[j]));
  }

  const std::vector<Vec3>& p_;
  const std::vector<std::uint32_t>& q_;
  const std::vector<Vec3>& border_;
  const std::vector<std::uint64_t>& edges_;
  std::size_t n_;
  std::vector<Weight> weight_;        // [i * n + j], j > i
  std::vector<std::uint32_t> split_;  // apex chosen for (i, j), or kNone
};

}  // namespace

std::vector<std::string> FillOptions::validate() const {
  std::vector<std::string> errors;
  if (max_edges > kLimit)
    errors.push_back("hole filling is limited to loops of at most " + std::to_string(kLimit) +
                     " edges, got " + std::to_string(max_edges));
  return errors;
}

FillStats fill_holes(Mesh& mesh, const FillOptions& options) {
  FillStats stats;
  if (mesh.triangles.empty()) return stats;
  const MeshReport report = analyze(mesh, true);
  if (report.non_manifold_edges > 0 || report.non_manifold_vertices > 0 ||
      !report.orientation_consistent) {
    stats.kept = report.loops.size();
    return stats;
  }
  const std::size_t limit = std::min(options.max_edges, FillOptions::kLimit);
  std::vector<char> on_small_loop(mesh.vertices.size(), 0);
  for (const BoundaryLoop& loop : report.loops)
    if (loop.closed && loop.vertices.size() >= 3 && loop.vertices.size() <= limit)
      for (std::uint32_t v : loop.vertices) on_small_loop[v] = 1;
  // The edges at those loops' vertices (a chord must not repeat one) and the triangle on each
  // boundary edge (directed as that triangle runs along it).
  std::vector<std::uint64_t> edges;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> directed;
  for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
    const Triangle& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t u = tri[k], v = tri[(k + 1) % 3];
      if (!on_small_loop[u] && !on_small_loop[v]) continue;
      edges.push_back(undirected_key(u, v));
      if (on_small_loop[u] && on_small_loop[v])
        directed.emplace_back((std::uint64_t{u} << 32) | v, t);
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  std::sort(directed.begin(), directed.end());
  auto triangle_on = [&](std::uint32_t u, std::uint32_t v) {
    const std::uint64_t key = (std::uint64_t{u} << 32) | v;
    const auto it = std::lower_bound(directed.begin(), directed.end(),
                                     std::make_pair(key, std::uint32_t{0}));
    return it != directed.end() && it->first == key ? it->second : kNone;
  };

  std::vector<Vec3> border;
  for (const BoundaryLoop& loop : report.loops) {
    const std::vector<std::uint32_t>& q = loop.vertices;
    if (!loop.closed || q.size() < 3 || q.size() > limit) {
      ++stats.kept;
      continue;
    }
    // The rim of a lone triangle: its patch would be the same triangle turned over. Any
    // triangle on these three vertices has the boundary edge q0 -> q1, so one look-up tells.
    const auto lone_rim = [&] {
      const std::uint32_t t = triangle_on(q[0], q[1]);
      if (t == kNone) return false;
      const Triangle& tri = mesh.triangles[t];
      return tri[0] == q[2] || tri[1] == q[2] || tri[2] == q[2];
    };
    if (q.size() == 3 && lone_rim()) {
      ++stats.kept;
      continue;
    }
    border.assign(q.size(), Vec3::Zero());
    bool found = true;
    for (std::size_t i = 0; i < q.size() && found; ++i) {
      const std::uint32_t t = triangle_on(q[i], q[(i + 1) % q.size()]);
      found = t != kNone;
      if (!found) break;
      const Triangle& tri = mesh.triangles[t];
      const Vec3 normal = (mesh.vertices[tri[1]] - mesh.vertices[tri[0]])
                              .cross(mesh.vertices[tri[2]] - mesh.vertices[tri[0]]);
      if (normal.norm() > 0) border[i] = normal.normalized();
    }
    const std::size_t before = mesh.triangles.size();
    if (found && LoopFiller(mesh.vertices, q, border, edges).run(mesh.triangles)) {
      ++stats.filled;
      stats.triangles += mesh.triangles.size() - before;
    } else {
      ++stats.kept;
    }
  }
  return stats;
}

}  // namespace scanmesh::recon
