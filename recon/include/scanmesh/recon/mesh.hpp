// Plain geometry value types shared by recon, meshio, preview and the tools.
// SPDX-License-Identifier: MIT
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace scanmesh::recon {

using Vec3 = Eigen::Vector3d;
using Triangle = std::array<std::uint32_t, 3>;  ///< vertex indices, counter-clockwise seen from outside

/// An unorganised point set (input units, usually millimetres).
struct PointCloud {
  std::vector<Vec3> points;
};

/// An indexed triangle mesh. Orientation: (v0, v1, v2) counter-clockwise seen from the outside.
struct Mesh {
  std::vector<Vec3> vertices;
  std::vector<Triangle> triangles;
};

/// The smallest axis-aligned box holding the points (empty, min > max, for none).
inline Eigen::AlignedBox3d bounding_box(std::span<const Vec3> points) {
  Eigen::AlignedBox3d box;
  for (const Vec3& p : points) box.extend(p);
  return box;
}

}  // namespace scanmesh::recon
