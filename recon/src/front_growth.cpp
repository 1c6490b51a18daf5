// The advancing front's growth: adding a triangle and updating the front, the growth loop,
// hole marking, small-loop filling, the bulk's patches and a context mesh as starting fronts.
// SPDX-License-Identifier: MIT
#include "front_builder.hpp"

namespace scanmesh::recon::front_impl {

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

}  // namespace scanmesh::recon::front_impl
