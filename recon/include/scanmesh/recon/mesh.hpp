// Plain geometry value types shared by recon, meshio, preview and the tools.
// SPDX-License-Identifier: MIT
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
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

}  // namespace scanmesh::recon
