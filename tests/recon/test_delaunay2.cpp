// The bulk's planar Delaunay triangulation (radial sweep, exact predicates).
// SPDX-License-Identifier: MIT
#include <array>
#include <catch2/catch.hpp>
#include <cstdint>
#include <map>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "delaunay2.hpp"

using scanmesh::recon::detail::Delaunay2;
using P = std::array<double, 2>;

namespace {

// Exact for the small integer coordinates of the grid cases; a relative tolerance guards the
// random cases against rounding (their points are in general position).
double orient(const P& a, const P& b, const P& c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}
double in_circle(const P& a, const P& b, const P& c, const P& d) {
  const double ax = a[0] - d[0], ay = a[1] - d[1], bx = b[0] - d[0], by = b[1] - d[1], cx = c[0] - d[0],
               cy = c[1] - d[1];
  return (ax * ax + ay * ay) * (bx * cy - cx * by) - (bx * bx + by * by) * (ax * cy - cx * ay) +
         (cx * cx + cy * cy) * (ax * by - bx * ay);
}

struct Summary {
  std::size_t inserted = 0, hull = 0;
};

/// Checks everything the bulk relies on and returns the counts.
Summary check_triangulation(const Delaunay2& dt, const std::vector<P>& p, double tol) {
  const auto c = dt.corners();
  const auto tw = dt.twins();
  REQUIRE(c.size() == 3 * dt.triangle_count());
  REQUIRE(tw.size() == c.size());
  std::vector<std::size_t> degree(p.size(), 0);
  std::set<std::pair<std::uint32_t, std::uint32_t>> directed;
  for (std::uint32_t h = 0; h < c.size(); ++h) {
    const std::uint32_t a = c[h], b = c[Delaunay2::next(h)];
    CHECK(dt.inserted(a));
    CHECK(directed.insert({a, b}).second);  // each directed edge once: a manifold, oriented
    ++degree[a];
    if (tw[h] != Delaunay2::kNone) {
      CHECK(tw[tw[h]] == h);
      CHECK(c[tw[h]] == b);
      CHECK(c[Delaunay2::next(tw[h])] == a);
    }
  }
  for (std::size_t t = 0; t < dt.triangle_count(); ++t) {
    const P &a = p[c[3 * t]], &b = p[c[3 * t + 1]], &d = p[c[3 * t + 2]];
    CHECK(orient(a, b, d) > 0);  // counter-clockwise, not degenerate
    // Empty circumcircle: no inserted point strictly inside.
    for (std::uint32_t v = 0; v < p.size(); ++v)
      if (dt.inserted(v)) CHECK_FALSE(in_circle(a, b, d, p[v]) > tol);
  }
  Summary s;
  for (std::uint32_t v = 0; v < p.size(); ++v) {
    if (!dt.inserted(v)) continue;
    ++s.inserted;
    s.hull += dt.on_hull(v) ? 1 : 0;
    // The walk from out_edge visits every triangle around v once.
    std::size_t walked = 0;
    std::uint32_t h = dt.out_edge(v);
    do {
      CHECK(c[h] == v);
      ++walked;
      h = tw[Delaunay2::prev(h)];
    } while (h != Delaunay2::kNone && h != dt.out_edge(v) && walked <= degree[v]);
    CHECK(walked == degree[v]);
    CHECK((h == Delaunay2::kNone) == dt.on_hull(v));
  }
  // Euler: a triangulated disc with n vertices, h of them on its boundary, has 2n - h - 2 faces.
  CHECK(dt.triangle_count() == 2 * s.inserted - s.hull - 2);
  return s;
}

}  // namespace

TEST_CASE("the radial-sweep Delaunay triangulation of random points is Delaunay, oriented and "
          "uses every point",
          "[recon][delaunay]") {
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (const std::size_t n : {3u, 4u, 10u, 100u, 700u}) {
    std::vector<P> p(n);
    for (auto& q : p) q = {u(gen), 0.3 * u(gen)};
    Delaunay2 dt;
    dt.triangulate(p);
    const Summary s = check_triangulation(dt, p, 1e-12);
    CHECK(s.inserted == n);
    CHECK(s.hull >= 3);
  }
}

TEST_CASE("the radial-sweep Delaunay triangulation handles cocircular grids, repeated points "
          "and collinear input",
          "[recon][delaunay]") {
  Delaunay2 dt;
  SECTION("a square grid: four cocircular points in every cell, collinear points on the hull") {
    std::vector<P> p;
    for (int y = 0; y < 20; ++y)
      for (int x = 0; x < 30; ++x) p.push_back({static_cast<double>(x), static_cast<double>(y)});
    dt.triangulate(p);
    const Summary s = check_triangulation(dt, p, 0);
    CHECK(s.inserted == p.size());
    CHECK(s.hull == 2 * (30 + 20) - 4);  // every boundary point, collinear ones included
    CHECK(dt.triangle_count() == 2 * 29 * 19);
  }
  SECTION("repeated points are left out once each, the rest is triangulated") {
    std::vector<P> p;
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) p.push_back({static_cast<double>(x * 3 + y % 2), static_cast<double>(y * 2)});
    const std::size_t distinct = p.size();
    for (std::size_t i = 0; i < distinct; i += 5) p.push_back(p[i]);
    dt.triangulate(p);
    const Summary s = check_triangulation(dt, p, 0);
    CHECK(s.inserted == distinct);
  }
  SECTION("points on one line give no triangle; one more point off it gives a fan") {
    std::vector<P> p;
    for (int i = 0; i < 10; ++i) p.push_back({static_cast<double>(i), static_cast<double>(2 * i)});
    dt.triangulate(p);
    CHECK(dt.triangle_count() == 0);
    p.push_back({0, 5});
    dt.triangulate(p);
    const Summary s = check_triangulation(dt, p, 0);
    CHECK(s.inserted == p.size());
    CHECK(dt.triangle_count() == 9);
  }
  SECTION("two small clusters far apart: every point is swept in order (the distances of a "
          "cluster's points tie as floats)") {
    std::mt19937 gen(3);
    std::uniform_real_distribution<double> u(-1e-3, 1e-3);
    std::vector<P> p;
    for (int i = 0; i < 1500; ++i) p.push_back({(i % 2 != 0 ? 100.0 : 0.0) + u(gen), u(gen)});
    dt.triangulate(p);
    const Summary s = check_triangulation(dt, p, 1e-18);
    CHECK(s.inserted == p.size());
  }
  SECTION("fewer than three distinct points give no triangle") {
    const std::vector<P> p = {{1, 1}, {1, 1}, {2, 2}, {1, 1}};
    dt.triangulate(p);
    CHECK(dt.triangle_count() == 0);
  }
}
