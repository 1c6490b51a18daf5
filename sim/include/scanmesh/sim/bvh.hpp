// A bounding volume hierarchy over a triangle mesh for the simulated sensors: nearest-hit rays,
// shadow (any-hit) rays, sphere casts for the touch probe and closest-point queries.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::sim {

namespace detail {
struct BvhBuilder;
}

/// Binned-SAH BVH (built binary, then collapsed to four children per node) in one flat,
/// depth-first array, traversed with an explicit stack, nearer children first; box tests are
/// 4-wide single precision, ray/triangle tests Moeller-Trumbore in double.
/// Immutable after construction, so concurrent queries are safe. Units are the mesh's (mm).
class Bvh {
 public:
  /// Builds the hierarchy. Degenerate (zero-area) triangles are kept out. Throws ConfigError for
  /// a vertex index out of range or a non-finite vertex.
  explicit Bvh(const recon::Mesh& mesh);

  struct Hit {
    double t = 0;                ///< ray parameter (distance for a unit direction)
    std::uint32_t triangle = 0;  ///< index into the mesh's triangles
    double u = 0;                ///< barycentric weight of vertex 1
    double v = 0;                ///< barycentric weight of vertex 2
  };

  /// Nearest hit with t in [t_min, t_max] on the ray origin + t dir (dir need not be unit, but
  /// t is then in units of |dir|). Both faces count. Returns false if none.
  bool intersect(const recon::Vec3& origin, const recon::Vec3& dir, double t_min, double t_max,
                 Hit& hit) const;

  /// Whether any triangle is hit with t in [t_min, t_max] (stops at the first).
  bool occluded(const recon::Vec3& origin, const recon::Vec3& dir, double t_min,
                double t_max) const;

  /// First contact of a sphere of radius `radius_mm` moving from `center` along the unit vector
  /// `dir`, up to distance t_max: t is the travel of the centre, `contact` the touched surface
  /// point. Returns false if no contact. A sphere already touching at t = 0 reports t = 0.
  struct SphereHit {
    double t = 0;
    recon::Vec3 contact{};
    std::uint32_t triangle = 0;
  };
  bool sphere_cast(const recon::Vec3& center, const recon::Vec3& dir, double radius_mm,
                   double t_max, SphereHit& hit) const;

  /// The closest surface point to p (meaningful only with at least one triangle).
  struct Closest {
    recon::Vec3 point{};
    double distance = 0;
    std::uint32_t triangle = 0;
  };
  Closest closest_point(const recon::Vec3& p) const;

  /// Unit geometric normal of mesh triangle `triangle` (from its counter-clockwise order).
  const recon::Vec3& normal(std::uint32_t triangle) const { return normals_[triangle]; }

  std::size_t triangle_count() const { return tris_.size(); }
  std::size_t node_count() const { return nodes_.size(); }
  /// Bounds of all triangles (lo, hi). Empty mesh: lo > hi.
  const recon::Vec3& bounds_lo() const { return lo_; }
  const recon::Vec3& bounds_hi() const { return hi_; }

 private:
  /// Four children per node, their boxes in single precision (rounded outwards) and laid out
  /// for one SIMD slab test of all four: b[plane * 4 + child] with planes lo x, y, z, hi x, y, z.
  /// Traversal stays conservative by moving the ray origin outwards by a per-ray rounding
  /// margin. An unused slot has an inverted (empty) box.
  struct alignas(64) Node {
    float b[24];
    std::uint32_t child[4];  ///< interior: node index; leaf: first triangle
    std::uint32_t count[4];  ///< leaf: triangle count (> 0); interior or unused: 0
  };
  struct Tri {
    double v0[3];
    double e1[3];
    double e2[3];
    std::uint32_t id;  ///< index in the mesh
  };

  std::vector<Node> nodes_;
  std::vector<Tri> tris_;
  std::vector<recon::Vec3> normals_;  ///< per mesh triangle (zero for degenerate ones)
  recon::Vec3 lo_;
  recon::Vec3 hi_;
  double max_abs_ = 0;  ///< largest absolute vertex coordinate (rounding margins)

  friend struct detail::BvhBuilder;
};

}  // namespace scanmesh::sim
