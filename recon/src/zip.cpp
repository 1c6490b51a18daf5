// Zippering of slits: a boundary edge with the boundary vertices that follow or precede it on
// its loop lying along it (Turk & Levoy, "Zippered polygon meshes from range images", 1994: the
// triangle on the edge is split at those vertices). Pure: no I/O, no globals.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "scanmesh/recon/fill.hpp"
#include "scanmesh/recon/intersections.hpp"

#include "loop_measure.hpp"
#include "triangle_shape.hpp"

namespace scanmesh::recon {
namespace {

constexpr std::uint32_t kNone = 0xffffffffu;

std::uint64_t directed_key(std::uint32_t u, std::uint32_t v) { return (std::uint64_t{u} << 32) | v; }

/// The corner of t that is neither u nor v.
std::uint32_t third(const Triangle& t, std::uint32_t u, std::uint32_t v) {
  return t[0] != u && t[0] != v ? t[0] : (t[1] != u && t[1] != v ? t[1] : t[2]);
}

/// The mesh's half-edges (sorted, with their triangle) and its boundary: for each vertex with
/// exactly one boundary edge out and one in, its successor and predecessor on its loop (kNone
/// elsewhere: inner vertices, and vertices where two loops touch).
struct Boundary {
  std::vector<std::pair<std::uint64_t, std::uint32_t>> half;  // (u << 32 | v, triangle)
  std::vector<std::uint32_t> next, prev, tri;                 // tri: the triangle on u -> next

  /// Over the triangles with a corner flagged in `near` (the others cannot hold a boundary
  /// edge, nor an edge at a boundary vertex).
  Boundary(std::size_t vertices, const std::vector<Triangle>& triangles,
           const std::vector<std::uint8_t>& near)
      : next(vertices, kNone), prev(vertices, kNone), tri(vertices, kNone) {
    for (std::uint32_t t = 0; t < triangles.size(); ++t) {
      const Triangle& tr = triangles[t];
      if ((near[tr[0]] | near[tr[1]] | near[tr[2]]) == 0) continue;
      for (int k = 0; k < 3; ++k) half.emplace_back(directed_key(tr[k], tr[(k + 1) % 3]), t);
    }
    std::sort(half.begin(), half.end());
    std::vector<std::uint8_t> outs(vertices, 0), ins(vertices, 0);
    for (const auto& [key, t] : half) {
      const auto u = static_cast<std::uint32_t>(key >> 32), v = static_cast<std::uint32_t>(key);
      // (an edge with an end not flagged may have its twin in a triangle left out)
      if (!near[u] || !near[v] || has_half(v, u)) continue;
      outs[u] = static_cast<std::uint8_t>(std::min(outs[u] + 1, 2));
      ins[v] = static_cast<std::uint8_t>(std::min(ins[v] + 1, 2));
      next[u] = v;
      tri[u] = t;
      prev[v] = u;
    }
    for (std::size_t v = 0; v < vertices; ++v)
      if (outs[v] > 1 || ins[v] > 1) next[v] = prev[v] = kNone;
    for (std::size_t v = 0; v < vertices; ++v) {  // both ends single
      if (next[v] != kNone && prev[next[v]] != v) next[v] = kNone;
      if (prev[v] != kNone && next[prev[v]] != v) prev[v] = kNone;
    }
  }
  [[nodiscard]] bool has_half(std::uint32_t u, std::uint32_t v) const { return triangle_on(u, v) != kNone; }
  [[nodiscard]] std::uint32_t triangle_on(std::uint32_t u, std::uint32_t v) const {
    const auto it = std::lower_bound(half.begin(), half.end(), std::make_pair(directed_key(u, v), std::uint32_t{0}));
    return it != half.end() && it->first == directed_key(u, v) ? it->second : kNone;
  }
  /// (the edges at a vertex flagged in `near` are all here)
  [[nodiscard]] bool has_edge(std::uint32_t u, std::uint32_t v) const {
    return has_half(u, v) || has_half(v, u);
  }
};

/// One zip: triangle t = (u, v, w) becomes the fan (s[i], s[i + 1], w) over s = u, splits..., v.
struct Zip {
  std::uint32_t t;
  std::vector<std::uint32_t> s;
};

Vec3 normal_of(const std::vector<Vec3>& p, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  return (p[b] - p[a]).cross(p[c] - p[a]);
}

}  // namespace

ZipStats zip_slits(Mesh& mesh, std::span<const float> vertex_spacing, double band,
                   std::span<const std::uint8_t> maybe_boundary) {
  if (vertex_spacing.size() < mesh.vertices.size())
    throw std::invalid_argument("zip_slits: the spacing of every vertex is needed (" +
                                std::to_string(vertex_spacing.size()) + " for " +
                                std::to_string(mesh.vertices.size()) + " vertices)");
  ZipStats stats;
  const std::vector<Vec3>& p = mesh.vertices;
  // Fan triangles may be thin (a coarse point's fan onto a dense row), but not this thin.
  const double cos_min_angle = std::cos(1.0 * std::numbers::pi / 180);
  std::vector<std::uint64_t> refused;  // split edges (u << 32 | v) whose fan crossed the mesh
  constexpr int kRounds = 8;
  // The vertices that may lie on a boundary: the caller's, or every one. A zip only closes
  // boundary edges and adds new ones between boundary vertices, so the set never grows.
  std::vector<std::uint8_t> near(p.size(), 1);
  if (maybe_boundary.size() >= p.size()) near.assign(maybe_boundary.begin(), maybe_boundary.begin() + static_cast<std::ptrdiff_t>(p.size()));
  for (int round = 0; round < kRounds; ++round) {
    const Boundary bd(p.size(), mesh.triangles, near);
    // One zip per vertex a round (its split points, its ends and w): the next round sees the
    // others on the mesh as it then is.
    std::vector<std::uint8_t> used_vertex(p.size(), 0);
    std::vector<std::uint8_t> used_tri(mesh.triangles.size(), 0);
    std::vector<Zip> zips;
    std::vector<std::uint32_t> fwd, back;
    for (std::uint32_t u = 0; u < p.size(); ++u) {
      const std::uint32_t v = bd.next[u];
      if (v == kNone || used_vertex[u] || std::binary_search(refused.begin(), refused.end(), directed_key(u, v)))
        continue;
      const std::uint32_t t = bd.tri[u];
      if (used_tri[t]) continue;
      const Triangle& tr = mesh.triangles[t];
      const std::uint32_t w = third(tr, u, v);
      const double len = (p[v] - p[u]).norm();
      if (!(len > 0)) continue;
      // Whether x lies along u -> v, and where.
      auto along = [&](std::uint32_t x, double& at) {
        return detail::lies_along(p[u], p[v], p[x], band * vertex_spacing[x], at);
      };
      // Forward from v: the loop's vertices after v, back along the edge towards u.
      fwd.clear();
      double last = len;
      for (std::uint32_t x = bd.next[v]; x != kNone && x != u && x != w && fwd.size() < 64;
           x = bd.next[x]) {
        double at = 0;
        if (!along(x, at) || !(at > 0 && at < last)) break;
        fwd.push_back(x);
        last = at;
      }
      // Backward from u: the loop's vertices before u, along the edge towards v (before the
      // forward ones).
      back.clear();
      double first = 0;
      for (std::uint32_t y = bd.prev[u]; y != kNone && y != v && y != w && fwd.size() + back.size() < 64;
           y = bd.prev[y]) {
        if (std::find(fwd.begin(), fwd.end(), y) != fwd.end()) break;
        double at = 0;
        if (!along(y, at) || !(at > first && at < last)) break;
        back.push_back(y);
        first = at;
      }
      if (fwd.empty() && back.empty()) continue;
      Zip z{t, {u}};
      z.s.insert(z.s.end(), back.begin(), back.end());
      z.s.insert(z.s.end(), fwd.rbegin(), fwd.rend());
      z.s.push_back(v);
      // The fan: each side along the old edge either closes a boundary edge of the loop (the
      // mesh has it one way only, against the fan) or is new; no split point already joined to
      // w; nothing thinner than the floor; no fold against t or the triangles it closes onto.
      const Vec3 nt = normal_of(p, u, v, w).normalized();
      bool ok = true;
      for (std::size_t i = 0; ok && i + 1 < z.s.size(); ++i) {
        const std::uint32_t a = z.s[i], b = z.s[i + 1];
        if (used_vertex[a] || (i > 0 && bd.has_edge(a, w))) ok = false;
        const Vec3 n = normal_of(p, a, b, w);
        const double twice_area = n.norm();
        if (!(twice_area > 0) || detail::min_angle_cos(p[a], p[b], p[w]) > cos_min_angle ||
            n.dot(nt) < 0.5 * twice_area)
          ok = false;
        if (!ok || !bd.has_edge(a, b)) continue;
        const std::uint32_t across = bd.triangle_on(b, a);
        if (across == kNone || bd.has_half(a, b) ||
            normal_of(p, mesh.triangles[across][0], mesh.triangles[across][1], mesh.triangles[across][2]).dot(n) <= 0)
          ok = false;
      }
      if (!ok || used_vertex[v] || used_vertex[w]) continue;
      used_tri[t] = 1;
      for (std::uint32_t x : z.s) used_vertex[x] = 1;
      used_vertex[w] = 1;
      zips.push_back(std::move(z));
    }
    if (zips.empty()) break;
    // Apply them all, then take back every zip whose fan crosses the mesh or another fan.
    std::vector<Triangle> kept;
    std::vector<std::uint8_t> removed(mesh.triangles.size(), 0);
    for (const Zip& z : zips) removed[z.t] = 1;
    kept.reserve(mesh.triangles.size() + 64);
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
      if (!removed[t]) kept.push_back(mesh.triangles[t]);
    const std::size_t from = kept.size();
    std::vector<std::uint32_t> zip_of;
    for (std::uint32_t zi = 0; zi < zips.size(); ++zi) {
      const Zip& z = zips[zi];
      const std::uint32_t w = third(mesh.triangles[z.t], z.s.front(), z.s.back());
      for (std::size_t i = 0; i + 1 < z.s.size(); ++i) {
        kept.push_back({z.s[i], z.s[i + 1], w});
        zip_of.push_back(zi);
      }
    }
    // Crossings of the fans: against the triangles whose boxes meet a fan's box (a few hundred
    // of them, not the whole mesh), with the fans last.
    std::vector<Eigen::AlignedBox3d> boxes(zips.size());
    for (std::size_t i = from; i < kept.size(); ++i)
      for (std::uint32_t c : kept[i]) boxes[zip_of[i - from]].extend(p[c]);
    std::vector<Triangle> local;
    std::vector<std::uint32_t> local_of;  // its index in `kept`
    for (std::size_t i = 0; i < kept.size(); ++i) {
      Eigen::AlignedBox3d box;
      for (std::uint32_t c : kept[i]) box.extend(p[c]);
      bool meets = i >= from;
      for (std::size_t zi = 0; zi < boxes.size() && !meets; ++zi) meets = boxes[zi].intersects(box);
      if (!meets) continue;
      local.push_back(kept[i]);
      local_of.push_back(static_cast<std::uint32_t>(i));
    }
    const std::size_t local_from =
        static_cast<std::size_t>(std::lower_bound(local_of.begin(), local_of.end(), from) - local_of.begin());
    const SelfIntersections crossing = find_self_intersections(p, local, kAllPairs, local_from);
    std::vector<std::uint8_t> bad(zips.size(), 0);
    for (const auto& [l1, l2] : crossing.examples) {
      const std::size_t t1 = local_of[l1], t2 = local_of[l2];
      if (t1 >= from) bad[zip_of[t1 - from]] = 1;
      if (t2 >= from) bad[zip_of[t2 - from]] = 1;
    }
    std::size_t good = 0;
    for (std::uint32_t zi = 0; zi < zips.size(); ++zi) {
      if (bad[zi]) {
        refused.push_back(directed_key(zips[zi].s.front(), zips[zi].s.back()));
        ++stats.refused;
      } else {
        ++good;
      }
    }
    std::sort(refused.begin(), refused.end());
    if (good == zips.size()) {
      mesh.triangles.swap(kept);
    } else {  // the good ones only (the bad ones' triangles stay as they were)
      for (std::uint32_t zi = 0; zi < zips.size(); ++zi)
        if (bad[zi]) removed[zips[zi].t] = 0;
      std::vector<Triangle> next;
      next.reserve(kept.size());
      for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
        if (!removed[t]) next.push_back(mesh.triangles[t]);
      for (std::size_t i = from; i < kept.size(); ++i)
        if (!bad[zip_of[i - from]]) next.push_back(kept[i]);
      mesh.triangles.swap(next);
    }
    for (std::uint32_t zi = 0; zi < zips.size(); ++zi)
      if (!bad[zi]) {
        ++stats.zipped;
        stats.split_points += zips[zi].s.size() - 2;
      }
  }
  return stats;
}

}  // namespace scanmesh::recon
