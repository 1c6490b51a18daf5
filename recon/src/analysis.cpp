// Topology and quality report of a triangle mesh: edges from a bucket sort of half-edges, fans and
// components by union-find, boundary loops by walking boundary edges. Pure: no I/O, no globals.
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/analysis.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <numeric>
#include <string>

#include "scanmesh/common/error.hpp"

namespace scanmesh::recon {
namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

/// Edges of a walked loop (an open walk, stopped at a non-manifold vertex, has one fewer).
std::size_t loop_edges(const BoundaryLoop& l) {
  return l.closed ? l.vertices.size() : l.vertices.size() - 1;
}

/// Union-find over dense indices with path halving.
class DisjointSets {
 public:
  explicit DisjointSets(std::size_t n) : parent_(n) {
    for (std::size_t i = 0; i < n; ++i) parent_[i] = static_cast<std::uint32_t>(i);
  }
  std::uint32_t find(std::uint32_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  /// Returns true when a and b were in different sets.
  bool unite(std::uint32_t a, std::uint32_t b) {
    a = find(a);
    b = find(b);
    if (a == b) return false;
    // Link the larger root under the smaller: deterministic, and path halving keeps finds short.
    if (a > b) std::swap(a, b);
    parent_[b] = a;
    return true;
  }

 private:
  std::vector<std::uint32_t> parent_;
};

/// One half-edge in the bucket of its smaller end vertex: the larger end and the half-edge id
/// (triangle * 3 + corner; half-edge t*3+k runs from tri[k] to tri[(k+1)%3]).
struct HalfEdgeEntry {
  std::uint32_t other;
  std::uint32_t he;
  friend bool operator<(const HalfEdgeEntry& a, const HalfEdgeEntry& b) {
    return a.other != b.other ? a.other < b.other : a.he < b.he;
  }
};

bool has_repeated_index(const Triangle& t) { return t[0] == t[1] || t[1] == t[2] || t[0] == t[2]; }

/// Corner (0..2) of vertex v in triangle t; v must be one of its vertices.
std::uint32_t corner_of(const Triangle& t, std::uint32_t v) {
  return t[0] == v ? 0u : (t[1] == v ? 1u : 2u);
}

/// A boundary edge as it is traversed by its triangle.
struct BoundaryEdge {
  std::uint32_t from, to;
};

/// Splits the boundary edges into loops. Each vertex's incident boundary edges are walked,
/// preferring edges that continue in the triangles' direction (from == current vertex), falling
/// back to any unused incident edge where orientation is inconsistent. Whenever the walk returns
/// to a vertex already on the current path the cycle is cut off as one loop, so a vertex where
/// two holes touch gives two loops. A walk that dead-ends (odd boundary degree, only possible
/// around non-manifold edges) is reported as one open loop. Each edge lands in exactly one loop.
/// A closed loop lists each of its vertices once, starting anywhere.
std::vector<BoundaryLoop> walk_boundary_loops(const std::vector<BoundaryEdge>& edges,
                                              std::size_t vertex_count) {
  std::vector<BoundaryLoop> loops;
  if (edges.empty()) return loops;
  // CSR adjacency: for each vertex, the boundary edges incident to it.
  std::vector<std::uint32_t> offset(vertex_count + 1, 0);
  for (const BoundaryEdge& e : edges) {
    ++offset[e.from + 1];
    ++offset[e.to + 1];
  }
  for (std::size_t v = 0; v < vertex_count; ++v) offset[v + 1] += offset[v];
  std::vector<std::uint32_t> incident(offset[vertex_count]);
  {
    std::vector<std::uint32_t> fill(offset.begin(), offset.end() - 1);
    for (std::uint32_t i = 0; i < edges.size(); ++i) {
      incident[fill[edges[i].from]++] = i;
      incident[fill[edges[i].to]++] = i;
    }
  }
  std::vector<char> used(edges.size(), 0);
  // Per-vertex scan cursor: skips edges already used, so the walk is linear overall.
  std::vector<std::uint32_t> cursor(offset.begin(), offset.end() - 1);
  std::vector<std::uint32_t> path_pos(vertex_count, kNone);  // position of a vertex on the path
  std::vector<std::uint32_t> path;                           // vertices of the current path

  auto next_edge = [&](std::uint32_t v) -> std::uint32_t {
    while (cursor[v] < offset[v + 1] && used[incident[cursor[v]]]) ++cursor[v];
    std::uint32_t fallback = kNone;
    for (std::uint32_t k = cursor[v]; k < offset[v + 1]; ++k) {
      const std::uint32_t e = incident[k];
      if (used[e]) continue;
      if (edges[e].from == v) return e;
      if (fallback == kNone) fallback = e;
    }
    return fallback;
  };

  for (std::uint32_t first = 0; first < edges.size(); ++first) {
    if (used[first]) continue;
    const std::uint32_t start = edges[first].from;
    path.assign(1, start);
    path_pos[start] = 0;
    std::uint32_t current = start;
    while (true) {
      const std::uint32_t e = next_edge(current);
      if (e == kNone) {
        // Dead end: what is left on the path is an open chain.
        if (path.size() > 1) loops.push_back({path, false});
        for (std::uint32_t v : path) path_pos[v] = kNone;
        path.clear();
        break;
      }
      used[e] = 1;
      const std::uint32_t next = edges[e].from == current ? edges[e].to : edges[e].from;
      if (path_pos[next] != kNone) {
        // Closed a cycle: cut it off the path (edges after position path_pos[next]).
        const std::uint32_t at = path_pos[next];
        loops.push_back({std::vector<std::uint32_t>(path.begin() + at, path.end()), true});
        for (std::size_t i = at + 1; i < path.size(); ++i) path_pos[path[i]] = kNone;
        path.resize(at + 1);
        current = next;
        if (path.size() == 1 && next_edge(current) == kNone) {
          path_pos[path[0]] = kNone;
          path.clear();
          break;
        }
      } else {
        path_pos[next] = static_cast<std::uint32_t>(path.size());
        path.push_back(next);
        current = next;
      }
    }
  }
  return loops;
}

}  // namespace

MeshReport analyze(const Mesh& mesh, bool keep_loops) {
  MeshReport r;
  const std::size_t nv = mesh.vertices.size();
  const std::size_t nt = mesh.triangles.size();
  r.vertices = nv;
  r.triangles = nt;
  if (nt == 0) return r;
  if (nt * 3 >= kNone || nv >= kNone) {
    throw GeometryError("analyze: mesh too large (" + std::to_string(nt) + " triangles, " +
                        std::to_string(nv) + " vertices; 32-bit indices)");
  }

  // Pass 1: index validity, referenced vertices, degenerate triangles, angles, volume, and the
  // size of each vertex's half-edge bucket (a half-edge goes to the bucket of its smaller end).
  std::vector<char> referenced(nv, 0);
  std::vector<char> topological(nt, 0);  // three distinct indices: takes part in the topology
  std::vector<std::uint32_t> bucket(nv + 1, 0);
  std::vector<std::uint32_t> corners_at(nv, 0);
  double max_cot = -std::numeric_limits<double>::infinity();  // of the smallest angle
  double min_cot = std::numeric_limits<double>::infinity();   // of the largest angle
  std::size_t angle_tris = 0, below10 = 0, below20 = 0;
  double volume6 = 0;
  constexpr double kCot10 = 5.671281819617709;   // cot(10 degrees)
  constexpr double kCot20 = 2.7474774194546216;  // cot(20 degrees)
  constexpr double kRadToDeg = 180.0 / std::numbers::pi;
  for (std::size_t t = 0; t < nt; ++t) {
    const Triangle& tri = mesh.triangles[t];
    for (std::uint32_t v : tri) {
      if (v >= nv) {
        throw GeometryError("analyze: triangle " + std::to_string(t) + " references vertex " +
                            std::to_string(v) + " but the mesh has " + std::to_string(nv) +
                            " vertices");
      }
      referenced[v] = 1;
    }
    const Vec3& a = mesh.vertices[tri[0]];
    const Vec3& b = mesh.vertices[tri[1]];
    const Vec3& c = mesh.vertices[tri[2]];
    volume6 += a.dot(b.cross(c));
    if (has_repeated_index(tri)) {
      ++r.degenerate_triangles;
      continue;
    }
    topological[t] = 1;
    for (int k = 0; k < 3; ++k) {
      ++bucket[std::min(tri[k], tri[(k + 1) % 3]) + 1];
      ++corners_at[tri[k]];
    }
    const Vec3 ab = b - a, bc = c - b, ca = a - c;
    const double cross = ab.cross(-ca).norm();
    const double longest_sq = std::max({ab.squaredNorm(), bc.squaredNorm(), ca.squaredNorm()});
    // Zero area up to rounding: 2 * area = |ab x ac| below 1e-12 of the longest edge squared
    // (an angle under about 1e-12 rad) is collinear as far as float-derived data can tell.
    if (!(cross > 1e-12 * longest_sq)) {
      ++r.degenerate_triangles;
      continue;
    }
    // The angle at a corner is atan2(|u x v|, u . v), so its cotangent is (u . v) / |u x v| with
    // the same |u x v| at all three corners; the cotangent falls monotonically over (0, 180)
    // degrees, so the smallest angle has the largest cotangent. No trigonometry per triangle.
    const double inv = 1.0 / cross;
    const double cot_a = -ab.dot(ca) * inv, cot_b = -bc.dot(ab) * inv, cot_c = -ca.dot(bc) * inv;
    const double cot_of_min = std::max({cot_a, cot_b, cot_c});
    max_cot = std::max(max_cot, cot_of_min);
    min_cot = std::min(min_cot, std::min({cot_a, cot_b, cot_c}));
    ++angle_tris;
    if (cot_of_min > kCot10) ++below10;
    if (cot_of_min > kCot20) ++below20;
  }
  r.signed_volume = volume6 / 6.0;
  for (char ref : referenced) r.referenced_vertices += static_cast<std::size_t>(ref);
  if (angle_tris > 0) {
    r.min_angle_deg = std::atan2(1.0, max_cot) * kRadToDeg;
    r.max_angle_deg = std::atan2(1.0, min_cot) * kRadToDeg;
    r.mean_angle_deg = 60.0;  // the angles of every triangle sum to 180 degrees
    r.frac_min_angle_below_10 = static_cast<double>(below10) / static_cast<double>(angle_tris);
    r.frac_min_angle_below_20 = static_cast<double>(below20) / static_cast<double>(angle_tris);
  }

  // Pass 2: counting sort of half-edges by smaller end vertex, then each bucket by larger end.
  for (std::size_t v = 0; v < nv; ++v) bucket[v + 1] += bucket[v];
  std::vector<HalfEdgeEntry> entries(bucket[nv]);
  {
    std::vector<std::uint32_t> fill(bucket.begin(), bucket.end() - 1);
    for (std::uint32_t t = 0; t < nt; ++t) {
      if (!topological[t]) continue;
      const Triangle& tri = mesh.triangles[t];
      for (std::uint32_t k = 0; k < 3; ++k) {
        const std::uint32_t u = tri[k], w = tri[(k + 1) % 3];
        entries[fill[std::min(u, w)]++] = HalfEdgeEntry{std::max(u, w), t * 3 + k};
      }
    }
  }
  for (std::size_t v = 0; v < nv; ++v) {
    auto first = entries.begin() + bucket[v], last = entries.begin() + bucket[v + 1];
    if (last - first < 2) continue;
    if (last - first <= 16) {
      for (auto i = first + 1; i < last; ++i) {  // insertion sort: buckets are tiny
        const HalfEdgeEntry x = *i;
        auto j = i;
        for (; j > first && x < *(j - 1); --j) *j = *(j - 1);
        *j = x;
      }
    } else {
      std::sort(first, last);
    }
  }

  // Pass 3: walk the edge groups.
  DisjointSets triangle_sets(nt);
  DisjointSets corner_sets(nt * 3);
  std::vector<std::uint32_t> fan_merges(nv, 0);
  std::vector<char> on_non_manifold_edge(nv, 0);
  std::vector<BoundaryEdge> boundary;
  double edge_length_sum = 0, edge_length_max = 0;
  for (std::uint32_t v = 0; v < nv; ++v) {
    for (std::uint32_t i = bucket[v]; i < bucket[v + 1];) {
      std::uint32_t j = i + 1;
      while (j < bucket[v + 1] && entries[j].other == entries[i].other) ++j;
      const std::uint32_t w = entries[i].other;
      const std::uint32_t n = j - i;
      ++r.edges;
      const double len = (mesh.vertices[v] - mesh.vertices[w]).norm();
      edge_length_sum += len;
      edge_length_max = std::max(edge_length_max, len);
      if (n == 1) {
        ++r.boundary_edges;
        const Triangle& tri = mesh.triangles[entries[i].he / 3];
        const std::uint32_t k = entries[i].he % 3;
        boundary.push_back(BoundaryEdge{tri[k], tri[(k + 1) % 3]});
      } else {
        if (n >= 3) {
          ++r.non_manifold_edges;
          on_non_manifold_edge[v] = on_non_manifold_edge[w] = 1;
        }
        for (std::uint32_t k = i + 1; k < j; ++k) {
          triangle_sets.unite(entries[i].he / 3, entries[k].he / 3);
        }
        if (n == 2) {
          const std::uint32_t h0 = entries[i].he, h1 = entries[i + 1].he;
          const Triangle& t0 = mesh.triangles[h0 / 3];
          const Triangle& t1 = mesh.triangles[h1 / 3];
          // Same direction in both triangles: t0[k0] == t1[k1] (both start at the same end).
          if (t0[h0 % 3] == t1[h1 % 3]) ++r.inconsistent_edges;
          // The two triangles are in the same fan around both ends of the edge.
          for (std::uint32_t end : {v, w}) {
            const std::uint32_t c0 = (h0 / 3) * 3 + corner_of(t0, end);
            const std::uint32_t c1 = (h1 / 3) * 3 + corner_of(t1, end);
            if (corner_sets.unite(c0, c1)) ++fan_merges[end];
          }
        }
        // Duplicates: count each group of triangles with the same vertex set once, on the edge
        // between its two smallest vertices (so a duplicate pair is not counted three times).
        for (std::uint32_t a = i; a < j; ++a) {
          const Triangle& ta = mesh.triangles[entries[a].he / 3];
          const std::uint32_t third_a = ta[(entries[a].he % 3 + 2) % 3];
          if (third_a < w) continue;  // v < w < third is the "smallest pair" edge
          for (std::uint32_t b = i; b < a; ++b) {
            const Triangle& tb = mesh.triangles[entries[b].he / 3];
            if (tb[(entries[b].he % 3 + 2) % 3] == third_a) {
              ++r.duplicate_triangles;  // a repeats an earlier triangle of this group
              break;
            }
          }
        }
      }
      i = j;
    }
  }
  r.orientation_consistent = r.inconsistent_edges == 0;
  if (r.edges > 0) {
    r.mean_edge_length = edge_length_sum / static_cast<double>(r.edges);
    r.max_edge_length = edge_length_max;
  }

  // Fans: a vertex with c corners and m successful merges has c - m fans. Vertices on a
  // non-manifold edge are already reported through that edge and are not counted again.
  for (std::size_t v = 0; v < nv; ++v) {
    if (corners_at[v] - fan_merges[v] > 1 && !on_non_manifold_edge[v]) ++r.non_manifold_vertices;
  }

  std::size_t faces = 0;
  for (std::uint32_t t = 0; t < nt; ++t) {
    if (!topological[t]) continue;
    ++faces;
    if (triangle_sets.find(t) == t) ++r.components;
  }

  std::vector<BoundaryLoop> loops = walk_boundary_loops(boundary, nv);
  // (edges, perimeter) per loop, most edges first (ordered on the edges only: a perimeter may be
  // NaN when the file's coordinates are).
  for (const std::size_t li : loop_report_order(loops)) {
    const BoundaryLoop& l = loops[li];
    const std::size_t edges = loop_edges(l);
    double perimeter = 0;
    for (std::size_t i = 0; i < edges; ++i)
      perimeter += (mesh.vertices[l.vertices[(i + 1) % l.vertices.size()]] -
                    mesh.vertices[l.vertices[i]])
                       .norm();
    r.boundary_loop_lengths.push_back(edges);
    r.boundary_loop_perimeters.push_back(perimeter);
  }
  r.boundary_loops = r.boundary_loop_lengths.size();
  if (keep_loops) r.loops = std::move(loops);

  r.euler_characteristic = static_cast<long>(r.referenced_vertices) - static_cast<long>(r.edges) +
                           static_cast<long>(faces);
  r.genus = (2 * static_cast<long>(r.components) - static_cast<long>(r.boundary_loops) -
             r.euler_characteristic) /
            2;
  return r;
}

std::vector<std::size_t> loop_report_order(const std::vector<BoundaryLoop>& loops) {
  std::vector<std::size_t> order(loops.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return loop_edges(loops[a]) > loop_edges(loops[b]);
  });
  return order;
}

double loop_width(const Mesh& mesh, std::span<const std::uint32_t> loop, double stop_above) {
  double widest2 = 0;
  const double stop2 = stop_above * stop_above;
  for (std::size_t i = 0; i < loop.size(); ++i) {
    const Vec3& a = mesh.vertices[loop[i]];
    for (std::size_t j = i + 1; j < loop.size(); ++j) {
      const double d2 = (mesh.vertices[loop[j]] - a).squaredNorm();
      if (!(d2 <= widest2)) {
        if (!std::isfinite(d2)) return std::numeric_limits<double>::infinity();
        widest2 = d2;
        if (widest2 > stop2) return std::sqrt(widest2);
      }
    }
  }
  return std::sqrt(widest2);
}

bool scan_like_vertices(const MeshReport& r) {
  return r.referenced_vertices >= 5000 && r.max_edge_length <= 6 * r.mean_edge_length &&
         r.frac_min_angle_below_20 <= 0.1;
}

}  // namespace scanmesh::recon
