// Built-in parametric reference parts: closed, manifold, outward-oriented triangle meshes made by
// code (sizes in millimetres), used as scan targets and as exact deviation references.
// SPDX-License-Identifier: MIT
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::sim {

/// One built-in part: its name, a one-line description and the genus of its closed surface.
struct PartInfo {
  std::string name;
  std::string description;
  long genus = 0;  ///< number of through-holes (0 for a sphere-like surface)
};

/// Every built-in part in a fixed order: container, sphere, cylinder, steps.
std::vector<PartInfo> part_catalog();

/// The names of part_catalog(), in the same order.
std::vector<std::string> part_names();

/// Builds a part by name. Every part is one closed, edge-manifold, consistently outward-oriented
/// triangle mesh (positive signed volume) with triangles no worse than about 5:1, edges of about
/// 1-2 mm. Throws scanmesh::ConfigError for an unknown name, listing the valid ones.
///
/// - `container`: 80 x 40 x 16 mm box base (corner at the origin, z up) with two vertical
///   through-holes of diameter 10 mm centred at (10, 20) and (70, 20), and a cylinder of radius
///   16 mm and height 20 mm centred at (40, 20) on top, closed by a flat top face at z = 36.
///   Genus 2.
/// - `sphere`: radius 20 mm at the origin (subdivided icosahedron). Genus 0.
/// - `cylinder`: radius 15 mm, height 40 mm, axis z from z = 0, flat caps. Genus 0.
/// - `steps`: stepped block 60 x 30 mm with three 20 mm wide steps of heights 10, 20 and 30 mm
///   (rising along +x). Genus 0.
recon::Mesh make_part(std::string_view name);

}  // namespace scanmesh::sim
