// Built-in reference parts. Every part is assembled from structured patches (rectangular grids,
// O-grid rings between a square and a circle, walls along a closed outline, voxel faces) whose
// shared borders are sampled identically; a tolerance weld then joins them into one closed mesh.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/parts.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "scanmesh/common/error.hpp"

namespace scanmesh::sim {
namespace {

using recon::Mesh;
using recon::Vec3;
using Vec2 = Eigen::Vector2d;

/// A structured (nu+1) x (nv+1) array of points; quad (i, j) spans (i..i+1, j..j+1). Without
/// flipping, the front side is the one the cross product du x dv points to.
struct Grid {
  int nu = 0;
  int nv = 0;
  std::vector<Vec3> pts;
  Grid(int u, int v) : nu(u), nv(v), pts(static_cast<std::size_t>((u + 1) * (v + 1))) {}
  Vec3& at(int i, int j) { return pts[static_cast<std::size_t>(j * (nu + 1) + i)]; }
  const Vec3& at(int i, int j) const { return pts[static_cast<std::size_t>(j * (nu + 1) + i)]; }
};

/// Collects triangles and merges vertices closer than the weld tolerance, so patches generated
/// independently join wherever they sample the same border points (up to rounding).
class MeshBuilder {
 public:
  std::uint32_t vertex(const Vec3& p) {
    // A point can round into a neighbouring cell; look in every cell within the tolerance.
    std::array<std::array<std::int64_t, 2>, 3> cells{};
    for (int a = 0; a < 3; ++a) {
      cells[a][0] = static_cast<std::int64_t>(std::floor((p[a] - kWeldMm) / kCellMm));
      cells[a][1] = static_cast<std::int64_t>(std::floor((p[a] + kWeldMm) / kCellMm));
    }
    for (const std::int64_t cx : cells[0])
      for (const std::int64_t cy : cells[1])
        for (const std::int64_t cz : cells[2]) {
          const auto it = cells_.find({cx, cy, cz});
          if (it == cells_.end()) continue;
          for (const std::uint32_t v : it->second)
            if ((mesh_.vertices[v] - p).squaredNorm() <= kWeldMm * kWeldMm) return v;
        }
    const auto id = static_cast<std::uint32_t>(mesh_.vertices.size());
    mesh_.vertices.push_back(p);
    cells_[{static_cast<std::int64_t>(std::floor(p.x() / kCellMm)),
            static_cast<std::int64_t>(std::floor(p.y() / kCellMm)),
            static_cast<std::int64_t>(std::floor(p.z() / kCellMm))}]
        .push_back(id);
    return id;
  }

  /// Quad a b c d, counter-clockwise seen from its front; split along the shorter diagonal.
  void quad(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    const std::uint32_t ia = vertex(a), ib = vertex(b), ic = vertex(c), id = vertex(d);
    if ((a - c).squaredNorm() <= (b - d).squaredNorm()) {
      triangle(ia, ib, ic);
      triangle(ia, ic, id);
    } else {
      triangle(ia, ib, id);
      triangle(ib, ic, id);
    }
  }

  void grid(const Grid& g, bool flip) {
    for (int j = 0; j < g.nv; ++j)
      for (int i = 0; i < g.nu; ++i) {
        const Vec3& a = g.at(i, j);
        const Vec3& b = g.at(i + 1, j);
        const Vec3& c = g.at(i + 1, j + 1);
        const Vec3& d = g.at(i, j + 1);
        if (flip) {
          quad(a, d, c, b);
        } else {
          quad(a, b, c, d);
        }
      }
  }

  Mesh take() { return std::move(mesh_); }

 private:
  static constexpr double kWeldMm = 1e-6;
  static constexpr double kCellMm = 1e-3;

  void triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    if (a == b || b == c || a == c) return;  // collapsed by the weld (never for these parts)
    mesh_.triangles.push_back({a, b, c});
  }

  Mesh mesh_;
  std::map<std::array<std::int64_t, 3>, std::vector<std::uint32_t>> cells_;
};

/// Number of segments of length about `step_mm` over `length_mm` (at least 1).
int segments(double length_mm, double step_mm) {
  return std::max(1, static_cast<int>(std::lround(length_mm / step_mm)));
}

/// 4m points on the border of the axis-aligned square of half side `half_mm` around `c`,
/// counter-clockwise from the corner (-half, -half), m per side, evenly spaced.
std::vector<Vec2> square_loop(const Vec2& c, double half_mm, int m) {
  std::vector<Vec2> pts;
  pts.reserve(static_cast<std::size_t>(4 * m));
  const std::array<Vec2, 4> corners{Vec2(-1, -1), Vec2(1, -1), Vec2(1, 1), Vec2(-1, 1)};
  for (int side = 0; side < 4; ++side) {
    const Vec2 a = c + half_mm * corners[static_cast<std::size_t>(side)];
    const Vec2 b = c + half_mm * corners[static_cast<std::size_t>((side + 1) % 4)];
    for (int k = 0; k < m; ++k) pts.push_back(a + (b - a) * (static_cast<double>(k) / m));
  }
  return pts;
}

/// 4m points evenly spaced in angle on the circle of radius r around c, counter-clockwise,
/// starting in the direction of square_loop's first corner so that point k of both loops face
/// each other (the angular skew between them stays below 5 degrees).
std::vector<Vec2> circle_loop(const Vec2& c, double r_mm, int m) {
  std::vector<Vec2> pts;
  pts.reserve(static_cast<std::size_t>(4 * m));
  for (int k = 0; k < 4 * m; ++k) {
    const double a = -0.75 * std::numbers::pi + 2 * std::numbers::pi * k / (4.0 * m);
    pts.push_back(c + r_mm * Vec2(std::cos(a), std::sin(a)));
  }
  return pts;
}

double mean_spacing(const std::vector<Vec2>& loop) {
  double sum = 0;
  for (std::size_t i = 0; i < loop.size(); ++i)
    sum += (loop[(i + 1) % loop.size()] - loop[i]).norm();
  return sum / static_cast<double>(loop.size());
}

/// Flat ring at height z between two closed loops with the same point count, `inner` inside
/// `outer`. Its front (unflipped) faces -z.
Grid flat_ring(const std::vector<Vec2>& inner, const std::vector<Vec2>& outer, double z_mm) {
  double gap = 0;
  for (std::size_t i = 0; i < inner.size(); ++i) gap += (outer[i] - inner[i]).norm();
  gap /= static_cast<double>(inner.size());
  const double step = 0.5 * (mean_spacing(inner) + mean_spacing(outer));
  const int n = static_cast<int>(inner.size());
  Grid g(n, segments(gap, step));
  for (int j = 0; j <= g.nv; ++j) {
    const double t = static_cast<double>(j) / g.nv;
    for (int i = 0; i <= n; ++i) {
      const auto k = static_cast<std::size_t>(i % n);
      const Vec2 p = j == g.nv ? outer[k] : inner[k] + (outer[k] - inner[k]) * t;
      g.at(i, j) = Vec3(p.x(), p.y(), z_mm);
    }
  }
  return g;
}

/// Axis-aligned rectangle at height z on a grid of about step_mm; front faces +z.
Grid flat_rect(const Vec2& lo, const Vec2& hi, double z_mm, double step_mm) {
  Grid g(segments(hi.x() - lo.x(), step_mm), segments(hi.y() - lo.y(), step_mm));
  for (int j = 0; j <= g.nv; ++j)
    for (int i = 0; i <= g.nu; ++i)
      g.at(i, j) =
          Vec3(lo.x() + (hi.x() - lo.x()) * i / g.nu, lo.y() + (hi.y() - lo.y()) * j / g.nv, z_mm);
  return g;
}

/// Vertical wall along a closed counter-clockwise loop from z0 to z1; front faces away from the
/// region the loop encloses.
Grid wall(const std::vector<Vec2>& loop, double z0_mm, double z1_mm, int layers) {
  const int n = static_cast<int>(loop.size());
  Grid g(n, layers);
  for (int j = 0; j <= layers; ++j) {
    const double z = j == layers ? z1_mm : z0_mm + (z1_mm - z0_mm) * j / layers;
    for (int i = 0; i <= n; ++i) {
      const Vec2& p = loop[static_cast<std::size_t>(i % n)];
      g.at(i, j) = Vec3(p.x(), p.y(), z);
    }
  }
  return g;
}

/// Layers for a wall of height h around a loop: quads close to square.
int wall_layers(const std::vector<Vec2>& loop, double height_mm) {
  return segments(height_mm, mean_spacing(loop));
}

/// Flat disk of radius r at height z (circle_loop(c, r, m) as border): a square grid in the
/// middle joined to the circle by an O-grid ring. `up` selects a +z or -z facing front.
void disk(MeshBuilder& mb, const Vec2& c, double r_mm, int m, double z_mm, bool up) {
  const double half = 0.55 * r_mm;  // inner square well inside the circle (corner at 0.78 r)
  const double step = 2 * half / m;
  mb.grid(flat_rect(c - Vec2(half, half), c + Vec2(half, half), z_mm, step), !up);
  mb.grid(flat_ring(square_loop(c, half, m), circle_loop(c, r_mm, m), z_mm), up);
}

/// Axis-aligned rectangle outline, counter-clockwise, every `step_mm` (sides must be multiples).
std::vector<Vec2> rect_loop(const Vec2& lo, const Vec2& hi, double step_mm) {
  const std::array<Vec2, 4> corners{lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y())};
  std::vector<Vec2> pts;
  for (std::size_t side = 0; side < 4; ++side) {
    const Vec2 a = corners[side];
    const Vec2 b = corners[(side + 1) % 4];
    const int n = segments((b - a).norm(), step_mm);
    for (int k = 0; k < n; ++k) pts.push_back(a + (b - a) * (static_cast<double>(k) / n));
  }
  return pts;
}

/// The container: a box base (80 x 40 x 16) with two through-holes, a cylinder on top.
/// The base faces are tiled by blocks on a 2 mm lattice: 20 x 20 blocks around the holes and a
/// 40 x 40 block under the cylinder are O-grids, the rest plain grids, so all block borders
/// carry the same 2 mm points.
Mesh make_container() {
  constexpr double kStep = 2.0;  // lattice step on the flat faces
  constexpr double kBaseX = 80, kBaseY = 40, kBaseZ = 16;
  constexpr double kHoleR = 5;  // through-hole radius
  constexpr double kCylR = 16, kCylH = 20;
  const std::array<Vec2, 2> holes{Vec2(10, 20), Vec2(70, 20)};
  const Vec2 cyl(40, 20);
  const int m_hole = segments(20, kStep);  // points per side of a hole block
  const int m_cyl = segments(40, kStep);   // points per side of the cylinder block

  MeshBuilder mb;
  // Plain blocks beside the holes (the strips above and below each hole block).
  const std::array<std::pair<Vec2, Vec2>, 4> strips{
      std::pair{Vec2(0, 0), Vec2(20, 10)}, std::pair{Vec2(0, 30), Vec2(20, 40)},
      std::pair{Vec2(60, 0), Vec2(80, 10)}, std::pair{Vec2(60, 30), Vec2(80, 40)}};
  for (const auto& [lo, hi] : strips) {
    mb.grid(flat_rect(lo, hi, kBaseZ, kStep), false);  // top, +z
    mb.grid(flat_rect(lo, hi, 0, kStep), true);        // bottom, -z
  }
  for (const Vec2& h : holes) {
    const auto sq = square_loop(h, 10, m_hole);
    const auto circ = circle_loop(h, kHoleR, m_hole);
    mb.grid(flat_ring(circ, sq, kBaseZ), true);
    mb.grid(flat_ring(circ, sq, 0), false);
    // The hole's wall faces its axis (out of the material): the reverse of an outer wall.
    mb.grid(wall(circ, 0, kBaseZ, wall_layers(circ, kBaseZ)), true);
  }
  // Under the cylinder: the bottom is a plain block, the top an O-grid to the cylinder's foot.
  mb.grid(flat_rect(Vec2(20, 0), Vec2(60, 40), 0, kStep), true);
  const auto cyl_circle = circle_loop(cyl, kCylR, m_cyl);
  mb.grid(flat_ring(cyl_circle, square_loop(cyl, 20, m_cyl), kBaseZ), true);
  // Outer walls of the base.
  const auto outline = rect_loop(Vec2(0, 0), Vec2(kBaseX, kBaseY), kStep);
  mb.grid(wall(outline, 0, kBaseZ, segments(kBaseZ, kStep)), false);
  // The cylinder and its flat top.
  mb.grid(wall(cyl_circle, kBaseZ, kBaseZ + kCylH, wall_layers(cyl_circle, kCylH)), false);
  disk(mb, cyl, kCylR, m_cyl, kBaseZ + kCylH, true);
  return mb.take();
}

Mesh make_cylinder() {
  constexpr double kR = 15, kH = 40;
  const int m = segments(2 * std::numbers::pi * kR / 4, 1.5);  // about 1.5 mm around
  const Vec2 c(0, 0);
  const auto circ = circle_loop(c, kR, m);
  MeshBuilder mb;
  mb.grid(wall(circ, 0, kH, wall_layers(circ, kH)), false);
  disk(mb, c, kR, m, 0, false);
  disk(mb, c, kR, m, kH, true);
  return mb.take();
}

/// Icosahedron subdivided `levels` times, every vertex pushed onto the sphere.
Mesh make_sphere() {
  constexpr double kR = 20;
  constexpr int kLevels = 4;  // edges of about 1.3 mm
  const double t = (1 + std::sqrt(5.0)) / 2;
  Mesh mesh;
  for (const Vec3& v : {Vec3(-1, t, 0), Vec3(1, t, 0), Vec3(-1, -t, 0), Vec3(1, -t, 0),
                        Vec3(0, -1, t), Vec3(0, 1, t), Vec3(0, -1, -t), Vec3(0, 1, -t),
                        Vec3(t, 0, -1), Vec3(t, 0, 1), Vec3(-t, 0, -1), Vec3(-t, 0, 1)})
    mesh.vertices.push_back(v.normalized());
  mesh.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                    {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                    {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                    {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < kLevels; ++level) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> midpoints;
    auto mid = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::minmax(a, b);
      const auto it = midpoints.find(key);
      if (it != midpoints.end()) return it->second;
      const auto id = static_cast<std::uint32_t>(mesh.vertices.size());
      mesh.vertices.push_back((mesh.vertices[a] + mesh.vertices[b]).normalized());
      midpoints.emplace(key, id);
      return id;
    };
    std::vector<recon::Triangle> next;
    next.reserve(mesh.triangles.size() * 4);
    for (const auto& tri : mesh.triangles) {
      const std::uint32_t ab = mid(tri[0], tri[1]), bc = mid(tri[1], tri[2]),
                          ca = mid(tri[2], tri[0]);
      next.push_back({tri[0], ab, ca});
      next.push_back({tri[1], bc, ab});
      next.push_back({tri[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    mesh.triangles = std::move(next);
  }
  for (Vec3& v : mesh.vertices) v *= kR;
  return mesh;
}

/// Three 20 mm steps of heights 10, 20, 30 mm on a 60 x 30 mm footprint, built from the faces
/// between filled and empty 2 mm voxels (a staircase has no edge-touching voxels, so the
/// surface is manifold).
Mesh make_steps() {
  constexpr double kStep = 2.0;
  constexpr int kNx = 30, kNy = 15;
  auto height_cells = [](int ix) { return ix < 10 ? 5 : ix < 20 ? 10 : 15; };
  auto filled = [&](int ix, int iy, int iz) {
    return ix >= 0 && ix < kNx && iy >= 0 && iy < kNy && iz >= 0 && iz < height_cells(ix);
  };
  MeshBuilder mb;
  for (int ix = 0; ix < kNx; ++ix)
    for (int iy = 0; iy < kNy; ++iy)
      for (int iz = 0; iz < height_cells(ix); ++iz)
        for (int axis = 0; axis < 3; ++axis)
          for (const int dir : {-1, 1}) {
            std::array<int, 3> n{ix, iy, iz};
            n[static_cast<std::size_t>(axis)] += dir;
            if (filled(n[0], n[1], n[2])) continue;
            // Face of the cell on the `dir` side of `axis`; eb x ec = e_axis.
            Vec3 origin(ix, iy, iz);
            if (dir > 0) origin[axis] += 1;
            Vec3 eb = Vec3::Zero(), ec = Vec3::Zero();
            eb[(axis + 1) % 3] = 1;
            ec[(axis + 2) % 3] = 1;
            const Vec3 a = origin * kStep, b = (origin + eb) * kStep,
                       c = (origin + eb + ec) * kStep, d = (origin + ec) * kStep;
            if (dir > 0) {
              mb.quad(a, b, c, d);
            } else {
              mb.quad(a, d, c, b);
            }
          }
  return mb.take();
}

}  // namespace

std::vector<PartInfo> part_catalog() {
  return {
      {"container",
       "80x40x16 mm box base with two 10 mm through-holes and a 32x20 mm cylinder on top", 2},
      {"sphere", "sphere of radius 20 mm", 0},
      {"cylinder", "closed cylinder of radius 15 mm and height 40 mm", 0},
      {"steps", "60x30 mm block with three steps of 10, 20 and 30 mm", 0},
  };
}

std::vector<std::string> part_names() {
  std::vector<std::string> names;
  for (const auto& p : part_catalog()) names.push_back(p.name);
  return names;
}

recon::Mesh make_part(std::string_view name) {
  if (name == "container") return make_container();
  if (name == "sphere") return make_sphere();
  if (name == "cylinder") return make_cylinder();
  if (name == "steps") return make_steps();
  std::string valid;
  for (const auto& n : part_names()) valid += (valid.empty() ? "" : ", ") + n;
  throw ConfigError("unknown part '" + std::string(name) + "' (valid parts: " + valid + ")");
}

}  // namespace scanmesh::sim
