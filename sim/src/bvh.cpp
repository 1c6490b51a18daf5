// Binned-SAH BVH build and stack-based traversal: nearest hit, any hit, sphere cast, closest point.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/bvh.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <string>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "scanmesh/common/error.hpp"

namespace scanmesh::sim {

using recon::Vec3;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// Barycentric slack: a ray through a shared edge hits at least one of its two triangles.
constexpr double kBaryEps = 1e-10;
/// Deeper than this the builder splits at the object median, which bounds the depth (and so the
/// traversal stack) for any input.
constexpr int kMaxSahDepth = 48;
/// Traversal stack: at most 3 entries per level plus a node's 4 (depth <= kMaxSahDepth + 32).
constexpr int kStackSize = 3 * (kMaxSahDepth + 40) + 8;
constexpr int kBins = 16;
constexpr std::uint32_t kMaxLeaf = 8;
constexpr double kTraversalCost = 1.0;  // relative to one triangle test

inline double dot3(const double* a, const double* b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
inline void cross3(const double* a, const double* b, double* out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}

struct Box {
  Vec3 lo = Vec3::Constant(kInf);
  Vec3 hi = Vec3::Constant(-kInf);
  void grow(const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void grow(const Box& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
  double half_area() const {
    if (!(hi.x() >= lo.x())) return 0;
    const Vec3 e = hi - lo;
    return e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
  }
};

/// Closest point to p on triangle abc (Ericson, Real-Time Collision Detection 5.1.5).
Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

/// A ray prepared for the single-precision slab tests of Node. The origin is moved outwards by
/// a margin (different for the entry and exit planes) larger than every rounding error of the
/// float computation, so a box is never missed: false positives only cost a little time.
struct RayF {
  alignas(16) float o_near[3][4];
  alignas(16) float o_far[3][4];
  alignas(16) float inv[3][4];
  int near_plane[3];  ///< plane index (0..5) of each axis' entry plane in Node::b
  int far_plane[3];
  /// `grow` extends every box by that much on each side (the sphere cast's radius).
  RayF(const Vec3& origin, const Vec3& dir, double max_abs, double grow = 0) {
    const double margin = 1e-6 * (origin.cwiseAbs().maxCoeff() + max_abs + grow) + 1e-30 + grow;
    for (int k = 0; k < 3; ++k) {
      const double d = dir[k];
      const double inv_d = std::abs(d) > 1e-20 ? 1.0 / d : std::copysign(1e20, d);
      const double sgn = inv_d >= 0 ? 1.0 : -1.0;
      // Entry plane: a larger (inv > 0) origin gives an earlier entry; exit: a later exit.
      for (int c = 0; c < 4; ++c) {
        inv[k][c] = static_cast<float>(inv_d);
        o_near[k][c] = static_cast<float>(origin[k] + sgn * margin);
        o_far[k][c] = static_cast<float>(origin[k] - sgn * margin);
      }
      near_plane[k] = inv_d >= 0 ? k : 3 + k;
      far_plane[k] = inv_d >= 0 ? 3 + k : k;
    }
  }
  /// Entry distances of the four children into tn; returns the mask of the children hit within
  /// [t0, t1] (bit c for child c).
  int test(const float* b, float t0, float t1, float tn[4]) const {
#if defined(__SSE2__)
    const __m128 nx =
        _mm_mul_ps(_mm_sub_ps(_mm_load_ps(b + 4 * near_plane[0]), _mm_load_ps(o_near[0])),
                   _mm_load_ps(inv[0]));
    const __m128 ny =
        _mm_mul_ps(_mm_sub_ps(_mm_load_ps(b + 4 * near_plane[1]), _mm_load_ps(o_near[1])),
                   _mm_load_ps(inv[1]));
    const __m128 nz =
        _mm_mul_ps(_mm_sub_ps(_mm_load_ps(b + 4 * near_plane[2]), _mm_load_ps(o_near[2])),
                   _mm_load_ps(inv[2]));
    const __m128 fx = _mm_mul_ps(
        _mm_sub_ps(_mm_load_ps(b + 4 * far_plane[0]), _mm_load_ps(o_far[0])), _mm_load_ps(inv[0]));
    const __m128 fy = _mm_mul_ps(
        _mm_sub_ps(_mm_load_ps(b + 4 * far_plane[1]), _mm_load_ps(o_far[1])), _mm_load_ps(inv[1]));
    const __m128 fz = _mm_mul_ps(
        _mm_sub_ps(_mm_load_ps(b + 4 * far_plane[2]), _mm_load_ps(o_far[2])), _mm_load_ps(inv[2]));
    const __m128 lo = _mm_max_ps(_mm_max_ps(nx, ny), _mm_max_ps(nz, _mm_set1_ps(t0)));
    const __m128 hi = _mm_min_ps(_mm_min_ps(fx, fy), _mm_min_ps(fz, _mm_set1_ps(t1)));
    _mm_storeu_ps(tn, lo);
    return _mm_movemask_ps(_mm_cmple_ps(lo, hi));
#else
    int mask = 0;
    for (int c = 0; c < 4; ++c) {
      float lo = t0, hi = t1;
      for (int k = 0; k < 3; ++k) {
        lo = std::max(lo, (b[4 * near_plane[k] + c] - o_near[k][c]) * inv[k][c]);
        hi = std::min(hi, (b[4 * far_plane[k] + c] - o_far[k][c]) * inv[k][c]);
      }
      tn[c] = lo;
      mask |= lo <= hi ? (1 << c) : 0;
    }
    return mask;
#endif
  }
};

/// The next float towards +infinity (finite f), without a libm call.
inline float next_up(float f) {
  if (f == 0) return std::numeric_limits<float>::denorm_min();
  const auto bits = std::bit_cast<std::uint32_t>(f);
  return std::bit_cast<float>(f > 0 ? bits + 1 : bits - 1);
}
inline float next_down(float f) { return -next_up(-f); }

/// The smallest float >= v (+infinity above the float range), and the largest float <= v.
inline float float_up(double v) {
  if (!(v < static_cast<double>(std::numeric_limits<float>::max())))
    return std::numeric_limits<float>::infinity();
  if (v < -static_cast<double>(std::numeric_limits<float>::max()))
    return -std::numeric_limits<float>::max();
  const float f = static_cast<float>(v);
  return static_cast<double>(f) < v ? next_up(f) : f;
}
inline float float_down(double v) {
  if (!(v > -static_cast<double>(std::numeric_limits<float>::max())))
    return -std::numeric_limits<float>::infinity();
  if (v > static_cast<double>(std::numeric_limits<float>::max()))
    return std::numeric_limits<float>::max();
  const float f = static_cast<float>(v);
  return static_cast<double>(f) > v ? next_down(f) : f;
}

/// Moeller-Trumbore, with one data-dependent branch (mispredicted branches dominate the cost
/// of a traversal). Returns t (or +inf on a miss) and the barycentrics.
inline double intersect_tri(const double* o, const double* d, const double* v0, const double* e1,
                            const double* e2, double& u_out, double& v_out) {
  double p[3];
  cross3(d, e2, p);
  const double det = dot3(e1, p);
  const double inv_det = 1.0 / det;  // +-inf for det == 0: u, v become nan or inf and fail
  const double s[3] = {o[0] - v0[0], o[1] - v0[1], o[2] - v0[2]};
  const double u = dot3(s, p) * inv_det;
  double q[3];
  cross3(s, e1, q);
  const double v = dot3(d, q) * inv_det;
  const double t = dot3(e2, q) * inv_det;
  const bool inside = (u >= -kBaryEps) & (v >= -kBaryEps) & (u + v <= 1 + kBaryEps) & (det != 0);
  if (!inside) return kInf;
  u_out = u;
  v_out = v;
  return t;
}

/// A pending child: node index or first triangle, triangle count (0: a node), entry distance.
struct StackEntry {
  std::uint32_t child;
  std::uint32_t count;
  float t;
};

/// The hit children of a node (mask) ordered near to far, at most four.
inline int sorted_children(int mask, const float tn[4], int order[4]) {
  int n = 0;
  for (int c = 0; c < 4; ++c) {
    if (!(mask & (1 << c))) continue;
    int j = n++;
    while (j > 0 && tn[order[j - 1]] > tn[c]) {
      order[j] = order[j - 1];
      --j;
    }
    order[j] = c;
  }
  return n;
}

}  // namespace

namespace detail {

struct BvhBuilder {
  struct Ref {
    Box box;
    Vec3 centroid;
    std::uint32_t id;
  };
  /// Binary build tree: interior nodes have count 0 and children left/right.
  struct BuildNode {
    Box box;
    std::uint32_t left = 0, right = 0;
    std::uint32_t first = 0, count = 0;
  };

  Bvh& bvh;
  std::vector<Ref> refs;
  std::vector<BuildNode> tree;

  std::uint32_t make_leaf(std::size_t begin, std::size_t end, const Box& box) {
    const auto index = static_cast<std::uint32_t>(tree.size());
    BuildNode n;
    n.box = box;
    n.first = static_cast<std::uint32_t>(begin);
    n.count = static_cast<std::uint32_t>(end - begin);
    tree.push_back(n);
    return index;
  }

  std::uint32_t build(std::size_t begin, std::size_t end, int depth) {
    Box box, cbox;
    for (std::size_t i = begin; i < end; ++i) {
      box.grow(refs[i].box);
      cbox.grow(refs[i].centroid);
    }
    const std::size_t count = end - begin;
    if (count <= 1) return make_leaf(begin, end, box);

    // Binned SAH over the axis with the cheapest split.
    int best_axis = -1;
    int best_bin = 0;
    double best_cost = kInf;
    if (depth < kMaxSahDepth) {
      for (int axis = 0; axis < 3; ++axis) {
        const double extent = cbox.hi[axis] - cbox.lo[axis];
        if (!(extent > 0)) continue;
        std::array<Box, kBins> bins;
        std::array<std::size_t, kBins> counts{};
        const double scale = kBins / extent;
        for (std::size_t i = begin; i < end; ++i) {
          int b = static_cast<int>((refs[i].centroid[axis] - cbox.lo[axis]) * scale);
          b = std::clamp(b, 0, kBins - 1);
          ++counts[static_cast<std::size_t>(b)];
          bins[static_cast<std::size_t>(b)].grow(refs[i].box);
        }
        std::array<double, kBins> right_cost{};
        Box acc;
        std::size_t n = 0;
        for (int b = kBins - 1; b > 0; --b) {
          acc.grow(bins[static_cast<std::size_t>(b)]);
          n += counts[static_cast<std::size_t>(b)];
          right_cost[static_cast<std::size_t>(b)] = acc.half_area() * static_cast<double>(n);
        }
        acc = Box{};
        n = 0;
        for (int b = 0; b < kBins - 1; ++b) {
          acc.grow(bins[static_cast<std::size_t>(b)]);
          n += counts[static_cast<std::size_t>(b)];
          const double cost = acc.half_area() * static_cast<double>(n) +
                              right_cost[static_cast<std::size_t>(b) + 1];
          if (n > 0 && n < count && cost < best_cost) {
            best_cost = cost;
            best_axis = axis;
            best_bin = b;
          }
        }
      }
    }
    const double area = box.half_area();
    const double leaf_cost = static_cast<double>(count);
    const double split_cost =
        area > 0 ? kTraversalCost + best_cost / area : static_cast<double>(count);
    std::size_t mid;
    if (best_axis >= 0 && (split_cost < leaf_cost || count > kMaxLeaf)) {
      const double lo = cbox.lo[best_axis];
      const double scale = kBins / (cbox.hi[best_axis] - lo);
      const auto it = std::partition(
          refs.begin() + static_cast<std::ptrdiff_t>(begin),
          refs.begin() + static_cast<std::ptrdiff_t>(end), [&](const Ref& r) {
            const int b =
                std::clamp(static_cast<int>((r.centroid[best_axis] - lo) * scale), 0, kBins - 1);
            return b <= best_bin;
          });
      mid = static_cast<std::size_t>(it - refs.begin());
    } else if (count > kMaxLeaf) {
      // No useful SAH split (coincident centroids, or too deep): object median on the widest
      // centroid axis, which always makes progress.
      int axis = 0;
      const Vec3 ext = cbox.hi - cbox.lo;
      if (ext.y() > ext[axis]) axis = 1;
      if (ext.z() > ext[axis]) axis = 2;
      mid = begin + count / 2;
      std::nth_element(refs.begin() + static_cast<std::ptrdiff_t>(begin),
                       refs.begin() + static_cast<std::ptrdiff_t>(mid),
                       refs.begin() + static_cast<std::ptrdiff_t>(end),
                       [axis](const Ref& a, const Ref& b) {
                         if (a.centroid[axis] != b.centroid[axis])
                           return a.centroid[axis] < b.centroid[axis];
                         return a.id < b.id;
                       });
    } else {
      return make_leaf(begin, end, box);
    }
    if (mid == begin || mid == end) mid = begin + count / 2;

    const std::uint32_t index = make_leaf(begin, end, box);  // becomes interior below
    const std::uint32_t left = build(begin, mid, depth + 1);
    const std::uint32_t right = build(mid, end, depth + 1);
    tree[index].left = left;
    tree[index].right = right;
    tree[index].count = 0;
    return index;
  }

  static void set_child(Bvh::Node& n, int c, const Box& box) {
    for (int k = 0; k < 3; ++k) {
      n.b[4 * k + c] = float_down(box.lo[k]);
      n.b[4 * (3 + k) + c] = float_up(box.hi[k]);
    }
  }
  static void set_empty(Bvh::Node& n, int c) {
    for (int k = 0; k < 3; ++k) {
      // Both bounds at +infinity: every slab test misses it, whatever the ray's direction.
      n.b[4 * k + c] = std::numeric_limits<float>::infinity();
      n.b[4 * (3 + k) + c] = std::numeric_limits<float>::infinity();
    }
    n.child[c] = 0;
    n.count[c] = 0;
  }

  /// Emits the four-child node for interior build node `bi` (depth first): its two children,
  /// repeatedly replacing the interior one with the largest surface by its own two children,
  /// until there are four. Returns the node's index.
  std::uint32_t emit(std::uint32_t bi) {
    std::uint32_t kids[4] = {tree[bi].left, tree[bi].right, 0, 0};
    int n = 2;
    while (n < 4) {
      int open = -1;
      double area = -1;
      for (int c = 0; c < n; ++c) {
        const BuildNode& k = tree[kids[c]];
        if (k.count == 0 && k.box.half_area() > area) {
          area = k.box.half_area();
          open = c;
        }
      }
      if (open < 0) break;
      const BuildNode& k = tree[kids[open]];
      kids[n++] = k.right;
      kids[open] = k.left;
    }
    const auto index = static_cast<std::uint32_t>(bvh.nodes_.size());
    bvh.nodes_.push_back(Bvh::Node{});
    for (int c = 0; c < 4; ++c) {
      if (c >= n) {
        set_empty(bvh.nodes_[index], c);
        continue;
      }
      const BuildNode& k = tree[kids[c]];
      set_child(bvh.nodes_[index], c, k.box);
      if (k.count > 0) {
        bvh.nodes_[index].child[c] = k.first;
        bvh.nodes_[index].count[c] = k.count;
      } else {
        const std::uint32_t child = emit(kids[c]);
        bvh.nodes_[index].child[c] = child;
        bvh.nodes_[index].count[c] = 0;
      }
    }
    return index;
  }
};

}  // namespace detail

Bvh::Bvh(const recon::Mesh& mesh) {
  normals_.assign(mesh.triangles.size(), Vec3::Zero());
  detail::BvhBuilder builder{*this, {}, {}};
  builder.refs.reserve(mesh.triangles.size());
  Box scene;
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& t = mesh.triangles[i];
    for (const auto v : t)
      if (v >= mesh.vertices.size())
        throw ConfigError("mesh triangle " + std::to_string(i) + " has vertex index " +
                          std::to_string(v) + " out of range (" +
                          std::to_string(mesh.vertices.size()) + " vertices)");
    const Vec3& a = mesh.vertices[t[0]];
    const Vec3& b = mesh.vertices[t[1]];
    const Vec3& c = mesh.vertices[t[2]];
    if (!a.allFinite() || !b.allFinite() || !c.allFinite())
      throw ConfigError("mesh triangle " + std::to_string(i) + " has a non-finite vertex");
    // The single-precision boxes need coordinates far inside the float range.
    constexpr double kMaxCoordinate = 1e15;
    if (std::max({a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff(), c.cwiseAbs().maxCoeff()}) >
        kMaxCoordinate)
      throw ConfigError("mesh triangle " + std::to_string(i) +
                        " has a vertex coordinate beyond 1e15 (mesh units)");
    const Vec3 n = (b - a).cross(c - a);
    const double len = n.norm();
    if (!(len > 0)) continue;  // degenerate: never hit
    normals_[i] = n / len;
    detail::BvhBuilder::Ref r;
    r.box.grow(a);
    r.box.grow(b);
    r.box.grow(c);
    r.centroid = (a + b + c) / 3.0;
    r.id = static_cast<std::uint32_t>(i);
    scene.grow(r.box);
    builder.refs.push_back(r);
  }
  lo_ = scene.lo;
  hi_ = scene.hi;
  if (builder.refs.empty()) return;
  max_abs_ = std::max(scene.lo.cwiseAbs().maxCoeff(), scene.hi.cwiseAbs().maxCoeff());
  builder.tree.reserve(2 * builder.refs.size());
  const std::uint32_t root = builder.build(0, builder.refs.size(), 0);
  nodes_.reserve(builder.refs.size() / 2 + 1);
  if (builder.tree[root].count > 0) {
    // A single leaf: wrap it in a node whose second child is an empty box (never entered).
    Node n{};
    detail::BvhBuilder::set_child(n, 0, builder.tree[root].box);
    for (int c = 1; c < 4; ++c) detail::BvhBuilder::set_empty(n, c);
    n.child[0] = builder.tree[root].first;
    n.count[0] = builder.tree[root].count;
    nodes_.push_back(n);
  } else {
    builder.emit(root);
  }
  tris_.reserve(builder.refs.size());
  for (const auto& r : builder.refs) {
    const auto& t = mesh.triangles[r.id];
    const Vec3& a = mesh.vertices[t[0]];
    const Vec3 e1 = mesh.vertices[t[1]] - a;
    const Vec3 e2 = mesh.vertices[t[2]] - a;
    Tri tri{};
    for (int k = 0; k < 3; ++k) {
      tri.v0[k] = a[k];
      tri.e1[k] = e1[k];
      tri.e2[k] = e2[k];
    }
    tri.id = r.id;
    tris_.push_back(tri);
  }
}

bool Bvh::intersect(const Vec3& origin, const Vec3& dir, double t_min, double t_max,
                    Hit& hit) const {
  if (nodes_.empty() || !(t_max >= t_min)) return false;
  const RayF ray(origin, dir, max_abs_);
  const double o[3] = {origin.x(), origin.y(), origin.z()};
  const double d[3] = {dir.x(), dir.y(), dir.z()};
  const float t0 = float_down(t_min);
  double best = t_max;
  float best_f = float_up(best);
  bool found = false;
  struct Entry {
    std::uint32_t child;
    std::uint32_t count;
    float t;
  };
  Entry stack[kStackSize];
  int sp = 0;
  // `cur` is a node (cur_count 0) or a leaf's triangle range. One hit child is entered
  // directly, of two the nearer (the other is pushed), of more the nearest (the rest pushed
  // farthest first): the fewest data-dependent branches, which dominate the cost.
  std::uint32_t cur = 0, cur_count = 0;
  for (;;) {
    if (cur_count > 0) {
      for (std::uint32_t i = cur; i < cur + cur_count; ++i) {
        const Tri& tri = tris_[i];
        double u = 0, v = 0;
        const double t = intersect_tri(o, d, tri.v0, tri.e1, tri.e2, u, v);
        if (t >= t_min && t <= best) {
          // Equal t (a ray through a shared edge): keep the lower triangle id, so the result
          // does not depend on the tree layout.
          if (t == best && found && tri.id > hit.triangle) continue;
          best = t;
          best_f = float_up(best);
          found = true;
          hit = Hit{t, tri.id, u, v};
        }
      }
    } else {
      const Node& n = nodes_[cur];
      alignas(16) float tn[4];
      int mask = ray.test(n.b, t0, best_f, tn);
      if (mask != 0) {
        const int c0 = __builtin_ctz(static_cast<unsigned>(mask));
        mask &= mask - 1;
        if (mask == 0) {
          cur = n.child[c0];
          cur_count = n.count[c0];
          continue;
        }
        const int c1 = __builtin_ctz(static_cast<unsigned>(mask));
        mask &= mask - 1;
        if (mask == 0) {
          const int nearc = tn[c1] < tn[c0] ? c1 : c0, farc = nearc == c0 ? c1 : c0;
          stack[sp++] = {n.child[farc], n.count[farc], tn[farc]};
          cur = n.child[nearc];
          cur_count = n.count[nearc];
          continue;
        }
        int order[4];
        const int k = sorted_children(mask | (1 << c0) | (1 << c1), tn, order);
        for (int j = k - 1; j >= 1; --j) {
          const int c = order[j];
          stack[sp++] = {n.child[c], n.count[c], tn[c]};
        }
        cur = n.child[order[0]];
        cur_count = n.count[order[0]];
        continue;
      }
    }
    // Pop, skipping subtrees the current best has made unreachable.
    for (;;) {
      if (sp == 0) return found;
      const Entry e = stack[--sp];
      if (e.t <= best_f) {
        cur = e.child;
        cur_count = e.count;
        break;
      }
    }
  }
}

bool Bvh::occluded(const Vec3& origin, const Vec3& dir, double t_min, double t_max) const {
  if (nodes_.empty() || !(t_max >= t_min)) return false;
  const RayF ray(origin, dir, max_abs_);
  const double o[3] = {origin.x(), origin.y(), origin.z()};
  const double d[3] = {dir.x(), dir.y(), dir.z()};
  const float t0 = float_down(t_min);
  const float t1 = float_up(t_max);
  struct Entry {
    std::uint32_t child;
    std::uint32_t count;
  };
  Entry stack[kStackSize];
  int sp = 0;
  std::uint32_t cur = 0, cur_count = 0;  // as in intersect(), without the ordering
  for (;;) {
    if (cur_count > 0) {
      for (std::uint32_t i = cur; i < cur + cur_count; ++i) {
        const Tri& tri = tris_[i];
        double u = 0, v = 0;
        const double t = intersect_tri(o, d, tri.v0, tri.e1, tri.e2, u, v);
        if (t >= t_min && t <= t_max) return true;
      }
    } else {
      const Node& n = nodes_[cur];
      alignas(16) float tn[4];
      int mask = ray.test(n.b, t0, t1, tn);
      if (mask != 0) {
        const int c0 = __builtin_ctz(static_cast<unsigned>(mask));
        mask &= mask - 1;
        while (mask != 0) {
          const int c = __builtin_ctz(static_cast<unsigned>(mask));
          mask &= mask - 1;
          stack[sp++] = {n.child[c], n.count[c]};
        }
        cur = n.child[c0];
        cur_count = n.count[c0];
        continue;
      }
    }
    if (sp == 0) return false;
    --sp;
    cur = stack[sp].child;
    cur_count = stack[sp].count;
  }
}

namespace {

/// First t in [0, t_max] at which a sphere (radius r) moving from c along unit d touches the
/// triangle (v0, v0 + e1, v0 + e2) with unit normal n; +inf if none.
double sphere_triangle(const Vec3& c, const Vec3& d, double r, const Vec3& a, const Vec3& e1,
                       const Vec3& e2, const Vec3& n, double t_max, Vec3& contact) {
  double best = kInf;
  auto inside = [&](const Vec3& p) {
    // Barycentric test of p (on the plane) against the triangle.
    const Vec3 w = p - a;
    const double d00 = e1.dot(e1), d01 = e1.dot(e2), d11 = e2.dot(e2);
    const double d20 = w.dot(e1), d21 = w.dot(e2);
    const double den = d00 * d11 - d01 * d01;
    const double v = (d11 * d20 - d01 * d21) / den;
    const double w2 = (d00 * d21 - d01 * d20) / den;
    return v >= -kBaryEps && w2 >= -kBaryEps && v + w2 <= 1 + kBaryEps;
  };
  // Face.
  const double dist0 = (c - a).dot(n);
  const double dn = d.dot(n);
  const double side = dist0 >= 0 ? 1.0 : -1.0;
  double tf = kInf;
  if (std::abs(dist0) <= r) {
    tf = 0;
  } else if (side * dn < 0) {
    tf = (std::abs(dist0) - r) / (-side * dn);
  }
  if (tf <= t_max) {
    const Vec3 p = c + d * tf - n * (side * r);
    const Vec3 on_plane = tf == 0 ? Vec3(c - n * dist0) : p;
    if (inside(on_plane)) {
      best = tf;
      contact = on_plane;
    }
  }
  // Edges (the side of an infinite cylinder, clamped to the segment).
  const Vec3 verts[3] = {a, a + e1, a + e2};
  for (int k = 0; k < 3; ++k) {
    const Vec3& p0 = verts[k];
    const Vec3 e = verts[(k + 1) % 3] - p0;
    const double ee = e.dot(e);
    const Vec3 m = c - p0;
    const Vec3 dp = d - e * (d.dot(e) / ee);
    const Vec3 mp = m - e * (m.dot(e) / ee);
    const double qa = dp.dot(dp), qb = 2 * mp.dot(dp), qc = mp.dot(mp) - r * r;
    double t;
    if (qc <= 0) {
      t = 0;
    } else {
      if (qa <= 0) continue;
      const double disc = qb * qb - 4 * qa * qc;
      if (disc < 0) continue;
      t = (-qb - std::sqrt(disc)) / (2 * qa);
      if (t < 0) continue;
    }
    if (t >= best || t > t_max) continue;
    const double s = (c + d * t - p0).dot(e) / ee;
    if (s < 0 || s > 1) continue;
    best = t;
    contact = p0 + e * s;
  }
  // Vertices.
  for (const Vec3& v : verts) {
    const Vec3 m = c - v;
    const double b = m.dot(d), cc = m.dot(m) - r * r;
    double t;
    if (cc <= 0) {
      t = 0;
    } else {
      const double disc = b * b - cc;
      if (disc < 0) continue;
      t = -b - std::sqrt(disc);
      if (t < 0) continue;
    }
    if (t < best && t <= t_max) {
      best = t;
      contact = v;
    }
  }
  return best;
}

}  // namespace

bool Bvh::sphere_cast(const Vec3& center, const Vec3& dir, double radius_mm, double t_max,
                      SphereHit& hit) const {
  if (nodes_.empty() || !(t_max >= 0)) return false;
  const RayF ray(center, dir, max_abs_, radius_mm);
  double best = t_max;
  bool found = false;
  StackEntry stack[kStackSize];
  int sp = 0;
  stack[sp++] = {0, 0, 0.0f};
  while (sp > 0) {
    const StackEntry e = stack[--sp];
    if (e.t > float_up(best)) continue;
    if (e.count > 0) {
      for (std::uint32_t i = e.child; i < e.child + e.count; ++i) {
        const Tri& tri = tris_[i];
        const Vec3 a(tri.v0[0], tri.v0[1], tri.v0[2]);
        const Vec3 e1(tri.e1[0], tri.e1[1], tri.e1[2]);
        const Vec3 e2(tri.e2[0], tri.e2[1], tri.e2[2]);
        Vec3 contact = Vec3::Zero();
        const double t =
            sphere_triangle(center, dir, radius_mm, a, e1, e2, normals_[tri.id], best, contact);
        if (t <= best && (!found || t < best || tri.id < hit.triangle)) {
          best = t;
          found = true;
          hit = SphereHit{t, contact, tri.id};
        }
      }
      continue;
    }
    const Node& n = nodes_[e.child];
    alignas(16) float tn[4];
    const int mask = ray.test(n.b, 0.0f, float_up(best), tn);
    int order[4];
    const int k = sorted_children(mask, tn, order);
    for (int j = k - 1; j >= 0; --j) {
      const int c = order[j];
      stack[sp++] = {n.child[c], n.count[c], tn[c]};
    }
  }
  return found;
}

Bvh::Closest Bvh::closest_point(const Vec3& p) const {
  Closest best;
  best.distance = kInf;
  if (nodes_.empty()) return best;
  double best_d2 = kInf;
  // Squared distance from p to child c's box: a lower bound (the float boxes contain the
  // exact ones).
  auto box_d2 = [&](const Node& n, int c) {
    double s = 0;
    for (int k = 0; k < 3; ++k) {
      const double lo = n.b[4 * k + c], hi = n.b[4 * (3 + k) + c];
      if (!(lo <= hi)) return kInf;  // unused slot
      const double e = std::max({lo - p[k], 0.0, p[k] - hi});
      s += e * e;
    }
    return s;
  };
  struct Entry {
    std::uint32_t child;
    std::uint32_t count;
    double d2;
  };
  Entry stack[kStackSize];
  int sp = 0;
  stack[sp++] = {0, 0, 0.0};
  while (sp > 0) {
    const Entry e = stack[--sp];
    if (e.d2 > best_d2) continue;
    if (e.count > 0) {
      for (std::uint32_t i = e.child; i < e.child + e.count; ++i) {
        const Tri& tri = tris_[i];
        const Vec3 a(tri.v0[0], tri.v0[1], tri.v0[2]);
        const Vec3 b = a + Vec3(tri.e1[0], tri.e1[1], tri.e1[2]);
        const Vec3 c = a + Vec3(tri.e2[0], tri.e2[1], tri.e2[2]);
        const Vec3 q = closest_on_triangle(p, a, b, c);
        const double d2 = (q - p).squaredNorm();
        if (d2 < best_d2) {
          best_d2 = d2;
          best.point = q;
          best.triangle = tri.id;
        }
      }
      continue;
    }
    const Node& n = nodes_[e.child];
    double d[4];
    int order[4];
    int k = 0;
    for (int c = 0; c < 4; ++c) {
      d[c] = box_d2(n, c);
      if (!(d[c] <= best_d2)) continue;
      int j = k++;
      while (j > 0 && d[order[j - 1]] > d[c]) {
        order[j] = order[j - 1];
        --j;
      }
      order[j] = c;
    }
    for (int j = k - 1; j >= 0; --j) {
      const int c = order[j];
      stack[sp++] = {n.child[c], n.count[c], d[c]};
    }
  }
  best.distance = std::sqrt(best_d2);
  return best;
}

}  // namespace scanmesh::sim
