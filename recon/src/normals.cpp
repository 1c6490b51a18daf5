// PCA normals over k nearest neighbours, oriented by propagation over the kNN graph (Hoppe et
// al.: most-parallel neighbour first, from an extreme point of each component facing outward).
// SPDX-License-Identifier: MIT
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <queue>

#include "scanmesh/recon/normals.hpp"

namespace scanmesh::recon {

LocalFrames estimate_frames(std::span<const Vec3> points, const PointGrid& grid,
                            const NormalOptions& options) {
  const std::size_t n = points.size();
  const int k = std::max(6, options.neighbours);
  LocalFrames f;
  f.normal.resize(n);
  f.spacing.resize(n);
  f.flatness.resize(n);
  std::vector<std::uint32_t> knn(n * static_cast<std::size_t>(k), 0xffffffffu);
  std::vector<std::pair<double, std::uint32_t>> near;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3& p = points[i];
    near.clear();
    int ring = 1;
    while (true) {
      grid.for_each_near(p, ring, [&](std::uint32_t j) {
        if (j != i) near.emplace_back((points[j] - p).squaredNorm(), j);
      });
      if (near.size() >= static_cast<std::size_t>(k) || ring >= 3) break;
      near.clear();
      ++ring;
    }
    const std::size_t m = std::min<std::size_t>(static_cast<std::size_t>(k), near.size());
    std::partial_sort(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(m), near.end());
    Vec3 mean = p;
    for (std::size_t q = 0; q < m; ++q) mean += points[near[q].second];
    mean /= static_cast<double>(m + 1);
    Eigen::Matrix3d cov = (p - mean) * (p - mean).transpose();
    for (std::size_t q = 0; q < m; ++q) {
      const Vec3 d = points[near[q].second] - mean;
      cov += d * d.transpose();
      knn[i * static_cast<std::size_t>(k) + q] = near[q].second;
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    const Vec3 ev = es.eigenvalues().cwiseMax(0.0);
    const double sum = ev.sum();
    f.flatness[i] = sum > 0 ? static_cast<float>(ev[0] / sum) : 1.0f;
    f.normal[i] = m >= 2 ? Eigen::Vector3f(es.eigenvectors().col(0).cast<float>())
                        : Eigen::Vector3f::UnitZ();
    double s = 0;
    const std::size_t ms = std::min<std::size_t>(6, m);
    for (std::size_t q = 0; q < ms; ++q) s += std::sqrt(near[q].first);
    f.spacing[i] = ms > 0 ? static_cast<float>(s / static_cast<double>(ms)) : 0.0f;
  }

  if (options.view_point) {
    for (std::size_t i = 0; i < n; ++i) {
      if (f.normal[i].cast<double>().dot(*options.view_point - points[i]) < 0)
        f.normal[i] = -f.normal[i];
    }
    return f;
  }

  // Propagation: Prim-like traversal of the symmetric kNN graph, most parallel edges first.
  std::vector<std::uint8_t> done(n, 0);
  // Start points: extreme in +z first, so a closed surface gets outward normals.
  std::vector<std::uint32_t> by_z(n);
  for (std::uint32_t i = 0; i < n; ++i) by_z[i] = i;
  std::sort(by_z.begin(), by_z.end(), [&](std::uint32_t a, std::uint32_t b) {
    return points[a].z() != points[b].z() ? points[a].z() > points[b].z() : a < b;
  });
  using Item = std::pair<float, std::uint64_t>;  // (cost, from << 32 | to)
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  for (std::uint32_t start : by_z) {
    if (done[start]) continue;
    if (f.normal[start].z() < 0) f.normal[start] = -f.normal[start];
    done[start] = 1;
    auto push_neighbours = [&](std::uint32_t i) {
      for (int q = 0; q < k; ++q) {
        const std::uint32_t j = knn[i * static_cast<std::size_t>(k) + static_cast<std::size_t>(q)];
        if (j == 0xffffffffu || done[j]) continue;
        const float c = 1.0f - std::abs(f.normal[i].dot(f.normal[j]));
        queue.emplace(c, (static_cast<std::uint64_t>(i) << 32) | j);
      }
    };
    push_neighbours(start);
    while (!queue.empty()) {
      const auto [cost, pair] = queue.top();
      queue.pop();
      const auto from = static_cast<std::uint32_t>(pair >> 32);
      const auto to = static_cast<std::uint32_t>(pair & 0xffffffffu);
      if (done[to]) continue;
      if (f.normal[from].dot(f.normal[to]) < 0) f.normal[to] = -f.normal[to];
      done[to] = 1;
      push_neighbours(to);
    }
  }
  return f;
}

}  // namespace scanmesh::recon
