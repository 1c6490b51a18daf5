// SPDX-License-Identifier: MIT
#include "restore.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "box_bins.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "triangle_shape.hpp"
#include "vertex_triangles.hpp"

namespace scanmesh::recon::detail {
namespace {

inline void box_of(const Mesh& m, const Triangle& t, Vec3& lo, Vec3& hi) {
  const Vec3 &a = m.vertices[t[0]], &b = m.vertices[t[1]], &c = m.vertices[t[2]];
  lo = a.cwiseMin(b).cwiseMin(c);
  hi = a.cwiseMax(b).cwiseMax(c);
}

}  // namespace

std::size_t restore_positions(Mesh& mesh, std::span<const std::pair<std::uint32_t, Vec3>> targets) {
  if (targets.empty() || mesh.triangles.empty()) return 0;
  constexpr std::uint32_t kOut = 0xffffffffu;
  // The movers' triangles (one pass), and the box each mover's triangles sweep.
  std::vector<std::uint32_t> slot(mesh.vertices.size(), kOut);
  for (std::uint32_t k = 0; k < targets.size(); ++k) slot[targets[k].first] = k;
  const VertexTriangles around(targets.size(), mesh.triangles,
                               [&](std::uint32_t v) { return slot[v]; });
  // A triangle's vertices only ever lie at their present positions or their targets, so each
  // mover's triangles stay within the union of the boxes of both.
  std::vector<std::pair<Vec3, Vec3>> swept(targets.size());
  std::vector<double> extent(targets.size());
  for (std::uint32_t k = 0; k < targets.size(); ++k) {
    Vec3 lo = targets[k].second, hi = lo;
    for (std::uint32_t t : around.of(k)) {
      for (std::uint32_t v : mesh.triangles[t]) {
        lo = lo.cwiseMin(mesh.vertices[v]);
        hi = hi.cwiseMax(mesh.vertices[v]);
        if (slot[v] != kOut) {
          lo = lo.cwiseMin(targets[slot[v]].second);
          hi = hi.cwiseMax(targets[slot[v]].second);
        }
      }
    }
    swept[k] = {lo, hi};
    extent[k] = (hi - lo).maxCoeff();
  }
  // Cells of the median swept extent: a triangle wider than that is "wide" below.
  std::nth_element(extent.begin(), extent.begin() + static_cast<std::ptrdiff_t>(extent.size() / 2),
                   extent.end());
  const double reach = extent[extent.size() / 2];
  std::vector<double>().swap(extent);
  std::vector<std::uint32_t>().swap(slot);
  // The triangles whose box meets a swept box: the only ones a move can make cross. A triangle
  // no wider than `reach` that meets one has all its corners within `reach` of it, so the
  // swept boxes are binned widened by that, and only the corners look them up; a wider
  // triangle looks up its whole box (BoxBins keeps boxes over 64 cells apart).
  const Vec3 margin = Vec3::Constant(reach);
  BoxBins near;
  near.reset(reach);
  for (std::uint32_t k = 0; k < targets.size(); ++k)
    near.insert(k, swept[k].first - margin, swept[k].second + margin);
  std::vector<std::uint8_t> close(mesh.vertices.size(), 0);
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    const Vec3& p = mesh.vertices[v];
    near.visit_point(p, [&](std::uint32_t k) {
      close[v] |=
          static_cast<std::uint8_t>(((swept[k].first - margin).array() <= p.array()).all() &&
                                    (p.array() <= (swept[k].second + margin).array()).all());
    });
  }
  BoxBins bins;  // those triangles, by their current box
  bins.reset(reach);
  for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t) {
    const Triangle& tr = mesh.triangles[t];
    Vec3 lo, hi;
    box_of(mesh, tr, lo, hi);
    bool meets = false;
    if ((hi - lo).maxCoeff() > reach) {
      near.visit(lo, hi, [&](std::uint32_t k) {
        meets = meets || ((swept[k].first.array() <= hi.array()).all() &&
                          (lo.array() <= swept[k].second.array()).all());
      });
    } else if (close[tr[0]] | close[tr[1]] | close[tr[2]]) {
      meets = true;  // may meet one: tested exactly at the crossing test
    }
    if (meets) bins.insert(t, lo, hi);
  }
  std::vector<std::uint8_t>().swap(close);
  const double max_tilt_cos = 0.5;                                      // 60 degrees
  const double min_angle_cos = std::cos(1.0 * std::numbers::pi / 180);  // 1 degree
  std::vector<std::uint32_t> stamp(mesh.triangles.size(), 0);
  std::uint32_t round = 0;
  std::size_t moved = 0;
  std::vector<Vec3> before;  // the normals of the mover's triangles before the move
  std::vector<std::pair<Vec3, Vec3>> fan_box;  // their boxes after it
  struct Near {
    Vec3 lo, hi;
    std::uint32_t id;
  };
  std::vector<Near> nearby;  // the triangles whose box meets the box of the moved fan
  for (std::uint32_t k = 0; k < targets.size(); ++k) {
    const auto& [v, target] = targets[k];
    const Vec3 old = mesh.vertices[v];
    if (target == old) continue;
    const auto fan = around.of(k);
    before.clear();
    for (std::uint32_t t : fan) {
      const Triangle& tr = mesh.triangles[t];
      before.push_back((mesh.vertices[tr[1]] - mesh.vertices[tr[0]])
                           .cross(mesh.vertices[tr[2]] - mesh.vertices[tr[0]]));
    }
    mesh.vertices[v] = target;
    bool ok = true;
    for (std::size_t i = 0; i < fan.size() && ok; ++i) {
      const Triangle& tr = mesh.triangles[fan[i]];
      const Vec3 &a = mesh.vertices[tr[0]], &b = mesh.vertices[tr[1]], &c = mesh.vertices[tr[2]];
      const Vec3 n = (b - a).cross(c - a);
      ok = n.dot(before[i]) > max_tilt_cos * n.norm() * before[i].norm() &&
           detail::min_angle_cos(a, b, c) < min_angle_cos;
    }
    // No triangle of the fan may cross another one (the fan's own included: triangles_intersect
    // ignores what two triangles share). The triangles near the fan are gathered once.
    if (ok) {
      Vec3 flo = target, fhi = target;
      fan_box.clear();
      for (std::uint32_t t : fan) {
        Vec3 lo, hi;
        box_of(mesh, mesh.triangles[t], lo, hi);
        fan_box.emplace_back(lo, hi);
        flo = flo.cwiseMin(lo);
        fhi = fhi.cwiseMax(hi);
      }
      ++round;
      nearby.clear();
      bins.visit(flo, fhi, [&](std::uint32_t u) {
        if (stamp[u] == round) return;
        stamp[u] = round;
        Vec3 ulo, uhi;
        box_of(mesh, mesh.triangles[u], ulo, uhi);
        if ((ulo.array() > fhi.array()).any() || (uhi.array() < flo.array()).any()) return;
        nearby.push_back({ulo, uhi, u});
      });
    }
    for (std::size_t i = 0; i < fan.size() && ok; ++i) {
      const std::uint32_t t = fan[i];
      const Triangle& tt = mesh.triangles[t];
      const auto& [lo, hi] = fan_box[i];
      // t's plane: a triangle whose corners off t lie strictly on one side of it meets t at
      // most where they share corners, which is no crossing. "Strictly" at least as far as
      // triangles_intersect's tolerance (1e-9 of the pair's longest edge, which is at most
      // sqrt(3) times the larger box extent), so that nothing it would count is skipped.
      const Vec3& a = mesh.vertices[tt[0]];
      const Vec3 n = (mesh.vertices[tt[1]] - a).cross(mesh.vertices[tt[2]] - a).normalized();
      const double extent = (hi - lo).maxCoeff();
      for (const Near& q : nearby) {
        if (q.id == t) continue;
        if ((q.lo.array() > hi.array()).any() || (q.hi.array() < lo.array()).any()) continue;
        const double tol = 1.8e-9 * std::max(extent, (q.hi - q.lo).maxCoeff());
        const Triangle& tu = mesh.triangles[q.id];
        int above = 0, below = 0, off = 0;
        for (std::uint32_t w : tu) {
          if (w == tt[0] || w == tt[1] || w == tt[2]) continue;
          ++off;
          const double d = n.dot(mesh.vertices[w] - a);
          above += d > tol ? 1 : 0;
          below += d < -tol ? 1 : 0;
        }
        if (off > 0 && (above == off || below == off)) continue;
        if (triangles_intersect(mesh.vertices, tt, tu)) {
          ok = false;
          break;
        }
      }
    }
    if (!ok) {
      mesh.vertices[v] = old;
      continue;
    }
    for (std::size_t i = 0; i < fan.size(); ++i)
      bins.insert(fan[i], fan_box[i].first, fan_box[i].second);
    ++moved;
  }
  return moved;
}

}  // namespace scanmesh::recon::detail
