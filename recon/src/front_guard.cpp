// The advancing front's crossing guard: turning points, the per-vertex triangle lists and the
// tests that keep a new triangle from crossing or overlapping the mesh.
// SPDX-License-Identifier: MIT
#include "front_builder.hpp"

namespace scanmesh::recon::front_impl {

void Builder::mark_turning_points() {
  // A point is a turning point when a point within the candidate reach has a normal more than
  // the normal rule's angle away from its own. Coarse first: per grid cell, the cone of its
  // normals (mean, widest deviation); a point whose normal is within that angle of every
  // neighbouring cell's cone has no such neighbour. The points the cones cannot clear get the
  // exact ball test.
  const std::size_t n = p_.size();
  turning_.assign(n, 0);
  if (n == 0) return;
  const double theta = std::acos(cos_normal_);
  const std::vector<std::uint32_t>& order = grid_.order();
  const std::vector<Eigen::Vector3f>& nrm = f_.normal;
  // Per cell: its first slot, the cone (mean, spread), limit = cos(theta - spread) (2: no
  // cone within theta); for the shortcuts below, a spread made safe against the rounding of
  // its float cosine (acos is ill-conditioned near 0): its cos and sin, and those of theta
  // minus it (cos_rest 2: that cone is not within theta).
  struct Cone {
    Eigen::Vector3f mean;
    float limit, cos_s, sin_s, cos_rest, sin_rest;
  };
  std::vector<std::uint32_t> cell_first, cell_of(n);  // cell_of: per slot, its cell
  std::vector<Cone> cone;
  grid_.for_each_cell([&](std::int64_t, std::int64_t, std::int64_t, std::uint32_t first,
                          std::uint32_t last) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (std::uint32_t s = first; s < last; ++s) sum += nrm[order[s]];
    const float len = sum.norm();
    const Eigen::Vector3f m = len > 0 ? Eigen::Vector3f(sum / len) : Eigen::Vector3f(1, 0, 0);
    float lowest = 1;
    for (std::uint32_t s = first; s < last; ++s) lowest = std::min(lowest, m.dot(nrm[order[s]]));
    const double spread = std::acos(std::clamp<double>(lowest, -1, 1));
    const double safe = std::acos(std::clamp<double>(static_cast<double>(lowest) - 1e-6, -1, 1));
    const bool ok = len > 0 && spread < theta;
    const bool safe_ok = len > 0 && safe < theta;
    for (std::uint32_t q = first; q < last; ++q) cell_of[q] = static_cast<std::uint32_t>(cell_first.size());
    cell_first.push_back(first);
    cone.push_back({m, ok ? static_cast<float>(std::cos(theta - spread)) : 2.0f,
                    static_cast<float>(std::cos(safe)), static_cast<float>(std::sin(safe)),
                    safe_ok ? static_cast<float>(std::cos(theta - safe)) : 2.0f,
                    static_cast<float>(std::sin(theta - safe))});
  });
  const std::size_t cells = cell_first.size();
  // Float slack of the cell-level shortcuts below (with the safe spreads): they skip only
  // where the point test would pass by more than the roundings, so the result is the point
  // test's.
  constexpr float kSlack = 1e-4f;
  // Two cones whose axes are at most theta - spread_c - spread_d apart hold no pair of normals
  // more than theta apart: cos of the axes' angle at least cos(theta - s_c - s_d), expanded.
  auto cones_agree = [&](std::size_t c, std::size_t d) {
    const Cone &cc = cone[c], &cd = cone[d];
    if (cc.cos_rest > 1 || cd.cos_rest > 1 || cc.sin_rest * cd.cos_s - cc.cos_rest * cd.sin_s <= 0)
      return false;  // theta - s_c - s_d <= 0 (its sine is the expression)
    return cc.mean.dot(cd.mean) >= cc.cos_rest * cd.cos_s + cc.sin_rest * cd.sin_s + kSlack;
  };
  grid_.for_each_cell([&](std::int64_t cx, std::int64_t cy, std::int64_t cz, std::uint32_t first,
                          std::uint32_t last) {
    const std::size_t c = cell_of[first];
    grid_.for_each_block_range(cx, cy, cz, 1, [&](std::uint32_t f, std::uint32_t l) {
      for (std::size_t d = cell_of[f]; d < cells && cell_first[d] < l; ++d) {
        if (cones_agree(c, d)) continue;
        for (std::uint32_t s = first; s < last; ++s) {
          const std::uint32_t v = order[s];
          if (!turning_[v] && nrm[v].dot(cone[d].mean) < cone[d].limit) turning_[v] = 1;
        }
      }
    });
  });
  const auto cos_limit = static_cast<float>(cos_normal_);
  for (std::uint32_t v = 0; v < n; ++v) {
    if (!turning_[v]) continue;
    const double r = opt_.radius_factor * 1.5 * spacing(v);
    const double r2 = r * r;
    const Vec3& pv = p_[v];
    const Eigen::Vector3f nv = nrm[v];
    bool found = false;
    // The ball's points cell by cell; a cell whose cone lies within theta of nv is skipped.
    grid_.for_each_range_within(pv, r, [&](std::uint32_t first, std::uint32_t last) {
      for (std::size_t d = cell_of[first]; d < cells && cell_first[d] < last && !found; ++d) {
        if (cone[d].cos_rest <= 1 && nv.dot(cone[d].mean) >= cone[d].cos_rest + kSlack) continue;
        const std::uint32_t end = std::min(last, d + 1 < cells ? cell_first[d + 1] : last);
        for (std::uint32_t s = std::max(first, cell_first[d]); s < end && !found; ++s) {
          const std::uint32_t u = order[s];
          if (nrm[u].dot(nv) < cos_limit && (p_[u] - pv).squaredNorm() <= r2) found = true;
        }
      }
    });
    turning_[v] = found ? 1 : 0;
  }
#ifndef NDEBUG
  if (check_every_step_) {
    // The cell shortcuts change nothing: the plain passes (every point against every
    // neighbouring cell's cone, then against every point of its ball) give the same flags.
    std::vector<std::uint8_t> plain(n, 0);
    grid_.for_each_cell([&](std::int64_t cx, std::int64_t cy, std::int64_t cz, std::uint32_t first,
                            std::uint32_t last) {
      grid_.for_each_block_range(cx, cy, cz, 1, [&](std::uint32_t f, std::uint32_t l) {
        for (std::size_t d = cell_of[f]; d < cells && cell_first[d] < l; ++d)
          for (std::uint32_t q = first; q < last; ++q)
            if (nrm[order[q]].dot(cone[d].mean) < cone[d].limit) plain[order[q]] = 1;
      });
    });
    for (std::uint32_t v = 0; v < n; ++v) {
      if (!plain[v]) continue;
      const double r = opt_.radius_factor * 1.5 * spacing(v);
      bool found = false;
      grid_.for_each_range_within(p_[v], r, [&](std::uint32_t first, std::uint32_t last) {
        for (std::uint32_t q = first; q < last; ++q)
          found = found || (nrm[order[q]].dot(nrm[v]) < cos_limit && (p_[order[q]] - p_[v]).squaredNorm() <= r * r);
      });
      plain[v] = found ? 1 : 0;
    }
    assert(plain == turning_ && "the turning points' cell shortcuts changed a flag");
  }
#endif
  // Points within reach of a turning point (2): a triangle there can cross one that a turning
  // point holds (a bevel across a sharp rim whose other face is unsampled: the cap beside it
  // has no turning point of its own, but the bevel's wall corner is one). Their triangles get
  // the test against everything near too; only turning points keep their lists.
  for (std::uint32_t v = 0; v < n; ++v)
    if (turning_[v] == 1) mark_near_turning(p_[v], opt_.radius_factor * 1.5 * spacing(v));
  for (std::uint8_t t : turning_) res_.turning_points += t == 1 ? 1 : 0;
}

void Builder::link_corner(std::uint32_t v, std::uint32_t tri) {
  std::uint32_t node = free_corner_;
  if (node != kNone) {
    free_corner_ = corners_[node].next;
    corners_[node] = {tri, corner_head_[v]};
  } else {
    node = static_cast<std::uint32_t>(corners_.size());
    corners_.push_back({tri, corner_head_[v]});
  }
  corner_head_[v] = node;
  slot_listed_[slot_of_[v]] = 1;
}

void Builder::release_corners(std::uint32_t v) {
  std::uint32_t node = corner_head_[v];
  if (node == kNone) return;
  std::uint32_t last = node;
  while (corners_[last].next != kNone) last = corners_[last].next;
  corners_[last].next = free_corner_;
  free_corner_ = node;
  corner_head_[v] = kNone;
  slot_listed_[slot_of_[v]] = 0;
}

void Builder::push_triangle(const Triangle& t) {
  const auto id = static_cast<std::uint32_t>(tris_.size());
  tris_.push_back(t);
  note_if_long(id);
  if (!pieces_stale_) pieces_.join(t);
  if (corner_head_.empty()) return;
  for (std::uint32_t v : t) link_corner(v, id);  // new corners are never closed yet
  mark_bent(t);
}

void Builder::mark_bent(const Triangle& t) {
  // A triangle more than 30 degrees off one of its corners' normals bends across a feature (a
  // bevel over a sharp edge). Where one face of the edge is sampled sparsely, the normals there
  // blend both faces and no turning point marks the edge, yet the triangles grown beside the
  // bevel later can cross it. So its corners become turning points (their lists stay, holding
  // the bevel), and the points within reach of it get the test against everything near.
  const Vec3 n = tri_normal(t[0], t[1], t[2]);
  const double len = n.norm();
  if (!(len > 0)) return;
  const Eigen::Vector3f nf = (n / len).cast<float>();
  bool bent = false;
  for (std::uint32_t v : t) bent = bent || std::abs(f_.normal[v].dot(nf)) < kCosBent;
  if (!bent) return;
  double r = 0;
  for (std::uint32_t v : t) {
    turning_[v] = 1;
    r = std::max(r, opt_.radius_factor * 1.5 * spacing(v));
  }
  const Vec3 c = (p_[t[0]] + p_[t[1]] + p_[t[2]]) / 3.0;
  const double reach = std::sqrt(std::max({(p_[t[0]] - c).squaredNorm(), (p_[t[1]] - c).squaredNorm(),
                                           (p_[t[2]] - c).squaredNorm()})) + r;
  mark_near_turning(c, reach);
}

void Builder::mark_near_turning(const Vec3& c, double r) {
  const double r2 = r * r;
  const std::uint32_t* order = grid_.order().data();
  grid_.for_each_range_within(c, r, [&](std::uint32_t first, std::uint32_t last) {
    for (std::uint32_t s = first; s < last; ++s) {
      const std::uint32_t u = order[s];
      if (turning_[u] == 0 && (p_[u] - c).squaredNorm() <= r2) turning_[u] = 2;
    }
  });
}

void Builder::rebuild_corner_lists() {
  if (corner_head_.empty()) return;
  std::fill(corner_head_.begin(), corner_head_.end(), kNone);
  std::fill(slot_listed_.begin(), slot_listed_.end(), std::uint8_t{0});
  corners_.clear();
  free_corner_ = kNone;
  for (std::uint32_t id = 0; id < tris_.size(); ++id)
    for (std::uint32_t v : tris_[id])
      if (keeps_list(v)) link_corner(v, id);
}

/// Whether triangle q lies strictly on one side of the plane through `o` with normal n (`tol`
/// scales with the triangles), ignoring its corners shared with the other triangle (`t`): then
/// the two meet at most at those shared corners. The cheap first step of the exact test.
bool Builder::apart(const Triangle& q, const Triangle& t, const Vec3& o, const Vec3& n,
                    double tol) const {
  int above = 0, below = 0;
  for (std::uint32_t w : q) {
    if (w == t[0] || w == t[1] || w == t[2]) continue;
    const double d = (p_[w] - o).dot(n);
    if (d > tol) ++above;
    else if (d < -tol) ++below;
    else return false;
  }
  return above == 0 || below == 0;
}

bool Builder::crosses_fans(const Triangle& t) {
  const Vec3& o = p_[t[0]];
  const Vec3 n = (p_[t[1]] - o).cross(p_[t[2]] - o);
  const double tol = on_plane_tol(n);
  for (std::uint32_t v : t)
    for (std::uint32_t c = corner_head_[v]; c != kNone; c = corners_[c].next) {
      const Triangle& q = tris_[corners_[c].tri];
      int shared = 0;
      for (std::uint32_t w : q) shared += (w == t[0] || w == t[1] || w == t[2]) ? 1 : 0;
      // Across a shared edge only a fold can overlap, and the dihedral rule refuses folds.
      if (shared >= 2 || apart(q, t, o, n, tol)) continue;
      const Vec3& oq = p_[q[0]];
      const Vec3 nq = (p_[q[1]] - oq).cross(p_[q[2]] - oq);
      if (apart(t, q, oq, nq, on_plane_tol(nq))) continue;
      if (triangles_intersect(p_, q, t, clear_)) return true;
    }
  return false;
}

bool Builder::crosses_mesh(const Triangle& t, double radius, bool touching) {
  const Vec3 &q0 = p_[t[0]], &q1 = p_[t[1]], &q2 = p_[t[2]];
  const detail::TriangleBounds tb(q0, q1, q2);
  near_tris_.clear();
  // Every point of a triangle lies within 0.58 of its longest edge of its nearest corner, and
  // edges are at most about `radius` long: a triangle that meets t has a corner within `near`
  // of t's centre. Only those corners' lists are walked (the cells hold about five times as
  // many points as the ball).
  any_listed_triangle_near(tb.centre, tb.reach + 0.6 * radius, [&](std::uint32_t id) {
    const Triangle& q = tris_[id];
    if (!tb.box_misses(p_[q[0]], p_[q[1]], p_[q[2]])) near_tris_.push_back(id);
    return false;
  });
  // The long triangles near t (the search above saw those it stamped). Their bins may name
  // a triangle no longer long or since rewritten: its box now decides, as in the list.
  long_bins_.visit(tb.lo, tb.hi, [&](std::uint32_t id) {
    LongTriangle q;
    if (seen_.seen(id) || !long_entry(id, q) || tb.box_misses(q.lo, q.hi)) return;
    seen_.take(id);
    near_tris_.push_back(id);
  });
#ifndef NDEBUG
  for (const LongTriangle& q : long_tris_)
    assert((tb.box_misses(q.lo, q.hi) || seen_.seen(q.id)) &&
           "the long triangles' bins missed one near a new triangle");
#endif
  const Vec3 n = (q1 - q0).cross(q2 - q0);
  const double tol = on_plane_tol(n);
  for (std::uint32_t id : near_tris_)
    if (!apart(tris_[id], t, q0, n, tol) && triangles_intersect(p_, tris_[id], t, clear_)) return true;
  if (touching)
    for (std::uint32_t id : near_tris_)
      if (triangles_touch(p_, tris_[id], t, clear_)) return true;
  return false;
}

}  // namespace scanmesh::recon::front_impl
