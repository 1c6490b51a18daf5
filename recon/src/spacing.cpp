// Sampling statistics: nearest-neighbour spacing, cross-line spacing and shell thickness.
// SPDX-License-Identifier: MIT
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/normals.hpp"
#include "scanmesh/recon/reduce.hpp"

#include "neighbour_order.hpp"
#include "quadric_fit.hpp"

namespace scanmesh::recon {
namespace {

double median(std::vector<double>& v) {
  if (v.empty()) return 0;
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

constexpr std::size_t kNeighbours = 20;  // neighbourhood of the noise (quadric) fit
/// The smaller neighbourhood that tells noise from structure in a thick shell.
constexpr std::size_t kFewNeighbours = 12;
/// A shell thicker than this share of the cross spacing is taken for noise only if it looks
/// like noise (auto_cube_size).
constexpr double kThickShell = 0.3;

/// Residuals of a quadric fit: their RMS (over k - 6 degrees of freedom) and their shape, the
/// mean absolute residual over the RMS (both over k): about sqrt(2 / pi) = 0.80 for Gaussian
/// noise, 1 for two layers (a thin wall seen from both sides: every point half the gap off).
struct Residual {
  double rms = 0, shape = 0;
};

/// Residuals of the least-squares quadric height field h(u, v) over the PCA plane of the
/// k >= 12 neighbour offsets d[0..k): noise, without the curvature of a coarsely sampled
/// surface. `extent` (about the neighbourhood radius) scales u and v.
Residual quadric_residual(const Vec3* d, std::size_t k, double extent) {
  Vec3 mean = Vec3::Zero();
  for (std::size_t m = 0; m < k; ++m) mean += d[m];
  mean /= static_cast<double>(k);
  double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
  for (std::size_t m = 0; m < k; ++m) {
    const Vec3 e = d[m] - mean;
    xx += e.x() * e.x();
    xy += e.x() * e.y();
    xz += e.x() * e.z();
    yy += e.y() * e.y();
    yz += e.y() * e.z();
    zz += e.z() * e.z();
  }
  Eigen::Matrix3d cov;
  cov << xx, xy, xz, xy, yy, yz, xz, yz, zz;
  const Vec3 normal = detail::plane_normal(cov).normal;
  // Any orthonormal in-plane axes do: the residual of a full quadric does not depend on them.
  // Scaling u and v to about [-1, 1] keeps the normal equations well conditioned.
  const Vec3 e1 = normal.unitOrthogonal();
  const Vec3 e2 = normal.cross(e1);
  const double s = extent > 0 ? 1.0 / extent : 1.0;
  using Row = Eigen::Matrix<double, 6, 1>;
  auto row_of = [&](const Vec3& dm, double* row) {
    const Vec3 e = dm - mean;
    detail::quadric_row(e.dot(e1) * s, e.dot(e2) * s, row);
    return e.dot(normal);
  };
  // Design matrix with zero rows beyond k (they change neither A^T A nor A^T h).
  Eigen::Matrix<double, kNeighbours, 6> a = Eigen::Matrix<double, kNeighbours, 6>::Zero();
  Eigen::Matrix<double, kNeighbours, 1> h = Eigen::Matrix<double, kNeighbours, 1>::Zero();
  for (std::size_t m = 0; m < k; ++m) {
    double row[6];
    const auto r = static_cast<Eigen::Index>(m);
    h[r] = row_of(d[m], row);
    for (int c = 0; c < 6; ++c) a(r, c) = row[c];
  }
  // Fixed-size lazy products: Eigen sends a 6x20 by 20x6 product to its general matrix kernel
  // (a tenth of the spacing estimate's instructions on the bunny).
  const Eigen::Matrix<double, 6, 6> ata = a.transpose().lazyProduct(a);
  const Row ath = a.transpose().lazyProduct(h);
  // Cholesky factorisation of the (scaled, well conditioned) normal equations; the pivoting
  // QR of the design matrix when they are (nearly) singular: points on a conic.
  Row coef;
  if (!detail::solve_quadric(ata, ath, coef)) {
    const auto kk = static_cast<Eigen::Index>(k);
    coef = a.topRows(kk).colPivHouseholderQr().solve(h.head(kk));
  }
  const Eigen::Matrix<double, kNeighbours, 1> res = a * coef - h;  // rows beyond k are 0
  const double rss = res.squaredNorm(), kd = static_cast<double>(k);
  Residual out;
  out.rms = std::sqrt(rss / (kd - 6));
  out.shape = rss > 0 ? res.cwiseAbs().sum() / kd / std::sqrt(rss / kd) : 0.0;
  return out;
}

/// Cross neighbour test: whether w (squared length len2) lies more than 45 degrees off the
/// unit direction u (|u.w| < |w| / sqrt 2, compared squared) and nearer than `best` (squared),
/// which it then becomes.
void cross_test(const Vec3& u, const Vec3& w, double len2, double& best) {
  if (len2 == 0 || len2 >= best) return;
  const double c = u.dot(w);
  if (c * c < 0.5 * len2) best = len2;
}

/// A point near the sample: squared distance, index, offset from the sample.
struct Near {
  double d2;
  std::uint32_t j;
  Vec3 d;
};


}  // namespace

SpacingEstimate estimate_spacing(std::span<const Vec3> points, std::size_t max_samples) {
  SpacingEstimate est;
  const std::size_t n = points.size();
  if (n < 2) return est;
  const Eigen::AlignedBox3d box = bounding_box(points);
  const Vec3 lo = box.min(), hi = box.max();
  const Vec3 ext = (hi - lo).cwiseMax(1e-12 * (hi - lo).norm() + 1e-300);
  // A surface sample of n points in a box: about n / (2 * area) points per unit area (surface
  // area ~ sum of the box face areas). `reach` (a few dozen points' worth) bounds every search.
  const double area = ext.x() * ext.y() + ext.y() * ext.z() + ext.z() * ext.x();
  double reach = std::sqrt(area / static_cast<double>(n)) * 4.0;
  if (!(reach > 0) || !std::isfinite(reach)) reach = ext.maxCoeff();
  // Cells of half the reach: about the radius of a query, which then looks at a few rows only.
  PointGrid grid;
  grid.build(points, std::max(0.5 * reach, 1e-6 * ext.maxCoeff()));
  const auto& order = grid.order();

  const std::size_t stride = std::max<std::size_t>(1, n / std::max<std::size_t>(1, max_samples));
  std::vector<double> d1s, d2s, thick, shape;
  // Samples with no cross neighbour within the reach: the sample, its nearest, the direction.
  struct NoCross {
    std::uint32_t i, nearest;
    Vec3 u;
  };
  std::vector<NoCross> no_cross;
  // Per fitted sample: its kFewNeighbours nearest offsets and the distance of the last, for the
  // smaller fit that only a thick shell needs (a second pass over 12 offsets, not a search).
  std::vector<Vec3> few;
  std::vector<double> few_extent;
  std::vector<Near> near;   // the points within the radius
  std::vector<detail::Neighbour> keys, sorted;  // (distance, index, position in near)
  detail::NeighbourOrder ordering;
  Vec3 nb[kNeighbours];
  double radius = 0.5 * reach;  // first guess; then from the previous sample's neighbourhood
  // The samples are the points with an index divisible by the stride, visited in grid order:
  // consecutive samples are then near each other and share cached neighbourhoods. (The
  // statistics do not depend on the visiting order.)
  // cross_test over the points the grid visits within `radius` of sample i (other than i and
  // its nearest), those within sqrt(limit2) of it: the rows visited reach a little further.
  auto cross_in_grid = [&](std::uint32_t i, std::uint32_t nearest, const Vec3& u, double radius,
                           double limit2, double& best) {
    const Vec3& p = points[i];
    grid.for_each_range_within(p, radius, [&](std::uint32_t b, std::uint32_t e) {
      for (std::uint32_t s = b; s < e; ++s) {
        const std::uint32_t j = order[s];
        if (j == i || j == nearest) continue;
        const Vec3 w = points[j] - p;
        const double len2 = w.squaredNorm();
        if (len2 <= limit2) cross_test(u, w, len2, best);
      }
    });
  };
  std::size_t visited = 0;  // samples looked at (d1s: those that told a spacing)
  std::vector<std::uint64_t> is_sample((n + 63) / 64, 0);
  for (std::size_t i = 0; i < n; i += stride) is_sample[i / 64] |= std::uint64_t{1} << (i % 64);
  for (const std::uint32_t i : order) {
    if ((is_sample[i / 64] >> (i % 64) & 1) == 0) continue;
    ++visited;
    const Vec3& p = points[i];
    // Every point within `radius` (radius doubled until it holds kNeighbours, up to the reach):
    // then the kNeighbours nearest are exact.
    double r = radius;
    std::size_t cnt = 0;
    while (true) {
      cnt = 0;
      const double r2 = r * r;
      grid.for_each_range_within(p, r, [&](std::uint32_t first, std::uint32_t last) {
        if (near.size() < cnt + (last - first)) near.resize(2 * (cnt + (last - first)));
        for (std::uint32_t s = first; s < last; ++s) {
          const std::uint32_t j = order[s];
          const Vec3 d = points[j] - p;
          const double d2 = d.squaredNorm();
          near[cnt] = {d2, j, d};
          cnt += ((d2 <= r2) & (j != i)) ? 1 : 0;
        }
      });
      if (cnt >= kNeighbours || r >= reach) break;
      r = std::min(2 * r, reach);
    }
    if (cnt == 0) continue;
    const std::size_t k = std::min(kNeighbours, cnt);
    // The set of the k nearest by (distance, index); the nearest at a non-zero distance (exact
    // duplicates say nothing about the direction); skip the sample when the k nearest are all
    // duplicates.
    // The points within r sorted by (distance, index): a counting sort into buckets of squared
    // distance (about uniformly filled on a surface), then an insertion sort that rarely moves
    // anything. The first k are the k nearest; the nearest at a non-zero distance gives the
    // direction (exact duplicates say nothing about it); the sample is skipped when the k
    // nearest are all duplicates.
    keys.resize(cnt);
    sorted.resize(cnt);
    for (std::uint32_t a = 0; a < cnt; ++a) keys[a] = {near[a].d2, near[a].j, a};
    ordering.sort(keys.data(), cnt, r * r, sorted.data());
    const double dk2 = sorted[k - 1].d2;  // squared distance of the k-th nearest
    radius = std::min(reach, 1.25 * std::sqrt(dk2));
    if (!(radius > 0)) radius = 0.5 * reach;
    std::size_t zeros = 0;
    while (zeros < k && sorted[zeros].d2 == 0) ++zeros;
    if (zeros == k) continue;
    const std::uint32_t first = sorted[zeros].tag;
    const Near& nearest = near[first];
    d1s.push_back(std::sqrt(nearest.d2));
    const Vec3 u = nearest.d / std::sqrt(nearest.d2);
    // Cross neighbour: the nearest point more than 45 degrees off u (|u.w| < |w| / sqrt 2,
    // compared squared). Among the points within r it is exact; when there is none there, look
    // further, up to the reach.
    double best = std::numeric_limits<double>::infinity();  // squared
    for (std::size_t a = 0; a < cnt; ++a)
      if (a != first) cross_test(u, near[a].d, near[a].d2, best);
    if (!std::isfinite(best) && r < reach)
      cross_in_grid(i, nearest.j, u, reach, std::numeric_limits<double>::infinity(), best);
    if (std::isfinite(best))
      d2s.push_back(std::sqrt(best));
    else
      no_cross.push_back({i, nearest.j, u});
    if (k >= kFewNeighbours) {
      for (std::size_t a = 0; a < k; ++a) nb[a] = near[sorted[a].tag].d;
      const Residual fit = quadric_residual(nb, k, std::sqrt(dk2));
      thick.push_back(fit.rms);
      shape.push_back(fit.shape);
      few.insert(few.end(), nb, nb + kFewNeighbours);
      few_extent.push_back(std::sqrt(sorted[kFewNeighbours - 1].d2));
    }
  }
  // Most samples saw only copies of themselves within the reach (a point sensor at rest
  // streams the same reading; quantised readings repeat): the copies also shrink the reach,
  // which assumes n distinct points. Then the statistics are those of the distinct points.
  if (4 * d1s.size() < visited) {
    std::vector<Vec3> distinct(points.begin(), points.end());
    const auto lex = [](const Vec3& a, const Vec3& b) {
      return a.x() != b.x() ? a.x() < b.x() : a.y() != b.y() ? a.y() < b.y() : a.z() < b.z();
    };
    std::sort(distinct.begin(), distinct.end(), lex);
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    if (distinct.size() < n) return estimate_spacing(distinct, max_samples);
  }
  // A raster scan more than about 16 times finer along its lines than across them has its
  // next line beyond the reach (4 sqrt(a) spacings at anisotropy a): when that hides the cross
  // neighbour from most samples, theirs is looked for further out, doubling the radius up to 16
  // reaches (anisotropy 4096). A 40:1 raster came out with no mesh at all before (stop 38).
  if (2 * no_cross.size() > d1s.size()) {
    for (const NoCross& c : no_cross) {
      double best = std::numeric_limits<double>::infinity();
      for (double r = 2 * reach; r <= 16 * reach && !std::isfinite(best); r *= 2)
        cross_in_grid(c.i, c.nearest, c.u, r, r * r, best);
      if (std::isfinite(best)) d2s.push_back(std::sqrt(best));
    }
  }
  est.sampled = d1s.size();
  est.nearest_mm = median(d1s);
  est.cross_mm = d2s.empty() ? est.nearest_mm : median(d2s);
  // Lower quartile: noise thickens every neighbourhood alike, while sharp features and
  // thin walls thicken only some; the quartile measures the noise and ignores the features.
  if (!thick.empty()) {
    auto q = thick.begin() + static_cast<std::ptrdiff_t>(thick.size() / 4);
    std::nth_element(thick.begin(), q, thick.end());
    est.thickness_mm = *q;
    if (est.thickness_mm > kThickShell * est.cross_mm) {
      std::vector<double> thin(few_extent.size());
      for (std::size_t m = 0; m < thin.size(); ++m)
        thin[m] = quadric_residual(&few[m * kFewNeighbours], kFewNeighbours, few_extent[m]).rms;
      auto qf = thin.begin() + static_cast<std::ptrdiff_t>(thin.size() / 4);
      std::nth_element(thin.begin(), qf, thin.end());
      est.thickness_few_mm = *qf;
      est.thickness_shape = median(shape);
    }
  }
  return est;
}

double auto_cube_size(const SpacingEstimate& s) {
  const double sampling = std::max(s.nearest_mm, 0.75 * s.cross_mm);
  // A "shell" thicker than about a third of the spacing may be structure the sampling can
  // barely resolve (thin walls seen from both sides, sharp features, the vertices of a CAD
  // mesh): a cube large enough to swallow it would erase the part, so the sampling alone
  // decides then. Or it may be the noise of a sensor sampling more finely than its noise: a
  // cube of the sampling would mesh the noise (a six-view line scan of the steps, noise 0.1 mm
  // at 0.13 mm spacing: genus 12-29, 300-400 loops). Noise does not shrink with the
  // neighbourhood: the residual of a 12-point quadric fit is sqrt((12-6)/12) / sqrt((20-6)/20)
  // = 0.85 of the 20-point fit's (measured 0.81-0.94 on noisy simulated and real scans), while
  // structure a larger neighbourhood spans more of shrinks with it (the casting: 0.40). And
  // noise is not two layers: the residuals' mean absolute value over their RMS is 0.80 for
  // Gaussian noise (measured 0.79-0.83 on the real and noisy simulated scans) and 1 for the
  // two faces of a wall thinner than the spacing (measured 0.93-0.97), whose faces a large cube
  // would merge into one.
  if (s.thickness_mm > kThickShell * s.cross_mm &&
      (s.thickness_few_mm < 0.6 * s.thickness_mm || s.thickness_shape > 0.9))
    return sampling;
  return std::max(sampling, 14.0 * s.thickness_mm);
}

}  // namespace scanmesh::recon
