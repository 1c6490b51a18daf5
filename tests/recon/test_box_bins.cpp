// The crossing searches' bins of long triangles' boxes (box_bins.hpp).
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <cstdint>
#include <limits>
#include <random>
#include <set>
#include <vector>

#include "box_bins.hpp"

using scanmesh::recon::Vec3;
using scanmesh::recon::detail::BoxBins;

namespace {

struct Box {
  Vec3 lo, hi;
};

bool overlap(const Box& a, const Box& b) {
  for (int k = 0; k < 3; ++k)
    if (a.lo[k] > b.hi[k] || a.hi[k] < b.lo[k]) return false;
  return true;
}

Box random_box(std::mt19937_64& rng, double extent, double size) {
  std::uniform_real_distribution<double> at(-extent, extent), len(0, size);
  Box b;
  for (int k = 0; k < 3; ++k) {
    b.lo[k] = at(rng);
    b.hi[k] = b.lo[k] + len(rng);
  }
  return b;
}

/// The keys visit() calls back for `q`, each once.
std::set<std::uint32_t> visited(const BoxBins& bins, const Box& q) {
  std::set<std::uint32_t> out;
  bins.visit(q.lo, q.hi, [&](std::uint32_t k) { out.insert(k); });
  return out;
}

}  // namespace

TEST_CASE("box bins call back every box that overlaps a query, and few others", "[box_bins]") {
  std::mt19937_64 rng(7);
  BoxBins bins;
  bins.reset(1.0);
  std::vector<Box> boxes;
  // Mostly boxes of one to three cells, some spanning far more than kMaxCells.
  for (std::uint32_t k = 0; k < 3000; ++k) {
    boxes.push_back(random_box(rng, 100, k % 50 == 0 ? 40.0 : 2.5));
    bins.insert(k, boxes.back().lo, boxes.back().hi);
  }
  std::size_t called = 0, overlapping = 0;
  for (int i = 0; i < 2000; ++i) {
    const Box q = random_box(rng, 110, i % 100 == 0 ? 30.0 : 2.0);  // some queries over 64 cells
    const std::set<std::uint32_t> got = visited(bins, q);
    for (std::uint32_t k = 0; k < boxes.size(); ++k)
      if (overlap(boxes[k], q)) {
        ++overlapping;
        REQUIRE(got.count(k) == 1);
      }
    called += got.size();
  }
  // Binned, a query meets the wide boxes (60) and a handful of near ones, not all 3000.
  CHECK(called < 2000 * 200);
  CHECK(overlapping > 0);
}

TEST_CASE("box bins hold while there are few keys, after clear, and at the clamp", "[box_bins]") {
  BoxBins bins;
  bins.reset(0.5);
  const Box a{Vec3(0, 0, 0), Vec3(1, 1, 1)};
  CHECK(visited(bins, a).empty());
  bins.insert(3, a.lo, a.hi);
  CHECK(visited(bins, a) == std::set<std::uint32_t>{3});
  bins.clear();
  CHECK(visited(bins, a).empty());

  // Coordinates far beyond the clamp (the core accepts up to 1e100) share the clamp's cells:
  // still found, no overflow (the sanitizer build runs this).
  for (std::uint32_t k = 0; k < 40; ++k) {
    const double s = k % 2 == 0 ? 1e90 : -1e90;
    bins.insert(k, Vec3(s, s, s), Vec3(s + 1e80, s, s));
  }
  const std::set<std::uint32_t> far = visited(bins, {Vec3(1e90, 1e90, 1e90), Vec3(1e90, 1e90, 1e90)});
  for (std::uint32_t k = 0; k < 40; k += 2) CHECK(far.count(k) == 1);

  // A cell edge that is zero or not finite puts every box in one cell.
  for (double cell : {0.0, -1.0, std::numeric_limits<double>::infinity(), 1e-320}) {
    BoxBins one;
    one.reset(cell);
    for (std::uint32_t k = 0; k < 40; ++k) one.insert(k, Vec3(double(k), 0, 0), Vec3(k + 0.5, 0, 0));
    CHECK(visited(one, {Vec3(39, 0, 0), Vec3(39, 0, 0)}).count(39) == 1);
  }
}
