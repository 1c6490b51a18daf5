// SPDX-License-Identifier: MIT
#include "scanmesh/recon/denoise.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/reduce.hpp"
#include "format.hpp"
#include "triangle_shape.hpp"
#include "vertex_triangles.hpp"

namespace scanmesh::recon {
namespace {

/// Rounds of undoing the moves that make triangles cross before the input is given back.
constexpr int kMaxSettleRounds = 8;
/// A range weight exp(-r) below exp(-kNegligible) (1e-11 of a parallel neighbour's) is left out.
constexpr double kNegligible = 25;
constexpr double kTableStep = 64;  ///< entries of the exp(-r) table per unit of r

}  // namespace

std::vector<std::string> DenoiseOptions::validate() const {
  std::vector<std::string> errors;
  if (!(feature_deg >= 0 && feature_deg < 90))
    errors.push_back("denoise: the feature angle must be 0 (auto) or above and below 90 degrees, got " +
                     detail::short_number(feature_deg));
  if (!(normal_iterations >= 1 && normal_iterations <= kMaxIterations))
    errors.push_back("denoise: the normal iterations must be 1 to " +
                     std::to_string(kMaxIterations) + ", got " +
                     std::to_string(normal_iterations));
  if (!(vertex_iterations >= 1 && vertex_iterations <= kMaxIterations))
    errors.push_back("denoise: the vertex iterations must be 1 to " +
                     std::to_string(kMaxIterations) + ", got " +
                     std::to_string(vertex_iterations));
  if (!(max_move > 0 && max_move <= 2))
    errors.push_back("denoise: the largest move must be above 0 and at most 2 edge lengths, got " +
                     detail::short_number(max_move));
  if (!(noise_mm >= 0 && std::isfinite(noise_mm)))
    errors.push_back("denoise: the noise must be 0 (measured) or a positive length, got " +
                     detail::short_number(noise_mm));
  if (!(noise_moves > 0 && noise_moves <= 100))
    errors.push_back("denoise: the largest move must be above 0 and at most 100 times the noise, got " +
                     detail::short_number(noise_moves));
  return errors;
}

DenoiseStats denoise_mesh(Mesh& mesh, const DenoiseOptions& options) {
  if (const auto errors = options.validate(); !errors.empty())
    throw std::invalid_argument(errors.front());
  DenoiseStats stats;
  const std::size_t nt = mesh.triangles.size(), nv = mesh.vertices.size();
  if (nt == 0) return stats;
  for (const Triangle& t : mesh.triangles)
    for (std::uint32_t v : t)
      if (v >= nv) throw std::invalid_argument("denoise: a triangle names a missing vertex");
  const std::vector<Vec3> orig = mesh.vertices;  // the input's positions, kept to the end
  auto centroid = [](const std::vector<Vec3>& x, const Triangle& t) {
    return (x[t[0]] + x[t[1]] + x[t[2]]) / 3.0;
  };

  // Each vertex's mean edge length (a move is cut to max_move of it).
  std::vector<double> edge_sum(nv, 0);
  std::vector<std::uint32_t> edge_count(nv, 0);
  for (const Triangle& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k], b = t[(k + 1) % 3];
      const double len = (orig[a] - orig[b]).norm();
      edge_sum[a] += len;
      edge_sum[b] += len;
      ++edge_count[a];
      ++edge_count[b];
    }
  // Squared distances (the noise's quadric fits, the filter's weights) must neither overflow nor
  // underflow in double precision: the reconstruction's bounds on its input.
  {
    constexpr double kHuge = 1e100, kTiny = 1e-100;
    Eigen::AlignedBox3d box;
    for (std::uint32_t v = 0; v < nv; ++v) {
      if (edge_count[v] == 0) continue;
      if (!orig[v].allFinite() || orig[v].cwiseAbs().maxCoeff() > kHuge)
        throw GeometryError("denoise: vertex #" + std::to_string(v) +
                            " has a coordinate that is not finite or beyond +-1e100; check the "
                            "mesh's units");
      box.extend(orig[v]);
    }
    if (!(box.sizes().maxCoeff() >= kTiny)) return stats;  // a point: nothing to measure
  }
  // The noise in length units: the shell's thickness about a quadric fit through each vertex's
  // neighbours (curvature absorbed), over the vertices that triangles use.
  if (options.noise_mm > 0) {
    stats.noise_mm = options.noise_mm;
  } else {
    std::vector<Vec3> used;
    used.reserve(nv);
    for (std::uint32_t v = 0; v < nv; ++v)
      if (edge_count[v] > 0) used.push_back(orig[v]);
    stats.noise_mm = estimate_spacing(used).thickness_mm;
  }
  // No measurable noise (a CAD part's vertices, a sampling too sparse to fit): nothing to do.
  if (!(stats.noise_mm > 0)) return stats;
  const double noise_limit = options.noise_moves * stats.noise_mm;

  // Each triangle's neighbours: the triangles sharing a corner with it (itself left out), as
  // compressed lists, each once.
  const detail::VertexTriangles around(nv, mesh.triangles);
  std::vector<std::uint32_t> nstart(nt + 1, 0), nlist;
  nlist.reserve(nt * 12);
  {
    std::vector<std::uint32_t> seen(nt, 0xffffffffu);
    for (std::uint32_t i = 0; i < nt; ++i) {
      seen[i] = i;
      for (std::uint32_t v : mesh.triangles[i])
        for (std::uint32_t j : around.of(v))
          if (seen[j] != i) {
            seen[j] = i;
            nlist.push_back(j);
          }
      nstart[i + 1] = static_cast<std::uint32_t>(nlist.size());
    }
  }

  // Unit normals (zero for a degenerate triangle: it neither weighs nor is filtered), areas,
  // centroids; the spatial scale is the mean distance between neighbouring centroids.
  std::vector<Vec3> normal(nt), cen(nt);
  std::vector<double> area(nt);
  for (std::uint32_t i = 0; i < nt; ++i) {
    const Triangle& t = mesh.triangles[i];
    const Vec3 c = (orig[t[1]] - orig[t[0]]).cross(orig[t[2]] - orig[t[0]]);
    const double len = c.norm();
    area[i] = 0.5 * len;
    normal[i] = len > 0 ? Vec3(c / len) : Vec3::Zero();
    cen[i] = centroid(orig, t);
  }
  double dsum = 0;
  std::size_t dcount = 0;
  for (std::uint32_t i = 0; i < nt; ++i)
    for (std::uint32_t k = nstart[i]; k < nstart[i + 1]; ++k) {
      dsum += (cen[nlist[k]] - cen[i]).norm();
      ++dcount;
    }
  if (dcount == 0 || !(dsum > 0)) return stats;  // lone triangles: nothing to average
  const double sigma_s = dsum / static_cast<double>(dcount);
  const double inv_2ss = 1.0 / (2 * sigma_s * sigma_s);
  // The noise's own normal scatter: the median angle between a triangle's normal and the
  // area-weighted mean of its neighbours' (a second difference: a smooth curvature, even a
  // coarsely sampled one, largely cancels in it, and a scan's sharp edges are too few to move
  // the median).
  {
    std::vector<double> bend;  // 1 - cos of the angle: in the angle's order, without a trig call
    bend.reserve(nt);
    for (std::uint32_t i = 0; i < nt; ++i) {
      if (normal[i].isZero()) continue;
      Vec3 m = Vec3::Zero();
      for (std::uint32_t k = nstart[i]; k < nstart[i + 1]; ++k)
        m += area[nlist[k]] * normal[nlist[k]];
      const double len = m.norm();
      if (len > 0) bend.push_back(1 - normal[i].dot(m) / len);
    }
    if (!bend.empty()) {
      auto mid = bend.begin() + static_cast<std::ptrdiff_t>(bend.size() / 2);
      std::nth_element(bend.begin(), mid, bend.end());
      stats.noise_deg = std::acos(std::clamp(1 - *mid, -1.0, 1.0)) * 180 / std::numbers::pi;
    }
  }
  stats.feature_deg = options.feature_deg > 0
                          ? options.feature_deg
                          : std::min(DenoiseOptions::kAutoFactor * stats.noise_deg,
                                     DenoiseOptions::kAutoMaxDeg);
  // Every neighbour parallel within rounding (a CAD part's flat faces): no noise to remove.
  if (!(stats.feature_deg >= DenoiseOptions::kNoNoiseDeg)) return stats;
  const double sigma_r = 2 * std::sin(0.5 * stats.feature_deg * std::numbers::pi / 180);
  const double inv_2rr = 1.0 / (2 * sigma_r * sigma_r);

  // exp(-r) for the weights, tabulated (a 64th apart, linear in between: within 3e-5 of it),
  // which the filter asks for a dozen times a triangle and round.
  std::vector<double> table(static_cast<std::size_t>(kNegligible * kTableStep) + 2);
  for (std::size_t k = 0; k < table.size(); ++k)
    table[k] = std::exp(-static_cast<double>(k) / kTableStep);
  auto falloff = [&](double r) {
    const double at = r * kTableStep;
    const auto k = static_cast<std::size_t>(at);
    return table[k] + (at - static_cast<double>(k)) * (table[k + 1] - table[k]);
  };
  // The weights of area and distance do not change while the normals are filtered.
  std::vector<double> wsp(nlist.size());
  for (std::uint32_t i = 0; i < nt; ++i)
    for (std::uint32_t k = nstart[i]; k < nstart[i + 1]; ++k) {
      const std::uint32_t j = nlist[k];
      const double r = (cen[j] - cen[i]).squaredNorm() * inv_2ss;
      wsp[k] = r < kNegligible ? area[j] * falloff(r) : 0.0;
    }
  std::vector<Vec3> next(nt);
  for (int it = 0; it < options.normal_iterations; ++it) {
    for (std::uint32_t i = 0; i < nt; ++i) {
      const Vec3& ni = normal[i];
      if (ni.isZero()) {
        next[i] = ni;
        continue;
      }
      Vec3 sum = area[i] * ni;
      for (std::uint32_t k = nstart[i]; k < nstart[i + 1]; ++k) {
        const Vec3& nj = normal[nlist[k]];
        if (nj.isZero()) continue;
        const double r = (nj - ni).squaredNorm() * inv_2rr;
        if (r < kNegligible) sum += wsp[k] * falloff(r) * nj;
      }
      const double len = sum.norm();
      next[i] = len > 0 ? Vec3(sum / len) : ni;
    }
    normal.swap(next);
  }
  std::vector<Vec3>().swap(next);
  std::vector<double>().swap(wsp);

  // The vertex update (Jacobi): each vertex moves by the mean over its triangles of its
  // offset from their planes (the filtered normal through the current centroid).
  std::vector<Vec3> x = orig, xn(nv);
  for (int it = 0; it < options.vertex_iterations; ++it) {
    for (std::uint32_t i = 0; i < nt; ++i) cen[i] = centroid(x, mesh.triangles[i]);
    for (std::uint32_t v = 0; v < nv; ++v) {
      Vec3 d = Vec3::Zero();
      std::size_t m = 0;
      for (std::uint32_t t : around.of(v)) {
        if (normal[t].isZero()) continue;
        d += normal[t] * normal[t].dot(cen[t] - x[v]);
        ++m;
      }
      xn[v] = m > 0 ? Vec3(x[v] + d / static_cast<double>(m)) : x[v];
    }
    x.swap(xn);
  }

  // Every vertex moved at once, then the moves that spoil a triangle undone: one that tilts
  // by more than 60 degrees or gets an angle under 1 degree (unless it had one before), or that
  // crosses another (a pair the input already had is left alone). Undoing a move can spoil a
  // neighbour in turn, so until nothing changes; the input itself passes.
  std::vector<std::uint8_t> moved(nv, 0);
  std::size_t wanted = 0;
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (edge_count[v] == 0 || x[v] == orig[v]) continue;
    Vec3 d = x[v] - orig[v];
    const double limit = std::min(options.max_move * edge_sum[v] / edge_count[v], noise_limit);
    if (const double len = d.norm(); len > limit) {
      d *= limit / len;
      ++stats.clamped;
    }
    if (!d.allFinite()) continue;
    mesh.vertices[v] = orig[v] + d;
    moved[v] = 1;
    ++wanted;
  }
  std::vector<Vec3>().swap(x);
  std::vector<Vec3>().swap(xn);
  const double min_angle_cos = std::cos(std::numbers::pi / 180);  // 1 degree
  // The vertices undone since the last crossing check: after the first (over the whole mesh),
  // only the triangles at them can cross anew.
  std::vector<std::uint8_t> recheck(nv, 0);
  auto undo = [&](const Triangle& t) {
    bool any = false;
    for (std::uint32_t v : t)
      if (moved[v]) {
        moved[v] = 0;
        recheck[v] = 1;
        mesh.vertices[v] = orig[v];
        any = true;
      }
    return any;
  };
  std::vector<Triangle> order;  // the others, then the triangles at a re-checked vertex
  std::vector<std::uint32_t> order_id;
  for (int round = 0; round < kMaxSettleRounds; ++round) {
    bool changed = true;
    while (changed) {
      changed = false;
      for (std::uint32_t i = 0; i < nt; ++i) {
        const Triangle& t = mesh.triangles[i];
        if (!(moved[t[0]] | moved[t[1]] | moved[t[2]])) continue;
        const Vec3 &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
        const Vec3 n = (b - a).cross(c - a);
        const Vec3 n0 = (orig[t[1]] - orig[t[0]]).cross(orig[t[2]] - orig[t[0]]);
        const bool tilted = !(n.dot(n0) > 0.5 * n.norm() * n0.norm());
        const double sharpest = detail::min_angle_cos(a, b, c);
        const bool thin = sharpest >= min_angle_cos &&
                          sharpest > detail::min_angle_cos(orig[t[0]], orig[t[1]], orig[t[2]]);
        if ((tilted || thin) && undo(t)) changed = true;
      }
    }
    SelfIntersections crossing;
    if (round == 0) {
      crossing = find_self_intersections(mesh, kAllPairs);
    } else {
      order.clear();
      order_id.clear();
      std::size_t from = 0;
      for (const bool at_recheck : {false, true}) {
        for (std::uint32_t i = 0; i < nt; ++i) {
          const Triangle& t = mesh.triangles[i];
          if ((recheck[t[0]] | recheck[t[1]] | recheck[t[2]]) != at_recheck) continue;
          order.push_back(t);
          order_id.push_back(i);
        }
        if (!at_recheck) from = order.size();
      }
      if (from == nt) break;  // nothing undone since the last check
      crossing = find_self_intersections(mesh.vertices, order, kAllPairs, from);
      for (auto& pair : crossing.examples) pair = {order_id[pair[0]], order_id[pair[1]]};
    }
    std::fill(recheck.begin(), recheck.end(), 0);
    bool undone = false;
    for (const auto& [i, j] : crossing.examples) {
      // Both undone: either may be the one that moved into the other.
      const bool ui = undo(mesh.triangles[i]);
      const bool uj = undo(mesh.triangles[j]);
      undone = undone || ui || uj;
    }
    if (!undone) break;
    if (round + 1 == kMaxSettleRounds) {  // give up on this mesh's moves: the input back
      mesh.vertices = orig;
      std::fill(moved.begin(), moved.end(), 0);
    }
  }
  double total = 0;
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (edge_count[v] > 0 && orig[v] != mesh.vertices[v]) {
      const double len = (mesh.vertices[v] - orig[v]).norm();
      total += len;
      stats.max_move = std::max(stats.max_move, len);
      ++stats.moved;
    }
  }
  stats.refused = wanted - stats.moved;
  stats.mean_move = stats.moved > 0 ? total / static_cast<double>(stats.moved) : 0;
  return stats;
}

}  // namespace scanmesh::recon
