// Internal to recon: ordering a neighbourhood's candidates by (squared distance, index), shared
// by the spacing statistics and the kNN of the normals.
// SPDX-License-Identifier: MIT
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <vector>

namespace scanmesh::recon::detail {

/// A neighbour candidate: squared distance, point index, and the caller's tag (its position in
/// the caller's arrays).
struct Neighbour {
  double d2;
  std::uint32_t j, tag;
  [[nodiscard]] bool before(const Neighbour& o) const {
    return d2 < o.d2 || (d2 == o.d2 && j < o.j);
  }
};

/// Sorts neighbours by (distance, index) with reusable scratch: a counting sort into buckets of
/// squared distance over [0, max_d2) (about uniformly filled for points on a surface; larger
/// distances share the last bucket), then an insertion sort that rarely moves anything.
class NeighbourOrder {
 public:
  static constexpr std::uint32_t kBuckets = 64;

  /// Sorts in[0, n) into out[0, n); max_d2 > 0. As many buckets as neighbours, up to kBuckets
  /// (for the usual 20-30 neighbours most of 64 buckets were empty and only cost their prefix
  /// sum: 5M of the bunny's instructions); the result does not depend on the bucket count.
  void sort(const Neighbour* in, std::size_t n, double max_d2, Neighbour* out) {
    const std::uint32_t buckets = n >= kBuckets ? kBuckets
                                                : std::max<std::uint32_t>(
                                                      4, std::bit_ceil(static_cast<std::uint32_t>(n)));
    const double scale = static_cast<double>(buckets) / max_d2;
    bucket_of_.resize(n);
    std::fill(start_, start_ + buckets + 1, 0u);
    for (std::size_t a = 0; a < n; ++a) {
      const auto b = std::min(buckets - 1, static_cast<std::uint32_t>(in[a].d2 * scale));
      bucket_of_[a] = b;
      ++start_[b + 1];
    }
    for (std::uint32_t b = 0; b < buckets; ++b) start_[b + 1] += start_[b];
    for (std::size_t a = 0; a < n; ++a) out[start_[bucket_of_[a]]++] = in[a];
    for (std::size_t a = 1; a < n; ++a) {
      if (!out[a].before(out[a - 1])) continue;
      const Neighbour c = out[a];
      std::size_t b = a;
      do {
        out[b] = out[b - 1];
        --b;
      } while (b > 0 && c.before(out[b - 1]));
      out[b] = c;
    }
  }

 private:
  std::vector<std::uint32_t> bucket_of_;
  std::uint32_t start_[kBuckets + 1] = {};
};

}  // namespace scanmesh::recon::detail
