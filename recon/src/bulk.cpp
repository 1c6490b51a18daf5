// Bulk meshing: planar Delaunay triangulation of height-field patches (see bulk.hpp).
// SPDX-License-Identifier: MIT
#include "bulk.hpp"

#include "delaunay2.hpp"
#include "triangle_shape.hpp"


#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

namespace scanmesh::recon::detail {
namespace {

constexpr std::uint32_t kNone = 0xffffffffu;

struct Cell {
  std::uint64_t key;  // z << 42 | y << 21 | x: cells come in this order from the grid
  std::uint32_t first, last;
  Eigen::Vector3f mean;  // mean normal of its eligible points (unit)
  std::uint32_t row = 0;  // index in the rows (runs of cells with one y and z)
  bool ok = false;        // it has eligible points
  bool clean = false;     // all its points are in its patch's triangulation
};

struct Row {
  std::uint64_t yz;  // z << 21 | y
  std::uint32_t first, end;  // its cells
};

std::uint64_t cell_key(std::int64_t x, std::int64_t y, std::int64_t z) {
  return (static_cast<std::uint64_t>(z) << 42) | (static_cast<std::uint64_t>(y) << 21) |
         static_cast<std::uint64_t>(x);
}

class Bulk {
 public:
  Bulk(std::span<const Vec3> p, const LocalFrames& f, const PointGrid& g,
       std::span<const std::uint8_t> excluded, const BulkOptions& o, BulkMesh& out, BulkStats& s)
      : p_(p), f_(f), grid_(g), excluded_(excluded), opt_(o), stats_(s), out_(out),
        first_triangle_(out.triangles.size()) {}

  void run() {
    collect_cells();
    patch_of_.assign(cells_.size(), kNone);
    slot_patch_.assign(p_.size(), kNone);
    cos_theta_ = static_cast<float>(std::cos(opt_.patch_cone_deg * std::numbers::pi / 180));
    std::vector<std::uint32_t> patch;
    std::uint32_t next_id = 0;
    for (std::uint32_t c = 0; c < cells_.size(); ++c) {
      if (!cells_[c].ok || patch_of_[c] != kNone) continue;
      // Grow a patch breadth-first from c (cells in key order): a neighbour joins when its mean
      // normal lies within the cone around c's; its points outside the cone stay out.
      const std::uint32_t id = next_id++;
      const Eigen::Vector3f dir = cells_[c].mean;
      patch.clear();
      patch.push_back(c);
      patch_of_[c] = id;
      std::size_t count = cells_[c].last - cells_[c].first;
      for (std::size_t head = 0; head < patch.size(); ++head) {
        for_each_neighbour(patch[head], [&](std::uint32_t d) {
          const Cell& cd = cells_[d];
          if (!cd.ok || patch_of_[d] != kNone || count >= opt_.max_patch_points) return;
          if (cd.mean.dot(dir) < cos_theta_) return;
          patch_of_[d] = id;
          patch.push_back(d);
          count += cd.last - cd.first;
        });
      }
      if (count < 3) continue;  // left to the front; its cells stay marked (not re-grown)
      ++stats_.patches;
      stats_.patch_points += count;
      std::sort(patch.begin(), patch.end());  // grid order: the patch's own arrays are spatial
      triangulate(patch, id, dir.cast<double>());
    }
    stats_.triangles = out_.triangles.size() - first_triangle_;
  }

 private:
  void collect_cells() {
    const std::vector<std::uint32_t>& order = grid_.order();
    grid_.for_each_cell([&](std::int64_t x, std::int64_t y, std::int64_t z, std::uint32_t first,
                            std::uint32_t last) {
      Cell c{cell_key(x, y, z), first, last, Eigen::Vector3f(0, 0, 1)};
      const std::uint64_t yz = c.key >> 21;
      const auto here = static_cast<std::uint32_t>(cells_.size());
      if (rows_.empty() || rows_.back().yz != yz) rows_.push_back({yz, here, here});
      ++rows_.back().end;
      c.row = static_cast<std::uint32_t>(rows_.size() - 1);
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      for (std::uint32_t s = first; s < last; ++s)
        if (eligible(order[s])) sum += f_.normal[order[s]];
      const float len = sum.norm();
      if (len > 0) {
        c.mean = sum / len;
        c.ok = true;
      }
      cells_.push_back(c);
    });
    // The nine rows around each row (dz, dy ascending), or kNone.
    row_near_.assign(9 * rows_.size(), kNone);
    for (std::uint32_t r = 0; r < rows_.size(); ++r) {
      const auto y = static_cast<std::int64_t>(rows_[r].yz & kMask), z = static_cast<std::int64_t>(rows_[r].yz >> 21);
      for (std::int64_t dz = -1, k = 0; dz <= 1; ++dz)
        for (std::int64_t dy = -1; dy <= 1; ++dy, ++k) {
          if (y + dy < 0 || z + dz < 0) continue;
          const std::uint64_t yz = (static_cast<std::uint64_t>(z + dz) << 21) | static_cast<std::uint64_t>(y + dy);
          const auto it = std::lower_bound(rows_.begin(), rows_.end(), yz,
                                           [](const Row& q, std::uint64_t v) { return q.yz < v; });
          if (it != rows_.end() && it->yz == yz)
            row_near_[9 * r + static_cast<std::size_t>(k)] = static_cast<std::uint32_t>(it - rows_.begin());
        }
    }
  }

  [[nodiscard]] bool eligible(std::uint32_t v) const { return excluded_.empty() || excluded_[v] == 0; }

  /// Calls f(d) for every occupied cell d next to cell c (26-neighbourhood), in key order.
  template <class F>
  void for_each_neighbour(std::uint32_t c, F&& f) const {
    const std::uint64_t x = cells_[c].key & kMask;
    const std::uint64_t lo = x > 0 ? x - 1 : 0, hi = x + 1;
    const std::uint32_t* near = &row_near_[9 * std::size_t{cells_[c].row}];
    for (int k = 0; k < 9; ++k) {
      if (near[k] == kNone) continue;
      const Row& r = rows_[near[k]];
      // The row's cells are in x order: the three around x are consecutive.
      const Cell* first = cells_.data() + r.first;
      const Cell* end = cells_.data() + r.end;
      const Cell* it = end - first > 8 ? std::lower_bound(first, end, lo, [](const Cell& q, std::uint64_t v) {
        return (q.key & kMask) < v;
      })
                                       : first;
      for (; it != end && (it->key & kMask) <= hi; ++it) {
        if ((it->key & kMask) < lo) continue;
        const auto d = static_cast<std::uint32_t>(it - cells_.data());
        if (d != c) f(d);
      }
    }
  }

  [[nodiscard]] double spacing(std::uint32_t v) const {
    return opt_.spacing[v];
  }

  /// Whether a point outside patch `id` lies strictly inside the circumsphere of (a, b, c).
  [[nodiscard]] bool foreign_inside(const Vec3& a, const Vec3& b, const Vec3& c, std::uint32_t id) const {
    const Vec3 u = a - c, w = b - c;
    const Vec3 uxw = u.cross(w);
    const double d = 2 * uxw.squaredNorm();
    if (!(d > 0)) return true;
    const Vec3 centre = c + (u.squaredNorm() * w - w.squaredNorm() * u).cross(uxw) / d;
    const double r2 = (a - centre).squaredNorm() * (1 - 1e-9);
    const std::vector<std::uint32_t>& order = grid_.order();
    bool found = false;
    grid_.for_each_range_within(centre, std::sqrt(r2), [&](std::uint32_t first, std::uint32_t last) {
      for (std::uint32_t s = first; s < last && !found; ++s)
        if (slot_patch_[s] != id && (p_[order[s]] - centre).squaredNorm() < r2) found = true;
    });
    return found;
  }

  void triangulate(const std::vector<std::uint32_t>& patch, std::uint32_t id, const Vec3& dir) {
    const std::vector<std::uint32_t>& order = grid_.order();
    const Eigen::Vector3f dir_f = dir.cast<float>();
    local_.clear();
    xy_.clear();
    lpos_.clear();
    lnrm_.clear();
    lspc_.clear();
    Vec3 sum = Vec3::Zero();
    for (std::size_t i = 0; i < patch.size(); ++i) {
      const Cell& c = cells_[patch[i]];
      for (std::uint32_t s = c.first; s < c.last; ++s) {
        const std::uint32_t pt = order[s];
        // Turning points and normals outside the patch's cone are left to the front.
        if (!eligible(pt) || f_.normal[pt].dot(dir_f) < cos_theta_) continue;
        local_.push_back({pt, s, static_cast<std::uint32_t>(i)});
        lpos_.push_back(p_[pt]);
        lnrm_.push_back(f_.normal[pt].cast<double>());
        lspc_.push_back(spacing(pt));
        sum += lnrm_.back();
      }
    }
    // Projected along the mean normal of the patch's points (less tilt than the seed cell's
    // direction, so the planar Delaunay choice is nearer the surface's own), unless some point
    // would then be steeper than the cone allows.
    Vec3 axis = sum.norm() > 0 ? Vec3(sum.normalized()) : dir;
    for (const Vec3& nm : lnrm_)
      if (nm.dot(axis) < cos_theta_) {
        axis = dir;
        break;
      }
    // A right-handed frame (u, v, axis): counter-clockwise in (u, v) is oriented with the
    // normals (every one within the cone around the axis).
    const Vec3 helper = std::abs(axis.x()) < 0.9 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
    const Vec3 u = helper.cross(axis).normalized();
    const Vec3 v = axis.cross(u);
    for (const Vec3& q : lpos_) xy_.push_back({q.dot(u), q.dot(v)});
    dt_.triangulate(xy_);
    // Too few points, or all in one line: left to the front. So is a point whose projection
    // repeats one already in.
    if (dt_.triangle_count() == 0) return;
    const std::size_t nv = local_.size();
    for (std::uint32_t j = 0; j < nv; ++j)
      if (dt_.inserted(j)) slot_patch_[local_[j].slot] = id;
    // inner: the cell's points and those of every occupied neighbour cell are all in the
    // triangulation, so no point outside it can lie in a triangle between its points.
    for (const std::uint32_t c : patch) {
      cells_[c].clean = true;
      for (std::uint32_t s = cells_[c].first; s < cells_[c].last; ++s)
        if (slot_patch_[s] != id) cells_[c].clean = false;
    }
    std::vector<std::uint8_t> inner(patch.size());
    for (std::size_t i = 0; i < patch.size(); ++i) {
      inner[i] = cells_[patch[i]].clean ? 1 : 0;
      if (inner[i])
        for_each_neighbour(patch[i], [&](std::uint32_t d) {
          if (patch_of_[d] != id || !cells_[d].clean) inner[i] = 0;
        });
    }
    const double cell = grid_.cell();
    const std::span<const std::uint32_t> corner = dt_.corners(), twin = dt_.twins();
    const std::size_t nt = dt_.triangle_count();
    kept_.assign(nt, 0);
    normal_.resize(nt);
    for (std::size_t t = 0; t < nt; ++t) {
      // The patch's own copies of its points' data: contiguous, in grid order.
      const std::uint32_t* q = &corner[3 * t];
      const Vec3 &a = lpos_[q[0]], &b = lpos_[q[1]], &c = lpos_[q[2]];
      const Vec3 e[3] = {c - b, a - c, b - a};  // edge k is opposite corner k
      bool ok = true;
      double longest2 = 0;
      for (int k = 0; k < 3 && ok; ++k) {
        const double len2 = e[k].squaredNorm();
        const double r = opt_.radius_factor * std::max(lspc_[q[(k + 1) % 3]], lspc_[q[(k + 2) % 3]]);
        ok = len2 > 0 && len2 <= r * r;
        longest2 = std::max(longest2, len2);
      }
      if (!ok || min_angle_cos(a, b, c) > opt_.cos_min_angle) continue;
      const Vec3 n = (b - a).cross(c - a).normalized();
      for (int k = 0; k < 3 && ok; ++k)
        ok = lnrm_[q[k]].dot(n) >= opt_.cos_corner;
      if (!ok) continue;
      // Near the patch's border (or longer than a cell), a point of another patch or a point
      // the patch left out could lie in the triangle: the circumsphere must hold none.
      const bool sheltered = inner[local_[q[0]].cell] && inner[local_[q[1]].cell] && inner[local_[q[2]].cell] &&
                             longest2 <= cell * cell;
      if (!sheltered && foreign_inside(a, b, c, id)) continue;
      kept_[t] = longest2 > opt_.long_edge2 ? kKeptLong : 1;
      normal_[t] = n.cast<float>();
    }
    // No fold between kept neighbours (both faces of such a pair are dropped), and the fans to
    // examine: only vertices beside a face not kept (or on the hull) can have several fans; a
    // closed fan only needs its size checked. One pass: a face dropped here queues its corners.
    vstate_.assign(nv, {});
    queue_.clear();
    auto enqueue = [&](std::uint32_t w) {
      if (vstate_[w].queued) return;
      vstate_[w].queued = true;
      queue_.push_back(w);
    };
    auto drop = [&](std::size_t t) {
      kept_[t] = 0;
      for (std::size_t k = 0; k < 3; ++k) enqueue(corner[3 * t + k]);
    };
    const auto cos_fold = static_cast<float>(opt_.cos_dihedral);
    for (std::size_t t = 0; t < nt; ++t) {
      if (!kept_[t]) {
        for (std::size_t k = 0; k < 3; ++k) enqueue(corner[3 * t + k]);
        continue;
      }
      for (std::size_t k = 0; k < 3; ++k) {
        const std::uint32_t g = twin[3 * t + k];
        if (g == Delaunay2::kNone) {  // a hull edge
          enqueue(corner[3 * t + k]);
          enqueue(corner[Delaunay2::next(static_cast<std::uint32_t>(3 * t + k))]);
          continue;
        }
        if (!kept_[t] || !kept_[g / 3]) continue;
        if (normal_[t].dot(normal_[g / 3]) <= cos_fold) {
          drop(t);
          drop(g / 3);
        }
      }
      // Counted before a later neighbour may drop it: an upper bound, enough to find the fans
      // that may be too large (the walk below counts exactly).
      for (std::size_t k = 0; k < 3; ++k) ++vstate_[corner[3 * t + k]].degree;
    }
    for (std::uint32_t j = 0; j < nv; ++j)
      if (vstate_[j].degree > opt_.max_valence) enqueue(j);
    auto kept = [&](std::uint32_t t) { return t != Delaunay2::kNone && kept_[t]; };
    while (!queue_.empty()) {
      const std::uint32_t vh = queue_.back();
      queue_.pop_back();
      vstate_[vh].queued = false;
      if (!dt_.inserted(vh)) continue;
      // The faces around vh in order; on the hull, a last slot for the outside (not kept).
      ring_.clear();
      const std::uint32_t h0 = dt_.out_edge(vh);
      std::uint32_t h = h0;
      do {
        ring_.push_back(h / 3);
        h = twin[Delaunay2::prev(h)];
      } while (h != Delaunay2::kNone && h != h0);
      if (h == Delaunay2::kNone) ring_.push_back(Delaunay2::kNone);
      const std::size_t m = ring_.size();
      std::size_t start = m;
      for (std::size_t i = 0; i < m; ++i)
        if (!kept(ring_[i])) {
          start = i;
          break;
        }
      // A vertex beside a face not kept is on the border (set again whenever its ring changes:
      // a neighbour's drop queues it once more); the others have closed fans.
      vstate_[vh].border = start != m;
      std::size_t runs = 0, best_len = 0, best_at = 0;
      if (start == m) {  // a closed fan
        if (static_cast<int>(m) <= opt_.max_valence) continue;
      } else {
        for (std::size_t i = 0; i < m;) {
          const std::size_t at = (start + i) % m;
          if (!kept(ring_[at])) {
            ++i;
            continue;
          }
          std::size_t len = 0;
          while (i < m && kept(ring_[(start + i) % m])) {
            ++len;
            ++i;
          }
          ++runs;
          if (len > best_len) {
            best_len = len;
            best_at = at;
          }
        }
        if (runs <= 1 && static_cast<int>(best_len) + 1 <= opt_.max_valence) continue;
      }
      // Too many edges: drop the whole fan; several fans: keep the largest.
      const bool keep_best = start != m && static_cast<int>(best_len) + 1 <= opt_.max_valence;
      for (std::size_t i = 0; i < m; ++i) {
        const std::uint32_t t = ring_[i];
        if (!kept(t)) continue;
        if (keep_best && ((i + m - best_at) % m) < best_len) continue;
        kept_[t] = 0;
        for (std::size_t k = 0; k < 3; ++k)
          if (corner[3 * t + k] != vh) enqueue(corner[3 * t + k]);
      }
    }
    // Output: the kept faces, their border edges (across from a face not kept), and the chords
    // (edges of two kept faces between border vertices; once, from the lower half-edge).
    for (std::uint32_t t = 0; t < nt; ++t) {
      if (!kept_[t]) continue;
      const std::uint32_t* q = &corner[3 * t];
      if (kept_[t] == kKeptLong) out_.long_triangles.push_back(static_cast<std::uint32_t>(out_.triangles.size()));
      out_.triangles.push_back({local_[q[0]].point, local_[q[1]].point, local_[q[2]].point});
      for (std::uint32_t k = 0; k < 3; ++k) {
        const std::uint32_t x = q[k], y = q[(k + 1) % 3];
        const std::uint32_t g = twin[3 * t + k];  // the same edge in the face across
        if (g == Delaunay2::kNone || !kept_[g / 3])
          out_.border.push_back({local_[x].point, local_[y].point, local_[q[(k + 2) % 3]].point});
        else if (3 * t + k < g && vstate_[x].border && vstate_[y].border)
          out_.border_chords.push_back({local_[x].point, local_[y].point});
      }
    }
  }

  static constexpr std::uint64_t kMask = (std::uint64_t{1} << 21) - 1;
  std::span<const Vec3> p_;
  const LocalFrames& f_;
  const PointGrid& grid_;
  std::span<const std::uint8_t> excluded_;
  const BulkOptions& opt_;
  BulkStats& stats_;
  std::vector<Cell> cells_;
  std::vector<Row> rows_;
  std::vector<std::uint32_t> row_near_;  // per row: the nine rows around it (kNone: none)
  std::vector<std::uint32_t> patch_of_;   // per cell
  std::vector<std::uint32_t> slot_patch_;  // per grid slot: the patch of the point's cell
  BulkMesh& out_;
  std::size_t first_triangle_;
  float cos_theta_ = 1;  // cosine of the patch cone
  // Per patch, reused: its points (grid slot, cell in the patch), their projections, the
  // triangulation, and the state of its faces and vertices.
  struct Local {
    std::uint32_t point, slot, cell;
  };
  struct VertexState {
    std::uint16_t degree = 0;  // kept faces around the vertex (before the fan repairs)
    bool queued = false;
    bool border = false;  // on the border of the kept triangles
  };
  std::vector<Local> local_;
  std::vector<std::array<double, 2>> xy_;
  std::vector<Vec3> lpos_, lnrm_;  // its points' positions and normals
  std::vector<double> lspc_;       // and capped spacings
  Delaunay2 dt_;
  /// Per face of the triangulation: 0 dropped, else kept (kKeptLong: with an edge longer than
  /// long_edge2, for BulkMesh::long_triangles).
  std::vector<std::uint8_t> kept_;
  static constexpr std::uint8_t kKeptLong = 2;
  std::vector<Eigen::Vector3f> normal_;  // unit normal of a face that passed the rules
  std::vector<VertexState> vstate_;
  std::vector<std::uint32_t> queue_, ring_;
};

}  // namespace

void bulk_triangles(std::span<const Vec3> points, const LocalFrames& frames, const PointGrid& grid,
                    std::span<const std::uint8_t> excluded, const BulkOptions& options,
                    BulkMesh& out, BulkStats& stats) {
  stats = {};
  out.border.clear();
  out.border_chords.clear();
  if (points.size() < 3 || grid.empty()) return;
  Bulk(points, frames, grid, excluded, options, out, stats).run();
}

}  // namespace scanmesh::recon::detail
