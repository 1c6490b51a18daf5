// Internal to recon: border triangles that cut a chord across the scan's border, peeled off.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::recon::detail {

/// Removes, until none is left, every triangle that has a border edge (an edge of no other
/// triangle) opposite an angle of more than `min_apex_deg` degrees at a vertex that is not on
/// a border itself. Such a triangle runs its border edge as a chord past a measured point (the
/// apex) that lies almost on it: where a curved scan line ends the surface, the front's relaxed
/// pass and the sampling-gap closing lay fans of them in the line's plane, inside a convex part
/// (fins). Peeling it moves the border onto the apex; the apex keeps its other triangles, so
/// every vertex stays used, each vertex keeps a single fan (the apex's closed fan opens at the
/// removed triangle) and the loops, components and genus do not change. Returns how many
/// triangles were removed; the others keep their order.
std::size_t peel_border_chords(Mesh& mesh, double min_apex_deg);

}  // namespace scanmesh::recon::detail
