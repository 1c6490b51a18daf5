// Sharp-edge recovery (sharpen.hpp): faces found by region growing over the triangles' normals,
// bevel triangles split at the meeting point of the faces around them, edges flipped along the
// recovered feature, and every new triangle checked against the mesh.
// SPDX-License-Identifier: MIT
#include "scanmesh/recon/sharpen.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <utility>

#include "scanmesh/recon/intersections.hpp"
#include "format.hpp"
#include "vertex_triangles.hpp"

namespace scanmesh::recon {
namespace {

constexpr std::uint32_t kNone = 0xffffffffu;
/// A new vertex must project into its bevel triangle at least this far (barycentric) from each
/// side, so that none of the three triangles it makes is a sliver.
constexpr double kInside = 0.05;
/// A split is refused when one of its triangles would bend against a neighbour that keeps its
/// shape by more than this (the cosine of about 100 degrees between their normals).
constexpr double kFoldCos = -0.2;
/// Three face planes make a corner only when they are this far from sharing a direction
/// (|det| of their unit normals); otherwise the two largest faces make an edge.
constexpr double kCornerDet = 0.25;
/// A face triangle's corner on another face is off its face's plane (see peel) only beyond this
/// slope over the triangle's longest edge (about 3 degrees), whatever the plane's scatter.
constexpr double kPeelSlope = 0.05;
/// A bevel's corner must lie within this share of its longest edge of one of the face planes
/// its new vertex comes from.
constexpr double kOnFace = 0.3;
/// The same for a corner none of whose triangles belongs to those faces.
constexpr double kFacelessOnFace = 0.1;
/// Sweeps of the tidy step's flips (each flips a triangle at most once).
constexpr int kTidySweeps = 4;
/// Rounds of refusals (each refuses every bevel triangle whose new triangles crossed the mesh).
constexpr int kMaxRounds = 16;

double cos_deg(double deg) { return std::cos(deg * std::numbers::pi / 180.0); }

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  return (static_cast<std::uint64_t>(a) << 32) | b;
}

/// across[3 t + k]: the triangle on the other side of edge (t[k], t[k+1]), kNone on a border.
/// False when an edge is used twice in the same direction (non-manifold or inconsistently
/// oriented): then nothing is done.
bool build_adjacency(const std::vector<Triangle>& tris, std::vector<std::uint32_t>& across) {
  std::vector<std::pair<std::uint64_t, std::uint32_t>> half;
  half.reserve(3 * tris.size());
  for (std::uint32_t t = 0; t < tris.size(); ++t)
    for (std::uint32_t k = 0; k < 3; ++k)
      half.emplace_back(edge_key(tris[t][k], tris[t][(k + 1) % 3]), 3 * t + k);
  std::sort(half.begin(), half.end());
  for (std::size_t i = 1; i < half.size(); ++i)
    if (half[i].first == half[i - 1].first) return false;
  across.assign(3 * tris.size(), kNone);
  for (const auto& [key, h] : half) {
    const auto a = static_cast<std::uint32_t>(key >> 32), b = static_cast<std::uint32_t>(key);
    const auto it = std::lower_bound(half.begin(), half.end(),
                                     std::make_pair(edge_key(b, a), std::uint32_t{0}));
    if (it != half.end() && it->first == edge_key(b, a)) across[h] = it->second / 3;
  }
  return true;
}

Vec3 unit_normal(const std::vector<Vec3>& v, const Triangle& t, double* area = nullptr) {
  const Vec3 c = (v[t[1]] - v[t[0]]).cross(v[t[2]] - v[t[0]]);
  const double len = c.norm();
  if (area != nullptr) *area = 0.5 * len;
  return len > 0 ? Vec3(c / len) : Vec3::Zero();
}

/// A face seen from a bevel triangle: the area-weighted sums of its triangles' normals and
/// centroids near the bevel.
struct FaceSum {
  std::uint32_t label;
  Vec3 normal, centroid;
  double area;
};

/// Where a bevel triangle's new vertex goes.
struct Candidate {
  bool ok = false;
  bool corner = false;
  bool rounded = false;  ///< refused: a corner of the bevel lies on a fillet (see place_vertex)
  Vec3 p = Vec3::Zero();
  Vec3 dir = Vec3::Zero();  ///< the recovered edge's direction (edges only)
};

}  // namespace

std::vector<std::string> SharpenOptions::validate() const {
  std::vector<std::string> errors;
  if (!(smooth_deg > 0 && smooth_deg < 90))
    errors.push_back("sharpen: the face angle must be above 0 and below 90 degrees, got " +
                     detail::short_number(smooth_deg));
  if (!(feature_deg > smooth_deg && feature_deg < 180))
    errors.push_back("sharpen: the feature angle must be above the face angle (" +
                     detail::short_number(smooth_deg) + ") and below 180 degrees, got " +
                     detail::short_number(feature_deg));
  if (!(passes >= 1 && passes <= kMaxPasses))
    errors.push_back("sharpen: the passes must be 1 to " + std::to_string(kMaxPasses) + ", got " +
                     std::to_string(passes));
  return errors;
}

namespace {

/// The mesh a pass works on: its triangles' neighbours, normals, centroids and areas, and each
/// vertex's triangles.
struct Surface {
  const std::vector<Vec3>& verts;
  const std::vector<Triangle>& tris;
  std::vector<std::uint32_t> across;
  std::vector<Vec3> normal, centroid;
  std::vector<double> area;
  detail::VertexTriangles vt;

  Surface(const Mesh& mesh, std::vector<std::uint32_t> adjacency)
      : verts(mesh.vertices),
        tris(mesh.triangles),
        across(std::move(adjacency)),
        normal(tris.size()),
        centroid(tris.size()),
        area(tris.size()),
        vt(verts.size(), tris) {
    for (std::size_t t = 0; t < tris.size(); ++t) {
      normal[t] = unit_normal(verts, tris[t], &area[t]);
      centroid[t] = (verts[tris[t][0]] + verts[tris[t][1]] + verts[tris[t][2]]) / 3.0;
    }
  }
  [[nodiscard]] std::size_t size() const { return tris.size(); }
  [[nodiscard]] bool degenerate(std::size_t t) const { return area[t] <= 0; }
  [[nodiscard]] double longest_edge(std::size_t t) const {
    const Vec3& p0 = verts[tris[t][0]];
    const Vec3& p1 = verts[tris[t][1]];
    const Vec3& p2 = verts[tris[t][2]];
    return std::max({(p1 - p0).norm(), (p2 - p1).norm(), (p0 - p2).norm()});
  }
  /// Appends to `out` the triangles within `rings` rings of triangle t's corners, each once
  /// (stamp[u] == mark marks those taken; a mark is used for one call only).
  void rings_of(std::uint32_t t, int rings, std::uint32_t mark, std::vector<std::uint32_t>& stamp,
                std::vector<std::uint32_t>& out) const {
    for (std::uint32_t v : tris[t])
      for (std::uint32_t u : vt.of(v))
        if (stamp[u] != mark) {
          stamp[u] = mark;
          out.push_back(u);
        }
    for (int r = 1, done = 0; r < rings; ++r) {
      const std::size_t first = out.size();
      for (std::size_t i = static_cast<std::size_t>(done); i < first; ++i)
        for (std::uint32_t v : tris[out[i]])
          for (std::uint32_t u : vt.of(v))
            if (stamp[u] != mark) {
              stamp[u] = mark;
              out.push_back(u);
            }
      done = static_cast<int>(first);
    }
  }
};

/// Adds triangle u to a face's area-weighted sums of normals and centroids.
void add_triangle(FaceSum& f, const Surface& s, std::uint32_t u) {
  f.normal += s.area[u] * s.normal[u];
  f.centroid += s.area[u] * s.centroid[u];
  f.area += s.area[u];
}

/// Faces: the triangles all of whose edges are smooth (normals within the face angle), joined
/// through smooth edges; then each triangle of no face joins the face of its most parallel
/// neighbour when it is within the face angle of it (twice: the triangles along a face's rim
/// have one bent edge, towards the bevel). kNone for the bevel triangles.
std::vector<std::uint32_t> find_faces(const Surface& s, double cos_smooth) {
  const std::size_t nt = s.size();
  auto smooth_edge = [&](std::size_t t, std::size_t k) {
    const std::uint32_t u = s.across[3 * t + k];
    return u == kNone || (!s.degenerate(u) && s.normal[t].dot(s.normal[u]) >= cos_smooth);
  };
  std::vector<std::uint32_t> label(nt, kNone);
  std::vector<char> smooth(nt, 0);
  for (std::size_t t = 0; t < nt; ++t)
    smooth[t] = !s.degenerate(t) && smooth_edge(t, 0) && smooth_edge(t, 1) && smooth_edge(t, 2);
  std::uint32_t faces = 0;
  std::vector<std::uint32_t> stack;
  for (std::size_t seed = 0; seed < nt; ++seed) {
    if (!smooth[seed] || label[seed] != kNone) continue;
    label[seed] = faces;
    stack.assign(1, static_cast<std::uint32_t>(seed));
    while (!stack.empty()) {
      const std::uint32_t t = stack.back();
      stack.pop_back();
      for (std::uint32_t k = 0; k < 3; ++k) {
        const std::uint32_t u = s.across[3 * t + k];
        if (u != kNone && smooth[u] && label[u] == kNone && smooth_edge(t, k)) {
          label[u] = faces;
          stack.push_back(u);
        }
      }
    }
    ++faces;
  }
  for (int round = 0; round < 2; ++round) {
    std::vector<std::pair<std::uint32_t, std::uint32_t>> joins;
    for (std::uint32_t t = 0; t < nt; ++t) {
      if (label[t] != kNone || s.degenerate(t)) continue;
      double best = cos_smooth;
      std::uint32_t to = kNone;
      for (std::uint32_t k = 0; k < 3; ++k) {
        const std::uint32_t u = s.across[3 * t + k];
        if (u == kNone || label[u] == kNone) continue;
        const double c = s.normal[t].dot(s.normal[u]);
        if (c >= best) {
          best = c;
          to = label[u];
        }
      }
      if (to != kNone) joins.emplace_back(t, to);
    }
    for (const auto& [t, l] : joins) label[t] = l;
  }
  return label;
}

/// For each face triangle, a corner of it that also belongs to another face (one whose triangle
/// there lies at least the feature angle off), kNone for the others and the bevels: the face
/// triangles along an edge.
std::vector<std::uint32_t> corners_on_other_faces(const Surface& s,
                                                  const std::vector<std::uint32_t>& label,
                                                  double cos_feature) {
  std::vector<std::uint32_t> off(s.size(), kNone);
  for (std::uint32_t t = 0; t < s.size(); ++t) {
    if (label[t] == kNone) continue;
    for (std::uint32_t v : s.tris[t])
      for (std::uint32_t u : s.vt.of(v))
        if (label[u] != kNone && label[u] != label[t] && s.normal[u].dot(s.normal[t]) < cos_feature)
          off[t] = v;
  }
  return off;
}

/// Bevels within the face angle of a face: a bevel cut 0.2 from the edge on one face and 1.1
/// on the other lies 10 degrees off the second and joined it in find_faces. A face triangle with
/// a corner on another face (one at least the feature angle off) is given back to the bevels
/// when that corner lies off its face's local plane (the face's triangles within two rings) by
/// more than the plane's own scatter allows: a corner on the edge itself lies on both planes.
void peel_bevels(const Surface& s, double cos_feature, std::vector<std::uint32_t>& label) {
  const std::size_t nt = s.size();
  std::vector<std::uint32_t> peel, near, stamp(nt, kNone);
  const std::vector<std::uint32_t> off = corners_on_other_faces(s, label, cos_feature);
  for (std::uint32_t t = 0; t < nt; ++t) {
    if (off[t] == kNone) continue;
    near.clear();
    s.rings_of(t, 2, t, stamp, near);
    // The plane from the face's triangles that touch no other face: the bevels that joined it
    // would tilt it towards themselves.
    FaceSum plane{label[t], Vec3::Zero(), Vec3::Zero(), 0};
    for (std::uint32_t u : near)
      if (label[u] == label[t] && off[u] == kNone) add_triangle(plane, s, u);
    if (!(plane.area > 0) || !(plane.normal.norm() > 0)) continue;
    const Vec3 n = plane.normal.normalized();
    const Vec3 c = plane.centroid / plane.area;
    double sq = 0, count = 0;
    for (std::uint32_t u : near)
      if (label[u] == label[t] && off[u] == kNone)
        for (std::uint32_t v : s.tris[u]) {
          const double d = n.dot(s.verts[v] - c);
          sq += d * d;
          count += 1;
        }
    if (count < 9) continue;
    const double allowed = std::max(4 * std::sqrt(sq / count), kPeelSlope * s.longest_edge(t));
    if (std::abs(n.dot(s.verts[off[t]] - c)) > allowed) peel.push_back(t);
  }
  for (std::uint32_t t : peel) label[t] = kNone;
}

/// Scratch space of place_vertex, reused over the bevels.
struct PlaceScratch {
  std::vector<std::uint32_t> stamp, ring;
  std::vector<std::uint32_t> off;  ///< corners_on_other_faces of the final faces
  std::uint32_t mark = 0;  ///< the last rings_of call's
  std::vector<FaceSum> sums, merged;
};

/// The faces among the triangles within `rings` rings of bevel t, merged where within the
/// feature angle of a larger one, largest first.
void faces_near(const Surface& s, const std::vector<std::uint32_t>& label, std::uint32_t t,
                int rings, double cos_feature, PlaceScratch& x) {
  std::vector<FaceSum>& sums = x.sums;
  sums.clear();
  x.ring.clear();
  s.rings_of(t, rings, x.mark++, x.stamp, x.ring);
  for (std::uint32_t u : x.ring) {
    if (label[u] == kNone) continue;
    // A face's plane from its triangles that touch no other face: those that do lie along the
    // edge, where a bevel within the face angle joined it and tilts it (a cylinder's side
    // below its rim: its vertices 0.15-0.4 inside the rim).
    if (x.off[u] != kNone) continue;
    auto it = std::find_if(sums.begin(), sums.end(),
                           [&](const FaceSum& f) { return f.label == label[u]; });
    if (it == sums.end()) {
      sums.push_back({label[u], Vec3::Zero(), Vec3::Zero(), 0});
      it = sums.end() - 1;
    }
    add_triangle(*it, s, u);
  }
  // Faces within the feature angle of a larger one are the same face for this purpose.
  std::stable_sort(sums.begin(), sums.end(),
                   [](const FaceSum& a, const FaceSum& b) { return a.area > b.area; });
  std::vector<FaceSum>& merged = x.merged;
  merged.clear();
  for (const FaceSum& f : sums) {
    if (!(f.normal.norm() > 0)) continue;
    const Vec3 n = f.normal.normalized();
    auto it = std::find_if(merged.begin(), merged.end(), [&](const FaceSum& m) {
      return m.normal.normalized().dot(n) > cos_feature;
    });
    if (it == merged.end()) {
      merged.push_back(f);
    } else {
      it->normal += f.normal;
      it->centroid += f.centroid;
      it->area += f.area;
    }
  }
  std::swap(sums, merged);
}

/// Bevel t's new vertex from the faces around its corners (their triangles within one ring, two
/// when one ring shows a single face); ok false when none fits.
Candidate place_vertex(const Surface& s, const std::vector<std::uint32_t>& label, std::uint32_t t,
                       double cos_feature, double cos_member, PlaceScratch& x) {
  const std::vector<FaceSum>& sums = x.sums;
  faces_near(s, label, t, 1, cos_feature, x);
  if (sums.size() < 2) faces_near(s, label, t, 2, cos_feature, x);
  if (sums.size() < 2) return {};
  const std::vector<Vec3>& verts = s.verts;
  const std::vector<Triangle>& tris = s.tris;
  Eigen::Matrix3d a;
  Vec3 h;
  Candidate c;
  for (int i = 0; i < 2; ++i) {
    const Vec3 n = sums[static_cast<std::size_t>(i)].normal.normalized();
    a.row(i) = n.transpose();
    h[i] = n.dot(sums[static_cast<std::size_t>(i)].centroid /
                  sums[static_cast<std::size_t>(i)].area);
  }
  bool solved = false;
  if (sums.size() >= 3) {
    const Vec3 n = sums[2].normal.normalized();
    a.row(2) = n.transpose();
    h[2] = n.dot(sums[2].centroid / sums[2].area);
    if (std::abs(a.determinant()) >= kCornerDet) {
      c.p = a.partialPivLu().solve(h);
      c.corner = true;
      solved = true;
    }
  }
  if (!solved) {
    const Vec3 d = Vec3(a.row(0).transpose()).cross(Vec3(a.row(1).transpose()));
    if (!(d.norm() > 0)) return {};
    c.dir = d.normalized();
    a.row(2) = c.dir.transpose();
    h[2] = c.dir.dot(s.centroid[t]);  // the point of the line nearest the bevel's centroid
    c.p = a.partialPivLu().solve(h);
  }
  if (!c.p.allFinite()) return {};
  // Every corner of a bevel is a sample of one of the faces it cuts between. A corner off all
  // their planes means the faces are not the bevel's own (fandisk: a face seen two rings away,
  // across a narrow face of its own, put vertices a spacing off the part). And a corner is a
  // face's sample when it has a triangle of that face (within twice the face angle of its
  // plane) or, all its triangles bevels, lies near the plane (a sample near the edge). A
  // corner with neither lies on a rounded blend between the faces (a fillet sampled across,
  // its middle rows off both planes): there the planes' meeting point is not the part's; it
  // stands off a fillet by 0.41 of its radius.
  const double longest = s.longest_edge(t);
  const double on_face = kOnFace * longest;
  const double faceless_on = kFacelessOnFace * longest;
  const std::size_t planes = c.corner ? 3 : 2;
  for (std::uint32_t v : s.tris[t]) {
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < planes; ++i) {
      const auto row = static_cast<Eigen::Index>(i);
      nearest = std::min(nearest, std::abs(a.row(row).dot(verts[v].transpose()) - h[row]));
    }
    if (nearest > on_face) return {};
    if (nearest <= faceless_on) continue;
    const bool member = std::any_of(s.vt.of(v).begin(), s.vt.of(v).end(), [&](std::uint32_t u) {
      if (label[u] == kNone) return false;
      for (std::size_t i = 0; i < planes; ++i)
        if (a.row(static_cast<Eigen::Index>(i)).dot(s.normal[u].transpose()) >= cos_member)
          return true;
      return false;
    });
    if (!member) {
      Candidate rounded;
      rounded.rounded = true;
      return rounded;
    }
  }
  const Vec3& p0 = verts[tris[t][0]];
  const Vec3& p1 = verts[tris[t][1]];
  const Vec3& p2 = verts[tris[t][2]];
  const Vec3* corner[3] = {&p0, &p1, &p2};
  // The sub-triangle over side k as a share of the bevel, both projected along the faces' mean
  // normal: the barycentric weight of the opposite corner, affine along the line. Not along
  // the bevel's own normal: a bevel cut far from the edge on one face and near it on the other
  // is nearly parallel to the first, and along its normal the edge projects onto its rim on
  // the second (the vertex was refused or clamped half-way).
  Vec3 up = Vec3::Zero();
  for (std::size_t i = 0; i < planes; ++i) up += a.row(static_cast<Eigen::Index>(i)).transpose();
  if (!(up.norm() > 0)) return {};
  up.normalize();
  const double projected = up.dot((p1 - p0).cross(p2 - p0));
  if (!(projected > 0.2 * 2 * s.area[t])) return {};
  auto weight = [&](int k, const Vec3& x) {
    const Vec3& u = *corner[k];
    const Vec3& w = *corner[(k + 1) % 3];
    return up.dot((w - u).cross(x - u)) / projected;
  };
  if (!c.corner) {
    // An edge: of the line's points over the bevel with every weight at least kInside, the
    // one nearest the point over its centroid (the line crosses a bevel strip slantwise, and
    // the point nearest the centroid may lie over a neighbour; taking the nearest rather than
    // the middle keeps the new vertices of a strip in the order of its triangles).
    double lo = -std::numeric_limits<double>::infinity(), hi = -lo;
    bool outside = false;
    for (int k = 0; k < 3; ++k) {
      const double w0 = weight(k, c.p), slope = weight(k, c.p + c.dir) - w0;
      if (std::abs(slope) < 1e-12) {
        outside |= w0 < kInside;  // parallel to side k
        continue;
      }
      const double s0 = (kInside - w0) / slope;
      if (slope > 0) lo = std::max(lo, s0);
      else hi = std::min(hi, s0);
    }
    if (outside || !(lo <= hi) || !std::isfinite(lo) || !std::isfinite(hi)) return {};
    c.p += std::clamp(0.0, lo, hi) * c.dir;
  }
  // Over the bevel (its projection inside, away from the sides) and within a longest edge of
  // its plane: farther, the faces' planes are no longer what the bevel cut.
  const double height = s.normal[t].dot(c.p - s.centroid[t]);
  if (std::abs(height) > longest) return {};
  if (weight(0, c.p) < kInside * 0.999 || weight(1, c.p) < kInside * 0.999 ||
      weight(2, c.p) < kInside * 0.999)
    return {};
  c.ok = true;
  return c;
}

/// Tidy: a new vertex near a side of its bevel lies in the plane of the face beyond that
/// side, and the triangle it makes over the side is a sliver in that plane. An edge of a new
/// triangle (not one of the recovered line's, between two new vertices) is flipped to the
/// other diagonal of its pair when the pair is flat (within the face angle), stays so, and
/// gets a larger smallest angle. A face triangle so rewritten is checked with the new
/// triangles and refused with its bevel.
void tidy(const Surface& s, double cos_smooth, const std::vector<Vec3>& v,
          std::vector<Triangle>& out, std::vector<std::uint32_t>& origin, SharpenStats& st) {
  const auto first_new = static_cast<std::uint32_t>(s.verts.size());
  for (int sweep = 0; sweep < kTidySweeps; ++sweep) {
    std::vector<std::pair<std::uint64_t, std::uint32_t>> half;
    std::vector<char> listed(out.size(), 0);
    auto list = [&](std::uint32_t i) {
      if (listed[i]) return;
      listed[i] = 1;
      for (std::uint32_t k = 0; k < 3; ++k)
        half.emplace_back(edge_key(out[i][k], out[i][(k + 1) % 3]), i);
    };
    // Every triangle at a corner of a new one (the input's at a measured corner, rewritten
    // or not, and the new ones), so that a diagonal's absence is known.
    for (std::uint32_t i = 0; i < out.size(); ++i)
      if (origin[i] != kNone) {
        list(i);
        for (std::uint32_t c : out[i])
          if (c < first_new)
            for (std::uint32_t u : s.vt.of(c)) list(u);
      }
    std::sort(half.begin(), half.end());
    auto find = [&](std::uint32_t a, std::uint32_t b) {
      const auto it = std::lower_bound(half.begin(), half.end(),
                                       std::make_pair(edge_key(a, b), std::uint32_t{0}));
      return it != half.end() && it->first == edge_key(a, b) ? it->second : kNone;
    };
    auto min_angle_cos = [&](const Triangle& x) {  // cosine of the smallest angle
      double worst = -1;
      for (int k = 0; k < 3; ++k) {
        const Vec3 e1 = v[x[(k + 1) % 3]] - v[x[k]], e2 = v[x[(k + 2) % 3]] - v[x[k]];
        const double d = e1.norm() * e2.norm();
        worst = std::max(worst, d > 0 ? e1.dot(e2) / d : 1.0);
      }
      return worst;
    };
    std::vector<char> touched(out.size(), 0);
    std::vector<std::uint64_t> made;  // diagonals made in this sweep (undirected)
    for (std::uint32_t i = 0; i < out.size(); ++i) {
      if (origin[i] == kNone || touched[i]) continue;
      for (std::uint32_t k = 0; k < 3 && !touched[i]; ++k) {
        const std::uint32_t a = out[i][k], b = out[i][(k + 1) % 3], p = out[i][(k + 2) % 3];
        if (a >= first_new && b >= first_new) continue;  // on the recovered line
        const std::uint32_t j = find(b, a);
        if (j == kNone || touched[j] || j == i) continue;
        std::uint32_t q = kNone;
        for (std::uint32_t c : out[j])
          if (c != a && c != b) q = c;
        if (q == kNone || q == p) continue;
        const std::uint64_t diagonal = edge_key(std::min(p, q), std::max(p, q));
        if (find(p, q) != kNone || find(q, p) != kNone ||
            std::find(made.begin(), made.end(), diagonal) != made.end())
          continue;
        double ai = 0, aj = 0;
        const Vec3 ni = unit_normal(v, out[i], &ai), nj = unit_normal(v, out[j], &aj);
        if (ni.dot(nj) < cos_smooth) continue;
        const Triangle x{p, a, q}, y{q, b, p};
        double ax = 0, ay = 0;
        const Vec3 pair = (ai * ni + aj * nj).normalized();
        const Vec3 nx = unit_normal(v, x, &ax), ny = unit_normal(v, y, &ay);
        if (!(ax > 0) || !(ay > 0) || nx.dot(pair) < cos_smooth || ny.dot(pair) < cos_smooth)
          continue;
        if (std::max(min_angle_cos(x), min_angle_cos(y)) >=
            std::max(min_angle_cos(out[i]), min_angle_cos(out[j])))
          continue;
        out[i] = x;
        out[j] = y;
        if (origin[j] == kNone) origin[j] = origin[i];
        touched[i] = touched[j] = 1;
        made.push_back(diagonal);
        ++st.tidied;
      }
    }
    if (made.empty()) break;
  }
}

/// One pass over `mesh`.
SharpenStats sharpen_pass(Mesh& mesh, const SharpenOptions& options) {
  SharpenStats stats;
  const std::size_t nt = mesh.triangles.size();
  if (nt == 0) return stats;
  for (const Triangle& t : mesh.triangles)
    for (std::uint32_t v : t)
      if (v >= mesh.vertices.size())
        throw std::invalid_argument("sharpen: a triangle's index is out of range");
  std::vector<std::uint32_t> adjacency;
  if (!build_adjacency(mesh.triangles, adjacency)) return stats;
  const Surface s(mesh, std::move(adjacency));
  const std::vector<Vec3>& verts = s.verts;
  const std::vector<Triangle>& tris = s.tris;
  const std::vector<std::uint32_t>& across = s.across;
  const std::vector<Vec3>& normal = s.normal;
  const std::vector<Vec3>& centroid = s.centroid;
  const double cos_smooth = cos_deg(options.smooth_deg);
  const double cos_feature = cos_deg(options.feature_deg);
  const double cos_member = cos_deg(std::min(2 * options.smooth_deg, options.feature_deg));

  std::vector<std::uint32_t> label = find_faces(s, cos_smooth);
  if (options.peel) peel_bevels(s, cos_feature, label);
  PlaceScratch scratch;
  scratch.stamp.assign(nt, kNone);
  scratch.off = corners_on_other_faces(s, label, cos_feature);
  std::vector<Candidate> cand(nt);
  std::vector<std::uint32_t> bevels;
  for (std::uint32_t t = 0; t < nt; ++t) {
    if (label[t] != kNone || s.degenerate(t)) continue;
    bevels.push_back(t);
    ++stats.bevel_triangles;
    cand[t] = place_vertex(s, label, t, cos_feature, cos_member, scratch);
    stats.rounded += cand[t].rounded ? 1 : 0;
  }

  // Apply the splits and flips of the bevels not refused; check the new triangles against the
  // mesh; refuse the bevels whose triangles cross and start again from the input.
  std::vector<char> refused(nt, 0);
  for (int round = 0; round < kMaxRounds; ++round) {
    std::vector<Vec3> v = verts;
    std::vector<Triangle> out = tris;
    std::vector<std::uint32_t> origin(nt, kNone);  // bevel triangle that made a triangle
    std::vector<std::uint32_t> partner(nt, kNone);  // the other bevel of a flipped pair
    std::vector<std::array<std::uint32_t, 3>> sub(nt, {kNone, kNone, kNone});
    std::vector<std::uint32_t> apex(nt, kNone);
    std::vector<char> split(nt, 0);
    for (std::uint32_t t : bevels)
      split[t] = cand[t].ok && !refused[t];
    // A split whose triangle bends against a neighbour that is not split (past ~100 degrees)
    // would fold; refuse it before anything is made.
    for (std::uint32_t t : bevels) {
      if (!split[t]) continue;
      for (std::uint32_t k = 0; k < 3 && split[t]; ++k) {
        const std::uint32_t u = across[3 * t + k];
        if (u == kNone || split[u]) continue;
        const Triangle s{tris[t][k], tris[t][(k + 1) % 3], 0};
        const Vec3 n = (v[s[1]] - v[s[0]]).cross(cand[t].p - v[s[0]]).normalized();
        if (n.dot(normal[u]) < kFoldCos) split[t] = 0;
      }
    }
    SharpenStats st;
    st.bevel_triangles = stats.bevel_triangles;
    st.rounded = stats.rounded;
    for (std::uint32_t t : bevels) {
      if (!split[t]) continue;
      const auto p = static_cast<std::uint32_t>(v.size());
      v.push_back(cand[t].p);
      apex[t] = p;
      (cand[t].corner ? st.corner_vertices : st.edge_vertices)++;
      const Triangle old = tris[t];
      for (std::uint32_t k = 0; k < 3; ++k) {
        const Triangle s{old[k], old[(k + 1) % 3], p};
        std::uint32_t id = t;
        if (k == 0) {
          out[t] = s;
        } else {
          id = static_cast<std::uint32_t>(out.size());
          out.push_back(s);
          origin.push_back(kNone);
          partner.push_back(kNone);
        }
        origin[id] = t;
        sub[t][k] = id;
      }
    }
    // Flips: across an edge (a, b) of two split bevels, (a, b, pT) and (b, a, pU) become
    // (pT, a, pU) and (pU, b, pT) when the new edge pT-pU follows the recovered feature. Two
    // split neighbours that cannot be flipped raise two tents over their edge that lean into
    // the triangles beside them: the one higher over its bevel is refused, and the round starts
    // again.
    const double cos_along = cos_deg(30);
    auto try_flip = [&](std::uint32_t t, std::uint32_t k, std::uint32_t u) {
      const std::uint32_t a = tris[t][k], b = tris[t][(k + 1) % 3];
      std::uint32_t ku = 0;
      while (ku < 3 && !(tris[u][ku] == b && tris[u][(ku + 1) % 3] == a)) ++ku;
      if (ku == 3) return false;
      const std::uint32_t pt = apex[t], pu = apex[u];
      const Vec3 e = v[pu] - v[pt];
      const double len = e.norm();
      if (!(len > 0)) return false;
      if (!cand[t].corner && std::abs(cand[t].dir.dot(e)) < cos_along * len) return false;
      if (!cand[u].corner && std::abs(cand[u].dir.dot(e)) < cos_along * len) return false;
      const Triangle x{pt, a, pu}, y{pu, b, pt};
      double ax = 0, ay = 0;
      const Vec3 nx = unit_normal(v, x, &ax), ny = unit_normal(v, y, &ay);
      const Vec3 before = unit_normal(v, out[sub[t][k]]) + unit_normal(v, out[sub[u][ku]]);
      if (!(ax > 1e-12 * len * len) || !(ay > 1e-12 * len * len)) return false;
      if (nx.dot(before) <= 0 || ny.dot(before) <= 0) return false;
      out[sub[t][k]] = x;
      out[sub[u][ku]] = y;
      // Both bevels are refused if the pair crosses the mesh.
      partner[sub[t][k]] = u;
      partner[sub[u][ku]] = t;
      ++st.flipped;
      return true;
    };
    auto lift = [&](std::uint32_t t) { return std::abs(normal[t].dot(cand[t].p - centroid[t])); };
    bool conflict = false;
    for (std::uint32_t t : bevels) {
      if (!split[t]) continue;
      for (std::uint32_t k = 0; k < 3; ++k) {
        const std::uint32_t u = across[3 * t + k];
        if (u == kNone || u < t || !split[u] || try_flip(t, k, u)) continue;
        refused[lift(u) > lift(t) ? u : t] = 1;
        conflict = true;
      }
    }
    if (conflict) continue;
    tidy(s, cos_smooth, v, out, origin, st);
    // The new triangles last, so the check tests only pairs with one of them.
    std::vector<std::uint32_t> order;
    order.reserve(out.size());
    for (std::uint32_t i = 0; i < out.size(); ++i)
      if (origin[i] == kNone) order.push_back(i);
    const std::size_t from = order.size();
    for (std::uint32_t i = 0; i < out.size(); ++i)
      if (origin[i] != kNone) order.push_back(i);
    std::vector<Triangle> sorted(out.size());
    for (std::size_t i = 0; i < order.size(); ++i) sorted[i] = out[order[i]];
    const SelfIntersections crossing = find_self_intersections(v, sorted, kAllPairs, from);
    if (crossing.pairs == 0) {
      st.refused = static_cast<std::size_t>(std::count_if(
          bevels.begin(), bevels.end(), [&](std::uint32_t t) { return cand[t].ok && !split[t]; }));
      mesh.vertices = std::move(v);
      mesh.triangles = std::move(sorted);
      return st;
    }
    for (const auto& pair : crossing.examples)
      for (std::uint32_t i : pair)
        if (i >= from) {
          refused[origin[order[i]]] = 1;
          if (partner[order[i]] != kNone) refused[partner[order[i]]] = 1;
        }
  }
  stats.refused = static_cast<std::size_t>(
      std::count_if(bevels.begin(), bevels.end(), [&](std::uint32_t t) { return cand[t].ok; }));
  return stats;  // every round crossed: the mesh is left as it was
}

}  // namespace

SharpenStats sharpen_edges(Mesh& mesh, const SharpenOptions& options) {
  if (const auto errors = options.validate(); !errors.empty())
    throw std::invalid_argument(errors.front());
  // Each pass after the first sees the edges the one before recovered: the bevels beside a
  // recovered stretch then see both faces, and the tents left where two new vertices could not
  // be joined are split again along the line.
  SharpenStats total;
  for (int pass = 0; pass < options.passes; ++pass) {
    const SharpenStats st = sharpen_pass(mesh, options);
    if (pass == 0) total.bevel_triangles = st.bevel_triangles;
    total.edge_vertices += st.edge_vertices;
    total.corner_vertices += st.corner_vertices;
    total.flipped += st.flipped;
    total.tidied += st.tidied;
    total.refused = st.refused;
    total.rounded += st.rounded;
    if (st.edge_vertices + st.corner_vertices == 0) break;
  }
  return total;
}

}  // namespace scanmesh::recon
