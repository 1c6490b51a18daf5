// Sampling statistics: nearest-neighbour spacing, cross-line spacing and shell thickness.
// SPDX-License-Identifier: MIT
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>

#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/reduce.hpp"

namespace scanmesh::recon {
namespace {

double median(std::vector<double>& v) {
  if (v.empty()) return 0;
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

SpacingEstimate estimate_spacing(std::span<const Vec3> points, std::size_t max_samples) {
  SpacingEstimate est;
  const std::size_t n = points.size();
  if (n < 2) return est;
  Vec3 lo = points[0], hi = points[0];
  for (const Vec3& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Vec3 ext = (hi - lo).cwiseMax(1e-12 * (hi - lo).norm() + 1e-300);
  // A surface sample of n points in a box: about n / (2 * area) points per unit area; choose the
  // cell so that a cell holds a few dozen points (surface area ~ sum of the box face areas).
  const double area = ext.x() * ext.y() + ext.y() * ext.z() + ext.z() * ext.x();
  double cell = std::sqrt(area / static_cast<double>(n)) * 4.0;
  if (!(cell > 0) || !std::isfinite(cell)) cell = ext.maxCoeff();
  PointGrid grid;
  grid.build(points, cell);

  const std::size_t stride = std::max<std::size_t>(1, n / max_samples);
  std::vector<double> d1s, d2s, thick;
  std::vector<std::pair<double, std::uint32_t>> near;
  for (std::size_t i = 0; i < n; i += stride) {
    const Vec3& p = points[i];
    near.clear();
    grid.for_each_near(p, 1, [&](std::uint32_t j) {
      if (j != i) near.emplace_back((points[j] - p).squaredNorm(), j);
    });
    if (near.empty()) continue;
    const std::size_t k = std::min<std::size_t>(20, near.size());
    std::partial_sort(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(k), near.end());
    // Skip exact duplicates for the direction of the nearest neighbour.
    std::size_t first = 0;
    while (first < k && near[first].first == 0) ++first;
    if (first == k) continue;
    d1s.push_back(std::sqrt(near[first].first));
    const Vec3 u = (points[near[first].second] - p).normalized();
    double d2 = std::numeric_limits<double>::infinity();
    for (std::size_t m = first + 1; m < near.size(); ++m) {
      // near beyond k is unsorted: scan all of it for the cross neighbour.
      const Vec3 w = points[near[m].second] - p;
      const double len2 = near[m].first;
      if (len2 == 0 || len2 >= d2 * d2) continue;
      if (std::abs(u.dot(w)) < std::sqrt(0.5 * len2)) d2 = std::sqrt(len2);
    }
    if (std::isfinite(d2)) d2s.push_back(d2);
    if (k >= 12) {
      // Noise: RMS residual of a local quadric (height over the PCA plane), so curvature of a
      // coarsely sampled surface does not count as noise.
      Vec3 mean = Vec3::Zero();
      for (std::size_t m = 0; m < k; ++m) mean += points[near[m].second];
      mean /= static_cast<double>(k);
      Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
      for (std::size_t m = 0; m < k; ++m) {
        const Vec3 d = points[near[m].second] - mean;
        cov += d * d.transpose();
      }
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
      const Eigen::Matrix3d frame = es.eigenvectors();  // col 0 = normal
      Eigen::MatrixXd a(k, 6);
      Eigen::VectorXd h(k);
      for (std::size_t m = 0; m < k; ++m) {
        const Vec3 d = frame.transpose() * (points[near[m].second] - mean);
        const double u = d.z(), v = d.y();
        a.row(static_cast<Eigen::Index>(m)) << u * u, u * v, v * v, u, v, 1.0;
        h[static_cast<Eigen::Index>(m)] = d.x();
      }
      const Eigen::VectorXd coef = a.colPivHouseholderQr().solve(h);
      const Eigen::VectorXd r = a * coef - h;
      thick.push_back(std::sqrt(r.squaredNorm() / static_cast<double>(k - 6)));
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
  }
  return est;
}

double auto_cube_size(const SpacingEstimate& s) {
  return std::max({s.nearest_mm, 0.75 * s.cross_mm, 14.0 * s.thickness_mm});
}

}  // namespace scanmesh::recon
