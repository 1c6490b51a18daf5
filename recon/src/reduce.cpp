// Cube reduction (reference method): keep, in every occupied cube, the point nearest its centre;
// minimum-distance thinning of the representatives; projection onto local planes.
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/reduce.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <string>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/normals.hpp"

#include "block_points.hpp"
#include "quadric_fit.hpp"

namespace scanmesh::recon {
namespace {

GeometryError too_many_cubes(double cube, double extent) {
  char buf[200];
  std::snprintf(buf, sizeof buf,
                "cube size %.6g is too small for the extent of the cloud (%.6g: over 2 million "
                "cubes per axis); use a larger cube, or split the input",
                cube, extent);
  return GeometryError(buf);
}

constexpr std::uint32_t kNone = 0xffffffffu;
/// Points a representative's ball needs for the second-order projection (a quadric has 6
/// coefficients; with fewer than 10 points the fit follows the noise).
constexpr std::size_t kQuadricPoints = 10;
/// How much more than noise the quadric's curvature terms must explain (F statistic, 3 and
/// n - 6 degrees of freedom): 10 would already be far beyond chance; 30 asks that curvature
/// clearly dominate (noisy merged views and CAD vertex sets reach 10-15; recon/README).
constexpr double kQuadricF = 30.0;
/// The smallest radius of curvature, in balls, the quadric may have.
constexpr double kQuadricMinRadius = 2.0;

/// Open-addressing table from cube key to the index of the input point nearest the cube centre
/// and its squared distance to the centre (24-byte slots, load at most one half; grows while
/// points are added). Used when the cubes' (y, z) rows are too many for a dense array.
class CubeTable {
 public:
  CubeTable(std::span<const Vec3> points, double cube) {
    if (!(cube > 0) || !std::isfinite(cube)) throw GeometryError("cube size must be positive");
    if (points.size() >= kNone) throw GeometryError("too many points (at most 2^32 - 1)");
    if (points.empty()) return;
    const Eigen::AlignedBox3d box = bounding_box(points);
    const Vec3 lo = box.min(), hi = box.max();
    const double inv = 1.0 / cube;
    if ((hi - lo).maxCoeff() * inv > 2.0e6) {
      throw too_many_cubes(cube, (hi - lo).maxCoeff());
    }
    resize(std::bit_ceil(std::max<std::size_t>(64, points.size() / 2)));
    std::uint64_t last_key = ~std::uint64_t{0};
    std::size_t last = 0;
    auto key_of = [&](const Vec3& p) {
      const Vec3 g = (p - lo) * inv;
      return (static_cast<std::uint64_t>(g.z()) << 42) | (static_cast<std::uint64_t>(g.y()) << 21) |
             static_cast<std::uint64_t>(g.x());
    };
    constexpr std::size_t kAhead = 16;  // the table is far larger than the caches: prefetch
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (i + kAhead < points.size()) __builtin_prefetch(&slots_[hash(key_of(points[i + kAhead]))]);
      // The reference method's expressions, kept as they were so ties resolve the same way.
      const Vec3 g = (points[i] - lo) * inv;
      const auto ix = static_cast<std::uint64_t>(g.x()), iy = static_cast<std::uint64_t>(g.y()),
                 iz = static_cast<std::uint64_t>(g.z());
      const std::uint64_t key = (iz << 42) | (iy << 21) | ix;
      const Vec3 centre =
          lo + (Vec3(static_cast<double>(ix), static_cast<double>(iy), static_cast<double>(iz)) +
                Vec3::Constant(0.5)) *
                   cube;
      const double d2 = (points[i] - centre).squaredNorm();
      if (key != last_key) {  // consecutive points often share a cube
        last = slot_of(key);
        last_key = key;
        Slot& sl = slots_[last];
        if (sl.best == kNone) {
          sl = {key, d2, static_cast<std::uint32_t>(i)};
          if (++size_ * 2 > slots_.size()) {
            resize(slots_.size() * 2);
            last = slot_of(key);
          }
          continue;
        }
      }
      Slot& sl = slots_[last];
      if (d2 < sl.d2) {  // strict: the lower index wins ties
        sl.best = static_cast<std::uint32_t>(i);
        sl.d2 = d2;
      }
    }
  }

  [[nodiscard]] std::size_t size() const { return size_; }

  /// Bit set over the input points: the representatives.
  [[nodiscard]] std::vector<std::uint64_t> representative_bits(std::size_t n) const {
    std::vector<std::uint64_t> bits((n + 63) / 64, 0);
    for (const Slot& sl : slots_)
      if (sl.best != kNone) bits[sl.best / 64] |= std::uint64_t{1} << (sl.best % 64);
    return bits;
  }

 private:
  struct Slot {
    std::uint64_t key;
    double d2;           // squared distance of `best` to the cube centre
    std::uint32_t best;  // input index, kNone when the slot is empty
  };
  [[nodiscard]] std::size_t hash(std::uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> shift_);
  }
  /// Slot holding `key`, or the empty slot where it would go.
  [[nodiscard]] std::size_t slot_of(std::uint64_t key) const {
    std::size_t h = hash(key);
    while (slots_[h].best != kNone && slots_[h].key != key) h = (h + 1) & mask_;
    return h;
  }
  void resize(std::size_t cap) {
    std::vector<Slot> old(cap, Slot{0, 0, kNone});
    old.swap(slots_);
    mask_ = cap - 1;
    shift_ = 64 - std::countr_zero(cap);
    for (const Slot& sl : old)
      if (sl.best != kNone) slots_[slot_of(sl.key)] = sl;
  }

  std::vector<Slot> slots_;
  std::size_t size_ = 0, mask_ = 0;
  int shift_ = 63;
};

/// Ascending list of the indices whose bit is set.
std::vector<std::uint32_t> indices_of(const std::vector<std::uint64_t>& bits, std::size_t count) {
  std::vector<std::uint32_t> out;
  out.reserve(count);
  for (std::size_t w = 0; w < bits.size(); ++w)
    for (std::uint64_t b = bits[w]; b != 0; b &= b - 1)
      out.push_back(
          static_cast<std::uint32_t>(w * 64 + static_cast<std::size_t>(std::countr_zero(b))));
  return out;
}

/// Result of the cube reduction: the representatives as a bit set over the input points and,
/// when the rows of cubes were dense, the representatives grouped by row (y, z) in key order and
/// sorted by x inside a row.
struct CubeReduction {
  std::vector<std::uint64_t> bits;
  std::size_t count = 0;
  Vec3 lo = Vec3::Zero();  ///< bounding-box minimum: the origin of the cubes
  bool dense = false;
  std::uint64_t ny = 0, nz = 0;          ///< rows are indexed z * ny + y
  std::vector<std::uint32_t> row_start;  ///< per row + 1: first representative of the row
  std::vector<std::uint32_t> rep_x;      ///< per representative: cube x
  std::vector<std::uint32_t> rep_index;  ///< per representative: input index
};

CubeReduction reduce_to_cubes(std::span<const Vec3> points, double cube, bool want_rows) {
  if (!(cube > 0) || !std::isfinite(cube)) throw GeometryError("cube size must be positive");
  CubeReduction cr;
  const std::size_t n = points.size();
  if (n == 0) return cr;
  if (n >= kNone) throw GeometryError("too many points (at most 2^32 - 1)");
  const Eigen::AlignedBox3d box = bounding_box(points);
  const Vec3 lo = box.min(), hi = box.max();
  cr.lo = lo;
  const double inv = 1.0 / cube;
  if ((hi - lo).maxCoeff() * inv > 2.0e6) {
    throw too_many_cubes(cube, (hi - lo).maxCoeff());
  }
  const Vec3 top = (hi - lo) * inv;
  const std::uint64_t ny = static_cast<std::uint64_t>(top.y()) + 1;
  const std::uint64_t nz = static_cast<std::uint64_t>(top.z()) + 1;
  if (static_cast<double>(ny) * static_cast<double>(nz) >
      static_cast<double>(std::max<std::size_t>(4096, 2 * n))) {
    const CubeTable table(points, cube);  // sparse extent: hash the cubes
    cr.bits = table.representative_bits(n);
    cr.count = table.size();
    return cr;
  }
  cr.dense = true;
  cr.ny = ny;
  cr.nz = nz;
  // Dense rows of cubes: the points' records (x, index, distance to the cube centre) are
  // counting-sorted into rows (y, z); in each row the best record per x is kept. The
  // expressions are the reference method's, so points land in the same cubes and ties resolve
  // the same way.
  struct Record {
    std::uint32_t x, index;
    double d2;
  };
  const std::size_t rows = static_cast<std::size_t>(ny * nz);
  std::vector<std::uint32_t> start(rows + 1, 0);
  for (const Vec3& p : points) {
    const Vec3 g = (p - lo) * inv;
    ++start[static_cast<std::uint64_t>(g.z()) * ny + static_cast<std::uint64_t>(g.y()) + 1];
  }
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<Record> rec(n);
  {
    std::vector<std::uint32_t> next(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3& p = points[i];
      const Vec3 g = (p - lo) * inv;
      const auto ix = static_cast<std::uint64_t>(g.x()), iy = static_cast<std::uint64_t>(g.y()),
                 iz = static_cast<std::uint64_t>(g.z());
      const Vec3 centre =
          lo + (Vec3(static_cast<double>(ix), static_cast<double>(iy), static_cast<double>(iz)) +
                Vec3::Constant(0.5)) *
                   cube;
      rec[next[iz * ny + iy]++] = {static_cast<std::uint32_t>(ix), static_cast<std::uint32_t>(i),
                                   (p - centre).squaredNorm()};
    }
  }
  cr.bits.assign((n + 63) / 64, 0);
  if (want_rows) cr.row_start.assign(rows + 1, 0);
  auto keep = [&](const Record& r) {
    cr.bits[r.index / 64] |= std::uint64_t{1} << (r.index % 64);
    ++cr.count;
    if (want_rows) {
      cr.rep_x.push_back(r.x);
      cr.rep_index.push_back(r.index);
    }
  };
  // Per cube the point nearest the centre. A row's records are in index order, so a strict
  // comparison lets the lower index win ties. Representatives come out in x order.
  std::vector<std::uint32_t> slot;  // per x in the row's range: best record, or kNone
  for (std::size_t r = 0; r < rows; ++r) {
    if (want_rows) cr.row_start[r] = static_cast<std::uint32_t>(cr.rep_index.size());
    Record* seg = rec.data() + start[r];
    const std::uint32_t len = start[r + 1] - start[r];
    if (len == 0) continue;
    if (len == 1) {
      keep(seg[0]);
      continue;
    }
    std::uint32_t min_x = seg[0].x, max_x = seg[0].x;
    for (std::uint32_t a = 1; a < len; ++a) {
      min_x = std::min(min_x, seg[a].x);
      max_x = std::max(max_x, seg[a].x);
    }
    const std::size_t range = std::size_t{max_x} - min_x + 1;
    if (range <= 4 * std::size_t{len} + 64) {
      if (slot.size() < range) slot.resize(range, kNone);
      for (std::uint32_t a = 0; a < len; ++a) {
        std::uint32_t& b = slot[seg[a].x - min_x];
        if (b == kNone || seg[a].d2 < seg[b].d2) b = a;
      }
      for (std::size_t x = 0; x < range; ++x) {
        if (slot[x] == kNone) continue;
        keep(seg[slot[x]]);
        slot[x] = kNone;
      }
    } else {  // very sparse row: sort it by (x, index)
      std::sort(seg, seg + len, [](const Record& a, const Record& b) {
        return a.x < b.x || (a.x == b.x && a.index < b.index);
      });
      for (std::uint32_t a = 0; a < len;) {
        std::uint32_t best = a, b = a + 1;
        for (; b < len && seg[b].x == seg[a].x; ++b)
          if (seg[b].d2 < seg[best].d2) best = b;
        keep(seg[best]);
        a = b;
      }
    }
  }
  if (want_rows) cr.row_start[rows] = static_cast<std::uint32_t>(cr.rep_index.size());
  return cr;
}

/// Greedy minimum-distance thinning from the clashing pairs: representatives are visited in
/// priority order (squared distance to the own cube centre in cube units, most central first,
/// input index breaking ties) and dropped when a clashing partner was kept. Only representatives
/// with a partner need the order; the others are kept whatever it is. Returns per representative
/// whether it is dropped.
std::vector<std::uint8_t> thin_clashes(
    std::span<const Vec3> rep_points, std::span<const std::uint32_t> rep_index,
    const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs, const Vec3& lo,
    double cube) {
  const std::size_t m = rep_points.size();
  std::vector<std::uint8_t> dropped(m, 0);
  if (pairs.empty()) return dropped;
  // Partners of each representative (compressed rows).
  std::vector<std::uint32_t> first(m + 1, 0);
  for (const auto& [a, b] : pairs) {
    ++first[a + 1];
    ++first[b + 1];
  }
  std::partial_sum(first.begin(), first.end(), first.begin());
  std::vector<std::uint32_t> partner(first[m]);
  {
    std::vector<std::uint32_t> next(first.begin(), first.end() - 1);
    for (const auto& [a, b] : pairs) {
      partner[next[a]++] = b;
      partner[next[b]++] = a;
    }
  }
  struct Prio {
    double value;
    std::uint32_t index, rep;
  };
  std::vector<Prio> prio;
  for (std::uint32_t k = 0; k < m; ++k) {
    if (first[k] == first[k + 1]) continue;
    // The reference method's expression, so the same order.
    const Vec3 g = (rep_points[k] - lo) / cube;
    const Vec3 c = (g.array().floor() + 0.5).matrix();
    prio.push_back({(g - c).squaredNorm(), rep_index[k], k});
  }
  std::sort(prio.begin(), prio.end(), [](const Prio& a, const Prio& b) {
    return a.value < b.value || (a.value == b.value && a.index < b.index);
  });
  std::vector<std::uint8_t> kept(m, 0);
  for (const Prio& p : prio) {
    bool hit = false;
    for (std::uint32_t q = first[p.rep]; q < first[p.rep + 1] && !hit; ++q) hit = kept[partner[q]];
    (hit ? dropped : kept)[p.rep] = 1;
  }
  return dropped;
}

}  // namespace

std::vector<std::uint32_t> cube_reduce(std::span<const Vec3> points, double cube) {
  const CubeReduction cr = reduce_to_cubes(points, cube, false);
  return indices_of(cr.bits, cr.count);
}

std::vector<std::uint32_t> thin_min_distance(std::span<const Vec3> points,
                                             std::span<const std::uint32_t> priority,
                                             double min_distance) {
  if (!(min_distance > 0) || !std::isfinite(min_distance))
    throw GeometryError("minimum distance must be positive");
  std::vector<Vec3> sub(priority.size());
  for (std::size_t i = 0; i < priority.size(); ++i) sub[i] = points[priority[i]];
  PointGrid grid;
  grid.build(sub, min_distance);
  const auto& order = grid.order();
  std::vector<std::uint8_t> kept(sub.size(), 0);
  const double r2 = min_distance * min_distance;
  std::vector<std::uint32_t> out;
  out.reserve(sub.size());
  for (std::uint32_t i = 0; i < sub.size(); ++i) {
    bool clash = false;
    const Vec3& p = sub[i];
    grid.for_each_range_within(p, min_distance, [&](std::uint32_t first, std::uint32_t last) {
      for (std::uint32_t s = first; s < last && !clash; ++s) {
        const std::uint32_t j = order[s];
        clash = kept[j] && (sub[j] - p).squaredNorm() < r2;
      }
    });
    if (clash) continue;
    kept[i] = 1;
    out.push_back(priority[i]);
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<Vec3> project_to_local_planes(std::span<const Vec3> input,
                                          std::span<const std::uint32_t> representatives,
                                          double radius, double max_move, bool second_order,
                                          double max_plane_rms,
                                          std::vector<std::uint32_t>* features) {
  std::vector<Vec3> out(representatives.size());
  if (features) features->clear();
  if (representatives.empty()) return out;
  if (input.size() >= kNone) throw GeometryError("too many points (at most 2^32 - 1)");
  // Cells of one radius: the 27 cells around a representative's cell hold its ball. The
  // representatives are processed cell by cell, so the candidates of a cell are gathered once
  // into flat arrays that every representative of the cell scans (branch-free) for its ball.
  PointGrid grid;
  grid.build(input, radius);
  const auto& order = grid.order();
  const double r2 = radius * radius;
  const double max_plane_ms = max_plane_rms * max_plane_rms;
  // Position of each input point in `representatives` (the first, if listed twice).
  std::vector<std::uint32_t> rep_of(input.size(), kNone);
  bool repeated = false;
  for (std::size_t i = 0; i < representatives.size(); ++i) {
    std::uint32_t& r = rep_of[representatives[i]];
    if (r == kNone)
      r = static_cast<std::uint32_t>(i);
    else
      repeated = true;
  }
  detail::BlockPoints block;
  std::vector<std::uint32_t> inside;
  std::vector<double> fitted;  // the quadric's design rows and heights of a ball, 7 a point
  grid.for_each_cell(
      [&](std::int64_t x, std::int64_t y, std::int64_t z, std::uint32_t first, std::uint32_t last) {
        bool any = false;
        for (std::uint32_t s = first; s < last && !any; ++s) any = rep_of[order[s]] != kNone;
        if (!any) return;
        const std::size_t cnt = block.gather(grid, x, y, z, 1, input);
        if (inside.size() < cnt) inside.resize(cnt);
        const double* cx = block.x.data();
        const double* cy = block.y.data();
        const double* cz = block.z.data();
        for (std::uint32_t s = first; s < last; ++s) {
          const std::uint32_t rep = rep_of[order[s]];
          if (rep == kNone) continue;
          const Vec3& p = input[order[s]];
          const double px = p.x(), py = p.y(), pz = p.z();
          std::size_t n = 0;
          for (std::size_t u = 0; u < cnt; ++u) {  // the ball, in the order of the 27 cells
            const double dx = cx[u] - px, dy = cy[u] - py, dz = cz[u] - pz;
            inside[n] = static_cast<std::uint32_t>(u);
            n += dx * dx + dy * dy + dz * dz <= r2 ? 1 : 0;
          }
          out[rep] = p;
          if (n < 6) continue;
          // Moments relative to p (well conditioned).
          double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
          for (std::size_t q = 0; q < n; ++q) {
            const std::uint32_t u = inside[q];
            const double dx = cx[u] - px, dy = cy[u] - py, dz = cz[u] - pz;
            sx += dx;
            sy += dy;
            sz += dz;
            sxx += dx * dx;
            sxy += dx * dy;
            sxz += dx * dz;
            syy += dy * dy;
            syz += dy * dz;
            szz += dz * dz;
          }
          const auto nd = static_cast<double>(n);
          const Vec3 mean = Vec3(sx, sy, sz) / nd;
          Eigen::Matrix3d outer;
          outer << sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz;
          const Eigen::Matrix3d cov = outer / nd - mean * mean.transpose();
          const detail::PlaneFit fit = detail::plane_normal(cov);
          const Vec3& normal = fit.normal;
          // Height of the surface over p along the normal: the plane's, or the quadric's.
          double height = mean.dot(normal);
          bool curved = false;  // the quadric explains the ball
          if (second_order && n >= kQuadricPoints) {
            // The plane through the ball's centroid lies inside a curved surface by about
            // radius^2 / (4 R) (the mean height of a cap of radius R over the ball's disk); the
            // quadric height field over that plane, centred on p, takes its value at p. It is
            // used only where the curvature is real: its three terms must explain clearly more
            // than noise (an F test of the residuals against the plane's), since on a flat or
            // finely sampled patch the quadric's value follows the noise more than the plane's
            // mean does.
            const Vec3 e1 = normal.unitOrthogonal(), e2 = normal.cross(e1);
            const double s = 1.0 / radius;
            Eigen::Matrix<double, 6, 6> ata;
            Eigen::Matrix<double, 6, 1> ath = Eigen::Matrix<double, 6, 1>::Zero(), coef;
            auto row_of = [&](std::uint32_t u, Eigen::Matrix<double, 6, 1>& row) {
              const Vec3 d(cx[u] - px, cy[u] - py, cz[u] - pz);
              detail::quadric_row(d.dot(e1) * s, d.dot(e2) * s, row.data());
              return d.dot(normal);
            };
            // The lower triangle of the normal equations, product by product as a rank-one
            // update makes it (Eigen's rankUpdate took temporaries and a general kernel for
            // these 6 x 6: a quarter of a merged multi-view run's instructions).
            double lower[21] = {};
            if (fitted.size() < 7 * n) fitted.resize(7 * n);
            for (std::size_t q = 0; q < n; ++q) {
              Eigen::Matrix<double, 6, 1> row;
              const double h = row_of(inside[q], row);
              for (int i = 0, k = 0; i < 6; ++i)
                for (int j = 0; j <= i; ++j, ++k) lower[k] += row[i] * row[j];
              ath += h * row;
              std::copy(row.data(), row.data() + 6, fitted.data() + 7 * q);
              fitted[7 * q + 6] = h;
            }
            for (int i = 0, k = 0; i < 6; ++i)
              for (int j = 0; j <= i; ++j, ++k) ata(i, j) = ata(j, i) = lower[k];
            // Principal curvatures of the fit (scaled coordinates): its Hessian's eigenvalues.
            auto max_curvature = [&] {
              const double a = 2 * coef[0], d = 2 * coef[2], b = coef[1];
              return std::abs(0.5 * (a + d)) + std::sqrt(0.25 * (a - d) * (a - d) + b * b);
            };
            // A radius of curvature under kQuadricMinRadius balls is no smooth surface the
            // sampling resolves: a crease (a quadric over a 30-degree fold bends about that
            // much), two layers, a wall's edge. The plane stays there.
            if (detail::solve_quadric(ata, ath, coef) &&
                max_curvature() * kQuadricMinRadius <= radius) {
              double rss_plane = 0, rss_quadric = 0;
              for (std::size_t q = 0; q < n; ++q) {
                const Eigen::Map<const Eigen::Matrix<double, 6, 1>> row(fitted.data() + 7 * q);
                const double h = fitted[7 * q + 6];
                const double off_plane = h - height, off_quadric = h - row.dot(coef);
                rss_plane += off_plane * off_plane;
                rss_quadric += off_quadric * off_quadric;
              }
              // F = ((rss_plane - rss_quadric) / 3) / (rss_quadric / (n - 6)) > kQuadricF
              if ((rss_plane - rss_quadric) * static_cast<double>(n - 6) >
                  3.0 * kQuadricF * rss_quadric)
                height = coef[5], curved = true;
            }
          }
          // A ball whose points lie farther from their plane than the scan's noise allows, and
          // that no quadric explains, straddles a feature: the plane cuts across a sharp edge,
          // a corner or a step (up to max_move inside it), where the measured point is on it.
          if (features && !curved && fit.eigenvalues[0] > max_plane_ms) features->push_back(rep);
          out[rep] = p + std::clamp(height, -max_move, max_move) * normal;
        }
      });
  if (repeated) {
    for (std::size_t i = 0; i < representatives.size(); ++i)
      out[i] = out[rep_of[representatives[i]]];
  }
  if (features) {
    // Found cell by cell; a representative listed twice is a feature at each of its positions.
    std::vector<std::uint32_t>& f = *features;
    if (repeated) {
      std::vector<std::uint8_t> flag(representatives.size(), 0);
      for (std::uint32_t i : f) flag[i] = 1;
      f.clear();
      for (std::size_t i = 0; i < representatives.size(); ++i)
        if (flag[rep_of[representatives[i]]]) f.push_back(static_cast<std::uint32_t>(i));
    } else {
      std::sort(f.begin(), f.end());
    }
  }
  return out;
}

std::vector<std::uint32_t> cube_reduce_thin(std::span<const Vec3> points, double cube) {
  // Thinning (reference: thin_min_distance(0.65 cube) in cube-centre order) only ever involves
  // representatives of neighbouring cubes: each cube has one and the distance is under a cube.
  CubeReduction cr = reduce_to_cubes(points, cube, true);
  if (cr.count == 0) return {};
  const double min_distance = 0.65 * cube;
  const double r2 = min_distance * min_distance;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;  // clashing representatives
  std::vector<std::uint32_t> rep_index;
  std::vector<Vec3> rep_points;
  if (cr.dense) {
    // Sweep over pairs of neighbouring rows (13 forward neighbour cubes: same row x + 1; row
    // y + 1 and the three rows z + 1, x - 1..x + 1), two pointers along x.
    rep_index = std::move(cr.rep_index);
    const std::size_t m = rep_index.size();
    rep_points.resize(m);
    for (std::size_t k = 0; k < m; ++k) rep_points[k] = points[rep_index[k]];
    const std::vector<std::uint32_t>& rx = cr.rep_x;
    const std::uint64_t ny = cr.ny, nz = cr.nz;
    for (std::uint64_t z = 0; z < nz; ++z) {
      for (std::uint64_t y = 0; y < ny; ++y) {
        const std::uint64_t r = z * ny + y;
        const std::uint32_t a0 = cr.row_start[r], a1 = cr.row_start[r + 1];
        if (a0 == a1) continue;
        auto sweep = [&](std::uint64_t nr, bool same_row) {
          std::uint32_t j = cr.row_start[nr];
          const std::uint32_t j1 = cr.row_start[nr + 1];
          for (std::uint32_t a = a0; a < a1 && j < j1; ++a) {
            const std::uint32_t x = rx[a];
            while (j < j1 && rx[j] + 1 < x) ++j;  // x' >= x - 1
            for (std::uint32_t b = j; b < j1 && rx[b] <= x + 1; ++b) {
              if (same_row && rx[b] <= x) continue;
              if ((rep_points[b] - rep_points[a]).squaredNorm() < r2) pairs.emplace_back(a, b);
            }
          }
        };
        sweep(r, true);
        if (y + 1 < ny) sweep(r + 1, false);
        if (z + 1 < nz) {
          if (y > 0) sweep(r + ny - 1, false);
          sweep(r + ny, false);
          if (y + 1 < ny) sweep(r + ny + 1, false);
        }
      }
    }
  } else {
    // Sparse extent: the representatives in index order, clashes from a grid of one cube.
    rep_index = indices_of(cr.bits, cr.count);
    const std::size_t m = rep_index.size();
    rep_points.resize(m);
    for (std::size_t k = 0; k < m; ++k) rep_points[k] = points[rep_index[k]];
    PointGrid grid;
    grid.build(rep_points, cube);
    const auto& order = grid.order();
    for (std::uint32_t a = 0; a < m; ++a) {
      const Vec3& p = rep_points[a];
      grid.for_each_range_within(p, min_distance, [&](std::uint32_t b, std::uint32_t e) {
        for (std::uint32_t s = b; s < e; ++s) {
          const std::uint32_t j = order[s];
          if (j > a && (rep_points[j] - p).squaredNorm() < r2) pairs.emplace_back(a, j);
        }
      });
    }
  }
  const std::vector<std::uint8_t> dropped = thin_clashes(rep_points, rep_index, pairs, cr.lo, cube);
  std::fill(cr.bits.begin(), cr.bits.end(), 0);
  std::size_t count = 0;
  for (std::size_t k = 0; k < rep_index.size(); ++k) {
    if (dropped[k]) continue;
    cr.bits[rep_index[k] / 64] |= std::uint64_t{1} << (rep_index[k] % 64);
    ++count;
  }
  return indices_of(cr.bits, count);
}

std::vector<std::uint32_t> far_points(std::span<const Vec3> points, double max_extent_ratio) {
  std::vector<std::uint32_t> far;
  const std::size_t n = points.size();
  if (n < 16) return far;
  const double extent = bounding_box(points).sizes().maxCoeff();
  // The body: 10th to 90th percentile of each coordinate over an evenly spread sample.
  constexpr std::size_t kSample = 4096;
  const std::size_t stride = (n + kSample - 1) / kSample;
  std::vector<double> v;
  v.reserve(n / stride + 1);
  Vec3 body_lo, body_hi;
  for (int a = 0; a < 3; ++a) {
    v.clear();
    for (std::size_t i = 0; i < n; i += stride) v.push_back(points[i][a]);
    const auto at = [&](double q) {
      const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(v.size() - 1));
      std::nth_element(v.begin(), v.begin() + k, v.end());
      return v[static_cast<std::size_t>(k)];
    };
    body_lo[a] = at(0.1);
    body_hi[a] = at(0.9);
  }
  const Vec3 width = body_hi - body_lo;
  const double w = width.maxCoeff();
  if (!(w > 0)) return far;  // the body is one point: nothing to measure the strays against
  // Surface-sampling distance of the body (as estimate_spacing's reach, without its factor).
  const Vec3 e = width.cwiseMax(1e-6 * w);
  const double area = e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
  const double sampling = std::sqrt(area / static_cast<double>(n));
  if (!(extent > max_extent_ratio * sampling)) return far;
  body_lo -= Vec3::Constant(w);
  body_hi += Vec3::Constant(w);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3& p = points[i];
    if ((p.array() < body_lo.array()).any() || (p.array() > body_hi.array()).any())
      far.push_back(static_cast<std::uint32_t>(i));
  }
  return far;
}

}  // namespace scanmesh::recon
