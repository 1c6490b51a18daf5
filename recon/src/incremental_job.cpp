// One meshing job of the incremental path (incremental_job.hpp).
// SPDX-License-Identifier: MIT
#include "incremental_job.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/fill.hpp"
#include "scanmesh/recon/front.hpp"
#include "scanmesh/recon/grid.hpp"
#include "scanmesh/recon/normals.hpp"
#include "triangle_components.hpp"

namespace scanmesh::recon::detail {

namespace {

/// The context of a job: the published triangles with a vertex within a band of the job's
/// blocks, then the whole fans of their vertices. The band is twice the longest published edge
/// plus kContextSlackCubes wide (a new triangle reaches about one edge out of the job, a
/// published one that could cross it has a corner within one edge of that), at least
/// kContextMinCubes, at most one block (then it is the whole neighbour blocks).
constexpr int kContextMinCubes = 4;
constexpr int kContextSlackCubes = 2;

/// The rotation of t that starts at its smallest vertex (orientation kept).
Triangle canonical(const Triangle& t) {
  const int k = t[0] < t[1] ? (t[0] < t[2] ? 0 : 2) : (t[1] < t[2] ? 1 : 2);
  return {t[k], t[(k + 1) % 3], t[(k + 2) % 3]};
}

}  // namespace

std::uint32_t JobMesher::publish_vertex(std::uint32_t cube, const Vec3& p,
                                        const Eigen::Vector3f& normal, float spacing) {
  const std::uint32_t id = mesh_.add_vertex(p);
  grid_.set_vertex(cube, id);
  vertex_cube_.push_back(cube);
  vertex_normal_.push_back(normal);
  vertex_spacing_.push_back(spacing);
  vertex_uses_.push_back(0);
  return id;
}

std::uint32_t JobMesher::publish_triangle(const Triangle& t) {
  const std::uint32_t id = mesh_.add_triangle(t);
  if (block_tris_.size() < grid_.block_count()) block_tris_.resize(grid_.block_count());
  for (int k = 0; k < 3; ++k)
    max_edge2_ = std::max(max_edge2_, (mesh_.vertex(t[k]) - mesh_.vertex(t[(k + 1) % 3])).squaredNorm());
  std::uint32_t seen[3];
  int n = 0;
  for (std::uint32_t v : t) {
    ++vertex_uses_[v];
    const std::uint32_t b = grid_.block_of(vertex_cube_[v]);
    if (std::find(seen, seen + n, b) != seen + n) continue;
    seen[n++] = b;
    block_tris_[b].push_back(id);
  }
  return id;
}

const std::vector<std::uint32_t>& JobMesher::live_triangles(std::uint32_t b) {
  if (block_tris_.size() < grid_.block_count()) block_tris_.resize(grid_.block_count());
  std::vector<std::uint32_t>& l = block_tris_[b];
  std::erase_if(l, [&](std::uint32_t id) { return !mesh_.alive(id); });
  return l;
}

void JobMesher::update_boundary(std::vector<std::uint32_t> vertices) {
  // By block: each block's triangle list is read once. (The ids come with many repeats: a
  // plain sort drops them before each vertex's block is looked up, once.)
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  std::vector<std::pair<std::uint32_t, std::uint32_t>> by_block;  // (block, vertex)
  by_block.reserve(vertices.size());
  for (std::uint32_t v : vertices) by_block.emplace_back(grid_.block_of(vertex_cube_[v]), v);
  std::sort(by_block.begin(), by_block.end());
  for (std::size_t k = 0; k < by_block.size(); ++k) vertices[k] = by_block[k].second;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> half;
  for (std::size_t i = 0; i < vertices.size();) {
    const std::uint32_t b = by_block[i].first;
    std::size_t j = i;
    while (j < vertices.size() && by_block[j].first == b) ++j;
    // The half-edges of the triangles around these vertices only: an out-edge's twin lies in
    // a triangle of the same vertex, and every triangle of a vertex is listed under its block.
    near_.resize(vertex_cube_.size(), 0);  // scratch: marks this block's vertices
    for (std::size_t k = i; k < j; ++k) near_[vertices[k]] = 1;
    half.clear();
    for (std::uint32_t id : live_triangles(b)) {
      const Triangle& t = mesh_.triangle(id);
      if ((near_[t[0]] | near_[t[1]] | near_[t[2]]) == 0) continue;
      for (int k = 0; k < 3; ++k) half.emplace_back(t[k], t[(k + 1) % 3]);
    }
    for (std::size_t k = i; k < j; ++k) near_[vertices[k]] = 0;
    std::sort(half.begin(), half.end());
    for (std::size_t k = i; k < j; ++k) {
      const std::uint32_t v = vertices[k];
      std::uint32_t next = kNoId;
      auto it = std::lower_bound(half.begin(), half.end(), std::make_pair(v, std::uint32_t{0}));
      for (; it != half.end() && it->first == v && next == kNoId; ++it)
        if (!std::binary_search(half.begin(), half.end(), std::make_pair(it->second, v))) next = it->second;
      if (next != kNoId || boundary_next_.find(v) != kNoId) boundary_next_.assign(v, next);
    }
    i = j;
  }
}

std::vector<std::vector<std::uint32_t>> JobMesher::loops_through(
    std::span<const std::uint32_t> touched) const {
  std::vector<std::vector<std::uint32_t>> loops;
  std::vector<std::uint32_t> seen;  // loop starts (smallest ids) already given
  // The vertices of the loops found (sorted): a touched vertex on one is not walked again
  // (many touched vertices share a loop: walking each was O(touched x loop)).
  std::vector<std::uint32_t> on_loop;
  for (const std::uint32_t t : touched) {
    if (boundary_next_.find(t) == kNoId) continue;
    if (std::binary_search(on_loop.begin(), on_loop.end(), t)) continue;
    std::vector<std::uint32_t> loop{t};
    std::uint32_t v = boundary_next_.find(t);
    while (v != kNoId && v != t && loop.size() <= mesh_.vertex_count()) {
      loop.push_back(v);
      v = boundary_next_.find(v);
    }
    if (v != t) continue;  // not closed (cannot happen on a manifold mesh)
    std::rotate(loop.begin(), std::min_element(loop.begin(), loop.end()), loop.end());
    if (std::find(seen.begin(), seen.end(), loop.front()) != seen.end()) continue;
    seen.push_back(loop.front());
    const std::size_t mid = on_loop.size();
    on_loop.insert(on_loop.end(), loop.begin(), loop.end());
    std::sort(on_loop.begin() + static_cast<std::ptrdiff_t>(mid), on_loop.end());
    std::inplace_merge(on_loop.begin(), on_loop.begin() + static_cast<std::ptrdiff_t>(mid), on_loop.end());
    loops.push_back(std::move(loop));
  }
  std::sort(loops.begin(), loops.end());
  return loops;
}

bool JobMesher::used(std::uint32_t vertex) const {
  return vertex < vertex_uses_.size() && vertex_uses_[vertex] > 0;
}

int JobMesher::sectors(std::span<const std::uint32_t> fan, std::uint32_t v) const {
  // Boundary out-edges at v among the fan's triangles: 0 for a closed fan, 1 for an open one.
  int outs = 0;
  for (std::uint32_t id : fan) {
    const Triangle& t = mesh_.triangle(id);
    const int k = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
    const std::uint32_t w = t[(k + 1) % 3];
    bool twin = false;  // (w, v) in another triangle of the fan
    for (std::uint32_t o : fan) {
      const Triangle& u = mesh_.triangle(o);
      for (int j = 0; j < 3 && !twin; ++j) twin = u[j] == w && u[(j + 1) % 3] == v;
    }
    if (!twin) ++outs;
  }
  return outs;
}

void JobMesher::run(std::span<const std::uint32_t> job) {
  ++stats_.jobs;
  if (block_tris_.size() < grid_.block_count()) block_tris_.resize(grid_.block_count());
  std::vector<std::uint32_t> changed;  // vertices whose fans changed: boundary successors
  auto remove = [&](std::uint32_t id) {
    if (!mesh_.alive(id)) return;
    for (std::uint32_t v : mesh_.triangle(id)) {
      --vertex_uses_[v];
      changed.push_back(v);
    }
    mesh_.remove_triangle(id);
    ++stats_.removed;
  };
  // A re-opened block: every triangle with a vertex in it goes (meshed again below). A vertex
  // around it whose fan that splits in two (the block's triangles met it on two sides) is freed
  // too, all its triangles removed, and meshed with the job: the front needs one fan a vertex.
  std::vector<std::uint32_t> freed, touched;
  for (std::uint32_t b : job)
    for (std::uint32_t id : std::vector<std::uint32_t>(live_triangles(b))) {
      for (std::uint32_t v : mesh_.triangle(id)) touched.push_back(v);
      remove(id);
    }
  while (!touched.empty()) {
    std::sort(touched.begin(), touched.end());
    touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
    std::vector<std::uint32_t> next;
    for (std::uint32_t v : touched) {
      if (vertex_uses_[v] == 0) continue;
      std::vector<std::uint32_t> fan;
      for (std::uint32_t id : live_triangles(grid_.block_of(vertex_cube_[v]))) {
        const Triangle& t = mesh_.triangle(id);
        if (t[0] == v || t[1] == v || t[2] == v) fan.push_back(id);
      }
      if (sectors(fan, v) <= 1) continue;
      freed.push_back(v);
      for (std::uint32_t id : fan) {
        for (std::uint32_t w : mesh_.triangle(id)) next.push_back(w);
        remove(id);
      }
    }
    touched.swap(next);
  }
  std::sort(freed.begin(), freed.end());
  freed.erase(std::unique(freed.begin(), freed.end()), freed.end());

  // The zone: the job and its neighbours. Context: every live triangle with a vertex there, and
  // the whole fan of any vertex outside the zone whose triangles in the context form more than
  // one sector (the front needs one fan a vertex).
  std::vector<std::uint32_t> zone;
  for (std::uint32_t b : job) {
    const std::vector<std::uint32_t> nb = grid_.neighbour_blocks(b);
    zone.insert(zone.end(), nb.begin(), nb.end());
  }
  std::sort(zone.begin(), zone.end());
  zone.erase(std::unique(zone.begin(), zone.end()), zone.end());
  std::vector<std::uint8_t> in_job(grid_.block_count(), 0);
  for (std::uint32_t b : job) in_job[b] = 1;
  // The context proper: the live triangles with a vertex within the band around the job's
  // blocks (see kContextMinCubes), not the whole neighbour blocks.
  const int band = std::clamp(
      static_cast<int>(std::ceil(2 * std::sqrt(max_edge2_) / grid_.cube())) + kContextSlackCubes,
      kContextMinCubes, grid_.block_cubes());
  near_.resize(vertex_cube_.size(), 0);
  auto is_near = [&](std::uint32_t v) {
    if (near_[v] == 0) {
      near_[v] = grid_.near_blocks(vertex_cube_[v], job, band) ? 1 : 2;
      near_set_.push_back(v);
    }
    return near_[v] == 1;
  };
  std::vector<std::uint32_t> context;
  for (std::uint32_t b : zone)
    for (std::uint32_t id : live_triangles(b)) {
      const Triangle& t = mesh_.triangle(id);
      if (is_near(t[0]) || is_near(t[1]) || is_near(t[2])) context.push_back(id);
    }
  std::sort(context.begin(), context.end());
  context.erase(std::unique(context.begin(), context.end()), context.end());
  // Every vertex of those triangles gets its whole fan (the repairs may remove triangles around
  // any of them, and must see the whole fan to keep it one); then the vertices at the rim whose
  // triangles in the context form two sectors get theirs too.
  auto add_fans = [&](const std::vector<std::uint32_t>& vertices) {
    // By block: each block's triangle list is read once (not once a vertex).
    std::vector<std::pair<std::uint32_t, std::uint32_t>> by_block;  // (block, vertex)
    by_block.reserve(vertices.size());
    for (std::uint32_t v : vertices) by_block.emplace_back(grid_.block_of(vertex_cube_[v]), v);
    std::sort(by_block.begin(), by_block.end());
    for (std::size_t i = 0; i < by_block.size();) {
      std::size_t j = i;
      while (j < by_block.size() && by_block[j].first == by_block[i].first) ++j;
      auto is_listed = [&](std::uint32_t v) {
        return std::binary_search(by_block.begin() + static_cast<std::ptrdiff_t>(i),
                                  by_block.begin() + static_cast<std::ptrdiff_t>(j),
                                  std::make_pair(by_block[i].first, v));
      };
      for (std::uint32_t id : live_triangles(by_block[i].first)) {
        const Triangle& t = mesh_.triangle(id);
        if (is_listed(t[0]) || is_listed(t[1]) || is_listed(t[2])) context.push_back(id);
      }
      i = j;
    }
    std::sort(context.begin(), context.end());
    context.erase(std::unique(context.begin(), context.end()), context.end());
  };
  {
    std::vector<std::uint32_t> outside;
    for (std::uint32_t id : context)
      for (std::uint32_t v : mesh_.triangle(id))
        if (!is_near(v)) outside.push_back(v);
    std::sort(outside.begin(), outside.end());
    outside.erase(std::unique(outside.begin(), outside.end()), outside.end());
    add_fans(outside);
  }
  std::vector<std::uint8_t> full;  // per vertex id: its whole fan is in the context
  for (int round = 0; round < 16; ++round) {
    // Directed edges of the context; a vertex with two boundary out-edges has two sectors.
    std::vector<std::pair<std::uint32_t, std::uint32_t>> half;
    half.reserve(context.size() * 3);
    for (std::uint32_t id : context) {
      const Triangle& t = mesh_.triangle(id);
      for (int k = 0; k < 3; ++k) half.emplace_back(t[k], t[(k + 1) % 3]);
    }
    std::sort(half.begin(), half.end());
    std::vector<std::uint32_t> split;
    std::uint32_t last = kNoId;
    int outs = 0;
    for (const auto& [u, v] : half) {
      if (u != last) {
        last = u;
        outs = 0;
      }
      if (std::binary_search(half.begin(), half.end(), std::make_pair(v, u))) continue;
      if (++outs == 2) split.push_back(u);
    }
    if (split.empty()) break;
    const std::size_t before = context.size();
    add_fans(split);
    if (context.size() == before) break;
  }
  for (std::uint32_t v : near_set_) near_[v] = 0;
  near_set_.clear();
  stats_.context_triangles += context.size();

  // The job's points: the context's vertices (ascending id), then the job's kept points after
  // thinning. Then, for the frames only, the free kept points of the neighbouring blocks near
  // the job.
  std::vector<std::uint32_t> ctx_vertices;
  for (std::uint32_t id : context)
    for (std::uint32_t v : mesh_.triangle(id)) ctx_vertices.push_back(v);
  std::sort(ctx_vertices.begin(), ctx_vertices.end());
  ctx_vertices.erase(std::unique(ctx_vertices.begin(), ctx_vertices.end()), ctx_vertices.end());
  std::vector<std::uint32_t> job_cubes = grid_.thinned_cubes_of(job);
  for (std::uint32_t v : freed)
    if (vertex_uses_[v] == 0) job_cubes.push_back(vertex_cube_[v]);
  const std::size_t nc = ctx_vertices.size(), n = nc + job_cubes.size();
  if (job_cubes.empty()) {
    update_boundary(std::move(changed));
    return;
  }
  std::vector<Vec3> pts;
  pts.reserve(n);
  for (std::uint32_t v : ctx_vertices) pts.push_back(mesh_.vertex(v));
  auto position = [&](std::uint32_t c) {
    const std::uint32_t v = grid_.vertex_of(c);
    return v != kNoId ? mesh_.vertex(v) : (opt_.project ? grid_.projected(c) : grid_.rep(c));
  };
  for (std::uint32_t c : job_cubes) pts.push_back(position(c));
  std::vector<std::uint32_t> ring;
  for (std::uint32_t b : zone)
    if (!in_job[b]) ring.push_back(b);
  for (std::uint32_t c : grid_.cubes_near(job, ring, 4))
    if (grid_.vertex_of(c) == kNoId) pts.push_back(position(c));
  if (pts.size() < 3) {
    update_boundary(std::move(changed));
    return;
  }

  // Frames over all of them; the context's vertices keep the normals and spacings they were
  // meshed with, and orient the rest (as sensor directions: each part the propagation orients
  // is turned to agree with them, or with the sensors where no context is near).
  std::vector<Vec3> towards(pts.size(), Vec3::Zero());
  bool any = false;
  for (std::size_t i = 0; i < nc; ++i) {
    towards[i] = vertex_normal_[ctx_vertices[i]].cast<double>();
    any = true;
  }
  for (std::size_t i = nc; i < n; ++i) {
    const std::uint32_t c = job_cubes[i - nc];
    towards[i] = grid_.towards(c);
    any = any || towards[i] != Vec3::Zero();
  }
  if (!any) towards.clear();
  LocalFrames frames;
  {
    PointGrid g;
    g.build(pts, 2.5 * grid_.cube());
    try {
      frames = estimate_frames(pts, g, opt_.normals, towards);
    } catch (const GeometryError&) {
      update_boundary(std::move(changed));
      return;  // not a surface yet
    }
  }
  pts.resize(n);
  frames.normal.resize(n);
  frames.spacing.resize(n);
  frames.flatness.resize(n);
  for (std::size_t i = 0; i < nc; ++i) {
    frames.normal[i] = vertex_normal_[ctx_vertices[i]];
    frames.spacing[i] = vertex_spacing_[ctx_vertices[i]];
  }
  // The front's grid: one ring of cells covers its reach (as the batch path).
  PointGrid grid;
  {
    std::vector<float> sp(frames.spacing.begin() + static_cast<std::ptrdiff_t>(nc), frames.spacing.end());
    std::nth_element(sp.begin(), sp.begin() + static_cast<std::ptrdiff_t>(sp.size() / 2), sp.end());
    const double median = std::max<double>(sp[sp.size() / 2], 1e-3 * grid_.cube());
    grid.build(pts, (opt_.front.radius_factor * 1.5 + 0.6) * median);
  }
  // The context in the job's numbering.
  std::vector<Triangle> ctx_local;
  ctx_local.reserve(context.size());
  auto local_of = [&](std::uint32_t v) {
    return static_cast<std::uint32_t>(std::lower_bound(ctx_vertices.begin(), ctx_vertices.end(), v) -
                                      ctx_vertices.begin());
  };
  for (std::uint32_t id : context) {
    const Triangle& t = mesh_.triangle(id);
    ctx_local.push_back({local_of(t[0]), local_of(t[1]), local_of(t[2])});
  }
  std::vector<std::uint8_t> active(n, 0);
  std::fill(active.begin() + static_cast<std::ptrdiff_t>(nc), active.end(), 1);
  const FrontResult fr =
      advance_front_from(pts, frames, grid, opt_.front, FrontContext{ctx_local, active});

  // Publish the difference: context triangles gone are removed, new ones added.
  std::vector<std::pair<Triangle, std::uint32_t>> before;  // canonical local -> published id
  before.reserve(context.size());
  for (std::size_t i = 0; i < context.size(); ++i) before.emplace_back(canonical(ctx_local[i]), context[i]);
  std::sort(before.begin(), before.end());
  std::vector<std::uint8_t> kept(before.size(), 0);
  std::vector<Triangle> added;
  for (const Triangle& t : fr.triangles) {
    const Triangle k = canonical(t);
    const auto it = std::lower_bound(before.begin(), before.end(), std::make_pair(k, std::uint32_t{0}));
    if (it != before.end() && it->first == k) {
      kept[static_cast<std::size_t>(it - before.begin())] = 1;
    } else {
      added.push_back(t);
    }
  }
  for (std::size_t i = 0; i < before.size(); ++i)
    if (!kept[i]) remove(before[i].second);
  std::vector<std::uint32_t> id_of(n, kNoId);
  for (std::size_t i = 0; i < nc; ++i) id_of[i] = ctx_vertices[i];
  for (const Triangle& t : added) {
    Triangle g;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t l = t[k];
      if (id_of[l] == kNoId) {
        const std::uint32_t c = job_cubes[l - nc];
        id_of[l] = grid_.vertex_of(c);
        if (id_of[l] == kNoId) id_of[l] = publish_vertex(c, pts[l], frames.normal[l], fr.spacing[l]);
      }
      g[k] = id_of[l];
      changed.push_back(g[k]);
    }
    publish_triangle(g);
  }
  update_boundary(std::move(changed));
}

void JobMesher::close() {
  // Sampling gaps: the batch path's gap closing over the whole published mesh (loops of at most
  // gap_max_edges edges within the perimeter limit, with their own vertices).
  if (opt_.close_gaps && opt_.gap_max_edges > 0 && mesh_.triangle_count() > 0) {
    const MeshSnapshot snap = mesh_.snapshot();
    std::vector<std::uint32_t> ids;
    Mesh m = snap.to_mesh(&ids);
    std::vector<float> spacing(ids.size());
    for (std::size_t i = 0; i < ids.size(); ++i) spacing[i] = vertex_spacing_[ids[i]];
    const std::size_t before = m.triangles.size();
    FillOptions gap_fill;
    gap_fill.max_edges = opt_.gap_max_edges;
    gap_fill.max_perimeter_spacings = opt_.front.fill_perimeter_factor;
    gap_fill.refine = false;
    const FillStats fs = fill_holes(m, gap_fill, spacing);
    stats_.gaps_closed += fs.filled;
    std::vector<std::uint32_t> changed;
    for (std::size_t i = before; i < m.triangles.size(); ++i) {
      const Triangle& t = m.triangles[i];
      publish_triangle({ids[t[0]], ids[t[1]], ids[t[2]]});
      for (std::uint32_t v : t) changed.push_back(ids[v]);
    }
    update_boundary(std::move(changed));
  }
  // Closed components face outward (each job orients what it starts; a closed surface is only
  // known as such at the end).
  const MeshSnapshot snap = mesh_.snapshot();
  std::vector<std::uint32_t> live;
  std::vector<Triangle> tris;
  for (std::uint32_t id = 0; id < snap.triangle_slots(); ++id)
    if (snap.alive(id)) {
      live.push_back(id);
      tris.push_back(snap.triangle(id));
    }
  if (tris.empty()) return;
  TriangleComponents comps(snap.vertex_count(), tris);
  const std::size_t nc = comps.count();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> half;
  half.reserve(tris.size() * 3);
  for (const Triangle& t : tris)
    for (int k = 0; k < 3; ++k) half.emplace_back(t[k], t[(k + 1) % 3]);
  std::sort(half.begin(), half.end());
  std::vector<std::uint8_t> open(nc, 0);
  std::vector<Vec3> centroid(nc, Vec3::Zero());
  std::vector<double> count(nc, 0), vol(nc, 0);
  for (const Triangle& t : tris) {
    const std::uint32_t c = comps.of(t);
    for (int k = 0; k < 3; ++k)
      if (!std::binary_search(half.begin(), half.end(), std::make_pair(t[(k + 1) % 3], t[k]))) open[c] = 1;
    centroid[c] += snap.vertex(t[0]);
    count[c] += 1;
  }
  for (const Triangle& t : tris) {
    const std::uint32_t k = comps.of(t);
    const Vec3 c = centroid[k] / count[k];
    vol[k] += (snap.vertex(t[0]) - c).dot((snap.vertex(t[1]) - c).cross(snap.vertex(t[2]) - c));
  }
  // (A closed component has no boundary: no successor changes.)
  for (std::size_t i = 0; i < tris.size(); ++i) {
    const std::uint32_t c = comps.of(tris[i]);
    if (open[c] || vol[c] >= 0) continue;
    for (std::uint32_t v : tris[i]) --vertex_uses_[v];
    mesh_.remove_triangle(live[i]);
    publish_triangle({tris[i][0], tris[i][2], tris[i][1]});
  }
  for (std::size_t c = 0; c < nc; ++c) stats_.flipped += !open[c] && vol[c] < 0 ? 1 : 0;
}

std::size_t JobMesher::heap_bytes() const {
  std::size_t b = vertex_cube_.heap_bytes() + vertex_normal_.heap_bytes() + vertex_spacing_.heap_bytes() +
                  vertex_uses_.heap_bytes() + near_.capacity() + near_set_.capacity() * 4 +
                  block_tris_.capacity() * sizeof(std::vector<std::uint32_t>);
  for (const auto& l : block_tris_) b += l.capacity() * 4;
  return b;
}

}  // namespace scanmesh::recon::detail
