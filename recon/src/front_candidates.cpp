// The advancing front's choice of apex: seeds, the candidate scan of a front edge and the
// validity tests of a candidate triangle (sectors, front edges, normals, stacking).
// SPDX-License-Identifier: MIT
#include "front_builder.hpp"

namespace scanmesh::recon::front_impl {

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

}  // namespace scanmesh::recon::front_impl
