// Planar Delaunay triangulation by radial sweep (see delaunay2.hpp).
// SPDX-License-Identifier: MIT
#include "delaunay2.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <algorithm>
#include <bit>
#include <utility>
#include <cmath>
#include <limits>

namespace scanmesh::recon::detail {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using P2 = Kernel::Point_2;

P2 pt(const std::array<double, 2>& a) { return {a[0], a[1]}; }

// The predicates: a floating-point evaluation with Shewchuk's a-priori error bound decides
// almost every case; the few it cannot go to CGAL's exact (filtered) predicates.
constexpr double kEps = 0x1p-53;  // half an ulp of 1
constexpr double kOrientBound = (3 + 16 * kEps) * kEps;
constexpr double kInCircleBound = (10 + 96 * kEps) * kEps;

/// Exactly: q lies strictly to the right of the directed line a -> b.
bool right_of(const std::array<double, 2>& a, const std::array<double, 2>& b, const std::array<double, 2>& q) {
  const double l = (a[0] - q[0]) * (b[1] - q[1]), r = (a[1] - q[1]) * (b[0] - q[0]);
  const double det = l - r;
  const double bound = kOrientBound * (std::abs(l) + std::abs(r));
  if (det > bound) return false;
  if (-det > bound) return true;
  return CGAL::orientation(pt(a), pt(b), pt(q)) == CGAL::RIGHT_TURN;
}

/// Exactly: d lies strictly inside the circle through a, b, c (counter-clockwise).
bool in_circle(const std::array<double, 2>& a, const std::array<double, 2>& b, const std::array<double, 2>& c,
               const std::array<double, 2>& d) {
  const double adx = a[0] - d[0], ady = a[1] - d[1], bdx = b[0] - d[0], bdy = b[1] - d[1];
  const double cdx = c[0] - d[0], cdy = c[1] - d[1];
  const double bc = bdx * cdy, cb = cdx * bdy, ca = cdx * ady, ac = adx * cdy, ab = adx * bdy, ba = bdx * ady;
  const double alift = adx * adx + ady * ady, blift = bdx * bdx + bdy * bdy, clift = cdx * cdx + cdy * cdy;
  const double det = alift * (bc - cb) + blift * (ca - ac) + clift * (ab - ba);
  const double permanent = (std::abs(bc) + std::abs(cb)) * alift + (std::abs(ca) + std::abs(ac)) * blift +
                           (std::abs(ab) + std::abs(ba)) * clift;
  const double bound = kInCircleBound * permanent;
  if (det > bound) return true;
  if (-det > bound) return false;
  return CGAL::side_of_oriented_circle(pt(a), pt(b), pt(c), pt(d)) == CGAL::ON_POSITIVE_SIDE;
}

double dist2(const std::array<double, 2>& a, const std::array<double, 2>& b) {
  const double dx = a[0] - b[0], dy = a[1] - b[1];
  return dx * dx + dy * dy;
}

std::array<double, 2> circumcentre(const std::array<double, 2>& a, const std::array<double, 2>& b,
                                   const std::array<double, 2>& c) {
  const double bx = b[0] - a[0], by = b[1] - a[1], cx = c[0] - a[0], cy = c[1] - a[1];
  const double d = 2 * (bx * cy - by * cx);
  const double b2 = bx * bx + by * by, c2 = cx * cx + cy * cy;
  return {a[0] + (cy * b2 - by * c2) / d, a[1] + (bx * c2 - cx * b2) / d};
}

/// Squared circumradius of (a, b, c), or infinity when they are (numerically) on one line.
double circumradius2(const std::array<double, 2>& a, const std::array<double, 2>& b,
                     const std::array<double, 2>& c) {
  if ((b[0] - a[0]) * (c[1] - a[1]) == (b[1] - a[1]) * (c[0] - a[0]))
    return std::numeric_limits<double>::infinity();
  const double r2 = dist2(circumcentre(a, b, c), a);
  return std::isfinite(r2) ? r2 : std::numeric_limits<double>::infinity();
}

/// A monotone stand-in for the angle of (dx, dy), in [0, 1]: cheaper than atan2.
double pseudo_angle(double dx, double dy) {
  const double s = std::abs(dx) + std::abs(dy);
  if (!(s > 0)) return 0;
  const double q = dx / s;
  return (dy > 0 ? 3 - q : 1 + q) / 4;
}

}  // namespace

std::uint32_t Delaunay2::hash_key(const std::array<double, 2>& p) const {
  const auto size = static_cast<double>(hash_.size());
  const double a = std::floor(pseudo_angle(p[0] - centre_[0], p[1] - centre_[1]) * size);
  return static_cast<std::uint32_t>(std::clamp(a, 0.0, size)) % static_cast<std::uint32_t>(hash_.size());
}

void Delaunay2::link(std::uint32_t h, std::uint32_t t) {
  twin_[h] = t;
  if (t != kNone)
    twin_[t] = h;
  else
    hull_edge_[corner_[h]] = h;  // a hull edge: the one leaving its start vertex
}

std::uint32_t Delaunay2::add_triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t ab,
                                      std::uint32_t bc, std::uint32_t ca) {
  const auto t = static_cast<std::uint32_t>(corner_.size());
  corner_.insert(corner_.end(), {a, b, c});
  twin_.resize(corner_.size());
  link(t, ab);
  link(t + 1, bc);
  link(t + 2, ca);
  return t;
}

void Delaunay2::legalize(std::uint32_t h) {
  // Every edge on the stack is opposite the point just inserted (w below): Lawson's flips.
  static constexpr std::uint32_t kNext[3] = {1, 2, 0}, kPrev[3] = {2, 0, 1};
  stack_.clear();
  stack_.push_back(h);
  while (!stack_.empty()) {
    const std::uint32_t a = stack_.back();
    stack_.pop_back();
    const std::uint32_t b = twin_[a];
    if (b == kNone) continue;
    // a: u -> v in (u, v, w); b: v -> u in (v, u, x).
    const std::uint32_t t1 = a / 3 * 3, t2 = b / 3 * 3;
    const std::uint32_t an = t1 + kNext[a - t1], ap = t1 + kPrev[a - t1];
    const std::uint32_t bn = t2 + kNext[b - t2], bp = t2 + kPrev[b - t2];
    const std::uint32_t u = corner_[a], v = corner_[an], w = corner_[ap], x = corner_[bp];
    if (!in_circle(p_[u], p_[v], p_[w], p_[x])) continue;
    // Flip to (w, u, x) and (x, v, w), in the slots of the two triangles.
    const std::uint32_t tap = twin_[ap], tbn = twin_[bn], tbp = twin_[bp], tan = twin_[an];
    corner_[t1] = w;
    corner_[t1 + 1] = u;
    corner_[t1 + 2] = x;
    corner_[t2] = x;
    corner_[t2 + 1] = v;
    corner_[t2 + 2] = w;
    link(t1, tap);
    link(t1 + 1, tbn);
    twin_[t1 + 2] = t2 + 2;
    twin_[t2 + 2] = t1 + 2;
    link(t2, tbp);
    link(t2 + 1, tan);
    stack_.push_back(t1 + 1);  // u -> x, opposite w
    stack_.push_back(t2);      // x -> v, opposite w
  }
}

void Delaunay2::triangulate(std::span<const std::array<double, 2>> points) {
  p_ = points;
  const std::size_t n = points.size();
  corner_.clear();
  twin_.clear();
  out_.assign(n, kNone);
  if (n < 3) return;

  // Seed: the point nearest the box's centre, its nearest neighbour, and the point making the
  // smallest circumcircle with them (exactly not on their line).
  std::array<double, 2> lo = points[0], hi = points[0];
  for (const auto& q : points)
    for (int k = 0; k < 2; ++k) {
      lo[k] = std::min(lo[k], q[k]);
      hi[k] = std::max(hi[k], q[k]);
    }
  const std::array<double, 2> mid = {(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2};
  auto nearest = [&](const std::array<double, 2>& c, std::uint32_t skip) {
    std::uint32_t best = kNone;
    double best_d = std::numeric_limits<double>::infinity();
    for (std::uint32_t i = 0; i < n; ++i) {
      const double d = dist2(points[i], c);
      if (i != skip && d < best_d && (skip == kNone || d > 0)) {
        best_d = d;
        best = i;
      }
    }
    return best;
  };
  const std::uint32_t i0 = nearest(mid, kNone);
  std::uint32_t i1 = nearest(points[i0], i0);
  if (i1 == kNone) return;  // every point in one place
  std::uint32_t i2 = kNone;
  double best_r2 = std::numeric_limits<double>::infinity();
  for (std::uint32_t i = 0; i < n; ++i) {
    const double r2 = circumradius2(points[i0], points[i1], points[i]);
    if (r2 < best_r2 && CGAL::orientation(pt(points[i0]), pt(points[i1]), pt(points[i])) != CGAL::COLLINEAR) {
      best_r2 = r2;
      i2 = i;
    }
  }
  if (i2 == kNone) return;  // all on one line
  if (right_of(points[i0], points[i1], points[i2])) std::swap(i1, i2);
  centre_ = circumcentre(points[i0], points[i1], points[i2]);

  // The sweep order: by distance from the centre, ties by index. A stable radix sort on the
  // distance as a float (three passes of 11 bits; non-negative floats order like their bit
  // patterns), then each run of equal floats by the exact distance: rounding to float is
  // monotone, so only points within such a run can be out of order.
  key_.clear();
  order_.clear();
  dist_.resize(n);
  for (std::uint32_t i = 0; i < n; ++i)
    if (i != i0 && i != i1 && i != i2) {
      dist_[i] = dist2(points[i], centre_);
      key_.push_back(std::bit_cast<std::uint32_t>(static_cast<float>(dist_[i])));
      order_.push_back(i);
    }
  sorted_.resize(order_.size());
  key_sorted_.resize(order_.size());
  for (int shift = 0; shift < 32; shift += 11) {
    std::array<std::uint32_t, 2048> count{};
    for (const std::uint32_t k : key_) ++count[(k >> shift) & 2047u];
    std::uint32_t sum = 0;
    for (std::uint32_t& c : count) sum += std::exchange(c, sum);
    for (std::size_t j = 0; j < order_.size(); ++j) {
      const std::uint32_t at = count[(key_[j] >> shift) & 2047u]++;
      sorted_[at] = order_[j];
      key_sorted_[at] = key_[j];
    }
    order_.swap(sorted_);
    key_.swap(key_sorted_);
  }
  for (std::size_t j = 0; j < order_.size();) {
    std::size_t e = j + 1;
    while (e < order_.size() && key_[e] == key_[j]) ++e;
    if (e - j > 1)
      std::sort(order_.begin() + static_cast<std::ptrdiff_t>(j), order_.begin() + static_cast<std::ptrdiff_t>(e),
                [&](std::uint32_t a, std::uint32_t b) { return dist_[a] != dist_[b] ? dist_[a] < dist_[b] : a < b; });
    j = e;
  }

  // The sweep runs on the points renumbered in its order (seed first): the points near the
  // hull, which every insertion and flip reads, are then the last few inserted, near each other
  // in memory, instead of scattered over the patch. The triangulation is the same; its corners
  // are numbered back at the end.
  perm_.clear();
  perm_.insert(perm_.end(), {i0, i1, i2});
  perm_.insert(perm_.end(), order_.begin(), order_.end());
  swept_.resize(n);
  for (std::size_t k = 0; k < n; ++k) swept_[k] = points[perm_[k]];
  const std::span<const std::array<double, 2>> sp = swept_;
  p_ = sp;
  corner_.reserve(6 * n);
  twin_.reserve(6 * n);
  hull_next_.assign(n, kNone);  // kNone: not on the hull (yet, or any more)
  hull_prev_.resize(n);
  hull_edge_.resize(n);
  hash_.assign(static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(n)))), kNone);

  add_triangle(0, 1, 2, kNone, kNone, kNone);
  hull_next_[0] = 1;
  hull_next_[1] = 2;
  hull_next_[2] = 0;
  hull_prev_[1] = 0;
  hull_prev_[2] = 1;
  hull_prev_[0] = 2;
  for (const std::uint32_t s : {0u, 1u, 2u}) hash_[hash_key(sp[s])] = s;
  std::uint32_t hull_start = 0;

  std::uint32_t last = kNone;
  for (std::uint32_t i = 3; i < n; ++i) {
    const auto& q = sp[i];
    if (last != kNone && q == sp[last]) continue;  // a repeat of the point before
    last = i;
    // A hull vertex near q's direction from the centre, then the first hull edge q sees.
    const std::uint32_t key = hash_key(q);
    std::uint32_t start = kNone;
    for (std::size_t j = 0; j < hash_.size(); ++j) {
      const std::uint32_t s = hash_[(key + j) % hash_.size()];
      if (s != kNone && hull_next_[s] != kNone) {
        start = s;
        break;
      }
    }
    start = hull_prev_[start];
    std::uint32_t e = start;
    while (!right_of(sp[e], sp[hull_next_[e]], q)) {
      e = hull_next_[e];
      if (e == start) {
        e = kNone;
        break;
      }
    }
    if (e == kNone) continue;  // q sees no hull edge: a repeat, or inside after rounding
    std::uint32_t nx = hull_next_[e];
    legalize(add_triangle(e, i, nx, kNone, kNone, hull_edge_[e]) + 2);
    // Walk forward, then backward, over the other hull edges q sees.
    for (std::uint32_t nn = hull_next_[nx]; right_of(sp[nx], sp[nn], q); nn = hull_next_[nx]) {
      legalize(add_triangle(nx, i, nn, hull_edge_[i], kNone, hull_edge_[nx]) + 2);
      hull_next_[nx] = kNone;
      nx = nn;
    }
    if (e == start)
      for (std::uint32_t pe = hull_prev_[e]; right_of(sp[pe], sp[e], q); pe = hull_prev_[e]) {
        legalize(add_triangle(pe, i, e, kNone, hull_edge_[e], hull_edge_[pe]) + 2);
        hull_next_[e] = kNone;
        e = pe;
      }
    hull_prev_[i] = e;
    hull_next_[e] = i;
    hull_prev_[nx] = i;
    hull_next_[i] = nx;
    hash_[hash_key(q)] = i;
    hash_[hash_key(sp[e])] = e;
    hull_start = i;
  }

  for (std::uint32_t h = 0; h < corner_.size(); ++h) {
    corner_[h] = perm_[corner_[h]];
    out_[corner_[h]] = h;
  }
  std::uint32_t v = hull_start;
  do {
    out_[perm_[v]] = hull_edge_[v];
    v = hull_next_[v];
  } while (v != hull_start);
  p_ = points;  // in the corners' numbering again
}

}  // namespace scanmesh::recon::detail
