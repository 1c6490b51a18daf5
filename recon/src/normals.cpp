// PCA normals over k nearest neighbours, oriented by propagation over the kNN graph (Hoppe et
// al.: most reliable neighbour first, from an extreme point of each component facing outward),
// repaired by ray-parity votes on closed objects with thin walls.
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/normals.hpp"

#include "block_points.hpp"
#include "neighbour_order.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numeric>

namespace scanmesh::recon {

namespace detail {

PlaneFit plane_normal(const Eigen::Matrix3d& cov) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);
  const Vec3 ev = es.eigenvalues();
  // The closed form resolves the normal to about eps * lambda2 / (lambda1 - lambda0); when the
  // two smallest eigenvalues nearly coincide the iterative solver does better.
  if (!(ev[1] - ev[0] > 1e-6 * std::abs(ev[2]))) es.compute(cov);
  return {es.eigenvectors().col(0), es.eigenvalues()};
}

}  // namespace detail

namespace {

constexpr std::uint32_t kNone = 0xffffffffu;

/// Writes normal, flatness and spacing of point i (at p) from its m nearest neighbours, given
/// by position t[q] in the coordinate arrays xs, ys, zs, at squared distances d2[q], both
/// ascending by (distance, index).
template <class Index>
void finish_point(const double* xs, const double* ys, const double* zs, const Index* t,
                  const Vec3& p, std::size_t i, const double* d2, std::size_t m, LocalFrames& f) {
  Vec3 mean = p;
  for (std::size_t q = 0; q < m; ++q) mean += Vec3(xs[t[q]], ys[t[q]], zs[t[q]]);
  mean /= static_cast<double>(m + 1);
  double dx = p.x() - mean.x(), dy = p.y() - mean.y(), dz = p.z() - mean.z();
  double xx = dx * dx, xy = dx * dy, xz = dx * dz, yy = dy * dy, yz = dy * dz, zz = dz * dz;
  for (std::size_t q = 0; q < m; ++q) {
    dx = xs[t[q]] - mean.x();
    dy = ys[t[q]] - mean.y();
    dz = zs[t[q]] - mean.z();
    xx += dx * dx;
    xy += dx * dy;
    xz += dx * dz;
    yy += dy * dy;
    yz += dy * dz;
    zz += dz * dz;
  }
  Eigen::Matrix3d cov;
  cov << xx, xy, xz, xy, yy, yz, xz, yz, zz;
  const detail::PlaneFit fit = detail::plane_normal(cov);
  const Vec3 ev = fit.eigenvalues.cwiseMax(0.0);
  const double sum = ev.sum();
  f.flatness[i] = sum > 0 ? static_cast<float>(ev[0] / sum) : 1.0f;
  f.normal[i] = m >= 2 ? Eigen::Vector3f(fit.normal.cast<float>()) : Eigen::Vector3f::UnitZ();
  double s = 0;
  const std::size_t ms = std::min<std::size_t>(6, m);
  for (std::size_t q = 0; q < ms; ++q) s += std::sqrt(d2[q]);
  f.spacing[i] = ms > 0 ? static_cast<float>(s / static_cast<double>(ms)) : 0.0f;
}

/// A neighbour candidate: squared distance, point index, position in the candidate arrays.
using Picked = detail::Neighbour;

/// Multiple of the previous point's k-th squared distance used to pre-filter candidates.
constexpr double kThresholdFactor = 1.5;

/// Indexed 4-ary min-heap of frontier vertices for the orientation propagation. Each vertex in
/// it carries its best edge from the visited set, ordered by (cost, from, to): the order in
/// which a lazy priority queue of (cost, from << 32 | to) edge pairs pops them. Cost and `from`
/// are packed into one 64-bit key (the cost's bits mapped to an unsigned order).
class Frontier {
 public:
  struct Item {
    std::uint64_t key;  // ordered cost bits << 32 | from
    std::uint32_t to;
    bool operator<(const Item& o) const { return key < o.key || (key == o.key && to < o.to); }
    [[nodiscard]] std::uint32_t from() const { return static_cast<std::uint32_t>(key); }
  };
  static constexpr std::uint32_t kUnseen = 0xffffffffu, kDone = 0xfffffffeu;

  /// Unsigned key with the order of the float (no NaN): flip all bits of negatives, the sign
  /// bit of the others. (The cost 1 - |dot| can come out a little below zero.)
  static std::uint64_t make_key(float cost, std::uint32_t from) {
    const auto b = std::bit_cast<std::uint32_t>(cost);
    const std::uint32_t ordered = (b & 0x80000000u) != 0 ? ~b : (b | 0x80000000u);
    return (static_cast<std::uint64_t>(ordered) << 32) | from;
  }

  explicit Frontier(std::size_t n) : pos_(n, kUnseen) {}
  [[nodiscard]] bool done(std::uint32_t v) const { return pos_[v] == kDone; }
  void set_done(std::uint32_t v) { pos_[v] = kDone; }
  [[nodiscard]] bool empty() const { return heap_.empty(); }

  /// Offers edge from -> to (to not done): kept when better than its current edge.
  void offer(float cost, std::uint32_t from, std::uint32_t to) {
    const Item it{make_key(cost, from), to};
    std::uint32_t at = pos_[to];
    if (at == kUnseen) {
      at = static_cast<std::uint32_t>(heap_.size());
      heap_.push_back(it);
    } else if (!(it < heap_[at])) {
      return;
    }
    sift_up(at, it);
  }
  Item pop() {
    const Item top = heap_.front();
    pos_[top.to] = kDone;
    const Item last = heap_.back();
    heap_.pop_back();
    if (!heap_.empty()) sift_down(last);
    return top;
  }

 private:
  void sift_up(std::uint32_t at, const Item& it) {
    while (at > 0) {
      const std::uint32_t parent = (at - 1) / 4;
      if (!(it < heap_[parent])) break;
      heap_[at] = heap_[parent];
      pos_[heap_[at].to] = at;
      at = parent;
    }
    heap_[at] = it;
    pos_[it.to] = at;
  }
  /// Places `it` at the root and moves it down.
  void sift_down(const Item& it) {
    const auto size = static_cast<std::uint32_t>(heap_.size());
    std::uint32_t at = 0;
    while (true) {
      const std::uint32_t c0 = 4 * at + 1;
      if (c0 >= size) break;
      std::uint32_t best = c0;
      const std::uint32_t end = std::min(c0 + 4, size);
      for (std::uint32_t c = c0 + 1; c < end; ++c)
        if (heap_[c] < heap_[best]) best = c;
      if (!(heap_[best] < it)) break;
      heap_[at] = heap_[best];
      pos_[heap_[at].to] = at;
      at = best;
    }
    heap_[at] = it;
    pos_[it.to] = at;
  }

  std::vector<std::uint32_t> pos_;  // heap position, kUnseen or kDone
  std::vector<Item> heap_;
};

/// Outward votes by ray parity (closed objects): a ray from a point along its normal that crosses
/// the sampled surface an even number of times before leaving the bounding box starts outward.
/// The surface is approximated by the points' splats (discs across their normals); hits closer
/// along the ray than half the point's spacing are one crossing. +1: the normal points out (even
/// ahead, odd behind), -1: it points in, 0: undecided.
class ParityCaster {
 public:
  ParityCaster(std::span<const Vec3> points, const PointGrid& grid, const LocalFrames& f)
      : points_(points), grid_(grid), f_(f), stamp_(points.size(), 0) {
    lo_ = hi_ = points[0];
    for (const Vec3& p : points) {
      lo_ = lo_.cwiseMin(p);
      hi_ = hi_.cwiseMax(p);
    }
  }

  int vote(std::uint32_t i) {
    const Vec3 p = points_[i];
    const Vec3 d = f_.normal[i].cast<double>();
    const double sp = f_.spacing[i];
    const double cell = grid_.cell();
    // The line through p, both ways, until it leaves the bounding box (slab test).
    double t_ahead = std::numeric_limits<double>::infinity(), t_behind = t_ahead;
    for (int a = 0; a < 3; ++a) {
      if (std::abs(d[a]) < 1e-12) continue;
      const double t_hi = (hi_[a] - p[a]) / d[a], t_lo = (lo_[a] - p[a]) / d[a];
      t_ahead = std::min(t_ahead, std::max(t_hi, t_lo));
      t_behind = std::min(t_behind, -std::min(t_hi, t_lo));
    }
    ahead_.clear();
    behind_.clear();
    ++ray_;
    const double r_cap = 0.5 * cell;
    const double t_min = 0.25 * sp;
    // Samples one cell apart: a splat (radius at most half a cell) hitting the line lies within
    // one cell of the nearest sample, so the 27 cells around the samples hold every hit.
    const auto steps_behind = static_cast<std::int64_t>(std::ceil(t_behind / cell));
    const auto steps_ahead = static_cast<std::int64_t>(std::ceil(t_ahead / cell));
    for (std::int64_t s = -steps_behind; s <= steps_ahead; ++s) {
      grid_.for_each_near(p + (static_cast<double>(s) * cell) * d, 1, [&](std::uint32_t j) {
        if (stamp_[j] == ray_ || j == i) return;
        stamp_[j] = ray_;
        const Vec3 nj = f_.normal[j].cast<double>();
        const double dn = d.dot(nj);
        if (std::abs(dn) < 0.15) return;  // grazing: the crossing is ill-defined
        const double t = (points_[j] - p).dot(nj) / dn;
        if (std::abs(t) < t_min) return;
        const double r = std::min(0.6 * static_cast<double>(f_.spacing[j]), r_cap);
        if ((p + t * d - points_[j]).squaredNorm() > r * r) return;
        (t > 0 ? ahead_ : behind_).push_back(std::abs(t));
      });
    }
    const int a = crossings(ahead_, 0.5 * sp), b = crossings(behind_, 0.5 * sp);
    if (a % 2 == 0 && b % 2 == 1) return 1;
    if (a % 2 == 1 && b % 2 == 0) return -1;
    return 0;
  }

 private:
  static int crossings(std::vector<double>& ts, double merge) {
    std::sort(ts.begin(), ts.end());
    int c = 0;
    for (std::size_t q = 0; q < ts.size(); ++q)
      if (q == 0 || ts[q] - ts[q - 1] > merge) ++c;
    return c;
  }

  std::span<const Vec3> points_;
  const PointGrid& grid_;
  const LocalFrames& f_;
  std::vector<std::uint32_t> stamp_;
  std::uint32_t ray_ = 0;
  Vec3 lo_, hi_;
  std::vector<double> ahead_, behind_;
};

/// Union-find with the relative orientation of each point to its root and the outward votes of
/// each set (in the root's frame).
struct OrientedSets {
  std::vector<std::uint32_t> parent;
  std::vector<std::uint8_t> flip;  // orientation relative to the parent
  std::vector<std::int32_t> votes;
  explicit OrientedSets(std::size_t n) : parent(n), flip(n, 0), votes(n, 0) {
    std::iota(parent.begin(), parent.end(), 0u);
  }
  /// Root of i and i's orientation relative to it (path halving keeps the flips consistent).
  std::pair<std::uint32_t, std::uint8_t> find(std::uint32_t i) {
    std::uint8_t fl = 0;
    while (parent[i] != i) {
      const std::uint32_t p = parent[i];
      if (parent[p] != p) {  // halve: i -> grandparent
        flip[i] ^= flip[p];
        parent[i] = parent[p];
      }
      fl ^= flip[i];
      i = parent[i];
    }
    return {i, fl};
  }
};

/// Closed objects with thin walls: the propagation can jump across a wall (the point on the other
/// side has a parallel normal) and orient a whole region inward. Ray parity gives each point an
/// outward vote independent of the propagation. When a sample of votes disagrees with the
/// propagated orientation, the orientation is rebuilt Kruskal-style: kNN edges in order of cost
/// join sets of points (with their relative orientation), except that two sets whose votes
/// firmly disagree across the edge stay apart (the edge crosses a wall); each set finally takes
/// the orientation its votes prefer. Open scans (rays escape both ways) and clouds the
/// propagation already oriented in agreement with the votes are left unchanged.
template <class Cost, class Agreement>
void repair_by_parity(std::span<const Vec3> points, const PointGrid& grid,
                      const std::vector<std::uint32_t>& knn, std::size_t k, const Cost& cost,
                      const Agreement& agreement, LocalFrames& f) {
  const std::size_t n = points.size();
  if (n < 64 || grid.order().size() != n) return;
  // Voters: every `stride`-th point (at most about 2000 rays pairs). A first sample of about
  // 500 of them decides whether the orientation needs the repair at all.
  constexpr std::size_t kMaxVoters = 2000, kCheckVoters = 500;
  const std::size_t stride = (n + kMaxVoters - 1) / kMaxVoters;
  const std::size_t check_stride = stride * ((n / stride + kCheckVoters - 1) / kCheckVoters);
  ParityCaster caster(points, grid, f);
  std::vector<std::int8_t> vote(n, 0);
  std::size_t sampled = 0, decided = 0, against = 0;
  for (std::size_t i = 0; i < n; i += check_stride) {
    ++sampled;
    vote[i] = static_cast<std::int8_t>(caster.vote(static_cast<std::uint32_t>(i)));
    decided += vote[i] != 0 ? 1 : 0;
    against += vote[i] < 0 ? 1 : 0;
  }
  // Mostly undecided: not a closed surface (rays escape both ways). Few votes against: the
  // propagation is right (the votes themselves err on a few per cent of the points).
  if (2 * decided < sampled || against * 20 <= decided) return;
  for (std::size_t i = 0; i < n; i += stride)
    if (i % check_stride != 0) vote[i] = static_cast<std::int8_t>(caster.vote(static_cast<std::uint32_t>(i)));

  struct Edge {
    float cost;
    std::uint32_t i, j;
  };
  std::vector<Edge> edges;
  edges.reserve(n * k);
  for (std::uint32_t i = 0; i < n; ++i)
    for (std::size_t q = 0; q < k; ++q) {
      const std::uint32_t j = knn[i * k + q];
      if (j == kNone) continue;
      edges.push_back({cost(i, j), i, j});
    }
  std::sort(edges.begin(), edges.end(), [](const Edge& a, const Edge& b) {
    return a.cost != b.cost ? a.cost < b.cost : (a.i != b.i ? a.i < b.i : a.j < b.j);
  });
  OrientedSets sets(n);
  for (std::size_t i = 0; i < n; ++i) sets.votes[i] = vote[i];
  constexpr std::int32_t kFirm = 2;  // votes that make a set's orientation firm
  for (const Edge& e : edges) {
    const auto [ri, fi] = sets.find(e.i);
    const auto [rj, fj] = sets.find(e.j);
    if (ri == rj) continue;
    // Orientation of rj's frame in ri's frame.
    const std::uint8_t x = static_cast<std::uint8_t>(fi ^ fj ^ (agreement(e.i, e.j) < 0 ? 1 : 0));
    const std::int32_t vi = sets.votes[ri], vj = x ? -sets.votes[rj] : sets.votes[rj];
    if ((vi >= kFirm && vj <= -kFirm) || (vi <= -kFirm && vj >= kFirm)) continue;
    sets.parent[rj] = ri;
    sets.flip[rj] = x;
    sets.votes[ri] = vi + vj;
  }
  for (std::uint32_t i = 0; i < n; ++i) {
    const auto [r, fl] = sets.find(i);
    const bool outward_root = sets.votes[r] >= 0;
    if ((fl != 0) == outward_root) f.normal[i] = -f.normal[i];
  }
}

}  // namespace

LocalFrames estimate_frames(std::span<const Vec3> points, const PointGrid& grid,
                            const NormalOptions& options, std::span<const Vec3> towards_sensor) {
  const std::size_t n = points.size();
  const auto k = static_cast<std::size_t>(std::max(6, options.neighbours));
  LocalFrames f;
  f.normal.resize(n);
  f.spacing.resize(n);
  f.flatness.resize(n);
  if (n == 0) return f;
  const bool propagate = !options.view_point.has_value();
  std::vector<std::uint32_t> knn(propagate ? n * k : 0, kNone);

  std::vector<std::uint32_t> best_j(k);
  std::vector<double> best_d2(k);
  // The reference neighbourhood: the k nearest among the points of the 27 cells around p
  // (125, 343, ... up to 17^3 cells when too few: a region sampled up to about 15 times more
  // sparsely than the grid was sized for still finds its k), ties broken by the lower index.
  std::vector<std::pair<double, std::uint32_t>> near;
  std::vector<double> sx(k), sy(k), sz(k);
  std::vector<std::uint32_t> seq(k);
  std::iota(seq.begin(), seq.end(), 0u);
  auto slow_point = [&](std::size_t i) {
    const Vec3& p = points[i];
    near.clear();
    int ring = 1;
    while (true) {
      grid.for_each_near(p, ring, [&](std::uint32_t j) {
        if (j != i) near.emplace_back((points[j] - p).squaredNorm(), j);
      });
      if (near.size() >= k || ring >= 8) break;
      near.clear();
      ++ring;
    }
    const std::size_t m = std::min(k, near.size());
    std::partial_sort(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(m), near.end());
    for (std::size_t q = 0; q < m; ++q) {
      best_d2[q] = near[q].first;
      best_j[q] = near[q].second;
      sx[q] = points[near[q].second].x();
      sy[q] = points[near[q].second].y();
      sz[q] = points[near[q].second].z();
    }
    finish_point(sx.data(), sy.data(), sz.data(), seq.data(), p, i, best_d2.data(), m, f);
    if (propagate)
      std::copy(best_j.begin(), best_j.begin() + static_cast<std::ptrdiff_t>(m),
                knn.data() + i * k);
  };

  if (grid.order().size() != n) {
    // Not the documented use (the grid indexes other points): the plain per-point search.
    for (std::size_t i = 0; i < n; ++i) slow_point(i);
  } else {
    // All points of a cell share the candidate set (the 27 cells around it): gather it once per
    // cell into flat arrays, then scan it for each point of the cell.
    const auto& order = grid.order();
    detail::BlockPoints block;
    std::vector<double> cd2;
    std::vector<std::uint32_t> best_t(k);
    std::vector<Picked> picked, sorted, top(k);
    detail::NeighbourOrder ordering;
    double threshold = std::numeric_limits<double>::infinity();
    grid.for_each_cell([&](std::int64_t x, std::int64_t y, std::int64_t z, std::uint32_t first,
                           std::uint32_t last) {
      const std::size_t cnt = block.gather(grid, x, y, z, 1, points);
      if (cnt < k + 1) {  // too few in the 27 cells (the point itself is one of them)
        for (std::uint32_t s = first; s < last; ++s) slow_point(order[s]);
        return;
      }
      if (cd2.size() < cnt) {
        cd2.resize(cnt);
        picked.resize(cnt);
        sorted.resize(cnt);
      }
      const std::uint32_t* cand = block.index.data();
      const double* xs = block.x.data();
      const double* ys = block.y.data();
      const double* zs = block.z.data();
      double* ds = cd2.data();
      for (std::uint32_t s = first; s < last; ++s) {
        const std::uint32_t i = order[s];
        const double px = points[i].x(), py = points[i].y(), pz = points[i].z();
        // Squared distances, pre-filtered (branch-free) by a multiple of the previous point's
        // k-th: when at least k candidates besides the point itself pass, the k nearest are
        // among them. Otherwise widen the filter, and in the end take all.
        std::size_t np = 0;
        double thr = threshold;
        for (std::size_t u = 0; u < cnt; ++u) {
          const double dx = xs[u] - px, dy = ys[u] - py, dz = zs[u] - pz;
          const double d2 = dx * dx + dy * dy + dz * dz;
          ds[u] = d2;
          picked[np] = {d2, cand[u], static_cast<std::uint32_t>(u)};
          np += ((d2 <= thr) & (cand[u] != i)) ? 1 : 0;
        }
        for (int widen = 0; np < k; ++widen) {  // four times the filter, then everything
          thr = widen == 0 ? 4 * thr : std::numeric_limits<double>::infinity();
          np = 0;
          for (std::size_t u = 0; u < cnt; ++u) {
            picked[np] = {ds[u], cand[u], static_cast<std::uint32_t>(u)};
            np += ((ds[u] <= thr) & (cand[u] != i)) ? 1 : 0;
          }
        }
        if (thr < std::numeric_limits<double>::infinity() && thr > 0) {
          // Sorted by (distance, index); the first k are the k nearest.
          ordering.sort(picked.data(), np, thr, sorted.data());
          std::copy(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(k), top.begin());
        } else {
          // Bounded insertion by (distance, index): the k nearest, ascending.
          std::size_t m = 0;
          for (std::size_t a = 0; a < np; ++a) {
            const Picked c = picked[a];
            if (m == k && !c.before(top[k - 1])) continue;
            std::size_t b = m < k ? m++ : k - 1;
            while (b > 0 && c.before(top[b - 1])) {
              top[b] = top[b - 1];
              --b;
            }
            top[b] = c;
          }
        }
        for (std::size_t q = 0; q < k; ++q) {
          best_t[q] = top[q].tag;
          best_j[q] = top[q].j;
          best_d2[q] = top[q].d2;
        }
        threshold = kThresholdFactor * best_d2[k - 1];
        finish_point(xs, ys, zs, best_t.data(), points[i], i, best_d2.data(), k, f);
        if (propagate) std::copy(best_j.begin(), best_j.end(), knn.data() + i * k);
      }
    });
  }

  if (!propagate) {
    for (std::size_t i = 0; i < n; ++i) {
      if (f.normal[i].cast<double>().dot(*options.view_point - points[i]) < 0)
        f.normal[i] = -f.normal[i];
    }
    return f;
  }

  // Propagation: Prim traversal of the kNN graph (edges i -> its k nearest), most reliable
  // edges first, with an indexed heap of frontier vertices (one entry per vertex, decreased when
  // a better edge appears) instead of a queue of every edge pushed.
  //
  // Edge rule (after Koenig & Gumhold, "Consistent propagation of normal orientations in point
  // clouds"): the surface between p_i and p_j is taken as a circular arc tangent to n_i at p_i,
  // whose normal at p_j is n_i mirrored across the plane bisecting the edge e (unit p_j - p_i):
  // agreement = n_i.n_j - 2 (n_i.e)(n_j.e), symmetric in i and j. On a flat or smoothly curved
  // sheet it is n_i.n_j; across a convex or concave sharp edge it stays positive where the
  // plain product is near zero; across a thin wall (e along the normals) it says "opposite",
  // which is right for the two sides of a wall. The cost adds the larger off-tangent-plane
  // component of e: an edge leaving both tangent planes steeply (a diagonal across a wall,
  // where the arc model fails) is used last.
  Frontier frontier(n);
  struct Arc {
    float agreement;  // n_i mirrored across the bisecting plane, dotted with n_j
    float off_plane;  // the larger off-tangent-plane component of e
  };
  auto arc = [&](std::uint32_t i, std::uint32_t j) {
    const Eigen::Vector3f& ni = f.normal[i];
    const Eigen::Vector3f& nj = f.normal[j];
    Eigen::Vector3f e = (points[j] - points[i]).cast<float>();
    const float len = e.norm();
    if (!(len > 0)) return Arc{ni.dot(nj), 0.0f};
    e /= len;
    const float a = ni.dot(e), b = nj.dot(e);
    return Arc{ni.dot(nj) - 2.0f * a * b, std::max(std::abs(a), std::abs(b))};
  };
  auto agreement = [&](std::uint32_t i, std::uint32_t j) { return arc(i, j).agreement; };
  auto cost = [&](std::uint32_t i, std::uint32_t j) {
    const Arc c = arc(i, j);
    return 1.0f - std::abs(c.agreement) + 0.5f * c.off_plane;
  };
  auto visit = [&](std::uint32_t i) {
    const std::uint32_t* row = knn.data() + i * k;
    for (std::size_t q = 0; q < k; ++q) {
      const std::uint32_t j = row[q];
      if (j == kNone || frontier.done(j)) continue;
      const float c = cost(i, j);
      // j is visited when popped: fetch its neighbour row ahead of time.
      __builtin_prefetch(knn.data() + static_cast<std::size_t>(j) * k);
      frontier.offer(c, i, j);
    }
  };
  // With sensor directions, the part each traversal orients is remembered, to be turned to its
  // sensors as one piece at the end.
  const bool sensors = towards_sensor.size() == n;
  std::vector<std::uint32_t> part(sensors ? n : 0);
  std::uint32_t parts = 0;
  auto grow_from = [&](std::uint32_t start) {
    if (f.normal[start].z() < 0) f.normal[start] = -f.normal[start];
    frontier.set_done(start);
    if (sensors) part[start] = parts;
    visit(start);
    while (!frontier.empty()) {
      const Frontier::Item it = frontier.pop();
      if (agreement(it.from(), it.to) < 0) f.normal[it.to] = -f.normal[it.to];
      if (sensors) part[it.to] = parts;
      visit(it.to);
    }
    ++parts;
  };
  // Start points: extreme in +z first (ties: lower index), so a closed surface gets outward
  // normals. The first is found by a scan; the rest (other components) are sorted once.
  auto higher = [&](std::uint32_t a, std::uint32_t b) {
    return points[a].z() != points[b].z() ? points[a].z() > points[b].z() : a < b;
  };
  std::uint32_t top = 0;
  for (std::uint32_t i = 1; i < n; ++i)
    if (higher(i, top)) top = i;
  grow_from(top);
  std::vector<std::uint32_t> rest;
  for (std::uint32_t i = 0; i < n; ++i)
    if (!frontier.done(i)) rest.push_back(i);
  std::sort(rest.begin(), rest.end(), higher);
  for (const std::uint32_t start : rest)
    if (!frontier.done(start)) grow_from(start);
  repair_by_parity(points, grid, knn, k, cost, agreement, f);
  if (sensors) {
    std::vector<double> facing(parts, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      const double len = towards_sensor[i].norm();
      if (len > 0 && std::isfinite(len))
        facing[part[i]] += f.normal[i].cast<double>().dot(towards_sensor[i]) / len;
    }
    for (std::size_t i = 0; i < n; ++i)
      if (facing[part[i]] < 0) f.normal[i] = -f.normal[i];
  }
  return f;
}

}  // namespace scanmesh::recon
