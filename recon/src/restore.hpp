// Internal to recon: vertices put back where they were measured, after the mesh is built.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon::detail {

/// Moves each listed vertex (ascending, each once) of `mesh` to its target where that keeps the
/// mesh as valid as it was: none of its triangles tilts by more than 60 degrees or gets an
/// angle under 1 degree, and none crosses another triangle. The connectivity never changes.
/// Returns how many moved. Used for the representatives whose projection cut across a sharp
/// edge, a corner or a step (reconstruct.cpp): the front meshes the projected points, whose
/// rounded features it follows more surely, and the mesh keeps the measured ones.
std::size_t restore_positions(Mesh& mesh, std::span<const std::pair<std::uint32_t, Vec3>> targets);

}  // namespace scanmesh::recon::detail
