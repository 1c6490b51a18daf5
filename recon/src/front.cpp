// Advancing front (boundary extension) over an oriented point set.
//
// The front is a set of directed loops of edges; the mesh lies on the left of every front edge
// (seen from the side its normals point to). A new triangle on front edge a->b with apex p is
// (b, a, p): it inherits the orientation of the triangle behind a->b, so every component is
// consistently oriented by construction. A vertex's gaps (open sectors of its fan) are its
// outgoing front edges; vertices with two gaps exist only transiently and are repaired at the
// end so that the output is vertex-manifold.
// SPDX-License-Identifier: MIT
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

namespace scanmesh::recon {
namespace {

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
double ccw_turn(const Vec3& u, const Vec3& w, const Vec3& n) {
  // Components in the plane normal to n: n . (u_p x w_p) = n . (u x w) and
  // u_p . w_p = u . w - (u . n)(w . n).
  const double x = u.dot(w) - u.dot(n) * w.dot(n);
  const double y = n.dot(u.cross(w));
  if (y >= 0) return x >= 0 ? (x + y > 0 ? y / (x + y) : 0.0) : 1.0 - x / (y - x);
  return x < 0 ? 2.0 - y / (-x - y) : 3.0 + x / (x - y);
}

/// ccw_turn of an angle given in degrees, in [0, 360).
double turn_of_degrees(double deg) {
  const double r = deg * kPi / 180;
  return ccw_turn(Vec3(1, 0, 0), Vec3(std::cos(r), std::sin(r), 0), Vec3(0, 0, 1));
}

/// Orientation of (p, q, r) in the plane with normal n: > 0 counter-clockwise.
double orient(const Vec3& p, const Vec3& q, const Vec3& r, const Vec3& n) {
  return n.dot((q - p).cross(r - p));
}

/// Whether segments p1-p2 and q1-q2 (no common end point) cross or touch, seen in the plane
/// with normal n. Touching counts: an end point within `clear` of the other segment, or
/// collinear segments that overlap. Raw range scans have points exactly on one line (a scan
/// line), and a triangle whose edge runs through a front vertex, or whose apex sits on a front
/// edge, overlaps the triangles there as soon as the surface is not exactly flat (bun000: 3 such
/// pairs with strict signs). `clear` is a distance: a few float roundings of the coordinates, so
/// that a configuration that only just misses does not touch once written as float (STL, PLY).
bool segments_meet(const Vec3& p1, const Vec3& p2, const Vec3& q1, const Vec3& q2, const Vec3& n,
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

bool Builder::try_seed(std::uint32_t s) {
  const Vec3& ps = p_[s];
  const double ls = spacing(s);
  if (!(ls > 0)) return false;
  ++res_.seed_attempts;
  const double r = 2.5 * ls;
  std::vector<std::pair<double, std::uint32_t>> nb;
  bool near_mesh = false;
  grid_.for_each_near(ps, grid_.ring_for(r), [&](std::uint32_t j) {
    if (j == s) return;
    const double d2 = (p_[j] - ps).squaredNorm();
    if (d2 > r * r) return;
    if (state_[j] != VertexState::kFree && state_[j] != VertexState::kOutlier) near_mesh = true;
    if (state_[j] == VertexState::kFree && d2 > 0) nb.emplace_back(d2, j);
  });
  if (near_mesh || nb.size() < 2) return false;
  std::sort(nb.begin(), nb.end());
  if (nb.size() > 10) nb.resize(10);
  const Vec3 ns = f_.normal[s].cast<double>();
  const double cos_seed = std::cos(30.0 * kPi / 180);
  for (std::size_t i = 0; i < nb.size(); ++i) {
    for (std::size_t j = i + 1; j < nb.size(); ++j) {
      std::uint32_t a = nb[i].second, b = nb[j].second;
      Vec3 n = tri_normal(s, a, b);
      const double len = n.norm();
      if (len == 0) continue;
      n /= len;
      if (std::abs(n.dot(ns)) < 0.9) continue;
      if (n.dot(ns) < 0) {
        std::swap(a, b);
        n = -n;
      }
      // all angles >= 30 degrees
      const Vec3 q[3] = {ps, p_[a], p_[b]};
      bool ok = true;
      for (int k = 0; k < 3 && ok; ++k) {
        const Vec3 u = (q[(k + 1) % 3] - q[k]).normalized(), w = (q[(k + 2) % 3] - q[k]).normalized();
        if (u.dot(w) > cos_seed) ok = false;
      }
      if (!ok) continue;
      if (std::abs(f_.normal[a].cast<double>().dot(n)) < 0.8 ||
          std::abs(f_.normal[b].cast<double>().dot(n)) < 0.8)
        continue;
      // No other neighbour inside the triangle (projected): the seed is a Delaunay-like face.
      for (const auto& [d2, m] : nb) {
        if (m == a || m == b) continue;
        const Vec3& pm = p_[m];
        if (orient(ps, p_[a], pm, n) > 0 && orient(p_[a], p_[b], pm, n) > 0 &&
            orient(p_[b], ps, pm, n) > 0) {
          ok = false;
          break;
        }
      }
      if (!ok) continue;
      push_triangle({s, a, b});
      const std::uint32_t e0 = new_edge(s, a, b), e1 = new_edge(a, b, s), e2 = new_edge(b, s, a);
      edges_[e0].next = e1;
      edges_[e1].next = e2;
      edges_[e2].next = e0;
      edges_[e0].prev = e2;
      edges_[e1].prev = e0;
      edges_[e2].prev = e1;
      for (std::uint32_t v : {s, a, b}) {
        valence_[v] = 2;
        set_state(v, VertexState::kFront);
      }
      push(e0);
      push(e1);
      push(e2);
      ++res_.seeds;
      return true;
    }
  }
  return false;
}

/// Exception to the signed normal rule, second chance only: p on a sharp feature (non-planar
/// neighbourhood) has the PCA normal of one of the faces meeting there, so the triangles of the
/// other face fail the rule at p and the front bridges the feature row (a bevel, the row left
/// unmeshed). Such a triangle is accepted when it agrees with the normals of the edge's own end
/// points (the face the front is on) and does not face against p's normal. A blanket wider
/// bound for feature points (80 degrees, or any neighbour's normal) in the first pass meshed
/// more of the casting but raised its genus (15 -> 29-36): the first pass must keep the rule.
bool Builder::feature_fits(std::uint32_t a, std::uint32_t b, std::uint32_t p, const Vec3& n1) const {
  constexpr float kFeatureFlatness = 0.01f;  // flatness above which a neighbourhood is not planar
  constexpr double kAgainst = -0.2;          // cosine: p's normal may not face against n1
  return f_.flatness[p] > kFeatureFlatness && f_.normal[p].cast<double>().dot(n1) >= kAgainst &&
         f_.normal[a].cast<double>().dot(n1) >= cos_normal_ &&
         f_.normal[b].cast<double>().dot(n1) >= cos_normal_;
}

/// Whether the new edge u-w would close a 3-cycle u-w-x (x != third) through an edge that
/// already has two triangles: the cycle can then never become a face, and an edge cycle of three
/// that is not a face is a tunnel (or a pinch) through the surface. Used when closing gaps by
/// ear clipping, where such ears wrap around the thin walls of CAD parts.
bool Builder::closes_empty_triangle(std::uint32_t u, std::uint32_t w, std::uint32_t third) {
  const double reach = opt_.relaxed_radius_factor * 1.5 * max_spacing_;  // longest edge possible
  const std::vector<std::uint32_t>& order = grid_.order();
  bool found = false;
  grid_.for_each_range_within(p_[u], reach, [&](std::uint32_t first, std::uint32_t last) {
    for (std::uint32_t s = first; s < last && !found; ++s) {
      const std::uint32_t x = order[s];
      if (x == u || x == w || x == third || state_[x] == VertexState::kFree) continue;
      const std::uint32_t* ux = edges_map_.find(u, x);
      if (ux == nullptr) continue;
      const std::uint32_t* wx = edges_map_.find(w, x);
      if (wx == nullptr || (*ux != kInterior && *wx != kInterior)) continue;
      // x joined to the ear's middle vertex too: the cycle u-w-x then only rings that vertex
      // (its fan closes), it is no tunnel.
      if (edges_map_.find(third, x) == nullptr) found = true;
    }
  });
  return found;
}

bool Builder::small_loop(std::uint32_t start, std::uint32_t v) const {
  std::uint32_t e = start;
  for (std::size_t n = 0; n < opt_.fill_max_edges; ++n) {
    if (edges_[e].a == v) return false;
    e = edges_[e].next;
    if (e == start) return true;
  }
  return false;
}

bool Builder::valid(std::uint32_t eid, std::uint32_t p, const Vec3& n1, double radius,
                    bool second_chance) {
  const FrontEdge& e = edges_[eid];
  const std::uint32_t a = e.a, b = e.b;
  if (!allowed(a, b, p)) return false;
  const Vec3 &pa = p_[a], &pb = p_[b], &pp = p_[p];
  // The new vertex's own surface normal must agree with the triangle.
  // Signed: the normals are oriented consistently (propagation) and every seed triangle agrees
  // with its point's normal, so a triangle facing against p's normal is built inside the
  // material: a membrane across a sharp corner, the start of a small tunnel. (Unsigned, this
  // rule let the demo part come out with genus 4 instead of 2.) A point whose orientation the
  // propagation got wrong (thin walls) stays unmeshed and is reported as an outlier.
  if (f_.normal[p].cast<double>().dot(n1) < cos_normal_ && !(second_chance && feature_fits(a, b, p, n1)))
    return false;
  // Existing edges: only the adjacent front edges may be closed. A free point has no edges (no
  // table look-up: on large scans each one is a cache miss).
  bool close_a = false, close_b = false;
  if (state_[p] != VertexState::kFree) {
    if (const std::uint32_t* v = edges_map_.find(a, p)) {
      if (*v != e.prev || edges_[*v].a != p) return false;
      close_a = true;
    }
    if (const std::uint32_t* v = edges_map_.find(p, b)) {
      if (*v != e.next || edges_[*v].b != p) return false;
      close_b = true;
    }
  }
  if (!close_a && valence_[a] >= opt_.max_valence) return false;
  if (!close_b && valence_[b] >= opt_.max_valence) return false;
  if (!close_a && !close_b && valence_[p] + 2 > opt_.max_valence) return false;
  // p must lie in the open sectors at a and at b.
  bool sliver = false;  // a sector nearly closed or nearly full (see kSliverTurn)
  auto sliver_wedge = [](double wedge) { return wedge < kSliverTurn || wedge > 4 - kSliverTurn; };
  if (!close_a) {
    const FrontEdge& pe = edges_[e.prev];
    const Vec3 na = vnormal(a, n1);
    const double wedge = ccw_turn(p_[pe.a] - pa, pb - pa, na);
    const double ang = ccw_turn(p_[pe.a] - pa, pp - pa, na);
    if (!(ang > 0 && ang < wedge)) return false;
    sliver = sliver || sliver_wedge(wedge);
  }
  if (!close_b) {
    const FrontEdge& ne = edges_[e.next];
    const Vec3 nb = vnormal(b, n1);
    const double wedge = ccw_turn(pa - pb, p_[ne.b] - pb, nb);
    const double ang = ccw_turn(pa - pb, pp - pb, nb);
    if (!(ang > 0 && ang < wedge)) return false;
    sliver = sliver || sliver_wedge(wedge);
  }
  const bool p_on_front = state_[p] == VertexState::kFront;
  if (p_on_front && !close_a && !close_b) {
    // Joining another part of the front: p must have a single open sector containing the new
    // triangle's corner (b then a, counter-clockwise).
    const std::uint32_t fo = head_out_[p];
    if (fo == kNone || edges_[fo].next_out != kNone) return false;
    const FrontEdge& out = edges_[fo];
    const FrontEdge& in = edges_[out.prev];
    const Vec3 np = vnormal(p, n1);
    const Vec3 r = p_[in.a] - pp;
    const double wedge = ccw_turn(r, p_[out.b] - pp, np);
    const double ab = ccw_turn(r, pb - pp, np), aa = ccw_turn(r, pa - pp, np);
    if (!(ab > 0 && ab < aa && aa < wedge)) return false;
    sliver = sliver || sliver_wedge(wedge);
  }
  // The new edges must not cross nearby front edges, and no front vertex may lie inside the
  // new triangle (both seen in the triangle's plane, within a band around it).
  const double band = 0.5 * radius;
  // Bounding sphere of the new triangle: front edges that cannot reach it are skipped cheaply.
  const Vec3 centre = (pa + pb + pp) / 3.0;
  const double reach = std::sqrt(std::max({(pa - centre).squaredNorm(), (pb - centre).squaredNorm(),
                                           (pp - centre).squaredNorm()}));
  // Within clear_ of a new edge counts as on it, as in segments_meet; so does a vertex within
  // clear_ of the base edge (the front running through one of its own vertices: a triangle on
  // that edge would lie over the vertex's fan).
  const double on_ap = clear_ * (pp - pa).norm(), on_pb = clear_ * (pb - pp).norm(),
               on_ab = clear_ * (pb - pa).norm();
  for (std::uint32_t v : near_front_) {
    if (state_[v] != VertexState::kFront) continue;
    const double hv = std::abs((p_[v] - pa).dot(n1));
    const double dv = (p_[v] - centre).norm();  // inside in projection: within reach + band
    // Inside, or on one of its new edges (a vertex there would be a T-junction).
    if (v != a && v != b && v != p && hv < band && dv < reach + band && orient(pb, pa, p_[v], n1) > -on_ab &&
        orient(pa, pp, p_[v], n1) >= -on_ap && orient(pp, pb, p_[v], n1) >= -on_pb)
      return false;
    for (std::uint32_t fe = head_out_[v]; fe != kNone; fe = edges_[fe].next_out) {
      const FrontEdge& g = edges_[fe];
      if (fe == eid) continue;
      const double hw = std::abs((p_[g.b] - pa).dot(n1));
      if (std::min(hv, hw) > band) continue;
      // every point of the segment is at least |mid - centre| - length / 2 from the centre
      const Vec3 gm = 0.5 * (p_[g.a] + p_[g.b]);
      if ((gm - centre).norm() - 0.5 * (p_[g.b] - p_[g.a]).norm() > reach + band) continue;
      // The other side of a thin wall faces away: its front cannot collide with this one.
      if (tri_normal(g.a, g.b, g.opp).dot(n1) < 0) continue;
      if (!close_a && g.a != a && g.b != a && g.a != p && g.b != p &&
          segments_meet(pa, pp, p_[g.a], p_[g.b], n1, clear_))
        return false;
      if (!close_b && g.a != b && g.b != b && g.a != p && g.b != p &&
          segments_meet(pp, pb, p_[g.a], p_[g.b], n1, clear_))
        return false;
    }
  }
  if (opt_.crossing_guard) {
    // Near a turning point: against everything near (fans included). Elsewhere against the
    // fans, unless the three corners' normals all lie within 5 degrees of the triangle's: the
    // surface is then flat at its scale and the sector tests above, made in projection on those
    // normals, are exact (measured: no fan crossing on any real scan below 5 degrees; 35-68 %
    // of the tests skipped) -- except at a sliver of the front: a front vertex 15 um beside a
    // 2 mm front edge that ends at it (the bunny's points thinned to 15 % towards +x) left the
    // open sector at the edge's end within a degree of a full turn, and an ear laid over two
    // triangles of that fan passed.
    const Eigen::Vector3f n1f = n1.cast<float>();
    const bool flat = !sliver && std::abs(f_.normal[a].dot(n1f)) >= kCosFlat &&
                      std::abs(f_.normal[b].dot(n1f)) >= kCosFlat &&
                      std::abs(f_.normal[p].dot(n1f)) >= kCosFlat;
    if (crosses({b, a, p}, radius, flat)) return false;
  }
  // A front point on another loop of the same piece of mesh: the triangle would merge the two
  // loops and make a handle. Where one of them is small (a sampling gap, for the gap closing),
  // that handle is false: refused (real tunnels, such as bolt holes, are larger). A small loop
  // that misses p, or a small loop through p that misses a, is another loop than the other's,
  // so no long loop is walked. Tested last, for a candidate that passed every other test (on
  // the seams between bulk patches most candidates are front points, and the walks are cache
  // misses), and the pieces last of all (the first look-up after the bulk or a fan repair
  // rebuilds them; most merges involve no small loop).
  if (!close_a && !close_b && state_[p] == VertexState::kFront) {
    bool small = small_loop(eid, p);
    for (std::uint32_t o = head_out_[p]; o != kNone && !small; o = edges_[o].next_out)
      small = small_loop(o, a);
    if (small && same_piece(a, p)) return false;
    // Nor may it lay a second layer over the mesh: a bevel across a sharp edge leaves the
    // feature row's points just above it, and the front meshes them later as a flap over the
    // bevel. The triangle that joins such a flap to the rest of its loop would close a tunnel
    // between the two layers (a false handle; measured on simulated scans of the steps and
    // the cylinder). Refused, the flap's points stay on the front and the loop open.
    if (stacked(a, b, p, n1)) return false;
  }
  return true;
}

void Builder::cover_free_points(std::uint32_t a, std::uint32_t b, std::uint32_t p, const Vec3& n,
                                double spacing) {
  // The front passes over a free point that lies too close to an edge for a 20-degree triangle
  // of its own: the Delaunay choice takes a farther candidate, and the new triangle covers the
  // point (the insertion stage later splits the triangle or edge under it). Used afterwards as
  // an apex (the relaxed second pass reaches it), the point made a triangle overlapping this
  // one: a crossing pair on a simulated six-view scan of the cylinder (1 of 600 scans of
  // bench_quality). Away from turning points no test sees that (the crossing guard looks only
  // at the fans there), so such points are marked covered and are no candidates again. Near a
  // turning point the guard tests every triangle near, and nothing is marked. Part of the
  // crossing guard: off with it.
  if (!opt_.crossing_guard || turning(Triangle{b, a, p})) return;
  const Vec3 &pa = p_[a], &pb = p_[b], &pp = p_[p];
  const double band = 0.5 * spacing;
  // A point inside the triangle is within its corners' farthest distance from the centroid.
  const Vec3 g = (pa + pb + pp) / 3.0;
  const double r2 = std::max({(pa - g).squaredNorm(), (pb - g).squaredNorm(), (pp - g).squaredNorm()}) +
                    band * band;
  for (const std::uint32_t q : near_free_) {
    const Vec3& pq = p_[q];
    if ((pq - g).squaredNorm() > r2 || q == p) continue;
    if (std::abs((pq - pb).dot(n)) > band) continue;
    if ((pa - pb).cross(pq - pb).dot(n) > 0 && (pp - pa).cross(pq - pa).dot(n) > 0 &&
        (pb - pp).cross(pq - pp).dot(n) > 0)
      covered_[q] = 1;
  }
}

bool Builder::stacked(std::uint32_t a, std::uint32_t b, std::uint32_t p, const Vec3& n) const {
  // Only near turning points do vertices keep their triangle lists, and only there can the
  // surface turn enough for a bevel.
  if (corner_head_.empty()) return false;
  const Vec3 g = (p_[a] + p_[b] + p_[p]) / 3.0;
  const double sp = std::max({spacing(a), spacing(b), spacing(p)});
  const double low = 0.05 * sp, high = kStackedSpacings * sp;
  return any_listed_triangle_near(g, 1.5 * sp, [&](std::uint32_t id) {
    const Triangle& t = tris_[id];
    const int shared = (t[0] == a || t[0] == b || t[0] == p) + (t[1] == a || t[1] == b || t[1] == p) +
                       (t[2] == a || t[2] == b || t[2] == p);
    if (shared >= 2) return false;  // a neighbour across an edge: the fold rules decide
    const Vec3& o = p_[t[0]];
    Vec3 nt = (p_[t[1]] - o).cross(p_[t[2]] - o);
    const double len = nt.norm();
    if (!(len > 0)) return false;
    nt /= len;
    if (nt.dot(n) <= kStackedCos) return false;  // the other side of a wall, or across an edge
    const double h = (g - o).dot(nt);
    if (!(h > low)) return false;
    if (!(h < high)) {
      // Higher above a bevel across a sharp edge: a corner's normal more than 45 degrees off
      // the triangle's, so the bevel turns more than half a right angle away from that face
      // (55 degrees in the traced case; the merged bunny's ear tips bend by 35).
      if (!(h < kStackedBevelSpacings * sp)) return false;
      const Eigen::Vector3f ntf = nt.cast<float>();
      if (std::min({f_.normal[t[0]].dot(ntf), f_.normal[t[1]].dot(ntf),
                    f_.normal[t[2]].dot(ntf)}) >= kCosBevel)
        return false;
    }
    const Vec3 q = g - h * nt;  // the centroid dropped onto t's plane: inside t?
    for (int k = 0; k < 3; ++k)
      if ((p_[t[(k + 1) % 3]] - p_[t[k]]).cross(q - p_[t[k]]).dot(nt) < 0) return false;
    return true;
  });
}

bool Builder::process(std::uint32_t eid, const Mode& mode) {
  FrontEdge& e = edges_[eid];
  // An edge that found no candidate at all in this mode finds none again: whether a point is a
  // candidate depends only on the edge, the mode, fixed point data and the point's state, and
  // while the front only grows states only move forward (free -> front -> done), so the set of
  // free or front points can only shrink. (Stale queue entries run such edges again and again:
  // a third of all evaluations on a 90k-point height field, most of them slivers of three
  // edges waiting for the end.) Removing triangles moves states back: candidate_gen_ changes.
  // Debug builds still run the scan and check that it finds nothing.
  const bool known_empty =
      (e.no_candidate & mode.bit) != 0 && e.no_candidate_gen == candidate_gen_;
  if (known_empty) {
    ++res_.skipped_evaluations;
    if (!check_every_step_) return false;
  }
  const std::uint32_t a = e.a, b = e.b, x = e.opp;
  const Vec3 &pa = p_[a], &pb = p_[b];
  const Vec3 n0 = edge_normal(e);
  const Vec3 mid = 0.5 * (pa + pb);
  const double lab = (pb - pa).norm();
  const double base = std::max(spacing(a), spacing(b));
  // How far a candidate j may lie from a and b at a radius factor: a sparser candidate may
  // reach a little further, but never more than 1.5x the edge's own spacing (an isolated point
  // must not pull long triangles across a gap).
  auto reach = [&](double factor, std::uint32_t j) {
    return std::min(factor * base * 1.5, factor * std::clamp<double>(spacing(j), base, 1.5 * base));
  };
  const double gather = mode.radius_factor * base * 1.5;
  // On a real hole's rim, the relaxed pass reaches front points only as far as the strict one.
  const bool on_hole = mode.bit == 2 && eid < hole_mark_.size() && hole_mark_[eid] == 2;
  bool hole_refused = false;
  cand_.clear();
  near_front_.clear();
  near_free_.clear();
  ++res_.edge_evaluations;
  // A point within reach of both end points: the full candidate test.
  auto consider = [&](std::uint32_t j, double la2, double lb2) {
    const Vec3& pj = p_[j];
    const double r = reach(mode.radius_factor, j);
    if (la2 > r * r || lb2 > r * r || la2 == 0 || lb2 == 0) return;
    if (on_hole && state_[j] == VertexState::kFront) {
      const double strict = reach(opt_.radius_factor, j);
      if (la2 > strict * strict || lb2 > strict * strict) {
        hole_refused = true;
        return;
      }
    }
    const Vec3 ua = pj - pa, ub = pj - pb;
    // new triangle (b, a, j)
    Vec3 n1 = (pa - pb).cross(pj - pb);
    const double nl = n1.norm();
    if (nl == 0) return;
    n1 /= nl;
    if (n1.dot(n0) <= mode.cos_dihedral) return;
    // interior angles via cosines: at a, at b, at j
    const double la = std::sqrt(la2), lb = std::sqrt(lb2);
    const Vec3 ab = pb - pa;
    const double cos_a = ab.dot(ua) / (lab * la);
    const double cos_b = -ab.dot(ub) / (lab * lb);
    const double cos_j = ua.dot(ub) / (la * lb);
    if (std::max({cos_a, cos_b, cos_j}) > mode.cos_min_angle) return;
    // Delaunay-like choice: the point that sees the edge under the largest angle, with a
    // preference for continuing the surface smoothly.
    const double score = std::acos(std::clamp(cos_j, -1.0, 1.0)) + 0.5 * n1.dot(n0);
    cand_.push_back({score, j});
  };
  // The scan: every point in the cells around the edge. Most are rejected by the first test
  // (beyond the largest radius any candidate may use), so it is written on plain coordinates
  // and reads nothing else before it.
  // Only cells within sqrt(gather^2 - lab^2 / 4) of the edge's midpoint: a point within
  // `gather` of both a and b is that close to the midpoint (parallelogram law), and so is every
  // point of a new triangle. (gather + lab / 2 before: 20 % more points scanned, same output.)
  const double gather2 = gather * gather;
  const double scan_radius = std::sqrt(std::max(gather2 - 0.25 * lab * lab, 0.0));
  const double ax = pa.x(), ay = pa.y(), az = pa.z(), bx = pb.x(), by = pb.y(), bz = pb.z();
  const std::uint32_t* order = grid_.order().data();
  const VertexState* slot_state = slot_state_.data();
  const Vec3* pts = p_.data();
  grid_.for_each_range_within(mid, scan_radius, [&](std::uint32_t first, std::uint32_t last) {
    res_.points_scanned += last - first;
    near_front_.reserve_more(last - first);
    near_free_.reserve_more(last - first);
    for (std::uint32_t slot = first; slot < last; ++slot) {
      const VertexState st = slot_state[slot];
      if (st != VertexState::kFree && st != VertexState::kFront) continue;
      const std::uint32_t j = order[slot];
      if (st == VertexState::kFront) near_front_.put(j);
      const double* q = pts[j].data();
      const double uax = q[0] - ax, uay = q[1] - ay, uaz = q[2] - az;
      const double la2 = uax * uax + uay * uay + uaz * uaz;
      if (la2 > gather2) continue;
      const double ubx = q[0] - bx, uby = q[1] - by, ubz = q[2] - bz;
      const double lb2 = ubx * ubx + uby * uby + ubz * ubz;
      if (lb2 > gather2 || j == a || j == b || j == x) continue;
      if (st == VertexState::kFree) {
        if (covered_[j] != 0) continue;
        near_free_.put(j);
      }
      consider(j, la2, lb2);
    }
  });
  if (cand_.empty()) {
    // Refused by the hole rule, the edge is not marked: the next pass may see its loop closed
    // to a gap.
    if (hole_refused) return false;
    if (e.no_candidate_gen != candidate_gen_) {
      e.no_candidate = 0;
      e.no_candidate_gen = candidate_gen_;
    }
    e.no_candidate |= mode.bit;
    return false;
  }
  assert(!known_empty && "an edge without candidates found one later");
  std::sort(cand_.begin(), cand_.end(), [](const Candidate& l, const Candidate& r) {
    return l.score != r.score ? l.score > r.score : l.p < r.p;
  });
  const std::size_t tries = std::min<std::size_t>(cand_.size(), 8);
  for (std::size_t i = 0; i < tries; ++i) {
    const std::uint32_t p = cand_[i].p;
    const Vec3 n1 = (pa - pb).cross(p_[p] - pb).normalized();
    if (valid(eid, p, n1, mode.radius_factor * base, mode.second_chance)) {
      cover_free_points(a, b, p, n1, base);
      add_triangle(eid, p);
      return true;
    }
  }
  return false;
}

void Builder::add_triangle(std::uint32_t eid, std::uint32_t p) {
  const FrontEdge e = edges_[eid];  // copy: the pool may grow below
  const std::uint32_t a = e.a, b = e.b, ep = e.prev, en = e.next;
  // The edges that replace a hole's edge during a relaxed pass are on that hole.
  const std::uint8_t hole = eid < hole_mark_.size() ? hole_mark_[eid] : 0;
  auto inherit = [&](std::uint32_t id) {
    if (hole != 2) return;
    if (hole_mark_.size() <= id) hole_mark_.resize(edges_.size(), 0);
    hole_mark_[id] = 2;
    hole_visited_.push_back(id);
  };
  push_triangle({b, a, p});
  const bool p_free = state_[p] == VertexState::kFree;  // a free point has no edges yet
  const bool close_a = !p_free && edges_map_.find(a, p) != nullptr;
  const bool close_b = !p_free && edges_map_.find(p, b) != nullptr;
  edges_map_.insert(a, b, kInterior);
  std::uint32_t touched[4];
  std::size_t nt = 0;
  if (close_a && close_b) {  // the sub-loop p->a->b->p was this triangle: it disappears
    edges_map_.insert(a, p, kInterior);
    edges_map_.insert(p, b, kInterior);
    const std::uint32_t before = edges_[ep].prev, after = edges_[en].next;
    if (before != en) {  // p was on the loop twice (two gaps): the rest of the loop joins up
      edges_[before].next = after;
      edges_[after].prev = before;
      touched[nt++] = before;
      touched[nt++] = after;
    }
    kill_edge(ep);
    kill_edge(en);
    kill_edge(eid);
  } else if (close_a) {  // p is the previous vertex: a is closed
    edges_map_.insert(a, p, kInterior);
    const std::uint32_t pp = edges_[ep].prev;
    kill_edge(ep);
    kill_edge(eid);
    const std::uint32_t e2 = new_edge(p, b, a);
    inherit(e2);
    edges_[e2].prev = pp;
    edges_[e2].next = en;
    edges_[pp].next = e2;
    edges_[en].prev = e2;
    touched[nt++] = e2;
    touched[nt++] = pp;
    touched[nt++] = en;
    ++valence_[p];
    ++valence_[b];
  } else if (close_b) {  // p is the next vertex: b is closed
    edges_map_.insert(p, b, kInterior);
    const std::uint32_t nn = edges_[en].next;
    kill_edge(en);
    kill_edge(eid);
    const std::uint32_t e1 = new_edge(a, p, b);
    inherit(e1);
    edges_[e1].prev = ep;
    edges_[e1].next = nn;
    edges_[ep].next = e1;
    edges_[nn].prev = e1;
    touched[nt++] = e1;
    touched[nt++] = ep;
    touched[nt++] = nn;
    ++valence_[a];
    ++valence_[p];
  } else {
    const bool p_front = state_[p] == VertexState::kFront;
    std::uint32_t fo = kNone, fi = kNone;
    if (p_front) {
      fo = head_out_[p];
      fi = edges_[fo].prev;
    }
    kill_edge(eid);
    const std::uint32_t e1 = new_edge(a, p, b);
    const std::uint32_t e2 = new_edge(p, b, a);
    inherit(e1);
    inherit(e2);
    edges_[ep].next = e1;
    edges_[e1].prev = ep;
    edges_[e2].next = en;
    edges_[en].prev = e2;
    if (p_front) {  // split or merge loops at p
      edges_[e1].next = fo;
      edges_[fo].prev = e1;
      edges_[fi].next = e2;
      edges_[e2].prev = fi;
    } else {
      edges_[e1].next = e2;
      edges_[e2].prev = e1;
    }
    touched[nt++] = e1;
    touched[nt++] = e2;
    touched[nt++] = ep;
    touched[nt++] = en;
    ++valence_[a];
    ++valence_[b];
    valence_[p] = static_cast<std::uint8_t>(valence_[p] + 2);
  }
  update_state(a);
  update_state(b);
  update_state(p);
  push_touched(touched, nt);
  // Debug builds: after every triangle up to kCheckAllUpTo points (the check costs the whole
  // edge pool, so on a large scan every step would make the debug run quadratic), then after
  // every 256th.
  if (check_every_step_ && (p_.size() <= kCheckAllUpTo || (++steps_ & 255u) == 0)) check_front();
  // The slot-ordered states (O(points) to check): every step on small clouds.
  if (check_every_step_ && p_.size() <= kCheckSlotsUpTo) check_slot_states();
}

void Builder::grow() {
  const double deg = kPi / 180;
  const Mode strict{opt_.radius_factor, std::cos(opt_.min_angle_deg * deg),
                    std::cos((180.0 - opt_.min_dihedral_deg) * deg), false, 1};
  const Mode relaxed{opt_.relaxed_radius_factor, std::cos(opt_.relaxed_min_angle_deg * deg),
                     std::cos((180.0 - opt_.relaxed_min_dihedral_deg) * deg), true, 2};
  while (true) {
    while (!ears_.empty() || !wave_.empty()) {
      QueueItem it;
      if (!ears_.empty()) {
        it = ears_.top();
        ears_.pop();
      } else {
        it = wave_.front();
        wave_.pop_front();
      }
      const FrontEdge& e = edges_[it.edge];
      if (!e.alive || e.stamp != it.stamp) continue;
      if (!process(it.edge, strict)) deferred_.push_back(it.edge);
    }
    if (deferred_.empty()) break;
    if (check_every_step_) check_slot_states();
    std::vector<std::uint32_t> batch;
    batch.swap(deferred_);
    mark_hole_loops(batch);
    for (std::uint32_t id : batch) {
      if (!edges_[id].alive) continue;
      const std::size_t before = tris_.size();
      if (process(id, relaxed)) res_.relaxed_triangles += tris_.size() - before;
    }
  }
  if (check_every_step_) check_slot_states();
}

void Builder::mark_hole_loops(const std::vector<std::uint32_t>& batch) {
  // Clear the previous pass's marks (only the edges it visited), then walk the loop of every
  // deferred edge once: 1 = visited, 2 = on a hole (see FrontOptions::keep_holes).
  for (const std::uint32_t id : hole_visited_)
    if (id < hole_mark_.size()) hole_mark_[id] = 0;
  hole_visited_.clear();
  if (!opt_.keep_holes) return;
  if (hole_mark_.size() < edges_.size()) hole_mark_.resize(edges_.size(), 0);
  for (const std::uint32_t start : batch) {
    if (!edges_[start].alive || hole_mark_[start] != 0) continue;
    const std::size_t first = hole_visited_.size();
    // Twice the loop's vector area (Newell), its perimeter, its vertices' summed normals and
    // spacings.
    Vec3 area2 = Vec3::Zero(), normals = Vec3::Zero();
    double perimeter = 0, spacing_sum = 0;
    std::uint32_t e = start;
    do {
      hole_mark_[e] = 1;
      hole_visited_.push_back(e);
      const FrontEdge& fe = edges_[e];
      area2 += p_[fe.a].cross(p_[fe.b]);
      perimeter += (p_[fe.b] - p_[fe.a]).norm();
      normals += f_.normal[fe.a].cast<double>();
      spacing_sum += spacing(fe.a);
      e = fe.next;
    } while (e != start);
    const double n = static_cast<double>(hole_visited_.size() - first);
    const double sp = spacing_sum / n, area = 0.5 * area2.norm();
    // The mesh lies on the left of its front edges: the rim of a hole winds clockwise seen
    // from the side the normals point to (its vector area against them), a border around the
    // mesh counter-clockwise.
    const bool surrounded = area2.dot(normals) <= kHoleWinding * area2.norm() * normals.norm();
    if (surrounded && area >= opt_.hole_min_area * sp * sp &&
        2 * area >= opt_.hole_min_width * perimeter * sp)
      for (std::size_t i = first; i < hole_visited_.size(); ++i) hole_mark_[hole_visited_[i]] = 2;
  }
}

void Builder::fill_small_loops() {
  // Walk every remaining loop once; close small ones by clipping their sharpest ears.
  const double cos_fill_angle = std::cos(0.05 * kPi / 180);  // only truly flat ears refused
  std::vector<std::uint32_t> loop;
  const std::size_t initial = edges_.size();
  std::vector<std::uint8_t> seen(initial, 0);
  for (std::uint32_t start = 0; start < initial; ++start) {
    if (!edges_[start].alive || seen[start]) continue;
    loop.clear();
    detail::LoopMeasure measure;
    std::uint32_t e = start;
    do {
      if (e < initial) seen[e] = 1;
      loop.push_back(e);
      const FrontEdge& fe = edges_[e];
      measure.add(p_[fe.a], p_[fe.b], spacing(fe.a), spacing(fe.b));
      e = fe.next;
    } while (e != start && loop.size() <= opt_.fill_max_edges + 1);
    if (e != start || loop.size() > opt_.fill_max_edges) continue;
    if (!measure.within(opt_.fill_perimeter_factor)) continue;
    // Clip ears: always the one with the smallest opening angle whose closing edge is new.
    std::size_t guard = loop.size() * 2;
    std::uint32_t cur = start;
    bool closed = false;
    while (guard-- > 0) {
      // collect the current loop
      std::vector<std::uint32_t> ring;
      std::uint32_t it = cur;
      do {
        ring.push_back(it);
        it = edges_[it].next;
      } while (it != cur && ring.size() < 64);
      if (ring.size() < 3) break;
      // A 3-loop around a single triangle (an isolated triangle's rim) must stay open:
      // closing it would duplicate that triangle with the opposite orientation.
      if (ring.size() == 3 && edges_[ring[0]].opp == edges_[ring[1]].b) break;
      std::uint32_t best = kNone;
      double best_angle = 1e9;
      for (std::uint32_t r : ring) {
        const FrontEdge& fe = edges_[r];
        const std::uint32_t c = edges_[fe.next].b;
        if (ring.size() > 3 && edges_map_.find(fe.a, c) != nullptr) continue;
        if (!allowed(fe.a, fe.b, c)) continue;
        if (min_angle_cos(fe.a, fe.b, c) > cos_fill_angle) continue;  // no slivers
        if (ring.size() > 3 && closes_empty_triangle(fe.a, c, fe.b)) continue;  // no tunnel
        if (opt_.crossing_guard) {  // the ear must not cross the mesh either
          if (crosses_mesh({fe.b, fe.a, c}, opt_.radius_factor * spacing(fe.a), true)) continue;
        }
        const double ang = front_turn_at_end(r);
        if (ang < best_angle) {
          best_angle = ang;
          best = r;
        }
      }
      if (best == kNone || (best_angle >= 2.0 && ring.size() > 3)) break;
      const std::uint32_t c = edges_[edges_[best].next].b;
      const bool last = ring.size() == 3;
      cur = edges_[best].prev;
      add_triangle(best, c);
      if (last) {
        closed = true;
        break;
      }
    }
    if (closed) ++res_.filled_gaps;
  }
}

std::size_t Builder::fans_of(std::uint32_t v, const std::uint32_t* ids, std::uint32_t m,
                             std::vector<int>& fan, std::vector<std::uint32_t>& size) const {
  return detail::fans_of(tris_, v, ids, m, fan, size);
}

void Builder::check_bulk_fans() const {
  // Debug builds: the vertices the thorough fan check skipped (all their triangles the bulk's,
  // untouched) have one fan indeed.
  if (bulk_kept_ == 0) return;
  std::vector<std::uint8_t> examined(p_.size(), 0);
  for (std::size_t t = bulk_kept_; t < tris_.size(); ++t)
    for (std::uint32_t v : tris_[t]) examined[v] = 1;
  for (std::uint32_t v : fan_dirty_) examined[v] = 1;
  const detail::VertexTriangles adj(p_.size(), tris_);
  std::vector<int> fan;
  std::vector<std::uint32_t> size;
  for (std::uint32_t v = 0; v < p_.size(); ++v) {
    const std::uint32_t m = adj.start[v + 1] - adj.start[v];
    if (examined[v] || m < 2) continue;
    [[maybe_unused]] const std::size_t fans = fans_of(v, adj.list.data() + adj.start[v], m, fan, size);
    assert(fans == 1 && "a vertex of untouched bulk triangles has several fans");
  }
}

std::size_t Builder::repair_fans(bool thorough) {
  forget_no_candidates();
  std::size_t total = 0;
  // A vertex whose triangles form several fans is non-manifold: keep its largest fan. While the
  // front matches the mesh, such vertices are exactly those with more than one open sector
  // (triangles are only ever added in a vertex's open sector), so only they are examined, and
  // in later rounds only the corners of the triangles just removed (the fans of no other vertex
  // changed). The thorough check examines every vertex.
  const std::size_t n = p_.size();
  std::vector<std::uint32_t> check;  // vertices to examine, ascending (thorough: all)
  if (!thorough) {
    for (std::uint32_t v = 0; v < n; ++v)
      if (head_out_[v] != kNone && edges_[head_out_[v]].next_out != kNone) check.push_back(v);
    if (check.empty()) return 0;
  }
  std::vector<std::uint8_t> marked(thorough ? 0 : n, 0);
  std::vector<Triangle> removed_tris;  // targeted mode: the front is updated around them
  std::vector<int> fan;
  std::vector<std::uint32_t> size;
  for (int round = 0; round < 8; ++round) {
    // Triangles around the examined vertices, in triangle order: vertex -> triangle lists over
    // all vertices when thorough, otherwise over the few vertices in `check` only.
    // Thorough: every vertex, numbered in order of first appearance in the triangles, whose
    // storage order is spatial (the bulk's patches, the front's waves): the lists are then
    // filled and read near each other (indexed by vertex they were cache misses on large
    // scans). Each vertex's verdict depends only on its own triangles, so the order of the
    // vertices does not matter; each list is in triangle order either way.
    // Thorough after the bulk: a vertex whose triangles are all the bulk's, none of them
    // removed or rewritten since, still has the single fan the bulk left it (the bulk's
    // guarantee; a point belongs to one patch): only the corners of the later triangles and
    // of the bulk triangles changed (`fan_dirty_`) are examined. On a scan the bulk covers
    // that skips most vertices (debug builds check them all at the end of run()).
    std::vector<std::uint32_t> start, vt, visit;
    if (thorough) {
      constexpr std::uint32_t kSelected = kNone - 1;
      std::vector<std::uint32_t> rank(n, kNone);
      const bool restricted = bulk_kept_ > 0;
      if (restricted) {
        for (std::size_t t = bulk_kept_; t < tris_.size(); ++t)
          for (std::uint32_t v : tris_[t]) rank[v] = kSelected;
        for (std::uint32_t v : fan_dirty_) rank[v] = kSelected;
      }
      const std::uint32_t wanted = restricted ? kSelected : kNone;
      visit.reserve(restricted ? 0 : n);
      for (const Triangle& t : tris_)
        for (std::uint32_t v : t)
          if (rank[v] == wanted) {
            rank[v] = static_cast<std::uint32_t>(visit.size());
            visit.push_back(v);
          }
      detail::VertexTriangles adj(visit.size(), tris_,
                          [&](std::uint32_t v) { return rank[v] < kSelected ? rank[v] : kNone; });
      start = std::move(adj.start);
      vt = std::move(adj.list);
    } else {
      SomeVertexTriangles adj(check, tris_, marked);
      start = std::move(adj.start);
      vt = std::move(adj.list);
    }
    const std::size_t count = thorough ? visit.size() : check.size();
    std::vector<std::uint8_t> dead(tris_.size(), 0);
    std::size_t removed = 0;
    std::vector<std::uint32_t> next_check;
    for (std::uint32_t c = 0; c < count; ++c) {
      const std::uint32_t v = thorough ? visit[c] : check[c];
      const std::uint32_t b0 = start[c], b1 = start[c + 1];
      if (b1 - b0 < 2) continue;
      const std::uint32_t m = b1 - b0;
      // Fast path: walking from the first triangle to the next one around v (its `next` corner
      // is the following triangle's `prev`, as in a consistently oriented fan) and back reaches
      // all m: one fan. Otherwise the exact test below decides.
      if (one_oriented_fan(v, vt.data() + b0, m)) continue;
      if (fans_of(v, vt.data() + b0, m, fan, size) < 2) continue;
      auto find = [&](int i) {
        while (fan[static_cast<std::size_t>(i)] >= 0) i = fan[static_cast<std::size_t>(i)];
        return i;
      };
      std::size_t keep = 0;
      for (std::size_t i = 0; i < m; ++i)
        if (size[i] > size[keep]) keep = i;
      for (std::uint32_t i = 0; i < m; ++i)
        if (static_cast<std::size_t>(find(static_cast<int>(i))) != keep && !dead[vt[b0 + i]]) {
          dead[vt[b0 + i]] = 1;
          ++removed;
          if (!thorough) {
            for (std::uint32_t x : tris_[vt[b0 + i]]) next_check.push_back(x);
            removed_tris.push_back(tris_[vt[b0 + i]]);
          }
        }
    }
    if (removed == 0) break;
    total += removed;
    std::size_t w = 0, bulk_removed = 0;
    for (std::size_t t = 0; t < tris_.size(); ++t) {
      if (!dead[t]) {
        tris_[w++] = tris_[t];
      } else if (t < bulk_kept_) {
        ++bulk_removed;
        for (std::uint32_t v : tris_[t]) fan_dirty_.push_back(v);
      }
    }
    // The long triangles, renumbered as the rest (their list is in ascending id order).
    std::size_t kept_long = 0, k = 0;
    for (std::uint32_t t = 0, dead_before = 0; k < long_tris_.size(); dead_before += dead[t] ? 1 : 0, ++t) {
      if (long_tris_[k].id != t) continue;
      if (!dead[t]) long_tris_[kept_long++] = {long_tris_[k].lo, long_tris_[k].hi, t - dead_before};
      ++k;
    }
    long_tris_.resize(kept_long);
    long_bins_.clear();
    for (const LongTriangle& q : long_tris_) long_bins_.insert(q.id, q.lo, q.hi);
    tris_.resize(w);
#ifndef NDEBUG
    check_long_list();
#endif
    bulk_kept_ -= bulk_removed;
    pieces_stale_ = true;
    res_.removed_fan_triangles += removed;
    if (thorough) front_stale_ = true;  // triangles went away behind the front's back
    if (!thorough) {
      std::sort(next_check.begin(), next_check.end());
      next_check.erase(std::unique(next_check.begin(), next_check.end()), next_check.end());
      check.swap(next_check);
    }
  }
  if (!removed_tris.empty()) update_front_after_removal(removed_tris, marked);
  if (total > 0 && !front_stale_) rebuild_corner_lists();  // else rebuild_front() does it
  return total;
}

void Builder::update_front_after_removal(const std::vector<Triangle>& removed,
                                         std::vector<std::uint8_t>& marked) {
  // Only the corners of the removed triangles changed: their front edges (in and out) are
  // replaced by the boundary edges of their remaining triangles, and the edge table, valences
  // and states are updated there. O(triangles) for one pass collecting their triangles, instead
  // of rebuilding the whole front and edge table.
  std::vector<std::uint32_t> touched;
  for (const Triangle& t : removed)
    for (std::uint32_t v : t) touched.push_back(v);
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  auto in_touched = [&](std::uint32_t v) {
    return std::binary_search(touched.begin(), touched.end(), v);
  };
  const SomeVertexTriangles adj(touched, tris_, marked);
  // Old front edges into and out of touched vertices go; their untouched neighbours along the
  // loops are relinked below.
  std::vector<std::uint32_t> dead, relink;
  for (std::uint32_t v : touched)
    for (std::uint32_t o = head_out_[v]; o != kNone; o = edges_[o].next_out) {
      dead.push_back(o);
      dead.push_back(edges_[o].prev);
    }
  std::sort(dead.begin(), dead.end());
  dead.erase(std::unique(dead.begin(), dead.end()), dead.end());
  for (std::uint32_t d : dead) {
    const std::uint32_t pv = edges_[d].prev;
    if (!std::binary_search(dead.begin(), dead.end(), pv)) relink.push_back(pv);
  }
  for (std::uint32_t d : dead) kill_edge(d);
  // New boundary edges and valences from the remaining triangles of each touched vertex.
  std::vector<std::uint32_t> created;
  std::vector<std::pair<std::uint32_t, int>> nbrs;  // (neighbour, triangles using the edge)
  for (std::size_t c = 0; c < touched.size(); ++c) {
    const std::uint32_t u = touched[c];
    nbrs.clear();
    for (std::uint32_t s = adj.start[c]; s < adj.start[c + 1]; ++s) {
      const Triangle& t = tris_[adj.list[s]];
      const std::size_t k = t[0] == u ? 0 : (t[1] == u ? 1 : 2);
      for (std::uint32_t w : {t[(k + 1) % 3], t[(k + 2) % 3]}) {
        auto it = std::find_if(nbrs.begin(), nbrs.end(), [&](const auto& q) { return q.first == w; });
        if (it == nbrs.end()) nbrs.emplace_back(w, 1);
        else ++it->second;
      }
    }
    valence_[u] = static_cast<std::uint8_t>(std::min<std::size_t>(nbrs.size(), 255));
    for (std::uint32_t s = adj.start[c]; s < adj.start[c + 1]; ++s) {
      const Triangle& t = tris_[adj.list[s]];
      const std::size_t k = t[0] == u ? 0 : (t[1] == u ? 1 : 2);
      const std::uint32_t next = t[(k + 1) % 3], prev = t[(k + 2) % 3];
      for (std::uint32_t w : {next, prev}) {
        if (in_touched(w) && w < u) continue;  // the edge is handled from its smaller end
        const int uses = std::find_if(nbrs.begin(), nbrs.end(), [&](const auto& q) { return q.first == w; })->second;
        if (uses >= 2) {
          edges_map_.insert(u, w, kInterior);
        } else if (w == next) {  // the front runs along its triangle: u -> next
          created.push_back(new_edge(u, next, prev));
        } else {  // prev -> u
          created.push_back(new_edge(prev, u, next));
        }
      }
    }
  }
  // Edges of removed triangles left without any triangle leave the table.
  for (const Triangle& t : removed)
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint32_t x = t[k], y = t[(k + 1) % 3];
      const auto c = static_cast<std::size_t>(
          std::lower_bound(touched.begin(), touched.end(), x) - touched.begin());
      bool used = false;
      for (std::uint32_t s = adj.start[c]; s < adj.start[c + 1] && !used; ++s) {
        const Triangle& o = tris_[adj.list[s]];
        used = o[0] == y || o[1] == y || o[2] == y;
      }
      if (!used) edges_map_.erase(x, y);
    }
  // Link the loops: every vertex has a single fan now, hence at most one outgoing edge.
  for (std::uint32_t id : created) relink.push_back(id);
  for (std::uint32_t id : relink) {
    FrontEdge& e = edges_[id];
    if (!e.alive) continue;
    const std::uint32_t nx = head_out_[e.b];
    if (nx == kNone) {  // inconsistent (should not happen): rebuild everything
      front_stale_ = true;
      return;
    }
    e.next = nx;
    edges_[nx].prev = id;
  }
  for (std::uint32_t v : touched) {
    if (valence_[v] == 0) set_state(v, VertexState::kFree);  // its triangles are gone: free again
    else update_state(v);
  }
  // Every front edge is evaluated again, as after a rebuild: the removal may have unblocked
  // edges elsewhere on the loops (the front is short by now: boundaries and stuck edges).
  for (std::uint32_t id = 0; id < edges_.size(); ++id)
    if (edges_[id].alive) push(id);
  if (check_every_step_) check_front();
}

void Builder::split_flat_triangle_holes() {
  forget_no_candidates();
  // A small hole whose corners are all collinear (points on a straight feature line: a slit,
  // every ear a sliver) cannot take triangles of its own. The triangle behind each of its edges
  // that spans other corners of the hole is split at them (a fan from its third vertex), so the
  // two sides of the slit meet edge to edge.
  if (front_stale_) rebuild_front();
  const std::size_t gaps_before = res_.filled_gaps;
  const double cos_flat = std::cos(0.05 * kPi / 180);
  std::vector<std::uint32_t> loop;
  std::vector<std::pair<double, std::uint32_t>> inner;
  std::vector<std::uint8_t> seen(edges_.size(), 0);
  for (std::uint32_t id = 0; id < edges_.size(); ++id) {
    if (!edges_[id].alive || seen[id]) continue;
    loop.clear();
    std::uint32_t e = id;
    do {
      loop.push_back(e);
      seen[e] = 1;
      e = edges_[e].next;
    } while (e != id && loop.size() <= opt_.fill_max_edges);
    if (e != id || loop.size() < 3 || loop.size() > opt_.fill_max_edges) continue;
    if (ctx_ != nullptr) {  // only around an active corner
      bool any = false;
      for (std::uint32_t r : loop) any = any || ctx_->active[edges_[r].a] != 0;
      if (!any) continue;
    }
    bool flat = true;
    for (std::uint32_t r : loop) {
      const FrontEdge& fe = edges_[r];
      flat = flat && min_angle_cos(fe.a, fe.b, edges_[fe.next].b) > cos_flat;
    }
    if (!flat) continue;
    bool split = false;
    for (std::uint32_t r : loop) {
      const std::uint32_t z = edges_[r].a, x = edges_[r].b, o = edges_[r].opp;
      const Vec3 d = p_[x] - p_[z];
      const double dd = d.squaredNorm();
      if (!(dd > 0)) continue;
      inner.clear();
      for (std::uint32_t q : loop) {
        const std::uint32_t m = edges_[q].a;
        if (m == z || m == x || m == o) continue;
        const double t = (p_[m] - p_[z]).dot(d) / dd;
        if (t > 0 && t < 1) inner.emplace_back(t, m);
      }
      if (inner.empty()) continue;
      bool fresh = true;  // the split edges must be new
      for (const auto& im : inner) fresh = fresh && edges_map_.find(im.second, o) == nullptr;
      if (!fresh) continue;
      std::sort(inner.begin(), inner.end());
      std::size_t at = tris_.size();  // the triangle (z, x, o), in any rotation
      for (std::size_t t = 0; t < tris_.size() && at == tris_.size(); ++t)
        for (std::size_t k = 0; k < 3; ++k)
          if (tris_[t][k] == z && tris_[t][(k + 1) % 3] == x && tris_[t][(k + 2) % 3] == o) at = t;
      if (at == tris_.size()) continue;
      if (at < bulk_kept_) fan_dirty_.insert(fan_dirty_.end(), {z, x, o});
      tris_[at] = {z, inner.front().second, o};
      renote(static_cast<std::uint32_t>(at));
      const auto first_new = static_cast<std::uint32_t>(tris_.size());
      for (std::size_t k = 1; k < inner.size(); ++k)
        tris_.push_back({inner[k - 1].second, inner[k].second, o});
      tris_.push_back({inner.back().second, x, o});
      for (auto id = first_new; id < tris_.size(); ++id) note_if_long(id);
#ifndef NDEBUG
      check_long_list();
#endif
      for (const auto& im : inner) edges_map_.insert(im.second, o, kInterior);
      split = true;
    }
    if (split) {
      ++res_.filled_gaps;
      front_stale_ = true;  // the slit's loop is closed now
    }
  }
  // Triangles were rewritten in place: once for all the splits.
  if (res_.filled_gaps != gaps_before) rebuild_corner_lists();
}

void Builder::rebuild_front() {
  forget_no_candidates();
  front_stale_ = false;
  // Every undirected edge with its triangle count; boundary half-edges become the new front.
  edges_.clear();
  free_edges_.clear();
  edges_map_ = EdgeMap(0);  // release the old table before the new one is built
  std::fill(head_out_.begin(), head_out_.end(), kNone);
  std::fill(valence_.begin(), valence_.end(), std::uint8_t{0});
  while (!ears_.empty()) ears_.pop();
  wave_.clear();
  deferred_.clear();
  // Vertex -> triangles (CSR, 4 bytes per corner): each undirected edge {u, v}, u < v, is
  // found from u's triangles, so no array of all half-edges is ever built (it was the peak of
  // the whole reconstruction). Edges are visited in (u, v) order, the half starting at u
  // first: the order the front's edge ids, and so its tie-breaking, depend on.
  const std::size_t n = p_.size();
  const detail::VertexTriangles adj(n, tris_);
  const std::vector<std::uint32_t>& start = adj.start;
  const std::vector<std::uint32_t>& vt = adj.list;
  edges_map_ = EdgeMap(tris_.size() * 3 / 2 + 16);
  struct Half {
    std::uint32_t other;  // the edge's larger end point
    std::uint32_t a, b, opp;
  };
  std::vector<Half> halves;
  for (std::uint32_t u = 0; u < n; ++u) {
    halves.clear();
    for (std::uint32_t s = start[u]; s < start[u + 1]; ++s) {
      const Triangle& t = tris_[vt[s]];
      const std::size_t k = t[0] == u ? 0 : (t[1] == u ? 1 : 2);
      const std::uint32_t next = t[(k + 1) % 3], prev = t[(k + 2) % 3];
      if (next > u) halves.push_back({next, u, next, prev});  // half u -> next
      if (prev > u) halves.push_back({prev, prev, u, next});  // half prev -> u
    }
    std::sort(halves.begin(), halves.end(), [](const Half& l, const Half& r) {
      return l.other != r.other ? l.other < r.other : l.a < r.a;
    });
    for (std::size_t i = 0; i < halves.size();) {
      std::size_t j = i;
      while (j < halves.size() && halves[j].other == halves[i].other) ++j;
      const Half& h = halves[i];
      ++valence_[h.a];
      ++valence_[h.b];
      if (j - i == 1) {
        new_edge(h.a, h.b, h.opp);  // inserts the map entry and the out-list link
      } else {
        edges_map_.insert(h.a, h.b, kInterior);
      }
      i = j;
    }
  }
  // After repair_fans every vertex has one fan, hence at most one outgoing edge.
  start_front();
}

/// A small component that crosses another grows from a seed among points a larger one left
/// unused under its triangles (at a sharp rim, where long triangles span the points along it; a
/// simulated line scan's cylinder rim had a 45-triangle flap over the cap): two sheets over one
/// surface, which no test of the growth sees (the other sheet has no front there, and its
/// vertices keep no corner lists). remove_crossing_components drops the smaller of each such
/// pair; its points become outliers, and the insertion stage puts them into the triangles they
/// lie on.
void Builder::drop_crossing_components() {
  triangles_moved();
  std::vector<std::uint8_t> keep;
  if (ctx_ != nullptr) {
    keep.resize(tris_.size());
    for (std::size_t i = 0; i < tris_.size(); ++i) keep[i] = from_context(tris_[i]) ? 1 : 0;
  }
  res_.dropped_components += remove_crossing_components(p_, tris_, keep);
}

/// Specks: components of at most kSpeckTriangles triangles beside one of at least
/// kSpeckContext. Such a piece is a seed that could not grow, among a few points off the
/// surface (a sensor's spikes that landed close together: a dense six-view scan with 1 %
/// spikes gets one to three lone triangles floating beside the part), not a surface the
/// scanner measured; its points become outliers (the insertion stage puts back any that lie on
/// a triangle). A cloud that is only specks keeps them.
bool Builder::drop_specks(detail::TriangleComponents& components) {
  constexpr std::uint32_t kSpeckTriangles = 2, kSpeckContext = 64;
  const std::vector<std::uint32_t>& size = components.sizes();
  if (size.size() < 2 || *std::max_element(size.begin(), size.end()) < kSpeckContext) return false;
  std::vector<std::uint8_t> kept(size.size(), 0);  // holding a context triangle
  if (ctx_ != nullptr)
    for (const Triangle& t : tris_)
      if (from_context(t)) kept[components.of(t)] = 1;
  std::size_t specks = 0;
  for (std::size_t c = 0; c < size.size(); ++c) specks += size[c] <= kSpeckTriangles && !kept[c] ? 1 : 0;
  if (specks == 0) return false;
  triangles_moved();
  std::erase_if(tris_, [&](const Triangle& t) {
    const std::uint32_t c = components.of(t);
    return size[c] <= kSpeckTriangles && !kept[c];
  });
  res_.dropped_specks += specks;
  return true;
}

void Builder::orient_components(detail::TriangleComponents& components) {
  const auto ncomp = static_cast<std::uint32_t>(components.count());
  // One component (the usual case): no look-ups in the passes below.
  auto comp = [&](const Triangle& t) { return ncomp == 1 ? 0u : components.of(t); };
  // Per component: whether it is open, and, for the closed ones, the signed volume. The front
  // matches the mesh here, so a component is open exactly when one of its vertices has a front
  // edge (an open fan).
  std::vector<std::uint8_t> open(ncomp, 0);
  std::uint32_t open_count = 0;
  for (const Triangle& t : tris_) {
    if (open_count == ncomp) break;  // all open (open scans: at once)
    const std::uint32_t c = comp(t);
    if (open[c]) continue;
    if (head_out_[t[0]] != kNone || head_out_[t[1]] != kNone || head_out_[t[2]] != kNone) {
      open[c] = 1;
      ++open_count;
    }
  }
#ifndef NDEBUG
  {
    // Checked against the edges: {u, v} is a boundary edge when exactly one of u's triangles
    // contains v.
    std::vector<std::uint8_t> open_edges(ncomp, 0);
    const detail::VertexTriangles adj(p_.size(), tris_);
    for (const Triangle& t : tris_)
      for (std::size_t k = 0; k < 3; ++k) {
        const std::uint32_t u = t[k], v = t[(k + 1) % 3];
        int uses = 0;
        for (std::uint32_t s = adj.start[u]; s < adj.start[u + 1]; ++s) {
          const Triangle& o = tris_[adj.list[s]];
          uses += (o[0] == v || o[1] == v || o[2] == v) ? 1 : 0;
        }
        if (uses == 1) open_edges[comp(t)] = 1;
      }
    assert(open_edges == open);
  }
#endif
  if (open_count == ncomp) return;  // the front's orientation stands
  std::vector<Vec3> centroid(ncomp, Vec3::Zero());
  std::vector<double> vol(ncomp, 0.0), count(ncomp, 0.0);
  for (const Triangle& t : tris_) {
    const std::uint32_t c = comp(t);
    centroid[c] += p_[t[0]];
    count[c] += 1;
  }
  for (const Triangle& t : tris_) {
    const std::uint32_t k = comp(t);
    const Vec3 c = centroid[k] / count[k];
    vol[k] += (p_[t[0]] - c).dot((p_[t[1]] - c).cross(p_[t[2]] - c));
  }
  std::vector<std::uint8_t> flip(ncomp, 0), fixed(ncomp, 0);
  if (ctx_ != nullptr)
    for (const Triangle& t : tris_)
      if (from_context(t)) fixed[comp(t)] = 1;
  for (std::uint32_t c = 0; c < ncomp; ++c)
    if (!open[c] && vol[c] < 0 && !fixed[c]) {
      flip[c] = 1;
      ++res_.flipped_components;
    }
  for (Triangle& t : tris_)
    if (flip[comp(t)]) std::swap(t[1], t[2]);
}

void Builder::cap_spacing(double median) {
  // A point's spacing is capped at kMaxSparsity times the cloud's median spacing, or, for a
  // point sparser than that, at kMaxSparsity times the median spacing (by area) of the points
  // within kRegionRadius of its own spacings, where it has at least kRegionPoints of them and
  // they lie on a plane with it. Where a whole region is sampled sparsely (an overview pass
  // beside a detail pass, a part scanned at a coarser line pitch) its points keep their own
  // spacing and connect; a point much sparser than its surroundings (a stray reading near the
  // surface) or a scatter of stray readings in the air (no plane) does not pull long triangles.
  // With the cloud's median alone, a region over about 5 times sparser than it fell apart.
  // Only the points over the cloud's cap are examined (none of the bunny's points, 85 of bun000's).
  const std::size_t n = p_.size();
  sp_.resize(n);
  res_.spacing_cap = kMaxSparsity * median;
  const auto cap = static_cast<float>(res_.spacing_cap);
  max_spacing_ = 0;
  const std::vector<std::uint32_t>& order = grid_.order();
  const std::vector<float>& raw = f_.spacing;
  struct Near {
    Vec3 d;     // offset from v
    float raw;  // its spacing
  };
  std::vector<Near> near;
  std::vector<float> on;
  for (std::uint32_t v = 0; v < n; ++v) {
    sp_[v] = std::min(raw[v], cap);
    if (raw[v] <= cap) continue;
    const double r = kRegionRadius * static_cast<double>(raw[v]);
    const Vec3& pv = p_[v];
    near.clear();
    Vec3 sum = Vec3::Zero();
    Eigen::Matrix3d moment = Eigen::Matrix3d::Zero();
    grid_.for_each_range_within(pv, r, [&](std::uint32_t first, std::uint32_t last) {
      for (std::uint32_t q = first; q < last; ++q) {
        const std::uint32_t u = order[q];
        const Vec3 d = p_[u] - pv;
        if (u == v || d.squaredNorm() > r * r) continue;
        near.push_back({d, raw[u]});
        sum += d;
        moment += d * d.transpose();
      }
    });
    if (near.size() < kRegionPoints) continue;
    // On a surface: the neighbourhood fits a plane, and v lies on it.
    const double m = static_cast<double>(near.size());
    const Vec3 mean = sum / m;
    const detail::PlaneFit fit = detail::plane_normal(moment / m - mean * mean.transpose());
    const Vec3 ev = fit.eigenvalues.cwiseMax(0.0);
    const double band = kRegionBand * static_cast<double>(raw[v]);
    if (!(ev[0] <= kRegionFlatness * ev.sum()) || std::abs(mean.dot(fit.normal)) > band) continue;
    // The median by area (each point weighs its spacing squared) of the neighbours on that
    // plane: beside a seam with a denser sampling, the dense points outnumber the sparse ones
    // but cover less of the surface; stray readings off the surface do not count.
    on.clear();
    for (const Near& q : near)
      if (std::abs((q.d - mean).dot(fit.normal)) <= band) on.push_back(q.raw);
    if (on.size() < kRegionPoints) continue;
    std::sort(on.begin(), on.end());
    double total = 0;
    for (float x : on) total += static_cast<double>(x) * x;
    double acc = 0;
    float mid = on.back();
    for (float x : on) {
      acc += static_cast<double>(x) * x;
      if (2 * acc >= total) {
        mid = x;
        break;
      }
    }
    sp_[v] = std::min(raw[v], std::max(cap, static_cast<float>(kMaxSparsity * static_cast<double>(mid))));
  }
  for (float x : sp_) max_spacing_ = std::max(max_spacing_, static_cast<double>(x));
}

void Builder::mark_turning_points() {
  // A point is a turning point when a point within the candidate reach has a normal more than
  // the normal rule's angle away from its own. Coarse first: per grid cell, the cone of its
  // normals (mean, widest deviation); a point whose normal is within that angle of every
  // neighbouring cell's cone has no such neighbour. The points the cones cannot clear get the
  // exact ball test.
  const std::size_t n = p_.size();
  turning_.assign(n, 0);
  if (n == 0) return;
  const double theta = std::acos(cos_normal_);
  const std::vector<std::uint32_t>& order = grid_.order();
  const std::vector<Eigen::Vector3f>& nrm = f_.normal;
  // Per cell: its first slot, the cone (mean, spread), limit = cos(theta - spread) (2: no
  // cone within theta); for the shortcuts below, a spread made safe against the rounding of
  // its float cosine (acos is ill-conditioned near 0): its cos and sin, and those of theta
  // minus it (cos_rest 2: that cone is not within theta).
  struct Cone {
    Eigen::Vector3f mean;
    float limit, cos_s, sin_s, cos_rest, sin_rest;
  };
  std::vector<std::uint32_t> cell_first, cell_of(n);  // cell_of: per slot, its cell
  std::vector<Cone> cone;
  grid_.for_each_cell([&](std::int64_t, std::int64_t, std::int64_t, std::uint32_t first,
                          std::uint32_t last) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (std::uint32_t s = first; s < last; ++s) sum += nrm[order[s]];
    const float len = sum.norm();
    const Eigen::Vector3f m = len > 0 ? Eigen::Vector3f(sum / len) : Eigen::Vector3f(1, 0, 0);
    float lowest = 1;
    for (std::uint32_t s = first; s < last; ++s) lowest = std::min(lowest, m.dot(nrm[order[s]]));
    const double spread = std::acos(std::clamp<double>(lowest, -1, 1));
    const double safe = std::acos(std::clamp<double>(static_cast<double>(lowest) - 1e-6, -1, 1));
    const bool ok = len > 0 && spread < theta;
    const bool safe_ok = len > 0 && safe < theta;
    for (std::uint32_t q = first; q < last; ++q) cell_of[q] = static_cast<std::uint32_t>(cell_first.size());
    cell_first.push_back(first);
    cone.push_back({m, ok ? static_cast<float>(std::cos(theta - spread)) : 2.0f,
                    static_cast<float>(std::cos(safe)), static_cast<float>(std::sin(safe)),
                    safe_ok ? static_cast<float>(std::cos(theta - safe)) : 2.0f,
                    static_cast<float>(std::sin(theta - safe))});
  });
  const std::size_t cells = cell_first.size();
  // Float slack of the cell-level shortcuts below (with the safe spreads): they skip only
  // where the point test would pass by more than the roundings, so the result is the point
  // test's.
  constexpr float kSlack = 1e-4f;
  // Two cones whose axes are at most theta - spread_c - spread_d apart hold no pair of normals
  // more than theta apart: cos of the axes' angle at least cos(theta - s_c - s_d), expanded.
  auto cones_agree = [&](std::size_t c, std::size_t d) {
    const Cone &cc = cone[c], &cd = cone[d];
    if (cc.cos_rest > 1 || cd.cos_rest > 1 || cc.sin_rest * cd.cos_s - cc.cos_rest * cd.sin_s <= 0)
      return false;  // theta - s_c - s_d <= 0 (its sine is the expression)
    return cc.mean.dot(cd.mean) >= cc.cos_rest * cd.cos_s + cc.sin_rest * cd.sin_s + kSlack;
  };
  grid_.for_each_cell([&](std::int64_t cx, std::int64_t cy, std::int64_t cz, std::uint32_t first,
                          std::uint32_t last) {
    const std::size_t c = cell_of[first];
    grid_.for_each_block_range(cx, cy, cz, 1, [&](std::uint32_t f, std::uint32_t l) {
      for (std::size_t d = cell_of[f]; d < cells && cell_first[d] < l; ++d) {
        if (cones_agree(c, d)) continue;
        for (std::uint32_t s = first; s < last; ++s) {
          const std::uint32_t v = order[s];
          if (!turning_[v] && nrm[v].dot(cone[d].mean) < cone[d].limit) turning_[v] = 1;
        }
      }
    });
  });
  const auto cos_limit = static_cast<float>(cos_normal_);
  for (std::uint32_t v = 0; v < n; ++v) {
    if (!turning_[v]) continue;
    const double r = opt_.radius_factor * 1.5 * spacing(v);
    const double r2 = r * r;
    const Vec3& pv = p_[v];
    const Eigen::Vector3f nv = nrm[v];
    bool found = false;
    // The ball's points cell by cell; a cell whose cone lies within theta of nv is skipped.
    grid_.for_each_range_within(pv, r, [&](std::uint32_t first, std::uint32_t last) {
      for (std::size_t d = cell_of[first]; d < cells && cell_first[d] < last && !found; ++d) {
        if (cone[d].cos_rest <= 1 && nv.dot(cone[d].mean) >= cone[d].cos_rest + kSlack) continue;
        const std::uint32_t end = std::min(last, d + 1 < cells ? cell_first[d + 1] : last);
        for (std::uint32_t s = std::max(first, cell_first[d]); s < end && !found; ++s) {
          const std::uint32_t u = order[s];
          if (nrm[u].dot(nv) < cos_limit && (p_[u] - pv).squaredNorm() <= r2) found = true;
        }
      }
    });
    turning_[v] = found ? 1 : 0;
  }
#ifndef NDEBUG
  if (check_every_step_) {
    // The cell shortcuts change nothing: the plain passes (every point against every
    // neighbouring cell's cone, then against every point of its ball) give the same flags.
    std::vector<std::uint8_t> plain(n, 0);
    grid_.for_each_cell([&](std::int64_t cx, std::int64_t cy, std::int64_t cz, std::uint32_t first,
                            std::uint32_t last) {
      grid_.for_each_block_range(cx, cy, cz, 1, [&](std::uint32_t f, std::uint32_t l) {
        for (std::size_t d = cell_of[f]; d < cells && cell_first[d] < l; ++d)
          for (std::uint32_t q = first; q < last; ++q)
            if (nrm[order[q]].dot(cone[d].mean) < cone[d].limit) plain[order[q]] = 1;
      });
    });
    for (std::uint32_t v = 0; v < n; ++v) {
      if (!plain[v]) continue;
      const double r = opt_.radius_factor * 1.5 * spacing(v);
      bool found = false;
      grid_.for_each_range_within(p_[v], r, [&](std::uint32_t first, std::uint32_t last) {
        for (std::uint32_t q = first; q < last; ++q)
          found = found || (nrm[order[q]].dot(nrm[v]) < cos_limit && (p_[order[q]] - p_[v]).squaredNorm() <= r * r);
      });
      plain[v] = found ? 1 : 0;
    }
    assert(plain == turning_ && "the turning points' cell shortcuts changed a flag");
  }
#endif
  // Points within reach of a turning point (2): a triangle there can cross one that a turning
  // point holds (a bevel across a sharp rim whose other face is unsampled: the cap beside it
  // has no turning point of its own, but the bevel's wall corner is one). Their triangles get
  // the test against everything near too; only turning points keep their lists.
  for (std::uint32_t v = 0; v < n; ++v)
    if (turning_[v] == 1) mark_near_turning(p_[v], opt_.radius_factor * 1.5 * spacing(v));
  for (std::uint8_t t : turning_) res_.turning_points += t == 1 ? 1 : 0;
}

void Builder::link_corner(std::uint32_t v, std::uint32_t tri) {
  std::uint32_t node = free_corner_;
  if (node != kNone) {
    free_corner_ = corners_[node].next;
    corners_[node] = {tri, corner_head_[v]};
  } else {
    node = static_cast<std::uint32_t>(corners_.size());
    corners_.push_back({tri, corner_head_[v]});
  }
  corner_head_[v] = node;
  slot_listed_[slot_of_[v]] = 1;
}

void Builder::release_corners(std::uint32_t v) {
  std::uint32_t node = corner_head_[v];
  if (node == kNone) return;
  std::uint32_t last = node;
  while (corners_[last].next != kNone) last = corners_[last].next;
  corners_[last].next = free_corner_;
  free_corner_ = node;
  corner_head_[v] = kNone;
  slot_listed_[slot_of_[v]] = 0;
}

void Builder::push_triangle(const Triangle& t) {
  const auto id = static_cast<std::uint32_t>(tris_.size());
  tris_.push_back(t);
  note_if_long(id);
  if (!pieces_stale_) pieces_.join(t);
  if (corner_head_.empty()) return;
  for (std::uint32_t v : t) link_corner(v, id);  // new corners are never closed yet
  mark_bent(t);
}

void Builder::mark_bent(const Triangle& t) {
  // A triangle more than 30 degrees off one of its corners' normals bends across a feature (a
  // bevel over a sharp edge). Where one face of the edge is sampled sparsely, the normals there
  // blend both faces and no turning point marks the edge, yet the triangles grown beside the
  // bevel later can cross it. So its corners become turning points (their lists stay, holding
  // the bevel), and the points within reach of it get the test against everything near.
  const Vec3 n = tri_normal(t[0], t[1], t[2]);
  const double len = n.norm();
  if (!(len > 0)) return;
  const Eigen::Vector3f nf = (n / len).cast<float>();
  bool bent = false;
  for (std::uint32_t v : t) bent = bent || std::abs(f_.normal[v].dot(nf)) < kCosBent;
  if (!bent) return;
  double r = 0;
  for (std::uint32_t v : t) {
    turning_[v] = 1;
    r = std::max(r, opt_.radius_factor * 1.5 * spacing(v));
  }
  const Vec3 c = (p_[t[0]] + p_[t[1]] + p_[t[2]]) / 3.0;
  const double reach = std::sqrt(std::max({(p_[t[0]] - c).squaredNorm(), (p_[t[1]] - c).squaredNorm(),
                                           (p_[t[2]] - c).squaredNorm()})) + r;
  mark_near_turning(c, reach);
}

void Builder::mark_near_turning(const Vec3& c, double r) {
  const double r2 = r * r;
  const std::uint32_t* order = grid_.order().data();
  grid_.for_each_range_within(c, r, [&](std::uint32_t first, std::uint32_t last) {
    for (std::uint32_t s = first; s < last; ++s) {
      const std::uint32_t u = order[s];
      if (turning_[u] == 0 && (p_[u] - c).squaredNorm() <= r2) turning_[u] = 2;
    }
  });
}

void Builder::rebuild_corner_lists() {
  if (corner_head_.empty()) return;
  std::fill(corner_head_.begin(), corner_head_.end(), kNone);
  std::fill(slot_listed_.begin(), slot_listed_.end(), std::uint8_t{0});
  corners_.clear();
  free_corner_ = kNone;
  for (std::uint32_t id = 0; id < tris_.size(); ++id)
    for (std::uint32_t v : tris_[id])
      if (keeps_list(v)) link_corner(v, id);
}

/// Whether triangle q lies strictly on one side of the plane through `o` with normal n (`tol`
/// scales with the triangles), ignoring its corners shared with the other triangle (`t`): then
/// the two meet at most at those shared corners. The cheap first step of the exact test.
bool Builder::apart(const Triangle& q, const Triangle& t, const Vec3& o, const Vec3& n,
                    double tol) const {
  int above = 0, below = 0;
  for (std::uint32_t w : q) {
    if (w == t[0] || w == t[1] || w == t[2]) continue;
    const double d = (p_[w] - o).dot(n);
    if (d > tol) ++above;
    else if (d < -tol) ++below;
    else return false;
  }
  return above == 0 || below == 0;
}

bool Builder::crosses_fans(const Triangle& t) {
  const Vec3& o = p_[t[0]];
  const Vec3 n = (p_[t[1]] - o).cross(p_[t[2]] - o);
  const double tol = on_plane_tol(n);
  for (std::uint32_t v : t)
    for (std::uint32_t c = corner_head_[v]; c != kNone; c = corners_[c].next) {
      const Triangle& q = tris_[corners_[c].tri];
      int shared = 0;
      for (std::uint32_t w : q) shared += (w == t[0] || w == t[1] || w == t[2]) ? 1 : 0;
      // Across a shared edge only a fold can overlap, and the dihedral rule refuses folds.
      if (shared >= 2 || apart(q, t, o, n, tol)) continue;
      const Vec3& oq = p_[q[0]];
      const Vec3 nq = (p_[q[1]] - oq).cross(p_[q[2]] - oq);
      if (apart(t, q, oq, nq, on_plane_tol(nq))) continue;
      if (triangles_intersect(p_, q, t, clear_)) return true;
    }
  return false;
}

bool Builder::crosses_mesh(const Triangle& t, double radius, bool touching) {
  const Vec3 &q0 = p_[t[0]], &q1 = p_[t[1]], &q2 = p_[t[2]];
  const detail::TriangleBounds tb(q0, q1, q2);
  near_tris_.clear();
  // Every point of a triangle lies within 0.58 of its longest edge of its nearest corner, and
  // edges are at most about `radius` long: a triangle that meets t has a corner within `near`
  // of t's centre. Only those corners' lists are walked (the cells hold about five times as
  // many points as the ball).
  any_listed_triangle_near(tb.centre, tb.reach + 0.6 * radius, [&](std::uint32_t id) {
    const Triangle& q = tris_[id];
    if (!tb.box_misses(p_[q[0]], p_[q[1]], p_[q[2]])) near_tris_.push_back(id);
    return false;
  });
  // The long triangles near t (the search above saw those it stamped). Their bins may name
  // a triangle no longer long or since rewritten: its box now decides, as in the list.
  long_bins_.visit(tb.lo, tb.hi, [&](std::uint32_t id) {
    LongTriangle q;
    if (seen_.seen(id) || !long_entry(id, q) || tb.box_misses(q.lo, q.hi)) return;
    seen_.take(id);
    near_tris_.push_back(id);
  });
#ifndef NDEBUG
  for (const LongTriangle& q : long_tris_)
    assert((tb.box_misses(q.lo, q.hi) || seen_.seen(q.id)) &&
           "the long triangles' bins missed one near a new triangle");
#endif
  const Vec3 n = (q1 - q0).cross(q2 - q0);
  const double tol = on_plane_tol(n);
  for (std::uint32_t id : near_tris_)
    if (!apart(tris_[id], t, q0, n, tol) && triangles_intersect(p_, tris_[id], t, clear_)) return true;
  if (touching)
    for (std::uint32_t id : near_tris_)
      if (triangles_touch(p_, tris_[id], t, clear_)) return true;
  return false;
}

void Builder::grow_from_bulk() {
  detail::BulkOptions bo;
  bo.radius_factor = opt_.radius_factor;
  bo.cos_min_angle = std::cos(opt_.min_angle_deg * kPi / 180);
  bo.cos_dihedral = std::cos((180.0 - opt_.min_dihedral_deg) * kPi / 180);
  bo.cos_corner = std::max<double>(kCosBent, cos_normal_);
  bo.spacing = sp_;
  bo.max_valence = opt_.max_valence;
  bo.max_patch_points = opt_.bulk_patch_points;
  bo.patch_cone_deg = opt_.bulk_patch_cone_deg;
  bo.long_edge2 = long_edge2_;
  step("front/bulk");
  detail::BulkStats stats;
  detail::BulkMesh bulk;
  bulk.triangles.swap(tris_);  // empty, with the storage reserved for the whole mesh
  if (ctx_ != nullptr) {
    // Only free points: the context's vertices have their triangles already.
    std::vector<std::uint8_t> excluded(p_.size(), 0);
    for (std::size_t v = 0; v < excluded.size(); ++v)
      excluded[v] = (!turning_.empty() && turning_[v] != 0) ? 1 : 0;
    for (const Triangle& t : ctx_->triangles)
      for (std::uint32_t v : t) excluded[v] = 1;
    // Nor the points near them: the bulk's triangles are not tested against the context's,
    // so the patches keep a grid ring away and the front (with its crossing guard) joins them.
    for (std::uint32_t v = 0; v < p_.size(); ++v) {
      if (excluded[v] || state_[v] != VertexState::kFree) continue;
      bool near = false;
      grid_.for_each_near(p_[v], 1, [&](std::uint32_t q) {
        near = near || (ctx_->active[q] == 0);
      });
      if (near) excluded[v] = 2;
    }
    for (std::uint8_t& e : excluded) e = e != 0 ? 1 : 0;
    detail::bulk_triangles(p_, f_, grid_, excluded, bo, bulk, stats);
  } else {
    detail::bulk_triangles(p_, f_, grid_, turning_, bo, bulk, stats);
  }
  tris_.swap(bulk.triangles);
  bulk_kept_ = tris_.size();
  for (const std::uint32_t id : bulk.long_triangles) note_if_long(id);
#ifndef NDEBUG
  check_long_list();
#endif
  pieces_stale_ = true;
  res_.bulk_patches = stats.patches;
  res_.bulk_triangles = stats.triangles;
  if (tris_.empty()) return;
  // The front along the bulk's border, as rebuild_front would make it but without a pass over
  // every edge: the bulk knows its border, and the interior edges the front can meet (those
  // between two border vertices).
  forget_no_candidates();
  for (const Triangle& t : tris_)
    for (std::uint32_t v : t) ++valence_[v];
  for (const auto& [a, b, opp] : bulk.border) {
    new_edge(a, b, opp);
    ++valence_[a];  // an open fan of k triangles has k + 1 edges
  }
  for (const auto& [u, w] : bulk.border_chords) edges_map_.insert(u, w, kInterior);
  start_front();  // the bulk leaves every vertex one fan
  if (check_every_step_) check_front();
}

void Builder::load_context() {
  for (const Triangle& t : ctx_->triangles) {
    const auto id = static_cast<std::uint32_t>(tris_.size());
    tris_.push_back(t);
    note_if_long(id);
  }
  pieces_stale_ = true;
  rebuild_front();
  if (check_every_step_) check_front();
}

FrontResult Builder::run() {
  const std::size_t n = p_.size();
  if (opt_.bulk) grow_from_bulk();
  if (ctx_ != nullptr) load_context();
  step("front/growth");
  grow();  // from the bulk's border (without the bulk there is no front yet)
  // Seeds, among the points still free (states only move forward while the front grows):
  // flattest first, index breaking ties, so the order is deterministic. A stable two-pass radix
  // sort on the bits of the flatness (non-negative floats order like their bit patterns; -0 is
  // made +0), which gives the order of a comparison sort by (flatness, index).
  std::vector<std::uint32_t> order;
  {
    std::vector<std::uint32_t> tmp;  // the input of each pass, ascending index
    for (std::uint32_t i = 0; i < n; ++i)
      if (state_[i] == VertexState::kFree) tmp.push_back(i);
    order.resize(tmp.size());
    auto key = [&](std::uint32_t i) { return std::bit_cast<std::uint32_t>(f_.flatness[i] + 0.0f); };
    std::vector<std::uint32_t> count(1u << 16);
    for (int shift = 0; shift < 32; shift += 16) {
      std::fill(count.begin(), count.end(), 0u);
      for (std::uint32_t i : tmp) ++count[(key(i) >> shift) & 0xffffu];
      std::uint32_t sum = 0;
      for (std::uint32_t& c : count) {
        const std::uint32_t here = c;
        c = sum;
        sum += here;
      }
      for (std::uint32_t i : tmp) order[count[(key(i) >> shift) & 0xffffu]++] = i;
      if (shift == 0) tmp.swap(order);
    }
  }
  for (std::uint32_t s : order) {
    if (state_[s] != VertexState::kFree || covered_[s] != 0) continue;
    if (try_seed(s)) grow();
  }
  std::vector<std::uint32_t>().swap(order);
  step("front/repairs");
  // Close sampling gaps, then keep vertices manifold; repairs can open small gaps again, so
  // one more round of each.
  fill_small_loops();
  // Dropping fans opens small gaps: rebuild the front from the mesh and let it close them.
  for (int round = 0; round < 2 && repair_fans() > 0; ++round) {
    if (front_stale_) rebuild_front();
    grow();
    fill_small_loops();
  }
  // The last word: every vertex keeps a single fan; gaps this opens are closed by ear clipping
  // only.
  for (int round = 0; round < 3 && repair_fans() > 0; ++round) {
    if (front_stale_) rebuild_front();
    fill_small_loops();
  }
  split_flat_triangle_holes();
  // Guarantee, checked at every vertex (two closed fans touching at one vertex leave no trace
  // in the front): no multi-fan vertex in the output. A pinch found here is cut and its gap
  // closed by ear clipping; one that survives two such rounds stays a small boundary loop. The
  // edge table is freed first: this check's vertex lists would otherwise sit on top of it at
  // the peak of the whole reconstruction.
  step("front/fan check");
  for (int round = 0; round < 3; ++round) {
    edges_map_ = EdgeMap(0);
    if (repair_fans(true) == 0) break;
    rebuild_front();
    if (round < 2) fill_small_loops();
  }
  if (check_every_step_) check_bulk_fans();
  if (front_stale_) rebuild_front();  // a slit closed above: the states and the orientation read it
  edges_map_ = EdgeMap(0);  // not needed any more
  step("front/orientation");
  {
    // Components can only cross when there are several; the orientation pass needs them too.
    detail::TriangleComponents components(n, tris_);
    if (components.count() > 1) {
      const std::size_t before = tris_.size();
      drop_crossing_components();
      if (tris_.size() != before) components = detail::TriangleComponents(n, tris_);
      if (drop_specks(components)) components = detail::TriangleComponents(n, tris_);
    }
    orient_components(components);
  }
  // Final states: vertices in no triangle are outliers; vertices with open fans are boundary.
  std::vector<std::uint8_t> used(n, 0);
  for (const Triangle& t : tris_)
    for (std::uint32_t v : t) used[v] = 1;
  for (std::uint32_t v = 0; v < n; ++v) {
    if (!used[v]) {
      state_[v] = VertexState::kOutlier;
      res_.outliers.push_back(v);
    } else if (head_out_[v] != kNone) {
      state_[v] = VertexState::kBoundary;
    } else {
      state_[v] = VertexState::kDone;
    }
  }
  res_.triangles = std::move(tris_);
  res_.state = std::move(state_);
  res_.spacing = std::move(sp_);
  return std::move(res_);
}

}  // namespace

std::vector<std::string> FrontOptions::validate() const {
  std::vector<std::string> errors;
  if (!(min_angle_deg >= 0 && min_angle_deg < 60))
    errors.push_back("min_angle_deg must be in [0, 60), got " + std::to_string(min_angle_deg));
  if (!(min_dihedral_deg >= 0 && min_dihedral_deg < 180))
    errors.push_back("min_dihedral_deg must be in [0, 180)");
  if (!(radius_factor > 0.5 && radius_factor <= 10)) errors.push_back("radius_factor must be in (0.5, 10]");
  if (!(relaxed_radius_factor >= radius_factor && relaxed_radius_factor <= 10))
    errors.push_back("relaxed_radius_factor must be in [radius_factor, 10]");
  if (!(relaxed_min_angle_deg >= 0 && relaxed_min_angle_deg <= min_angle_deg))
    errors.push_back("relaxed_min_angle_deg must be in [0, min_angle_deg]");
  if (max_valence < 6 || max_valence > 250) errors.push_back("max_valence must be in [6, 250]");
  if (!(hole_min_area >= 0 && hole_min_area <= 1e6)) errors.push_back("hole_min_area must be in [0, 1e6]");
  if (!(hole_min_width >= 0 && hole_min_width <= 1e3)) errors.push_back("hole_min_width must be in [0, 1e3]");
  if (bulk_patch_points < 3) errors.push_back("bulk_patch_points must be at least 3");
  if (!(bulk_patch_cone_deg > 0 && bulk_patch_cone_deg < 90))
    errors.push_back("bulk_patch_cone_deg must be in (0, 90) degrees");
  return errors;
}

FrontResult advance_front(std::span<const Vec3> points, const LocalFrames& frames,
                          const PointGrid& grid, const FrontOptions& options,
                          const StageObserver& observer) {
  Builder b(points, frames, grid, options, observer);
  return b.run();
}

namespace detail {

FrontResult advance_front_from(std::span<const Vec3> points, const LocalFrames& frames,
                               const PointGrid& grid, const FrontOptions& options,
                               const FrontContext& context) {
  const StageObserver none;
  Builder b(points, frames, grid, options, none, &context);
  return b.run();
}

}  // namespace detail

}  // namespace scanmesh::recon
