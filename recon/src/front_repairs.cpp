// The advancing front's repairs: one fan per vertex, the front rebuilt after removals,
// flat-triangle holes split, crossing components and specks dropped.
// SPDX-License-Identifier: MIT
#include "front_builder.hpp"

namespace scanmesh::recon::front_impl {

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

}  // namespace scanmesh::recon::front_impl
