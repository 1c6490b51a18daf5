// Inserting left-out points into the finished mesh (see refine.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/refine.hpp"

#include "scanmesh/recon/intersections.hpp"
#include "box_bins.hpp"
#include "triangle_shape.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>

namespace scanmesh::recon {
namespace {

constexpr std::uint32_t kNone = 0xffffffffu;
/// Local spacings beyond the search radius within which vertices get their triangle lists.
constexpr double kListReach = 3.0;

/// Position of `v` in `t` (0..2), or 3.
int corner_of(const Triangle& t, std::uint32_t v) {
  return t[0] == v ? 0 : t[1] == v ? 1 : t[2] == v ? 2 : 3;
}

/// Whether t holds the directed edge a -> b.
bool has_directed(const Triangle& t, std::uint32_t a, std::uint32_t b) {
  const int i = corner_of(t, a);
  return i < 3 && t[(i + 1) % 3] == b;
}

/// Smallest interior angle of triangle (a, b, c), radians (0 when degenerate).
double min_angle(const Vec3& a, const Vec3& b, const Vec3& c) {
  return std::acos(std::clamp(detail::min_angle_cos(a, b, c), -1.0, 1.0));
}

class Refiner {
 public:
  Refiner(std::span<const Vec3> points, const LocalFrames& frames, const PointGrid& grid,
          FrontResult& front, const RefineOptions& options)
      : p_(points), f_(frames), grid_(grid), fr_(front), tris_(front.triangles), o_(options),
        cos_dev_(std::cos(options.max_normal_deviation_deg * std::numbers::pi / 180)),
        spacing_(front.spacing.empty() ? std::span<const float>(frames.spacing)
                                       : std::span<const float>(front.spacing)) {}

  RefineStats run();

 private:
  [[nodiscard]] double spacing(std::uint32_t v) const { return spacing_[v]; }
  [[nodiscard]] bool complete(std::uint32_t v) const { return slot_[v] != kNone; }
  std::vector<std::uint32_t>& around(std::uint32_t v) { return lists_[slot_[v]]; }
  void make_complete(std::uint32_t v) {
    if (slot_[v] == kNone) {
      slot_[v] = static_cast<std::uint32_t>(lists_.size());
      lists_.emplace_back();
    }
  }
  void unlink(std::uint32_t v, std::uint32_t t) {
    auto& l = around(v);
    l.erase(std::find(l.begin(), l.end(), t));
  }
  void link(std::uint32_t v, std::uint32_t t) { around(v).push_back(t); }
  /// Replaces triangle t by `nt` (same slot), keeping the vertex lists right.
  void replace(std::uint32_t t, const Triangle& nt) {
    for (std::uint32_t v : tris_[t])
      if (corner_of(nt, v) == 3) unlink(v, t);
    for (std::uint32_t v : nt)
      if (corner_of(tris_[t], v) == 3) link(v, t);
    tris_[t] = nt;
    note_if_long(t);
  }
  void append(const Triangle& nt) {
    const auto t = static_cast<std::uint32_t>(tris_.size());
    tris_.push_back(nt);
    for (std::uint32_t v : nt) link(v, t);
    note_if_long(t);
  }
  /// Sets the crossing search's least reach (reach_floor_) and the edge beyond which a
  /// triangle is listed as long (long_edge2_).
  void set_reach_floor();
  /// Lists triangle t with its box when an edge is longer than long_edge2_ allows. A triangle
  /// listed before and rewritten since keeps its old entry too: crosses() tests what the slot
  /// holds now, so a stale entry costs a test, never a miss.
  void note_if_long(std::uint32_t t) {
    const Triangle& tr = tris_[t];
    detail::LongTriangle q;
    if (!detail::long_entry(p_[tr[0]], p_[tr[1]], p_[tr[2]], t, long_edge2_, q)) return;
    long_bins_.insert(static_cast<std::uint32_t>(long_.size()), q.lo, q.hi);
    long_.push_back(q);
  }
  /// The triangle holding directed edge a -> b (a complete), or kNone.
  std::uint32_t find_tri(std::uint32_t a, std::uint32_t b) {
    for (std::uint32_t t : around(a))
      if (has_directed(tris_[t], a, b)) return t;
    return kNone;
  }
  [[nodiscard]] Vec3 unit_normal(const Triangle& t) const {
    const Vec3 n = (p_[t[1]] - p_[t[0]]).cross(p_[t[2]] - p_[t[0]]);
    const double l = n.norm();
    return l > 0 ? Vec3(n / l) : Vec3::Zero();
  }
  /// The triangles with a corner under sliver_deg; lists the long ones on the way (one pass).
  std::vector<std::uint32_t> find_slivers_and_long();
  void list_triangles_near(const std::vector<std::uint32_t>& slivers);
  std::vector<std::uint32_t> insert_left_out();
  void flip_around(const std::vector<std::uint32_t>& inserted);
  void mend_slivers(const std::vector<std::uint32_t>& slivers);
  bool try_insert(std::uint32_t p);
  /// Puts q into triangle t (barycentrics of q's projection): splits t, or the edge near q.
  bool split_into(std::uint32_t q, std::uint32_t t, const double (&bary)[3]);
  struct Host {
    double h;
    std::uint32_t t;
    double bary[3];
  };
  static constexpr std::size_t kMaxHosts = 4;
  /// Height (local spacings) within which a point counts as on a triangle's plane.
  static constexpr double kOnPlane = 0.35;
  std::vector<Host> hosts_;
  /// Whether new triangle `nt` would cross a listed triangle of the mesh other than those
  /// it replaces (`gone`).
  bool crosses(const Triangle& nt, std::initializer_list<std::uint32_t> gone);
  /// Whether the triangles an operation makes, in place of `gone`, cross the mesh or each other
  /// (crosses() sees only the mesh as it is: an edge split across a spike made two new
  /// triangles through each other).
  bool made_cross(std::initializer_list<Triangle> made, std::initializer_list<std::uint32_t> gone);
  bool try_flip(std::uint32_t u, std::uint32_t v);
  void improve_around(std::uint32_t p);
#ifndef NDEBUG
  bool single_fan(std::uint32_t v);  // debug check: v's triangles form one fan
#endif

  std::span<const Vec3> p_;
  const LocalFrames& f_;
  const PointGrid& grid_;
  FrontResult& fr_;
  std::vector<Triangle>& tris_;
  const RefineOptions& o_;
  const double cos_dev_;
  /// The local spacing as the front capped it (a stray reading's own spacing can be many times
  /// the surface's), or the frames' where the front gave none.
  const std::span<const float> spacing_;
  std::vector<std::uint32_t> slot_;  // per vertex: its triangle list in lists_, or kNone
  std::vector<std::vector<std::uint32_t>> lists_;
  /// The crossing search finds a triangle through a corner within its reach of the new
  /// one's bounding sphere, which holds for every triangle whose edges are at most sqrt(3) times
  /// that reach (each of its points lies within longest edge / sqrt(3) of a corner). The reach
  /// is 2.5 local spacings, at least reach_floor_; the longer triangles are listed (long_).
  std::vector<detail::LongTriangle> long_;
  detail::BoxBins long_bins_;  // positions in long_, binned by their boxes
  double reach_floor_ = 0;
  double long_edge2_ = std::numeric_limits<double>::infinity();
  std::vector<std::uint32_t> cand_, near_;
  detail::SearchStamps seen_;  // crosses: the triangles the current call has seen
  std::vector<std::pair<std::uint32_t, std::uint32_t>> queue_;
  std::vector<std::uint8_t> touched_;  // per vertex: a flip changed its triangles
  bool mending_sliver_ = false;        // try_flip is mending slivers
  RefineStats stats_;
};

RefineStats Refiner::run() {
  touched_.assign(p_.size(), 0);
  set_reach_floor();
  const std::vector<std::uint32_t> slivers = find_slivers_and_long();
  list_triangles_near(slivers);
  const std::vector<std::uint32_t> inserted = insert_left_out();
  flip_around(inserted);
  mend_slivers(slivers);
  for (std::uint32_t q : inserted) {
    // A vertex on a boundary edge of the mesh stays a boundary vertex.
    bool open = false;
    for (std::uint32_t t : around(q)) {
      const Triangle& tr = tris_[t];
      const int i = corner_of(tr, q);
      if (find_tri(tr[(i + 1) % 3], q) == kNone) open = true;
    }
    fr_.state[q] = open ? VertexState::kBoundary : VertexState::kDone;
  }
  stats_.inserted = inserted.size();
#ifndef NDEBUG
  for (std::uint32_t v = 0; v < p_.size(); ++v)
    if (complete(v)) assert(single_fan(v));
#endif
  return stats_;
}

void Refiner::set_reach_floor() {
  // The reach floor: 2.5 times the 10th percentile of the used vertices' spacing (a sample of
  // at most about 4096), so that few calls are widened and few triangles listed; any floor
  // keeps the search complete.
  const std::size_t n = p_.size();
  const std::size_t stride = std::max<std::size_t>(1, n / 4096);
  std::vector<float> sample;
  for (std::size_t v = 0; v < n; v += stride)
    if (fr_.state[v] != VertexState::kOutlier && fr_.state[v] != VertexState::kFree &&
        spacing(static_cast<std::uint32_t>(v)) > 0)
      sample.push_back(spacing(static_cast<std::uint32_t>(v)));
  if (sample.empty()) return;  // no reach floor, and every triangle is found by its corners
  const auto at = sample.begin() + static_cast<std::ptrdiff_t>(sample.size() / 10);
  std::nth_element(sample.begin(), at, sample.end());
  reach_floor_ = 2.5 * static_cast<double>(*at);
  long_edge2_ = 3.0 * reach_floor_ * reach_floor_;
  long_bins_.reset(std::sqrt(long_edge2_));
}

std::vector<std::uint32_t> Refiner::find_slivers_and_long() {
  // A corner under sliver_deg, tested on squared lengths (no root). Corner k's u runs along
  // the edge from it, so the three u are the three edges.
  std::vector<std::uint32_t> slivers;
  const bool find = o_.sliver_deg > 0;
  const double c = std::cos(o_.sliver_deg * std::numbers::pi / 180), c2 = c * c;
  for (std::uint32_t t = 0; t < tris_.size(); ++t) {
    const Triangle& tr = tris_[t];
    bool sliver = false;
    double longest2 = 0;
    for (int k = 0; k < 3; ++k) {
      const Vec3 u = p_[tr[(k + 1) % 3]] - p_[tr[k]];
      const double uu = u.squaredNorm();
      longest2 = std::max(longest2, uu);
      if (!find || sliver) continue;
      const Vec3 w = p_[tr[(k + 2) % 3]] - p_[tr[k]];
      const double d = u.dot(w);
      sliver = d > 0 && d * d > c2 * uu * w.squaredNorm();
    }
    if (sliver) slivers.push_back(t);
    if (longest2 > long_edge2_) note_if_long(t);
  }
  stats_.slivers = slivers.size();
  return slivers;
}

void Refiner::list_triangles_near(const std::vector<std::uint32_t>& slivers) {
  // Every used vertex near a left-out point or a sliver gets its full triangle list (one pass
  // over the triangles), far enough around that the triangles an insertion and its flips touch
  // (edges are at most a few spacings long) have all their corners listed; an operation that
  // would touch an unlisted vertex is skipped.
  const std::size_t n = p_.size();
  std::vector<std::uint8_t> mark(n, 0);
  auto mark_around = [&](std::uint32_t q, double r) {
    grid_.for_each_range_within(p_[q], r, [&](std::uint32_t first, std::uint32_t last) {
      for (std::uint32_t s = first; s < last; ++s) {
        const std::uint32_t j = grid_.order()[s];
        if (fr_.state[j] != VertexState::kOutlier && (p_[j] - p_[q]).squaredNorm() <= r * r)
          mark[j] = 1;
      }
    });
  };
  for (std::uint32_t q : fr_.outliers)
    mark_around(q, (o_.search_factor + kListReach) * spacing(q));
  // Flips reach one edge beyond a sliver's corners (the quads' far corners): mark that far.
  for (std::uint32_t t : slivers) {
    const Triangle& tr = tris_[t];
    const double longest = std::sqrt(std::max({(p_[tr[0]] - p_[tr[1]]).squaredNorm(),
                                               (p_[tr[1]] - p_[tr[2]]).squaredNorm(),
                                               (p_[tr[2]] - p_[tr[0]]).squaredNorm()}));
    for (std::uint32_t v : tr) mark_around(v, std::max(1.2 * longest, 2.0 * spacing(v)));
  }
  slot_.assign(n, kNone);
  for (std::uint32_t v = 0; v < n; ++v)
    if (mark[v]) make_complete(v);
  for (std::uint32_t t = 0; t < tris_.size(); ++t)
    for (std::uint32_t v : tris_[t])
      if (mark[v]) link(v, t);
}

std::vector<std::uint32_t> Refiner::insert_left_out() {
  // A few rounds: an insertion can bring a neighbour within reach. fr_.outliers keeps the
  // points still left out.
  std::vector<std::uint32_t> left = fr_.outliers, inserted;
  for (int round = 0; round < o_.rounds && !left.empty(); ++round) {
    std::vector<std::uint32_t> still;
    for (std::uint32_t q : left) (try_insert(q) ? inserted : still).push_back(q);
    const bool progress = still.size() < left.size();
    left.swap(still);
    if (!progress) break;
  }
  fr_.outliers = std::move(left);
  return inserted;
}

void Refiner::flip_around(const std::vector<std::uint32_t>& inserted) {
  // Flip around the new vertices until nothing improves (a few passes at most); later passes
  // revisit only the points whose neighbourhood a flip changed.
  for (int pass = 0; pass < 4; ++pass) {
    const std::size_t before = stats_.flips;
    std::vector<std::uint8_t> changed;
    changed.swap(touched_);
    touched_.assign(p_.size(), 0);
    for (std::uint32_t q : inserted) {
      bool near_change = pass == 0 || changed[q] != 0;
      for (std::size_t k = 0; k < around(q).size() && !near_change; ++k)
        for (std::uint32_t w : tris_[around(q)[k]]) near_change = near_change || changed[w] != 0;
      if (near_change) improve_around(q);
    }
    if (stats_.flips == before) break;
  }
}

void Refiner::mend_slivers(const std::vector<std::uint32_t>& slivers) {
  // Flip their edges, longest first, where that improves the shape (flat) or lowers the
  // bending, or mends the sliver at a small cost in bending; each flip queues the quad's outer
  // edges.
  for (int pass = 0; pass < 2 && o_.flip && !slivers.empty(); ++pass) {
    const std::size_t before = stats_.flips;
    for (std::uint32_t t : slivers) {
      const Triangle tr = tris_[t];
      int order[3] = {0, 1, 2};  // edge k: tr[k] -> tr[k + 1]
      double len[3];
      for (int k = 0; k < 3; ++k) len[k] = (p_[tr[(k + 1) % 3]] - p_[tr[k]]).squaredNorm();
      std::sort(order, order + 3, [&](int l, int r) { return len[l] > len[r]; });
      queue_.clear();
      for (int k = 2; k >= 0; --k) queue_.emplace_back(tr[order[k]], tr[(order[k] + 1) % 3]);
      std::size_t budget = 16;
      while (!queue_.empty() && budget > 0) {
        const auto [u, v] = queue_.back();
        queue_.pop_back();
        mending_sliver_ = true;
        const bool flipped = try_flip(u, v);
        mending_sliver_ = false;
        if (flipped) {
          --budget;
          ++stats_.sliver_flips;
        }
      }
    }
    if (stats_.flips == before) break;
  }
}

#ifndef NDEBUG
bool Refiner::single_fan(std::uint32_t v) {
  // Each triangle (v, a, b) links a -> b; a vertex is manifold when these links form one path
  // or one cycle, and each directed edge at v is used once.
  const auto& l = around(v);
  std::vector<std::pair<std::uint32_t, std::uint32_t>> links;
  for (std::uint32_t t : l) {
    const Triangle& tr = tris_[t];
    const int i = corner_of(tr, v);
    if (i == 3) return false;
    links.emplace_back(tr[(i + 1) % 3], tr[(i + 2) % 3]);
  }
  if (links.empty()) return true;
  std::sort(links.begin(), links.end());
  for (std::size_t k = 1; k < links.size(); ++k)
    if (links[k].first == links[k - 1].first) return false;
  auto next = [&](std::uint32_t a) -> const std::pair<std::uint32_t, std::uint32_t>* {
    auto it = std::lower_bound(links.begin(), links.end(), std::make_pair(a, 0u));
    return it != links.end() && it->first == a ? &*it : nullptr;
  };
  // Start where no link ends (a border), else anywhere; walk and count.
  std::uint32_t start = links.front().first;
  for (const auto& [a, b] : links) {
    bool ends_here = false;
    for (const auto& lk : links) ends_here |= lk.second == a;
    if (!ends_here) {
      start = a;
      break;
    }
  }
  std::size_t walked = 0;
  for (auto* lk = next(start); lk != nullptr && walked <= links.size(); lk = next(lk->second)) {
    ++walked;
    if (lk->second == start) break;
  }
  return walked == links.size();
}
#endif

bool Refiner::try_insert(std::uint32_t q) {
  const Vec3& P = p_[q];
  const double sp = spacing(q);
  const Vec3 nq = f_.normal[q].cast<double>();
  const double r = o_.search_factor * sp, hmax = o_.max_height_factor * sp;
  cand_.clear();
  grid_.for_each_range_within(P, r, [&](std::uint32_t first, std::uint32_t last) {
    for (std::uint32_t s = first; s < last; ++s) {
      const std::uint32_t j = grid_.order()[s];
      if (j == q || !complete(j) || (p_[j] - P).squaredNorm() > r * r) continue;
      for (std::uint32_t t : around(j)) cand_.push_back(t);
    }
  });
  std::sort(cand_.begin(), cand_.end());
  cand_.erase(std::unique(cand_.begin(), cand_.end()), cand_.end());
  // The triangles whose plane the point lies close to, over their inside, nearest first; the
  // first into which it goes without a new triangle crossing the mesh takes it.
  hosts_.clear();
  for (std::uint32_t t : cand_) {
    const Triangle& tr = tris_[t];
    const Vec3 &a = p_[tr[0]], &b = p_[tr[1]], &c = p_[tr[2]];
    const Vec3 nn = (b - a).cross(c - a);
    const double area2 = nn.norm();
    if (area2 == 0) continue;
    const Vec3 nt = nn / area2;
    const double h = (P - a).dot(nt);
    if (std::abs(h) > hmax) continue;
    // The normal rule keeps the other side of a thin wall out; a point (nearly) on the
    // triangle's plane is on this side whatever its normal says (feature points, whose PCA
    // normal blends the faces meeting there): the crossing test guards what it changes.
    if (nt.dot(nq) < cos_dev_ && std::abs(h) > kOnPlane * sp) continue;
    const Vec3 x = P - h * nt;
    const double la = (c - b).cross(x - b).dot(nt) / area2;
    const double lb = (a - c).cross(x - c).dot(nt) / area2;
    const double lc = 1 - la - lb;
    if (std::min({la, lb, lc}) < -0.02) continue;
    hosts_.push_back({std::abs(h), t, {la, lb, lc}});
  }
  std::sort(hosts_.begin(), hosts_.end(), [](const Host& l, const Host& r) {
    return l.h != r.h ? l.h < r.h : l.t < r.t;
  });
  if (hosts_.size() > kMaxHosts) hosts_.resize(kMaxHosts);
  for (const Host& host : hosts_)
    if (split_into(q, host.t, host.bary)) {
      // Lawson-style: the edges opposite the new vertex.
      improve_around(q);
      return true;
    }
  return false;
}

bool Refiner::split_into(std::uint32_t q, std::uint32_t best, const double (&bary)[3]) {
  const Triangle t0 = tris_[best];
  for (std::uint32_t v : t0)
    if (!complete(v)) return false;
  const Vec3 n0 = unit_normal(t0);
  const int weakest = static_cast<int>(std::min_element(bary, bary + 3) - bary);
  const double min_ok = 3.0 * std::numbers::pi / 180;
  // A new triangle must keep some shape and not turn over against the one it replaces.
  auto fits = [&](const Triangle& nt, const Vec3& parent) {
    if (min_angle(p_[nt[0]], p_[nt[1]], p_[nt[2]]) < min_ok) return false;
    return unit_normal(nt).dot(parent) > 0.1;
  };
  make_complete(q);
  if (bary[weakest] < 0.2) {
    // Near the edge opposite the weakest corner: split that edge (and the triangle across it).
    const std::uint32_t u = t0[(weakest + 1) % 3], v = t0[(weakest + 2) % 3], x = t0[weakest];
    const std::uint32_t t1 = find_tri(v, u);
    if (t1 != kNone) {
      const Triangle tb = tris_[t1];
      const std::uint32_t y = tb[(corner_of(tb, v) + 2) % 3];
      if (!complete(y) || y == x) return false;
      const Vec3 n1 = unit_normal(tb);
      const Triangle a1{u, q, x}, a2{q, v, x}, b1{v, q, y}, b2{q, u, y};
      if (!fits(a1, n0) || !fits(a2, n0) || !fits(b1, n1) || !fits(b2, n1)) return false;
      if (made_cross({a1, a2, b1, b2}, {best, t1})) return false;
      replace(best, a1);
      append(a2);
      replace(t1, b1);
      append(b2);
    } else {
      const Triangle a1{u, q, x}, a2{q, v, x};
      if (!fits(a1, n0) || !fits(a2, n0)) return false;
      if (made_cross({a1, a2}, {best})) return false;
      replace(best, a1);
      append(a2);
    }
    ++stats_.edge_splits;
  } else {
    const Triangle a1{t0[0], t0[1], q}, a2{t0[1], t0[2], q}, a3{t0[2], t0[0], q};
    if (!fits(a1, n0) || !fits(a2, n0) || !fits(a3, n0)) return false;
    if (made_cross({a1, a2, a3}, {best})) return false;
    replace(best, a1);
    append(a2);
    append(a3);
  }
  return true;
}

bool Refiner::made_cross(std::initializer_list<Triangle> made,
                         std::initializer_list<std::uint32_t> gone) {
  for (auto s = made.begin(); s != made.end(); ++s)
    for (auto t = s + 1; t != made.end(); ++t)
      if (triangles_intersect(p_, *s, *t)) return true;
  for (const Triangle& nt : made)
    if (crosses(nt, gone)) return true;
  return false;
}

bool Refiner::crosses(const Triangle& nt, std::initializer_list<std::uint32_t> gone) {
  // Every listed triangle near nt: a triangle crossing it has a corner within its longest
  // edge / sqrt(3) of nt's bounding sphere; the longer ones are in long_ (see there).
  const detail::TriangleBounds nb(p_[nt[0]], p_[nt[1]], p_[nt[2]]);
  near_.clear();
  // Each triangle once (the long list's boxes may be stale, so there only a triangle taken is
  // marked).
  seen_.start(tris_.size());
  long_bins_.visit(nb.lo, nb.hi, [&](std::uint32_t k) {
    const detail::LongTriangle& l = long_[k];
    if (!nb.box_misses(l.lo, l.hi) && seen_.take(l.id)) near_.push_back(l.id);
  });
  grid_.for_each_range_within(nb.centre, nb.reach + std::max(2.5 * spacing(nt[0]), reach_floor_),
                              [&](std::uint32_t first, std::uint32_t last) {
    for (std::uint32_t s = first; s < last; ++s) {
      const std::uint32_t j = grid_.order()[s];
      if (!complete(j)) continue;
      for (std::uint32_t t : around(j)) {
        const Triangle& q = tris_[t];
        if (!seen_.take(t)) continue;  // taken, or its box tested (below)
        if (!nb.box_misses(p_[q[0]], p_[q[1]], p_[q[2]])) near_.push_back(t);
      }
    }
  });
  for (std::uint32_t t : near_) {
    if (std::find(gone.begin(), gone.end(), t) != gone.end()) continue;
    if (triangles_intersect(p_, tris_[t], nt)) return true;
  }
  return false;
}

void Refiner::improve_around(std::uint32_t q) {
  if (!o_.flip) return;
  // Edges opposite q (its link) and the edges at q; a flip brings new link edges.
  queue_.clear();
  for (std::uint32_t t : around(q)) {
    const Triangle& tr = tris_[t];
    const int i = corner_of(tr, q);
    queue_.emplace_back(tr[(i + 1) % 3], tr[(i + 2) % 3]);
    queue_.emplace_back(q, tr[(i + 1) % 3]);
  }
  std::size_t budget = 64;
  while (!queue_.empty() && budget > 0) {
    const auto [u, v] = queue_.back();
    queue_.pop_back();
    if (try_flip(u, v)) --budget;
  }
}

bool Refiner::try_flip(std::uint32_t u, std::uint32_t v) {
  if (!complete(u) || !complete(v)) return false;
  const std::uint32_t t1 = find_tri(u, v), t2 = find_tri(v, u);
  if (t1 == kNone || t2 == kNone) return false;
  const Triangle A = tris_[t1], B = tris_[t2];
  const std::uint32_t x = A[(corner_of(A, u) + 2) % 3], y = B[(corner_of(B, v) + 2) % 3];
  if (x == y || !complete(x) || !complete(y)) return false;
  if (find_tri(x, y) != kNone || find_tri(y, x) != kNone) return false;
  const Triangle C{x, u, y}, D{y, v, x};
  const Vec3 n1 = unit_normal(A), n2 = unit_normal(B), m1 = unit_normal(C), m2 = unit_normal(D);
  if (m1.isZero() || m2.isZero() || n1.isZero() || n2.isZero()) return false;
  const Vec3 avg = (n1 + n2).normalized();
  if (m1.dot(avg) < 0.5 || m2.dot(avg) < 0.5) return false;  // no fold
  // The four outer edges: which old and new triangle holds each, and the normal across it.
  struct Outer {
    std::uint32_t a, b;  // directed as in the quad
    const Vec3* old_n;
    const Vec3* new_n;
  };
  const Outer outer[4] = {{v, x, &n1, &m2}, {x, u, &n1, &m1}, {u, y, &n2, &m1}, {y, v, &n2, &m2}};
  // Cosines of the bending at the five edges, before and after; a border edge does not bend.
  double len[5], cos_old[5], cos_new[5];
  len[4] = 0;
  cos_old[4] = n1.dot(n2);
  cos_new[4] = m1.dot(m2);
  bool open[4];
  for (int k = 0; k < 4; ++k) {
    const std::uint32_t t = find_tri(outer[k].b, outer[k].a);
    open[k] = t == kNone;
    len[k] = (p_[outer[k].a] - p_[outer[k].b]).norm();
    if (open[k]) {
      cos_old[k] = cos_new[k] = 1;
      continue;
    }
    const Vec3 no = unit_normal(tris_[t]);
    cos_old[k] = outer[k].old_n->dot(no);
    cos_new[k] = outer[k].new_n->dot(no);
  }
  // A new triangle with two border edges would hang free at the border (bending is only
  // counted between triangles): never made.
  if ((open[1] && open[2]) || (open[0] && open[3])) return false;
  const double old_min = std::min(min_angle(p_[A[0]], p_[A[1]], p_[A[2]]),
                                  min_angle(p_[B[0]], p_[B[1]], p_[B[2]]));
  const double new_min = std::min(min_angle(p_[C[0]], p_[C[1]], p_[C[2]]),
                                  min_angle(p_[D[0]], p_[D[1]], p_[D[2]]));
  const double cos_flat = std::cos(12.0 * std::numbers::pi / 180);
  bool flat = true;
  for (int k = 0; k < 5; ++k) flat = flat && cos_old[k] > cos_flat && cos_new[k] > cos_flat;
  bool flip = false;
  if (flat) {
    flip = new_min > old_min * 1.05;  // flat: the better shape (Delaunay-like)
  } else {
    // Total bending: sum of length x angle between the normals on either side.
    double e_old = std::acos(std::clamp(cos_old[4], -1.0, 1.0)) * (p_[u] - p_[v]).norm();
    double e_new = std::acos(std::clamp(cos_new[4], -1.0, 1.0)) * (p_[x] - p_[y]).norm();
    for (int k = 0; k < 4; ++k) {
      if (open[k]) continue;
      e_old += std::acos(std::clamp(cos_old[k], -1.0, 1.0)) * len[k];
      e_new += std::acos(std::clamp(cos_new[k], -1.0, 1.0)) * len[k];
    }
    flip = e_new < 0.9 * e_old && new_min > std::min(0.5 * old_min, 10.0 * std::numbers::pi / 180);
    // Mending a sliver: a clearly better shape may cost a little bending.
    if (!flip && mending_sliver_)
      flip = new_min > 2 * old_min && e_new < 1.1 * e_old;
  }
  if (!flip || made_cross({C, D}, {t1, t2})) return false;
  for (std::uint32_t w : {u, v, x, y}) touched_[w] = 1;
  replace(t1, C);
  replace(t2, D);
  ++stats_.flips;
  // The quad's outer edges may now improve.
  queue_.emplace_back(v, x);
  queue_.emplace_back(x, u);
  queue_.emplace_back(u, y);
  queue_.emplace_back(y, v);
  return true;
}

}  // namespace

std::vector<std::string> RefineOptions::validate() const {
  std::vector<std::string> errors;
  if (!(search_factor > 0 && search_factor <= 10))
    errors.push_back("refine search factor must be in (0, 10]");
  if (!(max_height_factor >= 0 && max_height_factor <= 5))
    errors.push_back("refine height factor must be in [0, 5]");
  if (!(max_normal_deviation_deg >= 0 && max_normal_deviation_deg <= 180))
    errors.push_back("refine normal deviation must be in [0, 180] degrees");
  if (rounds < 0 || rounds > 10) errors.push_back("refine rounds must be in [0, 10]");
  if (!(sliver_deg >= 0 && sliver_deg <= 30))
    errors.push_back("sliver angle must be in [0, 30] degrees");
  return errors;
}

RefineStats insert_unused_points(std::span<const Vec3> points, const LocalFrames& frames,
                                 const PointGrid& grid, FrontResult& front,
                                 const RefineOptions& options) {
  if (!options.enabled || front.triangles.empty()) return {};
  Refiner r(points, frames, grid, front, options);
  return r.run();
}

}  // namespace scanmesh::recon
