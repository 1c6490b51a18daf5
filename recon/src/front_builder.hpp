// Internal to recon: the advancing front's Builder (declaration, front bookkeeping, helpers),
// whose member functions live in front*.cpp by responsibility.
// SPDX-License-Identifier: MIT
#pragma once
#include "scanmesh/recon/front.hpp"

#include "scanmesh/recon/intersections.hpp"
#include "box_bins.hpp"
#include "bulk.hpp"
#include "loop_measure.hpp"
#include "triangle_components.hpp"
#include "triangle_shape.hpp"
#include "vertex_triangles.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>
#include <deque>
#include <queue>

namespace scanmesh::recon::front_impl {

constexpr std::uint32_t kNone = 0xffffffffu;
constexpr std::uint32_t kInterior = 0xfffffffeu;  // edge-map value: edge of two triangles
constexpr double kPi = std::numbers::pi;

/// Undirected edge -> front edge id (when the edge is on the front) or kInterior.
/// Open addressing with linear probing; the table is sized to the expected number of edges at
/// a load of at most 0.8 (no power-of-two rounding, which cost up to twice the memory: it is
/// the front's largest structure, 12 bytes per slot).
class EdgeMap {
 public:
  explicit EdgeMap(std::size_t expected) { rehash(capacity_for(expected)); }
  std::uint32_t* find(std::uint32_t u, std::uint32_t v) {
    const std::uint64_t k = key(u, v);
    std::size_t h = hash(k);
    while (vals_[h] != kNone) {
      if (keys_[h] == k) return &vals_[h];
      if (++h == cap_) h = 0;
    }
    return nullptr;
  }
  /// Removes the edge if present (backward-shift deletion: no tombstones).
  void erase(std::uint32_t u, std::uint32_t v) {
    const std::uint64_t k = key(u, v);
    std::size_t i = hash(k);
    while (vals_[i] != kNone && keys_[i] != k)
      if (++i == cap_) i = 0;
    if (vals_[i] == kNone) return;
    std::size_t j = i;
    while (true) {
      if (++j == cap_) j = 0;
      if (vals_[j] == kNone) break;
      const std::size_t h = hash(keys_[j]);
      // The entry at j may move back to the hole at i unless its home lies in (i, j].
      const bool stays = i <= j ? (i < h && h <= j) : (i < h || h <= j);
      if (stays) continue;
      keys_[i] = keys_[j];
      vals_[i] = vals_[j];
      i = j;
    }
    vals_[i] = kNone;
    --size_;
  }
  void insert(std::uint32_t u, std::uint32_t v, std::uint32_t val) {
    if ((size_ + 1) * 5 > cap_ * 4) rehash(capacity_for(cap_ * 3 / 2));
    const std::uint64_t k = key(u, v);
    std::size_t h = hash(k);
    while (vals_[h] != kNone) {
      if (keys_[h] == k) {
        vals_[h] = val;
        return;
      }
      if (++h == cap_) h = 0;
    }
    keys_[h] = k;
    vals_[h] = val;
    ++size_;
  }

 private:
  static std::size_t capacity_for(std::size_t expected) {
    return std::max<std::size_t>(64, expected + expected / 4 + 1);
  }
  static std::uint64_t key(std::uint32_t u, std::uint32_t v) {
    return u < v ? (std::uint64_t{u} << 32) | v : (std::uint64_t{v} << 32) | u;
  }
  /// Fibonacci hashing mapped onto [0, cap) by a multiply-high (any capacity, no modulo).
  [[nodiscard]] std::size_t hash(std::uint64_t k) const {
    __extension__ using U128 = unsigned __int128;  // GCC/Clang; __extension__: -Wpedantic
    const U128 m = static_cast<U128>(k * 0x9E3779B97F4A7C15ull) * cap_;
    return static_cast<std::size_t>(m >> 64);
  }
  void rehash(std::size_t cap) {
    std::vector<std::uint64_t> old_keys = std::move(keys_);
    std::vector<std::uint32_t> old_vals = std::move(vals_);
    keys_.assign(cap, 0);
    vals_.assign(cap, kNone);
    cap_ = cap;
    for (std::size_t i = 0; i < old_keys.size(); ++i) {
      if (old_vals[i] == kNone) continue;
      std::size_t h = hash(old_keys[i]);
      while (vals_[h] != kNone)
        if (++h == cap_) h = 0;
      keys_[h] = old_keys[i];
      vals_[h] = old_vals[i];
    }
  }
  std::vector<std::uint64_t> keys_;
  std::vector<std::uint32_t> vals_;
  std::size_t cap_ = 0, size_ = 0;
};

/// The triangles around a few vertices `vs` (ascending), in triangle order: those of vs[c] are
/// list[start[c]] .. list[start[c + 1] - 1]. One pass over the triangles; `marked` is an
/// all-zero scratch array with one entry per vertex, left all zero.
struct SomeVertexTriangles {
  std::vector<std::uint32_t> start, list;

  SomeVertexTriangles(const std::vector<std::uint32_t>& vs, const std::vector<Triangle>& tris,
                      std::vector<std::uint8_t>& marked) {
    for (std::uint32_t v : vs) marked[v] = 1;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> corners;  // (vertex, triangle)
    for (std::uint32_t t = 0; t < tris.size(); ++t) {
      const Triangle& tri = tris[t];
      if ((marked[tri[0]] | marked[tri[1]] | marked[tri[2]]) == 0) continue;  // nearly all
      for (std::uint32_t v : tri)
        if (marked[v]) corners.emplace_back(v, t);
    }
    for (std::uint32_t v : vs) marked[v] = 0;
    std::sort(corners.begin(), corners.end());
    start.assign(vs.size() + 1, 0);
    list.resize(corners.size());
    std::size_t k = 0;
    for (std::size_t c = 0; c < vs.size(); ++c) {
      while (k < corners.size() && corners[k].first == vs[c]) {
        list[k] = corners[k].second;
        ++k;
      }
      start[c + 1] = static_cast<std::uint32_t>(k);
    }
  }
};

struct FrontEdge {
  std::uint32_t a, b;      // directed a -> b, mesh on the left
  std::uint32_t opp;       // third vertex of the triangle behind the edge
  std::uint32_t prev, next;  // neighbours along the front loop
  std::uint32_t next_out;    // next outgoing front edge of vertex a
  std::uint32_t stamp;       // bumped on every (re)queue; stale heap entries are skipped
  bool alive;
  // Modes (bit 0 strict, bit 1 relaxed) in which this edge found no candidate at all, valid
  // while no_candidate_gen equals the builder's candidate generation (see Builder::process).
  std::uint8_t no_candidate;
  std::uint16_t no_candidate_gen;
};

struct QueueItem {
  float key;
  std::uint32_t edge, stamp;
  /// Smallest key first, then lowest edge id, then newest stamp: a total order, so the run
  /// does not depend on how the heap breaks ties.
  bool operator>(const QueueItem& o) const {
    if (key != o.key) return key > o.key;
    return edge != o.edge ? edge > o.edge : stamp < o.stamp;
  }
};

/// A monotone stand-in for the counter-clockwise angle from u to w around the unit normal n:
/// the "diamond angle" of the (unnormalised) cosine and sine, in [0, 4): 0 = 0 degrees,
/// 1 = 90, 2 = 180, 3 = 270. Sector tests and the queue order need only the order of angles,
/// so this replaces atan2 (and every square root) on the front's hottest path.
inline double ccw_turn(const Vec3& u, const Vec3& w, const Vec3& n) {
  // Components in the plane normal to n: n . (u_p x w_p) = n . (u x w) and
  // u_p . w_p = u . w - (u . n)(w . n).
  const double x = u.dot(w) - u.dot(n) * w.dot(n);
  const double y = n.dot(u.cross(w));
  if (y >= 0) return x >= 0 ? (x + y > 0 ? y / (x + y) : 0.0) : 1.0 - x / (y - x);
  return x < 0 ? 2.0 - y / (-x - y) : 3.0 + x / (x - y);
}

/// ccw_turn of an angle given in degrees, in [0, 360).
inline double turn_of_degrees(double deg) {
  const double r = deg * kPi / 180;
  return ccw_turn(Vec3(1, 0, 0), Vec3(std::cos(r), std::sin(r), 0), Vec3(0, 0, 1));
}

/// Orientation of (p, q, r) in the plane with normal n: > 0 counter-clockwise.
inline double orient(const Vec3& p, const Vec3& q, const Vec3& r, const Vec3& n) {
  return n.dot((q - p).cross(r - p));
}

/// Whether segments p1-p2 and q1-q2 (no common end point) cross or touch, seen in the plane
/// with normal n. Touching counts: an end point within `clear` of the other segment, or
/// collinear segments that overlap. Raw range scans have points exactly on one line (a scan
/// line), and a triangle whose edge runs through a front vertex, or whose apex sits on a front
/// edge, overlaps the triangles there as soon as the surface is not exactly flat (bun000: 3 such
/// pairs with strict signs). `clear` is a distance: a few float roundings of the coordinates, so
/// that a configuration that only just misses does not touch once written as float (STL, PLY).
inline bool segments_meet(const Vec3& p1, const Vec3& p2, const Vec3& q1, const Vec3& q2, const Vec3& n,
                   double clear) {
  // orient(q1, q2, x) is |q2 - q1| times the signed distance of x from that line: compared in
  // squares, so that the hot path takes no square root.
  const double c2 = clear * clear;
  auto sign = [](double d, double tol2) { return d * d <= tol2 ? 0 : (d > 0 ? 1 : -1); };
  const double lq2 = (q2 - q1).squaredNorm(), tq2 = c2 * lq2;
  const int s1 = sign(orient(q1, q2, p1, n), tq2), s2 = sign(orient(q1, q2, p2, n), tq2);
  if (s1 * s2 > 0) return false;
  const double lp2 = (p2 - p1).squaredNorm(), tp2 = c2 * lp2;
  const int s3 = sign(orient(p1, p2, q1, n), tp2), s4 = sign(orient(p1, p2, q2, n), tp2);
  if (s3 * s4 > 0) return false;
  if (s1 != 0 || s2 != 0 || s3 != 0 || s4 != 0) return true;
  // collinear: do the intervals along p1-p2 overlap (by more than the clearance)?
  const Vec3 u = p2 - p1;
  const double t1 = (q1 - p1).dot(u), t2 = (q2 - p1).dot(u), tp = clear * std::sqrt(lp2);
  return std::max(t1, t2) > tp && std::min(t1, t2) < lp2 - tp;
}

class Builder {
 public:
  Builder(std::span<const Vec3> pts, const LocalFrames& frames, const PointGrid& grid,
          const FrontOptions& opt, const StageObserver& observer,
          const detail::FrontContext* context = nullptr)
      : p_(pts), f_(frames), grid_(grid), opt_(opt), observer_(observer),
        edges_map_(pts.size() * 3) {
    ctx_ = context;
    if (ctx_ != nullptr) {
      ctx_keys_.reserve(ctx_->triangles.size());
      for (const Triangle& t : ctx_->triangles) ctx_keys_.push_back(canonical(t));
      std::sort(ctx_keys_.begin(), ctx_keys_.end());
    }
    step("front/setup");
    const std::size_t n = pts.size();
    state_.assign(n, VertexState::kFree);
    slot_state_.assign(n, VertexState::kFree);
    slot_of_.resize(n);
    {
      const std::vector<std::uint32_t>& order = grid.order();
      for (std::uint32_t s = 0; s < order.size(); ++s) slot_of_[order[s]] = s;
    }
    head_out_.assign(n, kNone);
    valence_.assign(n, 0);
    covered_.assign(n, 0);
    tris_.reserve(n * 2 + 16);
    cos_normal_ = std::cos(opt.max_normal_deviation_deg * kPi / 180);
    if (n > 0) {
      std::vector<float> sp = frames.spacing;
      auto mid = sp.begin() + static_cast<std::ptrdiff_t>(sp.size() / 2);
      std::nth_element(sp.begin(), mid, sp.end());
      cap_spacing(static_cast<double>(*mid));
      // Long triangles (crosses_mesh): longer than the relaxed pass makes where the sampling
      // is as dense as its densest twentieth (a dense part may be few of the points).
      const auto low = sp.begin() + static_cast<std::ptrdiff_t>(sp.size() / 20);
      std::nth_element(sp.begin(), low, mid);
      const double long_edge = opt.relaxed_radius_factor * 1.5 * static_cast<double>(*low);
      long_edge2_ = long_edge * long_edge;
      long_bins_.reset(long_edge);
      // Clearance of the front-edge tests: 8 float roundings (2^-24 relative) of the largest
      // coordinate, so that no vertex that just misses an edge lands on it in a float file; at
      // most 1e-3 of the median spacing (a cloud far from the origin, which a float file cannot
      // hold to its spacing anyway, must not lose triangles to it).
      double extent = 0;
      for (const Vec3& q : pts) extent = std::max(extent, q.cwiseAbs().maxCoeff());
      clear_ = std::min(8.0 * 0x1.0p-24 * extent, 1e-3 * static_cast<double>(*mid));
    }
    if (opt_.crossing_guard) {
      step("front/turning");
      mark_turning_points();
      corner_head_.assign(n, kNone);
      slot_listed_.assign(n, 0);
    }
  }

  FrontResult run();

 private:
  // --- continuation of an existing mesh (detail::FrontContext) -----------------------------
  const detail::FrontContext* ctx_ = nullptr;
  std::vector<Triangle> ctx_keys_;  // the context's triangles, canonical, sorted
  /// The rotation of t that starts at its smallest vertex (orientation kept).
  static Triangle canonical(const Triangle& t) {
    const int k = t[0] < t[1] ? (t[0] < t[2] ? 0 : 2) : (t[1] < t[2] ? 1 : 2);
    return {t[k], t[(k + 1) % 3], t[(k + 2) % 3]};
  }
  [[nodiscard]] bool from_context(const Triangle& t) const {
    return ctx_ != nullptr && std::binary_search(ctx_keys_.begin(), ctx_keys_.end(), canonical(t));
  }
  /// Whether a new triangle may have these corners: one at least is active (always, without a
  /// context).
  [[nodiscard]] bool allowed(std::uint32_t a, std::uint32_t b, std::uint32_t c) const {
    return ctx_ == nullptr || ctx_->active[a] != 0 || ctx_->active[b] != 0 || ctx_->active[c] != 0;
  }
  /// Adds the context's triangles to the mesh (after the bulk's) and makes the front of both.
  void load_context();

  struct Candidate {
    double score;
    std::uint32_t p;
  };
  struct Mode {
    double radius_factor, cos_min_angle, cos_dihedral;
    bool second_chance;  // valid() may take a feature point for the other face (feature_fits)
    std::uint8_t bit;    // this mode's bit in FrontEdge::no_candidate
  };

  // --- front bookkeeping -------------------------------------------------------------------
  std::uint32_t new_edge(std::uint32_t a, std::uint32_t b, std::uint32_t opp) {
    std::uint32_t id;
    if (!free_edges_.empty()) {
      id = free_edges_.back();
      free_edges_.pop_back();
    } else {
      id = static_cast<std::uint32_t>(edges_.size());
      edges_.emplace_back();
    }
    FrontEdge& e = edges_[id];
    // Known quirk, kept on purpose for now: the stamp restarts at 0 in a reused slot, so a queue
    // entry left by the slot's previous edge can match the new edge and run it ahead of its
    // turn (about a third of all evaluations on the bunny). Carrying the stamp on (the clean
    // fix) was measured worse: bun000 98.9% used instead of 99.2%, the casting genus 21; a
    // strict retry or a depth-first wave did not recover it. The early runs of new edges act
    // as an ordering heuristic that a principled order has to match before this is changed.
    e = FrontEdge{a, b, opp, kNone, kNone, head_out_[a], 0, true, 0, 0};
    if (id < hole_mark_.size()) hole_mark_[id] = 0;  // a reused slot: see add_triangle
    head_out_[a] = id;
    edges_map_.insert(a, b, id);
    return id;
  }
  void kill_edge(std::uint32_t id) {
    FrontEdge& e = edges_[id];
    // unlink from a's outgoing list
    std::uint32_t* link = &head_out_[e.a];
    while (*link != id) link = &edges_[*link].next_out;
    *link = e.next_out;
    e.alive = false;
    ++e.stamp;
    free_edges_.push_back(id);
  }
  /// Every state change during the growth goes through here: the candidate scan reads the
  /// states in grid slot order (slot_state_), the rest by point.
  void set_state(std::uint32_t v, VertexState st) {
    state_[v] = st;
    slot_state_[slot_of_[v]] = st;
  }
  void update_state(std::uint32_t v) {
    set_state(v, head_out_[v] == kNone ? VertexState::kDone : VertexState::kFront);
    if (state_[v] == VertexState::kDone && !corner_head_.empty() && turning_[v] == 0) release_corners(v);
  }
  [[nodiscard]] Vec3 tri_normal(std::uint32_t a, std::uint32_t b, std::uint32_t c) const {
    return (p_[b] - p_[a]).cross(p_[c] - p_[a]);
  }
  /// Cosine of the smallest interior angle of triangle (a, b, c) (1 when degenerate).
  [[nodiscard]] double min_angle_cos(std::uint32_t a, std::uint32_t b, std::uint32_t c) const {
    return detail::min_angle_cos(p_[a], p_[b], p_[c]);
  }
  [[nodiscard]] Vec3 edge_normal(const FrontEdge& e) const {
    return tri_normal(e.a, e.b, e.opp).normalized();
  }
  /// PCA normal of v turned to the side of `ref`.
  [[nodiscard]] Vec3 vnormal(std::uint32_t v, const Vec3& ref) const {
    Vec3 n = f_.normal[v].cast<double>();
    return n.dot(ref) < 0 ? -n : n;
  }
  /// Local spacing, capped (cap_spacing) so that a point much sparser than its surroundings
  /// (a stray reading) cannot pull long triangles.
  [[nodiscard]] double spacing(std::uint32_t v) const { return sp_[v]; }
  void cap_spacing(double median);

  /// Unmeshed angle at the end vertex b of edge e (between e and its successor), as ccw_turn.
  [[nodiscard]] double front_turn_at_end(std::uint32_t eid) const {
    const FrontEdge& e = edges_[eid];
    const FrontEdge& n = edges_[e.next];
    const Vec3 nb = vnormal(e.b, tri_normal(e.a, e.b, e.opp));
    return ccw_turn(p_[e.a] - p_[e.b], p_[n.b] - p_[e.b], nb);
  }
  void push(std::uint32_t eid) { push_touched(&eid, 1); }
  /// Starts a front just made from the triangles (its edges, edge table and valences): links
  /// every edge to the outgoing edge at its end (each vertex has one fan, hence at most one
  /// outgoing edge), sets the states of the vertices in triangles, queues every edge and
  /// rebuilds the corner lists. Shared by rebuild_front and the bulk's load.
  void start_front() {
    for (std::uint32_t id = 0; id < edges_.size(); ++id) {
      const std::uint32_t nx = head_out_[edges_[id].b];
      edges_[id].next = nx;
      edges_[nx].prev = id;
    }
    for (std::uint32_t v = 0; v < state_.size(); ++v)
      if (valence_[v] != 0) update_state(v);
    for (std::uint32_t id = 0; id < edges_.size(); ++id) push(id);
    rebuild_corner_lists();
  }
  /// Queues several edges (those a new triangle touched): neighbours share end points, so each
  /// end turn is computed once (an edge's key needs the turns at both of its ends).
  void push_touched(const std::uint32_t* ids, std::size_t count) {
    std::uint32_t memo_id[8];
    double memo_turn[8];
    std::size_t memo = 0;
    auto turn_at_end = [&](std::uint32_t id) {
      for (std::size_t k = 0; k < memo; ++k)
        if (memo_id[k] == id) return memo_turn[k];
      const double t = front_turn_at_end(id);
      if (memo < 8) {
        memo_id[memo] = id;
        memo_turn[memo++] = t;
      }
      return t;
    };
    for (std::size_t i = 0; i < count; ++i) {
      const FrontEdge& e = edges_[ids[i]];
      if (!e.alive) continue;
      enqueue(ids[i], std::min(turn_at_end(ids[i]), turn_at_end(e.prev)));
    }
  }
  void enqueue(std::uint32_t eid, double turn) {
    FrontEdge& e = edges_[eid];
    ++e.stamp;
    if (turn < ear_turn_) {
      ears_.push(QueueItem{static_cast<float>(turn), eid, e.stamp});
    } else {
      wave_.push_back(QueueItem{0.0f, eid, e.stamp});
    }
  }

  /// Debug check of the front invariants: loops closed and linked both ways, out-lists and the
  /// edge map agree with the alive edges. O(front size): debug builds run it after every step.
  void check_front() const {
#ifndef NDEBUG
    for (std::uint32_t id = 0; id < edges_.size(); ++id) {
      const FrontEdge& e = edges_[id];
      if (!e.alive) continue;
      assert(edges_[e.next].alive && edges_[e.prev].alive);
      assert(edges_[e.next].prev == id && edges_[e.prev].next == id);
      assert(edges_[e.next].a == e.b);
      bool listed = false;
      for (std::uint32_t o = head_out_[e.a]; o != kNone; o = edges_[o].next_out) listed |= o == id;
      assert(listed);
      assert(*const_cast<EdgeMap&>(edges_map_).find(e.a, e.b) == id);
      (void)listed;
    }
#endif
  }
  /// Debug check that the scan's slot-ordered states mirror the states (set_state), and the
  /// per-slot list flags the lists; O(points): after every triangle on small clouds, at the end
  /// of every growth on all.
  void check_slot_states() const {
#ifndef NDEBUG
    for (std::uint32_t v = 0; v < state_.size(); ++v) assert(slot_state_[slot_of_[v]] == state_[v]);
    for (std::uint32_t v = 0; v < corner_head_.size(); ++v)
      assert((slot_listed_[slot_of_[v]] != 0) == (corner_head_[v] != kNone));
#endif
  }

  // --- growth --------------------------------------------------------------------------------
  bool try_seed(std::uint32_t s);
  bool process(std::uint32_t eid, const Mode& mode);
  /// Whether the front loop through edge `start` has at most fill_max_edges edges and does not
  /// pass through v.
  [[nodiscard]] bool small_loop(std::uint32_t start, std::uint32_t v) const;
  bool valid(std::uint32_t eid, std::uint32_t p, const Vec3& n1, double radius,
             bool second_chance);
  [[nodiscard]] bool feature_fits(std::uint32_t a, std::uint32_t b, std::uint32_t p,
                                  const Vec3& n1) const;
  [[nodiscard]] bool closes_empty_triangle(std::uint32_t u, std::uint32_t w,
                                           std::uint32_t third);
  void add_triangle(std::uint32_t eid, std::uint32_t p);
  void grow();
  void fill_small_loops();
  /// Marks the edges of the deferred edges' loops that are real holes (hole_mark_ 2), for the
  /// relaxed pass over `batch` (FrontOptions::keep_holes).
  void mark_hole_loops(const std::vector<std::uint32_t>& batch);
  std::vector<std::uint8_t> hole_mark_;       // per edge id: 0, 1 visited, 2 on a hole
  std::vector<std::uint32_t> hole_visited_;   // the ids marked, cleared on the next pass
  /// A loop is surrounded by the mesh when the cosine between its vector area and its
  /// vertices' summed normals is at most this (measured: the bunny's holes -0.69 to -0.95,
  /// raw scans' borders +0.96 to +1; the unscanned tops of rotary scans about -0.6).
  static constexpr double kHoleWinding = -0.3;
  /// Triangulates the bulk (bulk.hpp) and loads the front along its borders (run grows it).
  void grow_from_bulk();
  /// Whether the m triangles `ids` around v form one fan, walking across shared edges in the
  /// orientation of the first (false: not shown this way, which proves nothing).
  [[nodiscard]] bool one_oriented_fan(std::uint32_t v, const std::uint32_t* ids, std::uint32_t m) const {
    if (m > 64) return false;
    auto corners = [&](std::uint32_t id, std::uint32_t& next, std::uint32_t& prev) {
      const Triangle& t = tris_[id];
      const std::size_t k = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
      next = t[(k + 1) % 3];
      prev = t[(k + 2) % 3];
    };
    std::uint64_t visited = 1;  // triangle i: bit i
    std::uint32_t first_next = 0, first_prev = 0;
    corners(ids[0], first_next, first_prev);
    // Steps from `cur` to an unvisited triangle whose `from` corner is cur; returns its other
    // corner, or kNone.
    auto step = [&](std::uint32_t cur, bool forwards) {
      for (std::uint32_t i = 1; i < m; ++i) {
        if (visited >> i & 1u) continue;
        std::uint32_t nx = 0, pv = 0;
        corners(ids[i], nx, pv);
        if ((forwards ? pv : nx) == cur) {
          visited |= std::uint64_t{1} << i;
          return forwards ? nx : pv;
        }
      }
      return kNone;
    };
    for (std::uint32_t cur = first_next; cur != kNone && cur != first_prev;) cur = step(cur, true);
    for (std::uint32_t cur = first_prev; cur != kNone && cur != first_next;) cur = step(cur, false);
    return visited == (m == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << m) - 1);
  }
  /// Keeps the largest fan of every multi-fan vertex. thorough: examine every vertex, not only
  /// those the front shows with two open sectors (a vertex where two closed fans touch has no
  /// front edge at all).
  std::size_t repair_fans(bool thorough = false);
  /// Number of fans of v's m triangles ids[0..m) (union-find in `fan`, sizes in `size`).
  std::size_t fans_of(std::uint32_t v, const std::uint32_t* ids, std::uint32_t m,
                      std::vector<int>& fan, std::vector<std::uint32_t>& size) const;
  void check_bulk_fans() const;
  void orient_components(detail::TriangleComponents& components);
  /// Removes every smaller component that crosses another component (see the definition).
  void drop_crossing_components();
  /// Before whole components are erased from tris_ (the others move down): the candidates'
  /// no-candidate marks are forgotten, and later fan checks look at every vertex.
  void triangles_moved() {
    forget_no_candidates();
    bulk_kept_ = 0;
    fan_dirty_.clear();
  }
  bool drop_specks(detail::TriangleComponents& components);
  void rebuild_front();
  /// Replaces the front around the corners of `removed` (triangles repair_fans dropped).
  void update_front_after_removal(const std::vector<Triangle>& removed,
                                  std::vector<std::uint8_t>& marked);
  void split_flat_triangle_holes();

  // --- crossing guard (the new triangle must not cross or overlap the mesh) ---------------
  // A new triangle is tested against the triangles around its own corners (their fans), and,
  // where the surface turns back within reach (a thin wall, a sharp edge: `turning_`) or the
  // front-edge tests could not see part of the front near it, against every triangle near it.
  // The triangles around each vertex are linked lists in a recycled pool; a vertex whose fan has
  // closed gives its list back unless it is a turning point (a closed fan cannot take new
  // triangles, and away from turning points no new triangle reaches it except over the front).
  void mark_turning_points();
  void push_triangle(const Triangle& t);
  void mark_bent(const Triangle& t);
  /// Marks the points within r of c that are not turning points as near-turning (2).
  void mark_near_turning(const Vec3& c, double r);
  void link_corner(std::uint32_t v, std::uint32_t tri);
  void release_corners(std::uint32_t v);
  void rebuild_corner_lists();
  [[nodiscard]] bool keeps_list(std::uint32_t v) const {
    return turning_[v] != 0 || state_[v] != VertexState::kDone;
  }
  [[nodiscard]] bool turning(const Triangle& t) const {
    return (turning_[t[0]] | turning_[t[1]] | turning_[t[2]]) != 0;
  }
  /// Whether t crosses a triangle around one of its corners (other than across a shared edge).
  /// The guard itself: near a turning point crosses_mesh (which covers the fans), elsewhere
  /// crosses_fans unless `flat` (the corners' normals within 5 degrees of the triangle's).
  bool crosses(const Triangle& t, double radius, bool flat) {
    if (turning(t)) return crosses_mesh(t, radius);
    return !flat && crosses_fans(t);
  }
  bool crosses_fans(const Triangle& t);
  [[nodiscard]] bool apart(const Triangle& q, const Triangle& t, const Vec3& o, const Vec3& n,
                           double tol) const;
  /// apart()'s tolerance for a triangle with (unnormalised) normal n: heights within 1e-6 of
  /// its size, or within the clearance, count as on its plane (n is twice the area, so the
  /// tolerance is a height times |n|). Without the clearance, two triangles of one flat face
  /// overlapping 0.03 mm in the plane but 1e-7 apart in height passed as apart, and crossed in
  /// the float file (a 20-degree knife edge, from the simulator).
  [[nodiscard]] double on_plane_tol(const Vec3& n) const {
    const double len = n.norm();
    return std::max(1e-6 * std::sqrt(len), clear_) * len;
  }
  /// Whether t crosses any listed triangle with a corner within `radius` of its bounding sphere;
  /// `touching`: or comes within the clearance of one (ears closing gaps: no front-edge test
  /// sees their new edge, and a sliver ear passed 1e-7 beside an edge of the mesh, a crossing
  /// in the float file of a simulated line scan).
  bool crosses_mesh(const Triangle& t, double radius, bool touching = false);
  /// Whether the triangle (a, b, p) with unit normal n would lie over a listed triangle that
  /// faces the same way, less than kStackedSpacings local spacings above it (its centroid
  /// projecting into that triangle): a second layer, as a flap of feature-row points over a
  /// bevel that cut the corner under them.
  [[nodiscard]] bool stacked(std::uint32_t a, std::uint32_t b, std::uint32_t p, const Vec3& n) const;
  /// Marks the free points of the current scan that the new triangle (b, a, p) with unit
  /// normal n covers (see the definition).
  void cover_free_points(std::uint32_t a, std::uint32_t b, std::uint32_t p, const Vec3& n,
                         double spacing);
  /// Calls f(triangle id) once for every listed triangle of the vertices within `reach` of c,
  /// until f returns true; returns whether it did. A triangle is listed at each of its corners
  /// there: a 2-byte stamp per triangle (the call that last saw it) lets f see it once, and
  /// most of a search's time is those fetches (list node, triangle, corners: cache misses).
  template <class F>
  bool any_listed_triangle_near(const Vec3& c, double reach, F&& f) const {
    seen_.start(tris_.size());
    const std::uint32_t* order = grid_.order().data();
    const double reach2 = reach * reach;
    bool stop = false;
    grid_.for_each_range_within(c, reach, [&](std::uint32_t first, std::uint32_t last) {
      for (std::uint32_t s = first; s < last && !stop; ++s) {
        if (slot_listed_[s] == 0) continue;
        const std::uint32_t v = order[s];
        if ((p_[v] - c).squaredNorm() > reach2) continue;
        for (std::uint32_t n = corner_head_[v]; n != kNone && !stop; n = corners_[n].next) {
          const std::uint32_t id = corners_[n].tri;
          if (seen_.take(id)) stop = f(id);
        }
      }
    });
    return stop;
  }
  std::vector<std::uint8_t> turning_;
  std::vector<std::uint32_t> corner_head_;  // per vertex: first node of its list, or kNone
  /// Per grid slot: whether that slot's point has a list (corner_head_ not kNone), so that the
  /// searches of listed triangles read one byte a point in the grid's order and look up only
  /// the points with a list.
  std::vector<std::uint8_t> slot_listed_;
  struct CornerNode {
    std::uint32_t tri, next;
  };
  std::vector<CornerNode> corners_;
  std::uint32_t free_corner_ = kNone;  // recycled nodes, linked through next
  std::vector<std::uint32_t> near_tris_;
  /// any_listed_triangle_near: the triangles the current search has seen. Scratch state of a
  /// const search, hence mutable.
  mutable detail::SearchStamps seen_;
  /// Triangles with an edge longer than long_edge2_ (squared): those the corner search of
  /// crosses_mesh, which assumes edges about as long as the new triangle's radius, can miss
  /// (a triangle between sparse points passing over a dense region: its corners lie beyond the
  /// search). Every one is tested there. 1-7 on the bunny points, igea and the merged scans; a
  /// few hundred on a single raw view (its grazing fringe). Kept in ascending id order: noted
  /// as triangles are made, renumbered where removed ones are compacted away.
  /// crosses_mesh finds them through long_bins_ (cells as wide as the long-edge limit): a
  /// multi-view line scan lists thousands.
  using LongTriangle = detail::LongTriangle;
  std::vector<LongTriangle> long_tris_;
  /// The long triangles' ids binned by their boxes; a rewritten one is binned again under its
  /// new box (its old bins then name it too: crosses_mesh tests the box it has now), and all
  /// are binned anew where the ids are renumbered.
  detail::BoxBins long_bins_;
  double long_edge2_ = std::numeric_limits<double>::infinity();
  /// Whether triangle id is long; then `q` is its entry.
  bool long_entry(std::uint32_t id, LongTriangle& q) const {
    const Triangle& t = tris_[id];
    return detail::long_entry(p_[t[0]], p_[t[1]], p_[t[2]], id, long_edge2_, q);
  }
  /// A triangle just made (the highest id so far).
  void note_if_long(std::uint32_t id) {
    LongTriangle q;
    if (!long_entry(id, q)) return;
    long_tris_.push_back(q);
    long_bins_.insert(id, q.lo, q.hi);
  }
  /// Triangle id was rewritten in place: its entry is added, updated or dropped.
  void renote(std::uint32_t id) {
    const auto at = std::lower_bound(long_tris_.begin(), long_tris_.end(), id,
                                     [](const LongTriangle& q, std::uint32_t i) { return q.id < i; });
    const bool listed = at != long_tris_.end() && at->id == id;
    LongTriangle q;
    if (!long_entry(id, q)) {
      if (listed) long_tris_.erase(at);
    } else {
      if (listed) *at = q;
      else long_tris_.insert(at, q);
      long_bins_.insert(id, q.lo, q.hi);
    }
  }
#ifndef NDEBUG
  /// Debug: the list holds exactly the long triangles, in ascending id order, with their boxes.
  void check_long_list() const {
    std::size_t k = 0;
    LongTriangle q;
    for (std::uint32_t id = 0; id < tris_.size(); ++id) {
      const bool is_long = long_entry(id, q);
      const bool listed = k < long_tris_.size() && long_tris_[k].id == id;
      assert(is_long == listed && "the crossing guard's list of long triangles is off");
      if (!listed) continue;
      const LongTriangle& l = long_tris_[k++];
      assert(l.lo == q.lo && l.hi == q.hi && "a long triangle's listed box is not its own");
    }
    assert(k == long_tris_.size() && "the long list names a triangle that is gone");
  }
#endif

  static constexpr double kMaxSparsity = 2.5;
  /// cap_spacing: a sparse point keeps its own spacing only where at least kRegionPoints other
  /// points lie within kRegionRadius of its spacings and they form a plane (the smallest
  /// eigenvalue's share of their scatter at most kRegionFlatness: a scatter in the air is about
  /// 0.1, but groups of 6-7 stray readings were seen under 0.03, hence the count).
  static constexpr std::size_t kRegionPoints = 12;
  static constexpr double kRegionRadius = 3.0;
  static constexpr double kRegionFlatness = 0.03;
  /// ... and v, and the neighbours whose spacings count, lie within kRegionBand of v's spacing
  /// of the neighbourhood's plane.
  static constexpr double kRegionBand = 0.25;
  /// Cosine of 5 degrees: corner normals this close to a new triangle's skip its fan test.
  static constexpr float kCosFlat = 0.9961947f;
  /// An open sector narrower than this (ccw_turn units, about 1.1 degrees) or wider than a full
  /// turn less this is a sliver of the front, where the sector test decides by a hair: the fan
  /// test then runs even where the surface is flat.
  static constexpr double kSliverTurn = 0.02;
  /// Cosine of 30 degrees: a triangle further than this from a corner's normal is bent.
  static constexpr float kCosBent = 0.8660254f;
  /// stacked(): how far above a triangle facing the same way (normals less than about 73
  /// degrees apart) a new one may not lie, in local spacings. A flap over a bevel across a
  /// right-angled edge sits about 0.7 of the bevel's legs above it; 0.5 caught none of the
  /// two measured cases, 0.8 both, with six of the seven real scans byte-identical.
  static constexpr double kStackedSpacings = 0.8;
  /// ... and above a bevel across a sharp edge (kCosBevel), up to 1.2 spacings: the flap over
  /// a bevel whose legs are up to about 1.7 spacings long (a six-view line scan of the
  /// cylinder, seed 14: 0.89 spacings above a bevel whose corners' normals are 55 degrees off).
  static constexpr double kStackedBevelSpacings = 1.2;
  static constexpr float kCosBevel = 0.70710678f;  // cos 45 degrees
  static constexpr double kStackedCos = 0.3;
  /// Edges whose front angle at either end is below 120 degrees are processed first.
  const double ear_turn_ = turn_of_degrees(120);
  double max_spacing_ = 0;  // the largest capped spacing: bounds every edge's length
  std::vector<float> sp_;   // capped spacing per point (cap_spacing)
  std::span<const Vec3> p_;
  const LocalFrames& f_;
  const PointGrid& grid_;
  const FrontOptions& opt_;
  const StageObserver& observer_;  // hears the steps (advance_front)
  std::vector<VertexState> state_;
  /// Free points under a triangle (cover_free_points): never a candidate again.
  std::vector<std::uint8_t> covered_;
  // state_ in the grid's slot order (slot_state_[s] is the state of order()[s]), and each
  // point's slot: the candidate scan reads the states of a cell block in sequence and looks at
  // a point's index and position only when it is free or on the front (5 bytes a point).
  std::vector<VertexState> slot_state_;
  std::vector<std::uint32_t> slot_of_;
  std::vector<std::uint32_t> head_out_;
  std::vector<std::uint8_t> valence_;
  std::vector<FrontEdge> edges_;
  std::vector<std::uint32_t> free_edges_;
  EdgeMap edges_map_;
  std::vector<Triangle> tris_;
  /// The pieces of mesh: two points are in one set when triangles connect them (kept up to
  /// date as triangles are added; rebuilt on the next look-up after some were removed). For the
  /// loop-merge rule.
  detail::VertexSets pieces_;
  bool pieces_stale_ = true;
  bool same_piece(std::uint32_t u, std::uint32_t v) {
    if (pieces_stale_) {
      pieces_.reset(p_.size());
      for (const Triangle& t : tris_) pieces_.join(t);
      pieces_stale_ = false;
    }
    return pieces_.find(u) == pieces_.find(v);
  }
  // The order of work: edges with a small angle at either end first (ears, smallest angle
  // first: a heap), then the others first in, first out (the wave: a plain queue).
  std::priority_queue<QueueItem, std::vector<QueueItem>, std::greater<>> ears_;
  std::deque<QueueItem> wave_;
  std::vector<std::uint32_t> deferred_;
  bool front_stale_ = false;  // repair_fans removed triangles; rebuild_front() not yet called
  // tris_[0, bulk_kept_) are the bulk's triangles, none rewritten; fan_dirty_ lists (with
  // repeats) the corners of the bulk's triangles removed or rewritten (repair_fans).
  std::size_t bulk_kept_ = 0;
  std::vector<std::uint32_t> fan_dirty_;
  // Generation of the edges' no-candidate marks (process); changed by every step that removes
  // triangles or rebuilds the front, after which point states can move back.
  std::uint16_t candidate_gen_ = 1;
  void forget_no_candidates() {
    if (++candidate_gen_ == 0) {  // wrapped: clear every mark, start again
      for (FrontEdge& e : edges_) e.no_candidate = 0;
      candidate_gen_ = 1;
    }
  }
  void step(std::string_view name) const {
    if (observer_) observer_(name);
  }
#ifndef NDEBUG
  bool check_every_step_ = true;
#else
  bool check_every_step_ = false;
#endif
  static constexpr std::size_t kCheckAllUpTo = 60000;
  static constexpr std::size_t kCheckSlotsUpTo = 8000;
  std::uint32_t steps_ = 0;
  /// Point ids listed by the candidate scan: room is made once per cell range (reserve_more),
  /// then every id is written without a capacity check. (std::vector::push_back stayed an
  /// out-of-line call there: 18M of the bunny's 480M instructions in the growth.)
  class IdList {
   public:
    void clear() { n_ = 0; }
    void reserve_more(std::size_t extra) {
      if (ids_.size() < n_ + extra) ids_.resize(2 * (n_ + extra));
    }
    void put(std::uint32_t id) { ids_[n_++] = id; }  // after reserve_more
    [[nodiscard]] const std::uint32_t* begin() const { return ids_.data(); }
    [[nodiscard]] const std::uint32_t* end() const { return ids_.data() + n_; }

   private:
    std::vector<std::uint32_t> ids_;
    std::size_t n_ = 0;
  };
  // scratch buffers reused by every query (no allocation on the hot path once warmed up)
  std::vector<Candidate> cand_;
  IdList near_front_;
  IdList near_free_;  // the free points of the current edge's scan
  double cos_normal_ = 1.0;  // cosine of max_normal_deviation_deg
  double clear_ = 0;         // distance under which the front-edge tests count touching
  FrontResult res_;
};

}  // namespace scanmesh::recon::front_impl
