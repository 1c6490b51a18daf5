// Hole filling: minimum-weight triangulation of each small boundary loop by dynamic programming
// over its vertices (Liepa, "Filling holes in meshes", 2003: the weight of a triangulation is its
// largest dihedral angle, ties broken by its area), then Liepa's refinement (centroid splits
// down to the edge lengths around the hole, Delaunay edge swaps) and a bilaplacian fairing of the
// new vertices. Pure: no I/O, no globals.
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/fill.hpp"

#include "loop_measure.hpp"
#include "vertex_triangles.hpp"

#include <Eigen/SparseCore>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/intersections.hpp"

namespace scanmesh::recon {
namespace {

std::uint64_t undirected_key(std::uint32_t u, std::uint32_t v) {
  return u < v ? (std::uint64_t{u} << 32) | v : (std::uint64_t{v} << 32) | u;
}

/// Weight of a partial triangulation, compared lexicographically: its largest dihedral angle
/// between adjacent triangles, then its area. The angle is kept as its cosine (acos is
/// decreasing, so the largest angle is the smallest cosine): the search compares angles
/// O(n^3) times and never needs one in radians.
struct Weight {
  double worst_cos = 1;  // cosine of the largest dihedral angle; -infinity: no triangulation
  double area = 0;
  [[nodiscard]] bool better_than(const Weight& o) const {
    return worst_cos != o.worst_cos ? worst_cos > o.worst_cos : area < o.area;
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
        weight_(n_ * n_), split_(n_ * n_, kNone), unit_(n_ * n_, Vec3::Zero()) {}

  bool run(std::vector<Triangle>& out) {
    const std::size_t n = n_;
    for (std::size_t i = 0; i + 1 < n; ++i) unit_[i * n + i + 1] = border_[i];
    for (std::size_t len = 2; len < n; ++len) {
      for (std::size_t i = 0; i + len < n; ++i) {
        const std::size_t j = i + len;
        Weight& best = weight_[i * n + j];
        best = {-kInfinity, kInfinity};
        const bool outer = i == 0 && j == n - 1;  // its edge (j, i) is the loop's last edge
        if (!outer && chord_exists(i, j)) continue;
        for (std::size_t m = i + 1; m < j; ++m) {
          const Weight& left = weight_[i * n + m];
          const Weight& right = weight_[m * n + j];
          // The angle only grows with this triangle's creases: a side already sharper than the
          // best so far cannot win (exact pruning; -infinity: no triangulation).
          if (std::min(left.worst_cos, right.worst_cos) < best.worst_cos ||
              left.worst_cos == -kInfinity || right.worst_cos == -kInfinity)
            continue;
          const Vec3 normal = patch_normal(i, m, j);
          const double twice_area = normal.norm();
          double worst = std::min(left.worst_cos, right.worst_cos);
          if (twice_area == 0) {
            worst = -1;
          } else {
            const Vec3 unit = normal / twice_area;
            worst = std::min(worst, crease_cos(unit, unit_[i * n + m]));
            worst = std::min(worst, crease_cos(unit, unit_[m * n + j]));
            if (outer) worst = std::min(worst, crease_cos(unit, border_[n - 1]));
          }
          const Weight w{worst, left.area + right.area + 0.5 * twice_area};
          if (w.better_than(best)) {
            best = w;
            split_[i * n + j] = static_cast<std::uint32_t>(m);
          }
        }
        // The chosen triangle's unit normal, read by every larger sub-polygon that has (i, j)
        // as a side (zero when degenerate: a crease of 180 degrees).
        if (split_[i * n + j] != kNone) {
          const Vec3 normal = patch_normal(i, split_[i * n + j], j);
          const double len = normal.norm();
          if (len > 0) unit_[i * n + j] = normal / len;
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
  /// Cosine of the dihedral angle between two unit normals; -1 (180 degrees) when b is zero (a
  /// degenerate neighbour).
  static double crease_cos(const Vec3& a, const Vec3& b) {
    if (b.squaredNorm() == 0) return -1;
    return std::clamp(a.dot(b), -1.0, 1.0);
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
  std::vector<Vec3> unit_;            // unit normal of the triangle on side (i, j), j > i
};

/// The mesh triangles at the small loops' vertices: pairs (v, triangle), sorted.
using CornerPairs = std::vector<std::pair<std::uint32_t, std::uint32_t>>;

std::span<const std::pair<std::uint32_t, std::uint32_t>> triangles_at(const CornerPairs& pairs,
                                                                     std::uint32_t v) {
  const auto lo = std::lower_bound(pairs.begin(), pairs.end(), std::make_pair(v, std::uint32_t{0}));
  auto hi = lo;
  while (hi != pairs.end() && hi->first == v) ++hi;
  return {lo, hi};
}

/// Liepa's refinement and fairing of one loop's patch, the triangles mesh.triangles[first, end).
/// Splits a patch triangle at its centroid while the centroid is farther than sigma / sqrt(2)
/// from each corner (sigma: a loop vertex's mean edge length into the mesh; a new vertex takes
/// the mean of its triangle's corners), keeps the patch Delaunay by edge swaps, then moves the
/// new vertices to the solution of the cotangent bilaplacian (thin plate) with the loop and the
/// mesh ring around it held. Only the patch changes: the loop's vertices never move, no swap
/// adds an edge the mesh or the patch has, and every swap keeps the orientation.
class PatchRefiner {
 public:
  PatchRefiner(Mesh& mesh, std::size_t first, const std::vector<std::uint32_t>& loop,
               const std::vector<Vec3>& border, const CornerPairs& mesh_corners,
               const std::vector<std::uint64_t>& mesh_edges)
      : mesh_(mesh), first_(first), first_vertex_(mesh.vertices.size()), loop_(loop),
        mesh_corners_(mesh_corners), mesh_edges_(mesh_edges),
        // about n^2 / 11 vertices fill a round hole at the loop's own density: twice that at most
        max_new_(loop.size() * loop.size() / 4 + 64) {
    for (std::size_t i = 0; i < loop.size(); ++i)
      border_[undirected_key(loop[i], loop[(i + 1) % loop.size()])] = border[i];
    // sigma: the mean length of the edges from v into the mesh (each counted twice, once from
    // each triangle), not the rim's own edges, which are often stretched (scan borders, the
    // long edges the front left along a gap).
    for (std::uint32_t v : loop) {
      double sum = 0, rim = 0;
      std::size_t count = 0, rim_count = 0;
      for (const auto& [u, t] : triangles_at(mesh_corners, v))
        for (std::uint32_t w : mesh.triangles[t]) {
          if (w == v) continue;
          const double len = (mesh.vertices[w] - mesh.vertices[v]).norm();
          if (border_.contains(undirected_key(v, w))) {
            rim += len;
            ++rim_count;
          } else {
            sum += len;
            ++count;
          }
        }
      // a rim vertex with a single triangle has only rim edges
      sigma_[v] = count > 0 ? sum / static_cast<double>(count)
                            : rim_count > 0 ? rim / static_cast<double>(rim_count) : 0.0;
    }
    for (std::size_t t = first; t < mesh.triangles.size(); ++t) link(t);
  }

  enum class Outcome { kFlat, kRefined, kFaired };

  /// Refines and fairs. The minimum-weight patch kept its sharpest crease (largest angle between
  /// neighbouring normals, the mesh's across the loop) as small as the loop allows; where the
  /// hole spans a sharp edge of the part, refinement and fairing can fold it. Their result is
  /// kept only if that crease grows by at most 10 degrees: else the refined positions without
  /// fairing, else the minimum-weight patch itself (no new vertex).
  Outcome run(bool may_fair) {
    const double limit = sharpest_crease() + 10 * std::numbers::pi / 180;
    const std::vector<Triangle> plain(mesh_.triangles.begin() + static_cast<std::ptrdiff_t>(first_),
                                      mesh_.triangles.end());
    for (int pass = 0; pass < 64; ++pass) {
      bool created = false;
      const std::size_t end = mesh_.triangles.size();
      for (std::size_t t = first_; t < end; ++t)
        if (added() < max_new_ && split(t)) created = true;
      if (!created) break;
      relax_all();
    }
    if (added() == 0) return Outcome::kFlat;
    const auto first_new = mesh_.vertices.begin() + static_cast<std::ptrdiff_t>(first_vertex_);
    const std::vector<Vec3> refined(first_new, mesh_.vertices.end());
    if (may_fair && fair() && sharpest_crease() <= limit) return Outcome::kFaired;
    std::copy(refined.begin(), refined.end(),
              mesh_.vertices.begin() + static_cast<std::ptrdiff_t>(first_vertex_));
    if (sharpest_crease() <= limit) return Outcome::kRefined;
    mesh_.vertices.resize(first_vertex_);
    mesh_.triangles.resize(first_);
    mesh_.triangles.insert(mesh_.triangles.end(), plain.begin(), plain.end());
    return Outcome::kFlat;
  }
  /// Vertices the refinement added (kept unless the outcome is kFlat).
  [[nodiscard]] std::size_t added() const { return mesh_.vertices.size() - first_vertex_; }

 private:
  static constexpr std::uint32_t kFree = 0xffffffffu;

  [[nodiscard]] const Vec3& at(std::uint32_t v) const { return mesh_.vertices[v]; }

  void link(std::size_t t) {
    const Triangle& tri = mesh_.triangles[t];
    for (int k = 0; k < 3; ++k) {
      auto [it, fresh] = edge_tris_.try_emplace(undirected_key(tri[k], tri[(k + 1) % 3]),
                                                std::array<std::uint32_t, 2>{kFree, kFree});
      (it->second[0] == kFree ? it->second[0] : it->second[1]) = static_cast<std::uint32_t>(t);
    }
  }
  void unlink(std::size_t t) {
    const Triangle& tri = mesh_.triangles[t];
    for (int k = 0; k < 3; ++k) {
      const auto it = edge_tris_.find(undirected_key(tri[k], tri[(k + 1) % 3]));
      if (it->second[0] == t) it->second[0] = it->second[1];
      it->second[1] = kFree;
      if (it->second[0] == kFree) edge_tris_.erase(it);
    }
  }
  [[nodiscard]] bool edge_exists(std::uint32_t u, std::uint32_t v) const {
    const std::uint64_t key = undirected_key(u, v);
    return edge_tris_.contains(key) ||
           std::binary_search(mesh_edges_.begin(), mesh_edges_.end(), key);
  }

  bool split(std::size_t t) {
    const Triangle tri = mesh_.triangles[t];
    const Vec3 centre = (at(tri[0]) + at(tri[1]) + at(tri[2])) / 3.0;
    const double sigma = (sigma_[tri[0]] + sigma_[tri[1]] + sigma_[tri[2]]) / 3.0;
    double longest2 = 0;
    for (int k = 0; k < 3; ++k) {
      const double d = std::numbers::sqrt2 * (centre - at(tri[k])).norm();
      if (!(d > sigma && d > sigma_[tri[k]])) return false;
      longest2 = std::max(longest2, (at(tri[(k + 1) % 3]) - at(tri[k])).squaredNorm());
    }
    // A needle or a flat triangle is left whole: its centroid would only add slivers.
    if (!((at(tri[1]) - at(tri[0])).cross(at(tri[2]) - at(tri[0])).squaredNorm() >
          1e-6 * longest2 * longest2))
      return false;
    const auto v = static_cast<std::uint32_t>(mesh_.vertices.size());
    mesh_.vertices.push_back(centre);
    sigma_[v] = sigma;
    unlink(t);
    mesh_.triangles[t] = {v, tri[1], tri[2]};
    mesh_.triangles.push_back({tri[0], v, tri[2]});
    mesh_.triangles.push_back({tri[0], tri[1], v});
    for (std::size_t s : {t, mesh_.triangles.size() - 2, mesh_.triangles.size() - 1}) link(s);
    work_.clear();
    for (int k = 0; k < 3; ++k) work_.push_back(undirected_key(tri[k], tri[(k + 1) % 3]));
    // At most 64 swaps here; the full relaxation after each pass finishes the job.
    for (std::size_t step = 0; !work_.empty() && step < 64; ++step) {
      const std::uint64_t key = work_.back();
      work_.pop_back();
      relax(key);
    }
    return true;
  }

  static double angle(const Vec3& u, const Vec3& w) {
    return std::atan2(u.cross(w).norm(), u.dot(w));
  }

  [[nodiscard]] Vec3 normal_of(std::size_t t) const {
    const Triangle& tri = mesh_.triangles[t];
    return (at(tri[1]) - at(tri[0])).cross(at(tri[2]) - at(tri[0]));
  }

  /// The largest angle between the normals of two triangles across a patch edge (the mesh's
  /// triangle across a loop edge).
  [[nodiscard]] double sharpest_crease() const {
    double worst = 0;
    for (const auto& [key, tris] : edge_tris_) {
      const Vec3 other = tris[1] != kFree ? normal_of(tris[1]) : border_.at(key);
      if (other.squaredNorm() > 0) worst = std::max(worst, angle(normal_of(tris[0]), other));
    }
    return worst;
  }

  /// Swaps the patch edge `key` when it is not locally Delaunay (the angles facing it sum to
  /// more than pi) and the swap keeps the surface's orientation. Returns true on a swap.
  bool relax(std::uint64_t key) {
    const auto it = edge_tris_.find(key);
    if (it == edge_tris_.end() || it->second[1] == kFree) return false;  // a loop edge
    const std::size_t t1 = it->second[0], t2 = it->second[1];
    const auto u = static_cast<std::uint32_t>(key >> 32), w = static_cast<std::uint32_t>(key);
    // t1 = (a, b, c) runs a -> b; t2 must run b -> a with third vertex d.
    const Triangle& x = mesh_.triangles[t1];
    int k = 0;
    while (k < 3 && !((x[k] == u && x[(k + 1) % 3] == w) || (x[k] == w && x[(k + 1) % 3] == u)))
      ++k;
    if (k == 3) return false;
    const std::uint32_t a = x[k], b = x[(k + 1) % 3], c = x[(k + 2) % 3];
    const Triangle& y = mesh_.triangles[t2];
    std::uint32_t d = kFree;
    for (int m = 0; m < 3; ++m)
      if (y[m] == b && y[(m + 1) % 3] == a) d = y[(m + 2) % 3];
    if (d == kFree || d == c) return false;
    if (angle(at(a) - at(c), at(b) - at(c)) + angle(at(a) - at(d), at(b) - at(d)) <=
        std::numbers::pi + 1e-9)
      return false;
    if (edge_exists(c, d)) return false;
    const Vec3 old1 = (at(b) - at(a)).cross(at(c) - at(a)), old2 = (at(a) - at(b)).cross(at(d) - at(b));
    const Vec3 new1 = (at(d) - at(a)).cross(at(c) - at(a)), new2 = (at(b) - at(d)).cross(at(c) - at(d));
    if (old1.norm() == 0 || old2.norm() == 0) return false;
    const Vec3 facing = old1.normalized() + old2.normalized();
    if (!(new1.dot(facing) > 0 && new2.dot(facing) > 0 && new1.dot(new2) > 0)) return false;
    unlink(t1);
    unlink(t2);
    mesh_.triangles[t1] = {a, d, c};
    mesh_.triangles[t2] = {d, b, c};
    link(t1);
    link(t2);
    for (const auto& [p, q] : {std::pair{a, d}, std::pair{d, b}, std::pair{b, c}, std::pair{c, a}})
      work_.push_back(undirected_key(p, q));
    return true;
  }

  void relax_all() {
    std::vector<std::uint64_t> keys;
    for (int sweep = 0; sweep < 32; ++sweep) {
      keys.clear();
      for (const auto& [key, tris] : edge_tris_)
        if (tris[1] != kFree) keys.push_back(key);
      std::sort(keys.begin(), keys.end());  // a deterministic order
      bool swapped = false;
      for (std::uint64_t key : keys) swapped = relax(key) || swapped;
      work_.clear();
      if (!swapped) break;
    }
  }

  /// Bilaplacian fairing (thin plate): for every new vertex i, L(L x)_i = 0, with the
  /// cotangent Laplacian L x_v = 1 / (2 A_v) sum_w (cot alpha + cot beta)(x_w - x_v) (A_v: a
  /// third of v's triangles' area), weights and areas taken from the patch before fairing and
  /// the mesh around it. The loop's vertices and their mesh neighbours are held.
  bool fair() {
    const std::size_t unknowns = added();
    if (unknowns == 0) return false;
    // Triangles of every vertex whose Laplacian the system uses: the patch's and, for the loop's
    // vertices, the mesh's.
    std::vector<Triangle> tris(mesh_.triangles.begin() + static_cast<std::ptrdiff_t>(first_),
                               mesh_.triangles.end());
    for (std::uint32_t v : loop_)
      for (const auto& [u, t] : triangles_at(mesh_corners_, v)) tris.push_back(mesh_.triangles[t]);
    std::sort(tris.begin(), tris.end());
    tris.erase(std::unique(tris.begin(), tris.end()), tris.end());
    std::unordered_map<std::uint64_t, double> weight;  // undirected edge -> sum of cot / 2
    std::unordered_map<std::uint32_t, double> area;     // vertex -> a third of its triangles' area
    for (const Triangle& tri : tris) {
      const double third = (at(tri[1]) - at(tri[0])).cross(at(tri[2]) - at(tri[0])).norm() / 6;
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t o = tri[k], u = tri[(k + 1) % 3], w = tri[(k + 2) % 3];
        area[o] += third;
        const Vec3 eu = at(u) - at(o), ew = at(w) - at(o);
        const double cross = eu.cross(ew).norm();
        // cot of the angle at o, bounded (a needle must not dominate its vertex's Laplacian)
        const double cot = cross > 0 ? std::clamp(eu.dot(ew) / cross, -20.0, 20.0) : 0.0;
        weight[undirected_key(u, w)] += 0.5 * cot;
      }
    }
    std::unordered_map<std::uint32_t, std::vector<std::pair<std::uint32_t, double>>> ring;
    for (const auto& [key, w] : weight) {
      const auto u = static_cast<std::uint32_t>(key >> 32), v = static_cast<std::uint32_t>(key);
      const double wk = std::max(w, 1e-3);  // obtuse pairs: keep the edge, barely weighted
      ring[u].emplace_back(v, wk);
      ring[v].emplace_back(u, wk);
    }
    std::vector<Eigen::Triplet<double>> entries;
    Eigen::MatrixX3d rhs = Eigen::MatrixX3d::Zero(static_cast<Eigen::Index>(unknowns), 3);
    std::vector<std::pair<std::uint32_t, double>> row, inner;
    // One row of L = D^-1 W: (v, -sum / (2 A)) and (w, weight / (2 A)) for every neighbour w.
    // The equations L L x = 0 of the new vertices are taken times their own 2 A, i.e.
    // W D^-1 W x = 0: symmetric positive definite (W is symmetric), so a Cholesky factorisation
    // solves them, with the same solution.
    auto laplacian_row = [&](std::uint32_t v, std::vector<std::pair<std::uint32_t, double>>& out,
                             bool scaled) {
      out.clear();
      const double scale = scaled ? 1.0 / (2.0 * std::max(area[v], 1e-300)) : 1.0;
      double sum = 0;
      for (const auto& [w, wk] : ring[v]) {
        out.emplace_back(w, wk * scale);
        sum += wk;
      }
      out.emplace_back(v, -sum * scale);
    };
    for (std::size_t i = 0; i < unknowns; ++i) {
      const auto vi = static_cast<std::uint32_t>(first_vertex_ + i);
      laplacian_row(vi, row, false);
      for (const auto& [r, lr] : row) {
        laplacian_row(r, inner, true);
        for (const auto& [w, lw] : inner) {
          const double coef = lr * lw;
          if (w >= first_vertex_)
            entries.emplace_back(static_cast<int>(i), static_cast<int>(w - first_vertex_), coef);
          else
            rhs.row(static_cast<Eigen::Index>(i)) -= coef * at(w).transpose();
        }
      }
    }
    Eigen::SparseMatrix<double> system(static_cast<Eigen::Index>(unknowns),
                                       static_cast<Eigen::Index>(unknowns));
    system.setFromTriplets(entries.begin(), entries.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
    solver.compute(system);
    if (solver.info() != Eigen::Success) return false;  // the refined positions stay
    const Eigen::MatrixX3d x = solver.solve(rhs);
    if (solver.info() != Eigen::Success || !x.allFinite()) return false;
    for (std::size_t i = 0; i < unknowns; ++i)
      mesh_.vertices[first_vertex_ + i] = x.row(static_cast<Eigen::Index>(i)).transpose();
    return true;
  }

  Mesh& mesh_;
  std::size_t first_, first_vertex_;
  const std::vector<std::uint32_t>& loop_;
  const CornerPairs& mesh_corners_;
  const std::vector<std::uint64_t>& mesh_edges_;
  std::size_t max_new_;
  std::unordered_map<std::uint32_t, double> sigma_;
  std::unordered_map<std::uint64_t, std::array<std::uint32_t, 2>> edge_tris_;
  std::unordered_map<std::uint64_t, Vec3> border_;  // loop edge -> unit normal of the mesh's triangle
  std::vector<std::uint64_t> work_;
};

}  // namespace

std::vector<std::string> FillOptions::validate() const {
  std::vector<std::string> errors;
  if (max_edges > kLimit)
    errors.push_back("hole filling is limited to loops of at most " + std::to_string(kLimit) +
                     " edges, got " + std::to_string(max_edges));
  if (!(max_width >= 0) || !std::isfinite(max_width))
    errors.push_back("the hole width limit must be a finite size of 0 or more (0: none), got " +
                     std::to_string(max_width));
  return errors;
}

FillStats fill_holes(Mesh& mesh, const FillOptions& options,
                     std::span<const float> vertex_spacing) {
  if (options.max_perimeter_spacings > 0 && vertex_spacing.size() < mesh.vertices.size())
    throw std::invalid_argument(
        "fill_holes: a perimeter limit needs the spacing of every vertex (" +
        std::to_string(vertex_spacing.size()) + " for " + std::to_string(mesh.vertices.size()) +
        " vertices)");
  FillStats stats;
  if (mesh.triangles.empty()) return stats;
  const MeshReport report = analyze(mesh, true);
  if (report.non_manifold_edges > 0 || report.non_manifold_vertices > 0 ||
      !report.orientation_consistent) {
    stats.kept = report.loops.size();
    return stats;
  }
  const std::size_t limit = std::min(options.max_edges, FillOptions::kLimit);
  // Loops too long for their local spacing are holes or borders, not sampling gaps; loops wider
  // than the width limit are holes the user keeps.
  std::vector<char> too_long(report.loops.size(), 0);
  for (std::size_t li = 0; li < report.loops.size(); ++li) {
    const std::vector<std::uint32_t>& q = report.loops[li].vertices;
    if (!report.loops[li].closed || q.size() < 3 || q.size() > limit) continue;
    if (options.max_perimeter_spacings > 0) {
      detail::LoopMeasure measure;
      for (std::size_t i = 0; i < q.size(); ++i) {
        const std::uint32_t u = q[i], w = q[(i + 1) % q.size()];
        measure.add(mesh.vertices[u], mesh.vertices[w], vertex_spacing[u], vertex_spacing[w]);
      }
      // (a loop through a non-finite coordinate is not a short one)
      too_long[li] = !measure.within(options.max_perimeter_spacings);
    }
    // (at most kLimit^2 / 2 pairs; a non-finite coordinate makes a loop too wide)
    if (options.max_width > 0 && !too_long[li])
      too_long[li] = !(loop_width(mesh, q, options.max_width) <= options.max_width);
  }
  std::vector<char> on_small_loop(mesh.vertices.size(), 0);
  for (std::size_t li = 0; li < report.loops.size(); ++li) {
    const BoundaryLoop& loop = report.loops[li];
    if (loop.closed && loop.vertices.size() >= 3 && loop.vertices.size() <= limit && !too_long[li])
      for (std::uint32_t v : loop.vertices) on_small_loop[v] = 1;
  }
  // The edges at those loops' vertices (a chord must not repeat one) and the triangle on each
  // boundary edge (directed as that triangle runs along it).
  std::vector<std::uint64_t> edges;
  CornerPairs corners;  // (v, t) for every triangle t at a small loop's vertex v
  std::vector<std::pair<std::uint64_t, std::uint32_t>> directed;
  for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
    const Triangle& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t u = tri[k], v = tri[(k + 1) % 3];
      if (!on_small_loop[u] && !on_small_loop[v]) continue;
      edges.push_back(undirected_key(u, v));
      if (on_small_loop[u]) corners.emplace_back(u, t);
      if (on_small_loop[u] && on_small_loop[v])
        directed.emplace_back((std::uint64_t{u} << 32) | v, t);
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  std::sort(directed.begin(), directed.end());
  std::sort(corners.begin(), corners.end());
  auto triangle_on = [&](std::uint32_t u, std::uint32_t v) {
    const std::uint64_t key = (std::uint64_t{u} << 32) | v;
    const auto it = std::lower_bound(directed.begin(), directed.end(),
                                     std::make_pair(key, std::uint32_t{0}));
    return it != directed.end() && it->first == key ? it->second : kNone;
  };

  // How far each loop's patch may go: faired, refined (no fairing), the minimum-weight patch
  // (no new vertex), or none (the loop stays open).
  enum Level : std::uint8_t { kFair, kRefine, kPlain, kOpen };
  const Level start = options.refine ? kFair : kPlain;
  std::vector<Level> level(report.loops.size(), start);
  const std::size_t mesh_triangles = mesh.triangles.size(), mesh_vertices = mesh.vertices.size();
  std::vector<Vec3> border;
  // Closes loop li at its level, appending the patch; false when the loop is kept open.
  auto fill_loop = [&](std::size_t li) {
    const std::vector<std::uint32_t>& q = report.loops[li].vertices;
    if (!report.loops[li].closed || q.size() < 3 || q.size() > limit || too_long[li] ||
        level[li] == kOpen)
      return false;
    // The rim of a lone triangle: its patch would be the same triangle turned over. Any
    // triangle on these three vertices has the boundary edge q0 -> q1, so one look-up tells.
    if (q.size() == 3) {
      const std::uint32_t t = triangle_on(q[0], q[1]);
      if (t != kNone) {
        const Triangle& tri = mesh.triangles[t];
        if (tri[0] == q[2] || tri[1] == q[2] || tri[2] == q[2]) return false;
      }
    }
    border.assign(q.size(), Vec3::Zero());
    for (std::size_t i = 0; i < q.size(); ++i) {
      const std::uint32_t t = triangle_on(q[i], q[(i + 1) % q.size()]);
      if (t == kNone) return false;
      const Triangle& tri = mesh.triangles[t];
      const Vec3 normal = (mesh.vertices[tri[1]] - mesh.vertices[tri[0]])
                              .cross(mesh.vertices[tri[2]] - mesh.vertices[tri[0]]);
      if (normal.norm() > 0) border[i] = normal.normalized();
    }
    const std::size_t before = mesh.triangles.size();
    if (!LoopFiller(mesh.vertices, q, border, edges).run(mesh.triangles)) return false;
    if (level[li] != kPlain) {
      PatchRefiner refiner(mesh, before, q, border, corners, edges);
      if (refiner.run(level[li] == kFair) == PatchRefiner::Outcome::kFaired) ++stats.faired;
      stats.vertices += refiner.added();
    }
    ++stats.filled;
    stats.triangles += mesh.triangles.size() - before;
    return true;
  };
  // patch_of[t - mesh_triangles]: the loop whose patch triangle t is
  std::vector<std::uint32_t> patch_of;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> crossed;  // (loop, mesh triangle)
  while (true) {
    stats = {};
    patch_of.clear();
    for (std::size_t li = 0; li < report.loops.size(); ++li) {
      if (fill_loop(li)) {
        patch_of.resize(mesh.triangles.size() - mesh_triangles, static_cast<std::uint32_t>(li));
      } else {
        ++stats.kept;
        if (level[li] == kOpen) ++stats.crossing;
      }
    }
    // Guard: a patch must not cross the mesh, another patch or itself (a hole across a thin
    // part, a scan border capped through the surface, a faired patch bulging through a wall).
    // Every loop whose patch does is filled again one level flatter, until none does.
    bool demoted = false;
    if (!patch_of.empty()) {
      const SelfIntersections crossing = find_self_intersections(mesh, kAllPairs, mesh_triangles);
      std::vector<char> crosses(report.loops.size(), 0);
      auto loop_of = [&](std::uint32_t t) {
        return t >= mesh_triangles ? patch_of[t - mesh_triangles] : kNone;
      };
      // First the patches that cross the mesh or themselves; then, of two patches that only
      // cross each other, the larger loop's (the later one on a tie) yields.
      for (const auto& [t1, t2] : crossing.examples) {
        const std::uint32_t a = loop_of(t1), b = loop_of(t2);
        if (a == kNone || b == kNone || a == b) crosses[a == kNone ? b : a] = 1;
      }
      for (const auto& [t1, t2] : crossing.examples) {
        const std::uint32_t a = loop_of(t1), b = loop_of(t2);
        if (a == kNone || b == kNone || a == b || crosses[a] || crosses[b]) continue;
        const std::size_t na = report.loops[a].vertices.size(), nb = report.loops[b].vertices.size();
        crosses[na > nb || (na == nb && a > b) ? a : b] = 1;
      }
      // The mesh triangles that a loop's flattest patch crosses, for untangle_gaps.
      for (const auto& [t1, t2] : crossing.examples) {
        const std::uint32_t a = loop_of(t1), b = loop_of(t2);
        if (a == kNone && b != kNone && crosses[b] && level[b] == kPlain)
          crossed.emplace_back(b, t1);
      }
      for (std::size_t li = 0; li < level.size(); ++li)
        if (crosses[li] && level[li] != kOpen) {
          level[li] = static_cast<Level>(level[li] + 1);
          demoted = true;
        }
    }
    if (!demoted) break;
    mesh.triangles.resize(mesh_triangles);
    mesh.vertices.resize(mesh_vertices);
  }
  std::sort(crossed.begin(), crossed.end());
  crossed.erase(std::unique(crossed.begin(), crossed.end()), crossed.end());
  for (std::size_t i = 0; i < crossed.size(); ++i) {
    if (i == 0 || crossed[i].first != crossed[i - 1].first) stats.crossed.emplace_back();
    stats.crossed.back().push_back(crossed[i].second);
  }
  return stats;
}

namespace {

/// The triangles of vertex v's fans other than its largest, once the triangles `removed`
/// (sorted) are gone; empty when they form one fan. `undecided` is set when one of them repeats
/// a corner.
std::vector<std::uint32_t> smaller_fans(const Mesh& mesh, const detail::VertexTriangles& vt,
                                        std::span<const std::uint32_t> removed, std::uint32_t v,
                                        bool& undecided) {
  std::vector<std::uint32_t> ids;
  for (std::uint32_t t : vt.of(v)) {
    if (std::binary_search(removed.begin(), removed.end(), t)) continue;
    const Triangle& tri = mesh.triangles[t];
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
      undecided = true;
      return {};
    }
    ids.push_back(t);
  }
  std::vector<int> fan;
  std::vector<std::uint32_t> size;
  if (detail::fans_of(mesh.triangles, v, ids.data(), static_cast<std::uint32_t>(ids.size()), fan,
                      size) <= 1)
    return {};
  auto root = [&](std::size_t i) {
    int r = static_cast<int>(i);
    while (fan[static_cast<std::size_t>(r)] >= 0) r = fan[static_cast<std::size_t>(r)];
    return static_cast<std::size_t>(r);
  };
  // The largest fan stays; of equal ones, the fan of the earliest triangle (the lists are in
  // triangle order, so the first root met of a size is that fan's).
  std::size_t largest = 0;
  bool found = false;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const std::size_t r = root(i);
    if (!found || size[r] > size[largest]) {
      largest = r;
      found = true;
    }
  }
  std::vector<std::uint32_t> out;
  for (std::size_t i = 0; i < ids.size(); ++i)
    if (root(i) != largest) out.push_back(ids[i]);
  return out;
}

/// The triangles of an edge-connected piece of at most kUntangleSpeck triangles that vertex v's
/// triangles other than `removed` (sorted) make, which a removal cut loose (empty when none).
std::vector<std::uint32_t> speck_at(const Mesh& mesh, const detail::VertexTriangles& vt,
                                    std::span<const std::uint32_t> removed, std::uint32_t v) {
  auto kept = [&](std::uint32_t t) {
    return !std::binary_search(removed.begin(), removed.end(), t);
  };
  std::vector<std::uint32_t> out;
  for (std::uint32_t t0 : vt.of(v)) {
    if (!kept(t0) || std::find(out.begin(), out.end(), t0) != out.end()) continue;
    std::vector<std::uint32_t> piece{t0};
    for (std::size_t q = 0; q < piece.size() && piece.size() <= kUntangleSpeck; ++q) {
      const Triangle& t = mesh.triangles[piece[q]];
      for (int k = 0; k < 3 && piece.size() <= kUntangleSpeck; ++k) {
        const std::uint32_t a = t[k], b = t[(k + 1) % 3];
        for (std::uint32_t o : vt.of(a)) {
          if (!kept(o) || std::find(piece.begin(), piece.end(), o) != piece.end()) continue;
          const Triangle& ot = mesh.triangles[o];
          if (ot[0] == b || ot[1] == b || ot[2] == b) piece.push_back(o);
        }
      }
    }
    if (piece.size() <= kUntangleSpeck) out.insert(out.end(), piece.begin(), piece.end());
  }
  return out;
}

/// Whether every boundary loop through the corners `loose` of the triangles `removed` (sorted),
/// once they are gone, is one fill_holes may close: at least 3 and at most options.max_edges
/// edges, a perimeter within options.max_perimeter_spacings of its spacing. Walked on the mesh's
/// own triangles, so a widened removal that cannot help costs no trial (a copy, a fill and two
/// analyses of the whole mesh: 90 ms of a 1.1 s run on a 6-view line scan). True where a corner
/// has more than one boundary edge out (the trial decides).
bool loops_fillable(const Mesh& mesh, const detail::VertexTriangles& vt,
                    std::span<const std::uint32_t> removed, std::span<const std::uint32_t> loose,
                    const FillOptions& options, std::span<const float> vertex_spacing) {
  auto kept = [&](std::uint32_t t) {
    return !std::binary_search(removed.begin(), removed.end(), t);
  };
  // The one boundary edge out of u, u -> w, that the triangles left have (false: none, or more
  // than one, then `ambiguous`).
  bool ambiguous = false;
  auto out_edge = [&](std::uint32_t u, std::uint32_t& w) {
    std::size_t count = 0;
    for (std::uint32_t t : vt.of(u)) {
      if (!kept(t)) continue;
      const Triangle& tri = mesh.triangles[t];
      const int k = tri[0] == u ? 0 : tri[1] == u ? 1 : 2;
      const std::uint32_t next = tri[(k + 1) % 3];
      bool twin = false;
      for (std::uint32_t o : vt.of(u)) {
        if (!kept(o)) continue;
        const Triangle& ot = mesh.triangles[o];
        for (int m = 0; m < 3; ++m) twin |= ot[m] == next && ot[(m + 1) % 3] == u;
      }
      if (!twin) {
        ++count;
        w = next;
      }
    }
    if (count > 1) ambiguous = true;
    return count == 1;
  };
  const std::size_t limit = std::min(options.max_edges, FillOptions::kLimit);
  for (std::uint32_t start : loose) {
    std::uint32_t cur = start, next = 0;
    if (!out_edge(cur, next)) {
      if (ambiguous) return true;
      continue;  // inside the mesh, or stranded
    }
    detail::LoopMeasure measure;
    std::size_t edges = 0;
    do {
      if (!out_edge(cur, next)) return true;  // a pinch or an open walk: the trial decides
      measure.add(mesh.vertices[cur], mesh.vertices[next], vertex_spacing[cur],
                  vertex_spacing[next]);
      cur = next;
      if (++edges > limit) return false;
    } while (cur != start);
    if (edges < 3) return false;
    if (options.max_perimeter_spacings > 0 && !measure.within(options.max_perimeter_spacings))
      return false;
  }
  return true;
}

/// One gap's untangling (see untangle_gaps): `mesh` and `st` unchanged when it does not help.
/// `before` is analyze(mesh), computed here when first needed; `vt` the triangles of mesh's
/// vertices. Stranded vertices that cannot be put back are appended to `dropped` (they stay in
/// mesh.vertices, unused). Returns whether the mesh changed.
bool untangle_one(Mesh& mesh, std::optional<MeshReport>& before, const detail::VertexTriangles& vt,
                  const FillOptions& options, std::span<const float> vertex_spacing,
                  std::span<const std::uint32_t> gap_crossed, UntangleStats& st,
                  std::vector<std::uint32_t>& dropped) {
  std::vector<std::uint32_t> crossed(gap_crossed.begin(), gap_crossed.end());
  std::vector<std::uint32_t> loose;  // corners of the removed triangles
  // A removal that leaves a corner of the removed triangles with two fans leaves a mesh that
  // fill_holes cannot mend: the corner's smaller fans go too (a few rounds, a few triangles),
  // or the gap is left alone. Said here from the corners' own triangles instead of after a
  // copy of the mesh, a fill and an analysis of the whole of it (on a six-view line scan of 205k
  // points, three such trials were a fifth of the reconstruction's instructions).
  bool widened = false;
  for (int round = 0;; ++round) {
    loose.clear();
    for (std::uint32_t t : crossed)
      loose.insert(loose.end(), mesh.triangles[t].begin(), mesh.triangles[t].end());
    std::sort(loose.begin(), loose.end());
    loose.erase(std::unique(loose.begin(), loose.end()), loose.end());
    std::vector<std::uint32_t> more;
    bool undecided = false;
    for (std::uint32_t v : loose) {
      const auto extra = smaller_fans(mesh, vt, crossed, v, undecided);
      more.insert(more.end(), extra.begin(), extra.end());
      const auto speck = speck_at(mesh, vt, crossed, v);
      more.insert(more.end(), speck.begin(), speck.end());
    }
    std::sort(more.begin(), more.end());
    more.erase(std::unique(more.begin(), more.end()), more.end());
    if (undecided) return false;
    if (more.empty()) break;
    if (round == kUntangleRounds || crossed.size() + more.size() > kUntangleMaxTriangles) {
      ++st.split_fans;
      return false;
    }
    crossed.insert(crossed.end(), more.begin(), more.end());
    std::sort(crossed.begin(), crossed.end());
    crossed.erase(std::unique(crossed.begin(), crossed.end()), crossed.end());
    widened = true;
  }
  if (widened && !loops_fillable(mesh, vt, crossed, loose, options, vertex_spacing)) {
    ++st.unfillable;
    return false;
  }
  if (!before) before = analyze(mesh);
  Mesh trial;
  trial.vertices = mesh.vertices;
  trial.triangles.reserve(mesh.triangles.size());
  std::vector<std::uint32_t> uses(mesh.vertices.size(), 0);
  std::size_t next = 0;
  for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
    const Triangle& tri = mesh.triangles[t];
    if (next < crossed.size() && crossed[next] == t) {
      ++next;
      continue;
    }
    trial.triangles.push_back(tri);
    for (std::uint32_t v : tri) ++uses[v];
  }
  std::vector<std::uint32_t> stranded;
  for (std::uint32_t v : loose)
    if (uses[v] == 0) stranded.push_back(v);
  const std::size_t kept = trial.triangles.size();
  fill_holes(trial, options, vertex_spacing);
  // A stranded vertex goes back into the patch triangle it lies in, split in three, or, when
  // it lies on one of the triangle's edges (a point left in the middle of a gap's edge), into
  // that edge, split with the triangles on both sides. Every part keeps its triangle's
  // orientation; none is a sliver (the vertex is not near a corner).
  constexpr double kMinShare = 0.1;  // barycentric coordinates, of the other corners at least
  std::size_t reinserted = 0;
  std::vector<std::size_t> rewritten;  // triangles below `kept` that an edge split changed
  auto split_edge = [&](std::size_t t, int k, std::uint32_t s) {
    const Triangle tri = trial.triangles[t];
    const std::uint32_t w = tri[k], u = tri[(k + 1) % 3], v = tri[(k + 2) % 3];
    trial.triangles[t] = {w, u, s};
    trial.triangles.push_back({w, s, v});
    for (std::size_t o = 0; o < trial.triangles.size(); ++o) {  // the triangle across: v -> u
      const Triangle other = trial.triangles[o];
      for (int m = 0; m < 3; ++m) {
        if (other[m] != v || other[(m + 1) % 3] != u) continue;
        const std::uint32_t x = other[(m + 2) % 3];
        trial.triangles[o] = {x, v, s};
        trial.triangles.push_back({x, s, u});
        if (o < kept) rewritten.push_back(o);
        return;
      }
    }
  };
  for (std::uint32_t s : stranded) {
    const Vec3& p = trial.vertices[s];
    for (std::size_t t = kept; t < trial.triangles.size(); ++t) {
      const Triangle tri = trial.triangles[t];
      const Vec3 &a = trial.vertices[tri[0]], &b = trial.vertices[tri[1]],
                 &c = trial.vertices[tri[2]];
      const Vec3 n = (b - a).cross(c - a);
      const double n2 = n.squaredNorm();
      if (!(n2 > 0)) continue;
      if (std::abs((p - a).dot(n)) > 0.25 * vertex_spacing[s] * std::sqrt(n2)) continue;
      const double share[3] = {(c - b).cross(p - b).dot(n) / n2, (a - c).cross(p - c).dot(n) / n2,
                               (b - a).cross(p - a).dot(n) / n2};
      int low = -1, lows = 0;
      for (int k = 0; k < 3; ++k)
        if (!(share[k] > kMinShare)) {
          low = k;
          ++lows;
        }
      if (lows == 0) {
        trial.triangles[t] = {tri[0], tri[1], s};
        trial.triangles.push_back({tri[1], tri[2], s});
        trial.triangles.push_back({tri[2], tri[0], s});
      } else if (lows == 1 && share[low] > -kMinShare) {
        split_edge(t, low, s);
      } else {
        continue;
      }
      ++reinserted;
      break;
    }
  }
  // Everything new at the end, for the crossing test: the triangles an edge split changed
  // below `kept` move there.
  std::sort(rewritten.begin(), rewritten.end());
  rewritten.erase(std::unique(rewritten.begin(), rewritten.end()), rewritten.end());
  for (auto it = rewritten.rbegin(); it != rewritten.rend(); ++it) {
    const Triangle moved = trial.triangles[*it];
    trial.triangles.erase(trial.triangles.begin() + static_cast<std::ptrdiff_t>(*it));
    trial.triangles.push_back(moved);
  }
  const std::size_t unchanged = kept - rewritten.size();
  // A vertex of a wrongly meshed fold that lies on no patch (widened removals only) leaves the
  // mesh, reported with the outliers.
  st.widened += widened ? 1 : 0;
  const std::size_t left_out = stranded.size() - reinserted;
  if (left_out > (widened ? kUntangleMaxDropped : 0)) return false;
  const MeshReport after = analyze(trial);
  if (after.non_manifold_edges > 0 || after.non_manifold_vertices > 0 ||
      !after.orientation_consistent || after.boundary_loops >= before->boundary_loops ||
      after.components != before->components ||
      find_self_intersections(trial, 1, unchanged).pairs > 0)
    return false;
  if (left_out > 0) {
    std::vector<std::uint32_t> used(mesh.vertices.size(), 0);
    for (const Triangle& t : trial.triangles)
      for (std::uint32_t v : t) used[v] = 1;
    for (std::uint32_t v : stranded)
      if (!used[v]) dropped.push_back(v);
  }
  st.removed += crossed.size();
  st.closed += before->boundary_loops - after.boundary_loops;
  st.reinserted += reinserted;
  mesh = std::move(trial);
  return true;
}

}  // namespace

UntangleStats untangle_gaps(Mesh& mesh, const FillOptions& options,
                            std::span<const float> vertex_spacing, const FillStats& first) {
  UntangleStats st;
  if (vertex_spacing.size() < mesh.vertices.size()) return st;
  // Gap by gap, each on the mesh the ones before left, which renumbered the triangles: the
  // crossed triangles are found by their corners (one an earlier gap changed is gone, and that
  // gap is left alone).
  std::vector<std::vector<Triangle>> targets;
  for (const std::vector<std::uint32_t>& crossed : first.crossed) {
    if (crossed.empty() || crossed.size() > 2 * options.max_edges) continue;
    std::vector<Triangle>& tris = targets.emplace_back();
    for (std::uint32_t t : crossed) tris.push_back(mesh.triangles[t]);
    std::sort(tris.begin(), tris.end());
  }
  if (targets.size() > kMaxUntangledGaps) {
    st.skipped = targets.size() - kMaxUntangledGaps;
    targets.resize(kMaxUntangledGaps);
  }
  if (targets.empty()) return st;
  // The corner lists below index by vertex: a triangle naming a vertex beyond the mesh is the
  // error analyze() reports (it throws, naming the triangle).
  const auto n = mesh.vertices.size();
  if (std::any_of(mesh.triangles.begin(), mesh.triangles.end(), [n](const Triangle& t) {
        return t[0] >= n || t[1] >= n || t[2] >= n;
      }))
    (void)analyze(mesh);
  std::vector<std::uint32_t> list;
  std::optional<MeshReport> report;  // of the mesh as it is now, once needed
  std::optional<detail::VertexTriangles> vt;
  std::vector<std::uint32_t> dropped;
  for (const std::vector<Triangle>& tris : targets) {
    // Every triangle equal to one of the gap's (there is one each unless an earlier gap's
    // untangling removed it; a duplicate would be found twice): through their first corners.
    if (!vt) vt.emplace(mesh.vertices.size(), mesh.triangles);
    list.clear();
    for (std::size_t i = 0; i < tris.size(); ++i) {
      if (i > 0 && tris[i] == tris[i - 1]) continue;
      for (std::uint32_t t : vt->of(tris[i][0]))
        if (mesh.triangles[t] == tris[i]) list.push_back(t);
    }
    std::sort(list.begin(), list.end());
    if (list.size() != tris.size()) continue;
    if (untangle_one(mesh, report, *vt, options, vertex_spacing, list, st, dropped)) {
      report.reset();
      vt.reset();
    }
  }
  if (!dropped.empty()) {
    // The vertices left out go; the others keep their order.
    std::sort(dropped.begin(), dropped.end());
    st.renumber.assign(mesh.vertices.size(), kNoVertex);
    std::uint32_t next = 0;
    std::size_t d = 0;
    for (std::uint32_t v = 0; v < mesh.vertices.size(); ++v) {
      if (d < dropped.size() && dropped[d] == v) {
        st.dropped.push_back(mesh.vertices[v]);
        ++d;
        continue;
      }
      mesh.vertices[next] = mesh.vertices[v];
      st.renumber[v] = next++;
    }
    mesh.vertices.resize(next);
    for (Triangle& t : mesh.triangles)
      for (std::uint32_t& v : t) v = st.renumber[v];
  }
  return st;
}

}  // namespace scanmesh::recon
