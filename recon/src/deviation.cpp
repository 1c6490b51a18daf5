// Point-to-surface distances (exact closest point on triangles, BVH with branch-and-bound
// nearest queries, angle-weighted pseudo-normals for the sign) and mesh deviation statistics.
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/deviation.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "closest_point.hpp"
#include "scanmesh/common/error.hpp"

namespace scanmesh::recon {
namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
constexpr std::uint32_t kLeafSize = 8;

using detail::ClosestPoint;
using detail::Feature;
using detail::closest_on_triangle;

/// Float bounds that contain the double value (boxes must stay conservative).
float round_down(double v) {
  const auto f = static_cast<float>(v);
  return static_cast<double>(f) <= v ? f
                                     : std::nextafter(f, -std::numeric_limits<float>::infinity());
}
float round_up(double v) {
  const auto f = static_cast<float>(v);
  return static_cast<double>(f) >= v ? f
                                     : std::nextafter(f, std::numeric_limits<float>::infinity());
}

/// BVH node with a float box rounded outwards (so box distances stay lower bounds). Leaf
/// (count > 0): triangles [first, first + count) of the leaf-ordered triangle array. Internal
/// (count == 0): its two children are the pair `first`. 32 bytes; a pair fills one cache line, so
/// one memory access yields both children's boxes.
struct Node {
  float lo[3] = {0, 0, 0};
  float hi[3] = {0, 0, 0};
  std::uint32_t first = 0;
  std::uint32_t count = 0;

  [[nodiscard]] double dist_sq(const Vec3& p) const {
    double sum = 0;
    for (int k = 0; k < 3; ++k) {
      const double d =
          std::max({static_cast<double>(lo[k]) - p[k], p[k] - static_cast<double>(hi[k]), 0.0});
      sum += d * d;
    }
    return sum;
  }
};

struct alignas(64) NodePair {
  Node child[2];
};

/// A triangle in leaf order with what the signed distance needs.
struct LeafTriangle {
  Vec3 a, b, c;
  std::uint32_t index;  ///< triangle index in the input mesh
};

}  // namespace

struct SurfaceDistance::Impl {
  Node root;
  std::vector<NodePair> pairs;
  std::vector<LeafTriangle> tris;
  std::vector<Vec3> face_normal;    ///< unit (zero if degenerate), by input triangle index
  std::vector<Vec3> edge_normal;    ///< pseudo-normal of edge k of triangle t at t*3+k
  std::vector<Vec3> vertex_normal;  ///< angle-weighted pseudo-normal per vertex
  std::vector<Triangle> triangles;  ///< input triangles (for the vertex normals' indices)

  void build(const Mesh& mesh);
  void build_normals(const Mesh& mesh);
  [[nodiscard]] ClosestPoint nearest(const Vec3& p, std::uint32_t* triangle) const;
};

void SurfaceDistance::Impl::build(const Mesh& mesh) {
  const std::size_t nt = mesh.triangles.size();
  const std::size_t nv = mesh.vertices.size();
  if (nt == 0) throw GeometryError("distance query: the reference surface has no triangles");
  if (nt >= kNone / 4 || nv >= kNone) {
    throw GeometryError("distance query: surface too large (32-bit indices)");
  }
  for (std::size_t t = 0; t < nt; ++t) {
    for (std::uint32_t v : mesh.triangles[t]) {
      if (v >= nv) {
        throw GeometryError("distance query: triangle " + std::to_string(t) +
                            " references vertex " + std::to_string(v) + " but the mesh has " +
                            std::to_string(nv) + " vertices");
      }
    }
  }
  triangles = mesh.triangles;

  // Median split over centroids along the longest axis of the centroid box; iterative with an
  // explicit work list so deep inputs cannot overflow the call stack.
  // Work on compact per-triangle items (float centroid and outward-rounded float box) that are
  // partitioned in place: sequential memory instead of indirection through an index array.
  struct Item {
    float centroid[3];
    float lo[3], hi[3];
    std::uint32_t index;
  };
  std::vector<Item> items(nt);
  for (std::uint32_t t = 0; t < nt; ++t) {
    const Triangle& tri = mesh.triangles[t];
    const Vec3 &a = mesh.vertices[tri[0]], &b = mesh.vertices[tri[1]], &c = mesh.vertices[tri[2]];
    const Vec3 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    const Vec3 mid = (a + b + c) / 3.0;
    Item& item = items[t];
    for (int k = 0; k < 3; ++k) {
      item.centroid[k] = static_cast<float>(mid[k]);
      item.lo[k] = round_down(lo[k]);
      item.hi[k] = round_up(hi[k]);
    }
    item.index = t;
  }
  pairs.reserve(nt / kLeafSize + 1);
  // A slot names where a node lives: kNone for the root, else pair * 2 + side.
  auto node_at = [&](std::uint32_t slot) -> Node& {
    return slot == kNone ? root : pairs[slot / 2].child[slot % 2];
  };
  struct Work {
    std::uint32_t slot, begin, end;
  };
  constexpr float kInf = std::numeric_limits<float>::infinity();
  std::vector<Work> work{{kNone, 0, static_cast<std::uint32_t>(nt)}};
  while (!work.empty()) {
    const Work job = work.back();
    work.pop_back();
    Node& node = node_at(job.slot);
    float clo[3] = {kInf, kInf, kInf}, chi[3] = {-kInf, -kInf, -kInf};
    for (int k = 0; k < 3; ++k) {
      node.lo[k] = kInf;
      node.hi[k] = -kInf;
    }
    for (std::uint32_t i = job.begin; i < job.end; ++i) {
      const Item& item = items[i];
      for (int k = 0; k < 3; ++k) {
        node.lo[k] = std::min(node.lo[k], item.lo[k]);
        node.hi[k] = std::max(node.hi[k], item.hi[k]);
        clo[k] = std::min(clo[k], item.centroid[k]);
        chi[k] = std::max(chi[k], item.centroid[k]);
      }
    }
    const std::uint32_t n = job.end - job.begin;
    if (n <= kLeafSize) {
      node.first = job.begin;
      node.count = n;
      continue;
    }
    int axis = 0;
    for (int k = 1; k < 3; ++k) {
      if (chi[k] - clo[k] > chi[axis] - clo[axis]) axis = k;
    }
    const std::uint32_t mid = job.begin + n / 2;
    std::nth_element(items.begin() + job.begin, items.begin() + mid, items.begin() + job.end,
                     [axis](const Item& x, const Item& y) {
                       return x.centroid[axis] != y.centroid[axis]
                                  ? x.centroid[axis] < y.centroid[axis]
                                  : x.index < y.index;
                     });
    const auto pair = static_cast<std::uint32_t>(pairs.size());
    pairs.emplace_back();  // may reallocate: `node` is not used after this point
    node_at(job.slot).first = pair;
    node_at(job.slot).count = 0;
    work.push_back(Work{pair * 2 + 1, mid, job.end});
    work.push_back(Work{pair * 2, job.begin, mid});
  }
  tris.resize(nt);
  for (std::uint32_t i = 0; i < nt; ++i) {
    const std::uint32_t t = items[i].index;
    const Triangle& tri = mesh.triangles[t];
    tris[i] = LeafTriangle{mesh.vertices[tri[0]], mesh.vertices[tri[1]], mesh.vertices[tri[2]], t};
  }
  build_normals(mesh);
}

void SurfaceDistance::Impl::build_normals(const Mesh& mesh) {
  // Pseudo-normals (Baerentzen and Aanaes 2005): the sign of p - q against the angle-weighted
  // vertex normal or the edge normal (sum of the adjacent face normals) is correct wherever the
  // closest point is a vertex or an edge, where a single face normal can give the wrong sign.
  const std::size_t nt = mesh.triangles.size();
  const std::size_t nv = mesh.vertices.size();
  face_normal.assign(nt, Vec3::Zero());
  vertex_normal.assign(nv, Vec3::Zero());
  for (std::size_t t = 0; t < nt; ++t) {
    const Triangle& tri = mesh.triangles[t];
    const Vec3 n = (mesh.vertices[tri[1]] - mesh.vertices[tri[0]])
                       .cross(mesh.vertices[tri[2]] - mesh.vertices[tri[0]]);
    const double len = n.norm();
    if (!(len > 0) || !std::isfinite(len)) continue;
    face_normal[t] = n / len;
    for (int k = 0; k < 3; ++k) {
      const Vec3 u = mesh.vertices[tri[(k + 1) % 3]] - mesh.vertices[tri[k]];
      const Vec3 w = mesh.vertices[tri[(k + 2) % 3]] - mesh.vertices[tri[k]];
      const double angle = std::atan2(u.cross(w).norm(), u.dot(w));
      vertex_normal[tri[k]] += angle * face_normal[t];
    }
  }
  // Edge normals: group half-edges by undirected edge with a counting sort on the smaller end.
  std::vector<std::uint32_t> bucket(nv + 1, 0);
  for (const Triangle& tri : mesh.triangles) {
    for (int k = 0; k < 3; ++k) ++bucket[std::min(tri[k], tri[(k + 1) % 3]) + 1];
  }
  for (std::size_t v = 0; v < nv; ++v) bucket[v + 1] += bucket[v];
  std::vector<std::pair<std::uint32_t, std::uint32_t>> entries(bucket[nv]);  // (larger end, he)
  {
    std::vector<std::uint32_t> fill(bucket.begin(), bucket.end() - 1);
    for (std::uint32_t t = 0; t < nt; ++t) {
      const Triangle& tri = mesh.triangles[t];
      for (std::uint32_t k = 0; k < 3; ++k) {
        const std::uint32_t u = tri[k], w = tri[(k + 1) % 3];
        entries[fill[std::min(u, w)]++] = {std::max(u, w), t * 3 + k};
      }
    }
  }
  edge_normal.assign(nt * 3, Vec3::Zero());
  for (std::size_t v = 0; v < nv; ++v) {
    const auto first = entries.begin() + bucket[v], last = entries.begin() + bucket[v + 1];
    std::sort(first, last);
    for (auto i = first; i != last;) {
      auto j = i + 1;
      while (j != last && j->first == i->first) ++j;
      Vec3 sum = Vec3::Zero();
      for (auto k = i; k != j; ++k) sum += face_normal[k->second / 3];
      for (auto k = i; k != j; ++k) {
        // Opposite orientations cancel (flipped neighbour): fall back to the own face normal.
        edge_normal[k->second] = sum.squaredNorm() > 1e-12 ? sum : face_normal[k->second / 3];
      }
      i = j;
    }
  }
}

ClosestPoint SurfaceDistance::Impl::nearest(const Vec3& p, std::uint32_t* triangle) const {
  ClosestPoint best{p, std::numeric_limits<double>::infinity(), Feature::kFace};
  std::uint32_t best_tri = kNone;
  // Stack of (box distance, node); the distance is kept so that a node pruned by a better
  // result found meanwhile is dropped without touching its memory. A median split is at most
  // ~32 levels deep for 32-bit counts and the stack holds at most one entry per level plus one.
  struct Entry {
    double dist_sq;
    const Node* node;
  };
  Entry stack[128];
  int top = 0;
  stack[top++] = Entry{root.dist_sq(p), &root};
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.dist_sq >= best.dist_sq) continue;
    const Node& node = *e.node;
    if (node.count > 0) {
      for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
        const LeafTriangle& t = tris[i];
        // The triangle's own box is a cheap, branch-free lower bound that rejects most of the
        // triangles of a visited leaf before the exact (branchy) closest-point computation.
        const Vec3 lo = t.a.cwiseMin(t.b).cwiseMin(t.c), hi = t.a.cwiseMax(t.b).cwiseMax(t.c);
        if ((lo - p).cwiseMax(p - hi).cwiseMax(0.0).squaredNorm() >= best.dist_sq) continue;
        const ClosestPoint c = closest_on_triangle(p, t.a, t.b, t.c);
        if (c.dist_sq < best.dist_sq) {
          best = c;
          best_tri = t.index;
        }
      }
      continue;
    }
    // Visit the nearer child first: push it last.
    const NodePair& pair = pairs[node.first];
    const double d0 = pair.child[0].dist_sq(p);
    const double d1 = pair.child[1].dist_sq(p);
    const bool first_near = d0 <= d1;
    const Entry near{first_near ? d0 : d1, &pair.child[first_near ? 0 : 1]};
    const Entry far{first_near ? d1 : d0, &pair.child[first_near ? 1 : 0]};
    if (far.dist_sq < best.dist_sq) stack[top++] = far;
    if (near.dist_sq < best.dist_sq) stack[top++] = near;
  }
  if (triangle != nullptr) *triangle = best_tri;
  return best;
}

SurfaceDistance::SurfaceDistance(const Mesh& surface) : impl_(std::make_unique<Impl>()) {
  impl_->build(surface);
}
SurfaceDistance::~SurfaceDistance() = default;
SurfaceDistance::SurfaceDistance(SurfaceDistance&&) noexcept = default;
SurfaceDistance& SurfaceDistance::operator=(SurfaceDistance&&) noexcept = default;

double SurfaceDistance::distance(const Vec3& p) const {
  return std::sqrt(impl_->nearest(p, nullptr).dist_sq);
}

double SurfaceDistance::signed_distance(const Vec3& p) const {
  std::uint32_t t = kNone;
  const ClosestPoint c = impl_->nearest(p, &t);
  const double d = std::sqrt(c.dist_sq);
  if (t == kNone || !(d > 0)) return d;
  Vec3 normal;
  switch (c.feature) {
    case Feature::kFace:
      normal = impl_->face_normal[t];
      break;
    case Feature::kEdge0:
    case Feature::kEdge1:
    case Feature::kEdge2:
      normal = impl_->edge_normal[t * 3 + (static_cast<int>(c.feature) -
                                           static_cast<int>(Feature::kEdge0))];
      break;
    default:
      normal = impl_->vertex_normal[impl_->triangles[t][static_cast<int>(c.feature) -
                                                        static_cast<int>(Feature::kVertex0)]];
      break;
  }
  return (p - c.point).dot(normal) < 0 ? -d : d;
}

DistanceStats stats_of(std::vector<double> values) {
  std::erase_if(values, [](double v) { return !std::isfinite(v); });
  DistanceStats s;
  s.count = values.size();
  if (values.empty()) return s;
  double sum = 0, sum_sq = 0, max = -std::numeric_limits<double>::infinity();
  for (double v : values) {
    sum += v;
    sum_sq += v * v;
    max = std::max(max, v);
  }
  const auto n = static_cast<double>(values.size());
  s.mean = sum / n;
  s.rms = std::sqrt(sum_sq / n);
  s.max = max;
  // Nearest-rank percentile: the smallest value with at least 95 % of the values <= it.
  const auto rank = static_cast<std::size_t>(std::ceil(0.95 * n));
  const auto nth = values.begin() + static_cast<std::ptrdiff_t>(std::max<std::size_t>(rank, 1) - 1);
  std::nth_element(values.begin(), nth, values.end());
  s.p95 = *nth;
  return s;
}

DistanceStats DeviationReport::hausdorff() const {
  DistanceStats h;
  h.count = mesh_to_ref.count + ref_to_mesh.count;
  if (h.count == 0) return h;
  const auto a = static_cast<double>(mesh_to_ref.count);
  const auto b = static_cast<double>(ref_to_mesh.count);
  const auto n = static_cast<double>(h.count);
  h.mean = (a * mesh_to_ref.mean + b * ref_to_mesh.mean) / n;
  h.rms = std::sqrt(
      (a * mesh_to_ref.rms * mesh_to_ref.rms + b * ref_to_mesh.rms * ref_to_mesh.rms) / n);
  h.p95 = std::max(mesh_to_ref.p95, ref_to_mesh.p95);  // an upper bound, not the joint p95
  h.max = std::max(mesh_to_ref.max, ref_to_mesh.max);
  return h;
}

namespace {

/// Unsigned distances from the samples of `from` (its referenced vertices, or all vertices when it
/// has no triangles, plus its triangle centroids) to `to`. `vertex_distance`, when given, holds
/// precomputed distances of from's vertices.
std::vector<double> sample_distances(const Mesh& from, const SurfaceDistance& to,
                                     const std::vector<double>* vertex_distance) {
  std::vector<char> use(from.vertices.size(), from.triangles.empty() ? 1 : 0);
  for (const Triangle& t : from.triangles) {
    for (std::uint32_t v : t) {
      if (v < use.size()) use[v] = 1;
    }
  }
  std::vector<double> out;
  out.reserve(from.vertices.size() + from.triangles.size());
  for (std::size_t v = 0; v < from.vertices.size(); ++v) {
    if (!use[v]) continue;
    out.push_back(vertex_distance != nullptr ? std::abs((*vertex_distance)[v])
                                             : to.distance(from.vertices[v]));
  }
  for (const Triangle& t : from.triangles) {
    if (t[0] >= from.vertices.size() || t[1] >= from.vertices.size() ||
        t[2] >= from.vertices.size()) {
      continue;
    }
    const Vec3 c = (from.vertices[t[0]] + from.vertices[t[1]] + from.vertices[t[2]]) / 3.0;
    out.push_back(to.distance(c));
  }
  return out;
}

}  // namespace

DeviationReport deviation(const Mesh& mesh, const Mesh& reference) {
  DeviationReport r;
  const SurfaceDistance to_ref(reference);
  r.vertex_signed_distance.resize(mesh.vertices.size());
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    r.vertex_signed_distance[v] = to_ref.signed_distance(mesh.vertices[v]);
  }
  r.mesh_to_ref = stats_of(sample_distances(mesh, to_ref, &r.vertex_signed_distance));
  // Without triangles the mesh has no surface to measure the reference against.
  if (!mesh.triangles.empty()) {
    const SurfaceDistance to_mesh(mesh);
    r.ref_to_mesh = stats_of(sample_distances(reference, to_mesh, nullptr));
  }
  return r;
}

}  // namespace scanmesh::recon
