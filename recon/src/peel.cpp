// SPDX-License-Identifier: MIT
#include "peel.hpp"

#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include "vertex_triangles.hpp"

#ifndef NDEBUG
#include <cassert>

#include "scanmesh/recon/analysis.hpp"
#endif

namespace scanmesh::recon::detail {
namespace {

inline std::uint64_t mix(std::uint64_t x) {  // splitmix64's finaliser
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

}  // namespace

std::size_t peel_border_chords(Mesh& mesh, double min_apex_deg) {
  auto& tris = mesh.triangles;
  const auto& p = mesh.vertices;
  if (tris.empty() || !(min_apex_deg > 0 && min_apex_deg < 180)) return 0;
  const double cos_max = std::cos(min_apex_deg * std::numbers::pi / 180);
  // A corner w of triangle (w, x, y) links x -> y in w's fan. The links of a closed fan form a
  // cycle, where every vertex starts one link and ends one: the hashed starts minus the hashed
  // ends cancel. An open fan (a border vertex) leaves its first start and last end (distinct
  // vertices), which cancel only on a 64-bit hash collision; so do several fans.
  std::vector<std::uint64_t> links(p.size(), 0);
  for (const Triangle& t : tris)
    for (int k = 0; k < 3; ++k)
      links[t[k]] += mix(t[(k + 1) % 3]) - mix(t[(k + 2) % 3]);
  std::vector<std::uint8_t> border(p.size(), 0);
  bool any_border = false;
  for (std::size_t v = 0; v < p.size(); ++v)
    if (links[v] != 0) border[v] = 1, any_border = true;
  std::vector<std::uint64_t>().swap(links);
  if (!any_border) return 0;  // closed
  // The angle at w, opposite u -> v, is over the bound.
  auto obtuse = [&](std::uint32_t u, std::uint32_t v, std::uint32_t w) {
    const Vec3 a = p[u] - p[w], b = p[v] - p[w];
    const double la = a.norm(), lb = b.norm();
    return la > 0 && lb > 0 && a.dot(b) < cos_max * la * lb;
  };
  // Candidates: two corners on a border, the third inside, and the angle there over the bound
  // (whether the edge between the two is a border edge needs the adjacency below).
  std::vector<std::uint32_t> queue;
  for (std::uint32_t t = 0; t < tris.size(); ++t) {
    const Triangle& tr = tris[t];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t u = tr[k], v = tr[(k + 1) % 3], w = tr[(k + 2) % 3];
      if (border[u] != 0 && border[v] != 0 && border[w] == 0 && obtuse(u, v, w)) {
        queue.push_back(t);
        break;
      }
    }
  }
  if (queue.empty()) return 0;
#ifndef NDEBUG
  const MeshReport before = analyze(mesh);
#endif
  const VertexTriangles around(p.size(), tris);
  std::vector<std::uint8_t> removed(tris.size(), 0);
  // Another live triangle has the directed edge v -> u (the twin of u -> v in t).
  auto has_twin = [&](std::uint32_t t, std::uint32_t u, std::uint32_t v) {
    for (std::uint32_t s : around.of(u)) {
      if (s == t || removed[s] != 0) continue;
      const Triangle& q = tris[s];
      for (int k = 0; k < 3; ++k)
        if (q[k] == v && q[(k + 1) % 3] == u) return true;
    }
    return false;
  };
  std::size_t peeled = 0;
  while (!queue.empty()) {
    const std::uint32_t t = queue.back();
    queue.pop_back();
    if (removed[t] != 0) continue;
    const Triangle tr = tris[t];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t u = tr[k], v = tr[(k + 1) % 3], w = tr[(k + 2) % 3];
      if (border[u] == 0 || border[v] == 0 || border[w] != 0 || !obtuse(u, v, w) ||
          has_twin(t, u, v))
        continue;
      // Peel: w's closed fan opens here (w keeps its other triangles, one fan); u and v lose
      // the end triangle of their open fans. The triangles of w may now be candidates.
      removed[t] = 1;
      ++peeled;
      border[w] = 1;
      for (std::uint32_t s : around.of(w))
        if (removed[s] == 0) queue.push_back(s);
      break;
    }
  }
  if (peeled == 0) return 0;
  std::size_t out = 0;
  for (std::size_t t = 0; t < tris.size(); ++t)
    if (removed[t] == 0) tris[out++] = tris[t];
  tris.resize(out);
#ifndef NDEBUG
  const MeshReport after = analyze(mesh);
  assert(after.non_manifold_edges <= before.non_manifold_edges &&
         after.non_manifold_vertices <= before.non_manifold_vertices &&
         after.boundary_loops == before.boundary_loops && after.components == before.components &&
         after.euler_characteristic == before.euler_characteristic &&
         after.referenced_vertices == before.referenced_vertices && "peeling a chord changed the topology");
#endif
  return peeled;
}

}  // namespace scanmesh::recon::detail
