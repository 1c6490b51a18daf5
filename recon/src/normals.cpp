// PCA normals over k nearest neighbours, oriented by propagation over the kNN graph (Hoppe et
// al.: most-parallel neighbour first, from an extreme point of each component facing outward).
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

}  // namespace

LocalFrames estimate_frames(std::span<const Vec3> points, const PointGrid& grid,
                            const NormalOptions& options) {
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
  // (125, then 343 when too few), ties broken by the lower index.
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
      if (near.size() >= k || ring >= 3) break;
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

  // Propagation: Prim traversal of the kNN graph (edges i -> its k nearest), most parallel
  // edges first, with an indexed heap of frontier vertices (one entry per vertex, decreased when
  // a better edge appears) instead of a queue of every edge pushed.
  Frontier frontier(n);
  auto visit = [&](std::uint32_t i) {
    const Eigen::Vector3f ni = f.normal[i];
    const std::uint32_t* row = knn.data() + i * k;
    for (std::size_t q = 0; q < k; ++q) {
      const std::uint32_t j = row[q];
      if (j == kNone || frontier.done(j)) continue;
      const float c = 1.0f - std::abs(ni.dot(f.normal[j]));
      // j is visited when popped: fetch its neighbour row ahead of time.
      __builtin_prefetch(knn.data() + static_cast<std::size_t>(j) * k);
      frontier.offer(c, i, j);
    }
  };
  auto grow_from = [&](std::uint32_t start) {
    if (f.normal[start].z() < 0) f.normal[start] = -f.normal[start];
    frontier.set_done(start);
    visit(start);
    while (!frontier.empty()) {
      const Frontier::Item it = frontier.pop();

      if (f.normal[it.from()].dot(f.normal[it.to]) < 0) f.normal[it.to] = -f.normal[it.to];
      visit(it.to);
    }
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
  return f;
}

}  // namespace scanmesh::recon
