// Self-intersection check (see intersections.hpp): a uniform grid over the triangles' bounding
// boxes finds the candidate pairs, and an interval test on the line where the two planes meet
// (Möller, "A fast triangle-triangle intersection test", 1997), or an overlap test in the plane
// for coplanar pairs, decides each one, leaving out what the pair legitimately shares.
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/intersections.hpp"

#include "closest_point.hpp"
#include "triangle_components.hpp"

#include <algorithm>
#include <bit>
#include <utility>
#include <cmath>
#include <limits>

namespace scanmesh::recon {
namespace {

constexpr double kTolerance = 1e-9;  // of the pair's longest edge
constexpr double kParallel2 = 1e-12;  // squared sine: planes closer than 1e-6 rad are one
/// A triangle whose bounding box covers more cells than this is tested against every triangle
/// whose box it overlaps (a long patch triangle must not fill the grid).
constexpr std::size_t kMaxCells = 512;

struct Box {
  Vec3 lo, hi;
  [[nodiscard]] bool overlaps(const Box& o) const {
    return (lo.array() <= o.hi.array()).all() && (o.lo.array() <= hi.array()).all();
  }
};

/// The points of a triangle on the other triangle's plane (signed distances d, exact zeros for
/// vertices on it), as an interval of their coordinate along `dir`. False when none is.
bool interval_on_line(const std::array<Vec3, 3>& p, const std::array<double, 3>& d, const Vec3& dir,
                      double& lo, double& hi) {
  lo = std::numeric_limits<double>::infinity();
  hi = -lo;
  for (int k = 0; k < 3; ++k) {
    const int l = (k + 1) % 3;
    if (d[k] == 0) {
      const double t = dir.dot(p[k]);
      lo = std::min(lo, t);
      hi = std::max(hi, t);
    }
    if ((d[k] > 0 && d[l] < 0) || (d[k] < 0 && d[l] > 0)) {
      const double t = dir.dot(p[k] + (d[k] / (d[k] - d[l])) * (p[l] - p[k]));
      lo = std::min(lo, t);
      hi = std::max(hi, t);
    }
  }
  return lo <= hi;
}

double orient2(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const Eigen::Vector2d u = b - a, w = c - a;
  return u.x() * w.y() - u.y() * w.x();
}

/// Two triangles in one plane (projected to 2D): do they overlap beyond the corners they share
/// (shared_p[k]: corner k of p is a corner of q; likewise shared_q)?
bool coplanar_overlap(const std::array<Eigen::Vector2d, 3>& p, const std::array<Eigen::Vector2d, 3>& q,
                      const std::array<bool, 3>& shared_p, const std::array<bool, 3>& shared_q,
                      int shared, double eps2) {
  auto sign = [eps2](double v) { return v > eps2 ? 1 : (v < -eps2 ? -1 : 0); };
  if (shared == 2) {  // on the same side of the shared edge: one folds onto the other
    int op = 0, oq = 0;
    while (shared_p[op]) ++op;
    while (shared_q[oq]) ++oq;
    const Eigen::Vector2d& a = p[(op + 1) % 3];
    const Eigen::Vector2d& b = p[(op + 2) % 3];
    const int sp = sign(orient2(a, b, p[op])), sq = sign(orient2(a, b, q[oq]));
    return sp != 0 && sp == sq;
  }
  // Edges that cross properly (edges of a shared corner meet there, and are left out).
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3;
    for (int j = 0; j < 3; ++j) {
      const int j1 = (j + 1) % 3;
      if ((shared_p[i] || shared_p[i1]) && (shared_q[j] || shared_q[j1])) continue;
      const int a = sign(orient2(p[i], p[i1], q[j])), b = sign(orient2(p[i], p[i1], q[j1]));
      const int c = sign(orient2(q[j], q[j1], p[i])), d = sign(orient2(q[j], q[j1], p[i1]));
      if (a * b < 0 && c * d < 0) return true;
    }
  }
  // A corner strictly inside the other triangle.
  auto inside = [&](const Eigen::Vector2d& x, const std::array<Eigen::Vector2d, 3>& t) {
    const int s0 = sign(orient2(t[0], t[1], x)), s1 = sign(orient2(t[1], t[2], x)),
              s2 = sign(orient2(t[2], t[0], x));
    return s0 != 0 && s0 == s1 && s1 == s2;
  };
  for (int k = 0; k < 3; ++k) {
    if (!shared_p[k] && inside(p[k], q)) return true;
    if (!shared_q[k] && inside(q[k], p)) return true;
  }
  return false;
}


/// Squared distance between segments p0-p1 and q0-q1 (Ericson 5.1.9, clamped parameters).
double segment_segment_d2(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
  const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0, t = 0;
  if (a <= 0 && e <= 0) return r.squaredNorm();
  if (a <= 0) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 0) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), den = a * e - b * b;
      s = den > 0 ? std::clamp((b * f - c * e) / den, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return (p0 + d1 * s - (q0 + d2 * t)).squaredNorm();
}

}  // namespace

bool triangles_touch(std::span<const Vec3> vertices, const Triangle& s, const Triangle& t,
                     double clearance) {
  int shared = 0;
  for (std::uint32_t v : s) shared += (v == t[0] || v == t[1] || v == t[2]) ? 1 : 0;
  if (shared >= 2) return false;  // across a shared edge: only a fold, triangles_intersect's case
  const double c2 = clearance * clearance;
  auto in = [](std::uint32_t v, const Triangle& x) { return v == x[0] || v == x[1] || v == x[2]; };
  auto d2 = [&](std::uint32_t v, const Triangle& x) {
    return detail::closest_on_triangle(vertices[v], vertices[x[0]], vertices[x[1]], vertices[x[2]])
        .dist_sq;
  };
  // A corner of one (not shared) near the other triangle.
  for (int k = 0; k < 3; ++k) {
    if (!in(s[k], t) && d2(s[k], t) <= c2) return true;
    if (!in(t[k], s) && d2(t[k], s) <= c2) return true;
  }
  // Two edges without a common end point near each other.
  for (int i = 0; i < 3; ++i) {
    const std::uint32_t a = s[i], b = s[(i + 1) % 3];
    for (int j = 0; j < 3; ++j) {
      const std::uint32_t c = t[j], d = t[(j + 1) % 3];
      if (a == c || a == d || b == c || b == d) continue;
      if (segment_segment_d2(vertices[a], vertices[b], vertices[c], vertices[d]) <= c2) return true;
    }
  }
  return false;
}

bool triangles_intersect(std::span<const Vec3> vertices, const Triangle& s, const Triangle& t,
                         double on_plane) {
  std::array<bool, 3> shared_p{}, shared_q{};
  int shared = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (s[i] == t[j]) {
        shared_p[i] = shared_q[j] = true;
        ++shared;
      }
  if (shared == 3) return true;  // the same triangle twice
  const std::array<Vec3, 3> p{vertices[s[0]], vertices[s[1]], vertices[s[2]]};
  const std::array<Vec3, 3> q{vertices[t[0]], vertices[t[1]], vertices[t[2]]};
  double longest = 0;
  for (int k = 0; k < 3; ++k) {
    longest = std::max(longest, (p[(k + 1) % 3] - p[k]).squaredNorm());
    longest = std::max(longest, (q[(k + 1) % 3] - q[k]).squaredNorm());
  }
  longest = std::sqrt(longest);
  const double eps = kTolerance * longest;
  const Vec3 n1 = (p[1] - p[0]).cross(p[2] - p[0]).normalized();
  const Vec3 n2 = (q[1] - q[0]).cross(q[2] - q[0]).normalized();
  // Signed distances to the other plane; shared corners and near-zero ones are on it.
  std::array<double, 3> dp{}, dq{};
  // Every corner within on_plane of the other plane: one plane (only then; zeroing single
  // heights with so wide a tolerance would put a corner on the line where two nearly parallel
  // planes meet when it lies far from it).
  bool near_coplanar = on_plane > eps;
  for (int k = 0; k < 3; ++k) {
    dp[k] = shared_p[k] ? 0.0 : n2.dot(p[k] - q[0]);
    dq[k] = shared_q[k] ? 0.0 : n1.dot(q[k] - p[0]);
    near_coplanar = near_coplanar && std::abs(dp[k]) <= on_plane && std::abs(dq[k]) <= on_plane;
    if (std::abs(dp[k]) <= eps) dp[k] = 0;
    if (std::abs(dq[k]) <= eps) dq[k] = 0;
  }
  auto one_side = [](const std::array<double, 3>& d) {
    return (d[0] > 0 && d[1] > 0 && d[2] > 0) || (d[0] < 0 && d[1] < 0 && d[2] < 0);
  };
  if (!near_coplanar && (one_side(dp) || one_side(dq))) return false;
  // Planes within 1e-6 rad of each other count as one: the line where they meet is then
  // ill-conditioned, and the tolerance above zeroes some distances but not others (two
  // triangles of a flat face meeting at a corner, their edges through it collinear, were
  // reported as crossing), so the pair is decided in the plane instead.
  const bool coplanar = near_coplanar || (dp[0] == 0 && dp[1] == 0 && dp[2] == 0) ||
                        (dq[0] == 0 && dq[1] == 0 && dq[2] == 0) ||
                        n1.cross(n2).squaredNorm() < kParallel2;
  if (coplanar) {
    int drop = 0;  // project along the normal's largest axis
    n1.cwiseAbs().maxCoeff(&drop);
    const int a = (drop + 1) % 3, b = (drop + 2) % 3;
    std::array<Eigen::Vector2d, 3> p2, q2;
    for (int k = 0; k < 3; ++k) {
      p2[k] = Eigen::Vector2d(p[k][a], p[k][b]);
      q2[k] = Eigen::Vector2d(q[k][a], q[k][b]);
    }
    return coplanar_overlap(p2, q2, shared_p, shared_q, shared, eps * longest);
  }
  // Two planes through one edge meet only on that edge's line, and each triangle lies on one
  // side of it: the triangles share the edge and nothing else.
  if (shared == 2) return false;
  const Vec3 dir = n1.cross(n2).normalized();
  double lo1 = 0, hi1 = 0, lo2 = 0, hi2 = 0;
  if (!interval_on_line(p, dp, dir, lo1, hi1) || !interval_on_line(q, dq, dir, lo2, hi2))
    return false;
  const double overlap = std::min(hi1, hi2) - std::max(lo1, lo2);
  // A shared corner is in both intervals: only more than that point is an intersection.
  return shared == 1 ? overlap > eps : overlap >= 0;
}

SelfIntersections find_self_intersections(const Mesh& mesh, std::size_t max_examples,
                                          std::size_t from) {
  return find_self_intersections(mesh.vertices, mesh.triangles, max_examples, from);
}

SelfIntersections find_self_intersections(std::span<const Vec3> vertices,
                                          std::span<const Triangle> triangles,
                                          std::size_t max_examples, std::size_t from) {
  SelfIntersections out;
  const std::size_t nt = triangles.size();
  const std::size_t nv = vertices.size();
  std::vector<std::uint32_t> valid;
  std::vector<Box> box(nt);
  // With `from`, an older triangle outside the box of all new ones cannot meet any of them.
  Box added{Vec3::Constant(std::numeric_limits<double>::infinity()),
            Vec3::Constant(-std::numeric_limits<double>::infinity())};
  for (const bool is_new : {true, false}) {
    if (!is_new && from == 0) break;
    for (std::uint32_t i = 0; i < nt; ++i) {
      if (from > 0 && (i >= from) != is_new) continue;
      const Triangle& t = triangles[i];
      if (t[0] >= nv || t[1] >= nv || t[2] >= nv || t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
        continue;
      const Vec3 &a = vertices[t[0]], &b = vertices[t[1]], &c = vertices[t[2]];
      if (!(a.allFinite() && b.allFinite() && c.allFinite())) continue;
      box[i] = {a.cwiseMin(b).cwiseMin(c), a.cwiseMax(b).cwiseMax(c)};
      if (from > 0 && !is_new && !box[i].overlaps(added)) continue;
      if ((b - a).cross(c - a).squaredNorm() == 0) continue;
      if (from > 0 && is_new) added = {added.lo.cwiseMin(box[i].lo), added.hi.cwiseMax(box[i].hi)};
      valid.push_back(i);
    }
  }
  if (valid.size() < 2) return out;
  // The grid: from the new triangles alone when there are any (nothing else is entered beyond
  // their cells), else from all.
  double edge_sum = 0;
  std::size_t sized = 0;
  Vec3 origin = Vec3::Constant(std::numeric_limits<double>::infinity());
  for (const std::uint32_t i : valid) {
    origin = origin.cwiseMin(box[i].lo);
    if (from > 0 && i < from) continue;
    const Triangle& t = triangles[i];
    const Vec3 &a = vertices[t[0]], &b = vertices[t[1]], &c = vertices[t[2]];
    edge_sum += (b - a).norm() + (c - b).norm() + (a - c).norm();
    ++sized;
  }
  if (sized == 0) return out;  // nothing new to test
  // Cells two mean edges wide, at most 2^20 a side (21 bits a coordinate in the key).
  Vec3 extent = Vec3::Zero();
  for (std::uint32_t i : valid) extent = extent.cwiseMax(box[i].hi - origin);
  double cell = 2 * edge_sum / (3.0 * static_cast<double>(sized));
  cell = std::max(cell, extent.maxCoeff() / double(1 << 20));
  if (!(cell > 0)) return out;
  // Clamped, NaN to 0: an extent that overflows (coordinates near the double range) must not
  // make an out-of-range conversion; such triangles then share a few cells.
  constexpr double kTop = double((1 << 21) - 1);
  auto coord = [&](double v, int axis) {
    const double c = std::floor((v - origin[axis]) / cell);
    return static_cast<std::uint32_t>(c >= 0 && c <= kTop ? c : (c > kTop ? kTop : 0.0));
  };
  std::vector<std::uint32_t> big;                       // triangles over kMaxCells cells
  std::vector<std::array<std::uint32_t, 6>> range(nt);  // cell ranges: lo xyz, hi xyz
  auto is_big = [&](std::uint32_t i) {
    const auto& r = range[i];
    return std::uint64_t{r[3] - r[0] + 1} * (r[4] - r[1] + 1) * (r[5] - r[2] + 1) > kMaxCells;
  };
  std::uint32_t top[3] = {0, 0, 0};  // the largest cell coordinate per axis
  for (const std::uint32_t i : valid) {
    auto& r = range[i];
    for (int k = 0; k < 3; ++k) {
      r[k] = coord(box[i].lo[k], k);
      r[3 + k] = coord(box[i].hi[k], k);
    }
    if (is_big(i)) {
      big.push_back(i);
      continue;
    }
    for (int k = 0; k < 3; ++k) top[k] = std::max(top[k], r[3 + k]);
  }
  // Cells numbered densely over the occupied box, (z, y, x) ascending, and an entry packed as
  // cell << tri_bits | triangle: sorted as integers they come by cell, then by triangle.
  const std::uint64_t nx = std::uint64_t{top[0]} + 1, ny = std::uint64_t{top[1]} + 1,
                      nz = std::uint64_t{top[2]} + 1;
  const int cell_bits = std::bit_width(nx * ny * nz - 1);  // at most 63: 21 bits an axis
  const int tri_bits = std::max(1, static_cast<int>(std::bit_width(nt - 1)));
  const bool packed = cell_bits + tri_bits <= 64;
  auto for_each_cell = [&](std::uint32_t i, auto&& f) {  // the cells of a triangle that is not big
    const auto& r = range[i];
    for (std::uint64_t z = r[2]; z <= r[5]; ++z)
      for (std::uint64_t y = r[1]; y <= r[4]; ++y)
        for (std::uint64_t x = r[0]; x <= r[3]; ++x) f((z * ny + y) * nx + x);
  };
  // With `from`, an older triangle is entered only in the cells of the new ones (nothing else
  // can meet a new one).
  std::vector<std::uint64_t> wanted;
  if (from > 0) {
    for (const std::uint32_t i : valid)
      if (i >= from && !is_big(i)) for_each_cell(i, [&](std::uint64_t c) { wanted.push_back(c); });
    std::sort(wanted.begin(), wanted.end());
    wanted.erase(std::unique(wanted.begin(), wanted.end()), wanted.end());
  }
  // (cell, triangle) entries: packed into one integer and radix sorted when they fit (the usual
  // case: a comparison sort of the pairs was a third of the check), else pairs sorted.
  std::vector<std::uint64_t> keys;                              // packed
  std::vector<std::pair<std::uint64_t, std::uint32_t>> pairs;  // otherwise
  for (const std::uint32_t i : valid) {
    if (is_big(i)) continue;
    const bool is_new = i >= from;
    for_each_cell(i, [&](std::uint64_t c) {
      if (!is_new && !std::binary_search(wanted.begin(), wanted.end(), c)) return;
      if (packed)
        keys.push_back((c << tri_bits) | i);
      else
        pairs.emplace_back(c, i);
    });
  }
  if (packed) {
    // LSD radix sort on the used bits, digits of at most 11 bits.
    const int bits = cell_bits + tri_bits;
    const int passes = (bits + 10) / 11, digit = (bits + passes - 1) / passes;
    std::vector<std::uint64_t> tmp(keys.size());
    std::vector<std::uint32_t> count(std::size_t{1} << digit);
    const std::uint64_t mask = (std::uint64_t{1} << digit) - 1;
    for (int pass = 0; pass < passes; ++pass) {
      const int shift = pass * digit;
      std::fill(count.begin(), count.end(), 0u);
      for (const std::uint64_t k : keys) ++count[(k >> shift) & mask];
      std::uint32_t sum = 0;
      for (std::uint32_t& c : count) sum += std::exchange(c, sum);
      for (const std::uint64_t k : keys) tmp[count[(k >> shift) & mask]++] = k;
      keys.swap(tmp);
    }
    std::vector<std::uint64_t>().swap(tmp);
  } else {
    std::sort(pairs.begin(), pairs.end());
  }
  const std::uint64_t tri_mask = (std::uint64_t{1} << tri_bits) - 1;  // tri_bits <= 32
  const std::size_t n_entries = packed ? keys.size() : pairs.size();
  auto cell_at = [&](std::size_t q) { return packed ? keys[q] >> tri_bits : pairs[q].first; };
  auto tri_at = [&](std::size_t q) {
    return packed ? static_cast<std::uint32_t>(keys[q] & tri_mask) : pairs[q].second;
  };
  std::vector<std::uint8_t> involved(nt, 0);
  auto record = [&](std::uint32_t a, std::uint32_t b) {
    ++out.pairs;
    involved[a] = involved[b] = 1;
    if (out.examples.size() < max_examples) out.examples.push_back({std::min(a, b), std::max(a, b)});
  };
  for (std::size_t g = 0; g < n_entries;) {
    const std::uint64_t key = cell_at(g);
    std::size_t e = g;
    while (e < n_entries && cell_at(e) == key) ++e;
    if (tri_at(e - 1) < from) {  // ids ascend within a cell: none is new
      g = e;
      continue;
    }
    const std::uint64_t cx = key % nx, cy = key / nx % ny, cz = key / nx / ny;
    for (std::size_t i = g; i < e; ++i) {
      const std::uint32_t a = tri_at(i);
      for (std::size_t j = i + 1; j < e; ++j) {
        const std::uint32_t b = tri_at(j);
        if (b < from || !box[a].overlaps(box[b])) continue;
        // Test the pair once: in the cell holding the low corner of the boxes' overlap.
        if (std::max(range[a][0], range[b][0]) != cx || std::max(range[a][1], range[b][1]) != cy ||
            std::max(range[a][2], range[b][2]) != cz)
          continue;
        if (triangles_intersect(vertices, triangles[a], triangles[b])) record(a, b);
      }
    }
    g = e;
  }
  std::sort(big.begin(), big.end());
  for (std::uint32_t a : big) {
    for (std::uint32_t b : valid) {
      if (b == a || (b < a && std::binary_search(big.begin(), big.end(), b))) continue;
      if (a < from && b < from) continue;
      if (!box[a].overlaps(box[b])) continue;
      if (triangles_intersect(vertices, triangles[a], triangles[b])) record(a, b);
    }
  }
  out.triangles = static_cast<std::size_t>(std::count(involved.begin(), involved.end(), 1));
  return out;
}

std::size_t remove_crossing_components(std::span<const Vec3> vertices,
                                       std::vector<Triangle>& triangles,
                                       std::span<const std::uint8_t> keep) {
  const std::size_t n = vertices.size();
  for (const Triangle& t : triangles)
    for (std::uint32_t v : t)
      if (v >= n) return 0;  // not a mesh of these vertices: nothing to decide
  detail::TriangleComponents components(n, triangles);
  if (components.count() < 2) return 0;
  const std::vector<std::uint32_t>& size = components.sizes();
  auto comp = [&](const Triangle& t) { return components.of(t); };
  const auto largest =
      static_cast<std::uint32_t>(std::max_element(size.begin(), size.end()) - size.begin());
  // The largest component's triangles first, so that only pairs with a smaller one are tested.
  std::vector<std::uint32_t> order;
  order.reserve(triangles.size());
  for (int pass = 0; pass < 2; ++pass)
    for (std::uint32_t i = 0; i < triangles.size(); ++i)
      if ((comp(triangles[i]) == largest) == (pass == 0)) order.push_back(i);
  std::vector<Triangle> sorted(triangles.size());
  for (std::size_t i = 0; i < order.size(); ++i) sorted[i] = triangles[order[i]];
  const SelfIntersections crossing =
      find_self_intersections(vertices, sorted, kAllPairs, size[largest]);
  std::vector<Triangle>().swap(sorted);
  std::vector<std::uint8_t> drop(size.size(), 0), kept(size.size(), 0);
  if (!keep.empty())
    for (std::size_t i = 0; i < triangles.size(); ++i)
      if (keep[i] != 0) kept[comp(triangles[i])] = 1;
  for (const auto& [i, j] : crossing.examples) {
    const std::uint32_t ci = comp(triangles[order[i]]), cj = comp(triangles[order[j]]);
    if (ci == cj) continue;
    const std::uint32_t smaller = size[ci] < size[cj] || (size[ci] == size[cj] && ci > cj) ? ci : cj;
    const std::uint32_t other = smaller == ci ? cj : ci;
    if (!kept[smaller]) {
      drop[smaller] = 1;
    } else if (!kept[other]) {
      drop[other] = 1;
    }
  }
  const auto dropped = static_cast<std::size_t>(std::count(drop.begin(), drop.end(), 1));
  if (dropped > 0) std::erase_if(triangles, [&](const Triangle& t) { return drop[comp(t)] != 0; });
  return dropped;
}

}  // namespace scanmesh::recon
