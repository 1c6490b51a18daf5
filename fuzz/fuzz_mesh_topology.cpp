// libFuzzer entry point for the mesh topology code that `scanmesh inspect` and the hole filling
// run on meshes from outside: a mesh parsed from the bytes (first byte: OBJ, ASCII/binary STL or
// PLY; next bits of that byte: flat patches or refined and faired ones, and whether only loops
// short for a spacing from the second byte are closed, and whether only loops at most as wide
// as a size from the third byte are) goes through analyze(), sharpen_edges(), denoise_mesh(), fill_holes(),
// untangle_gaps() and find_self_intersections(). Only scanmesh::Error is an expected outcome; a
// manifold, consistently oriented input must stay so after sharpening (of the same topology,
// without crossings when it had none), denoising (the same triangles, finite vertices, no
// crossing), filling and untangling, with each
// filled loop gone, the added vertices counted, the existing ones unmoved, and no crossing added
// by a patch.
// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/denoise.hpp"
#include "scanmesh/recon/fill.hpp"
#include "scanmesh/recon/intersections.hpp"
#include "scanmesh/recon/sharpen.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string_view bytes(reinterpret_cast<const char*>(data + 1), size - 1);
  namespace meshio = scanmesh::meshio;
  namespace recon = scanmesh::recon;
  try {
    recon::Mesh mesh;
    switch (data[0] % 3) {
      case 0:
        mesh = meshio::parse_obj(bytes, "fuzz.obj");
        break;
      case 1:
        mesh = meshio::parse_stl(bytes, "fuzz.stl");
        break;
      default:
        mesh = meshio::parse_ply(bytes, "fuzz.ply");
        break;
    }
    if (mesh.triangles.size() > 4096) return 0;  // keep each run short
    const recon::MeshReport before = recon::analyze(mesh, true);
    const recon::SelfIntersections crossing = recon::find_self_intersections(mesh, 4);
    if (crossing.examples.size() > crossing.pairs || crossing.triangles > 2 * crossing.pairs ||
        crossing.triangles > mesh.triangles.size())
      __builtin_trap();
    for (const auto& [a, b] : crossing.examples)
      if (a >= b || b >= mesh.triangles.size()) __builtin_trap();
    const std::size_t old_triangles = mesh.triangles.size();
    // Sharp-edge recovery on a copy: a clean input without crossings stays clean, of the same
    // topology and without crossings, its vertices unmoved and the new ones counted.
    if (before.non_manifold_edges == 0 && before.non_manifold_vertices == 0 &&
        before.orientation_consistent && crossing.pairs == 0) {
      recon::Mesh sharp = mesh;
      recon::SharpenOptions so;
      so.passes = 1 + (data[0] / 3) % 2;  // the first byte's other bits: one pass or two
      const recon::SharpenStats st = recon::sharpen_edges(sharp, so);
      if (sharp.vertices.size() != mesh.vertices.size() + st.edge_vertices + st.corner_vertices ||
          (!mesh.vertices.empty() &&
           std::memcmp(sharp.vertices.data(), mesh.vertices.data(),
                       mesh.vertices.size() * sizeof(recon::Vec3)) != 0))
        __builtin_trap();
      const recon::MeshReport r = recon::analyze(sharp);
      if (r.non_manifold_edges != 0 || r.non_manifold_vertices != 0 || !r.orientation_consistent ||
          r.boundary_loops != before.boundary_loops || r.components != before.components ||
          r.genus != before.genus || recon::find_self_intersections(sharp, 0).pairs != 0)
        __builtin_trap();
      // Noise removal on a copy: only vertices move, to finite places, and nothing crosses.
      recon::Mesh smooth = mesh;
      recon::DenoiseOptions dn;
      dn.feature_deg = (data[0] / 6) % 2 == 1 ? 30 : 0;  // fixed, or from the mesh's own scatter
      const recon::DenoiseStats ds = recon::denoise_mesh(smooth, dn);
      if (smooth.triangles != mesh.triangles || smooth.vertices.size() != mesh.vertices.size() ||
          ds.moved + ds.refused > mesh.vertices.size() ||
          recon::find_self_intersections(smooth, 0).pairs != 0)
        __builtin_trap();
      for (std::size_t v = 0; v < smooth.vertices.size(); ++v)
        if (!smooth.vertices[v].allFinite() && mesh.vertices[v].allFinite()) __builtin_trap();
    }
    recon::FillOptions opt;
    opt.max_edges = 64;
    opt.refine = (data[0] / 3) % 2 == 0;
    // Third bit: only loops short for the spacing (as the reconstruction's gap stage does), with
    // every vertex's spacing from the next byte.
    std::vector<float> spacing;
    if ((data[0] / 6) % 2 == 1) {
      opt.max_perimeter_spacings = 10;
      spacing.assign(mesh.vertices.size(), static_cast<float>(size > 1 ? data[1] : 1) / 64.0f);
    }
    // Fourth bit: only loops at most (third byte) / 16 wide.
    if ((data[0] / 12) % 2 == 1) opt.max_width = static_cast<double>(size > 2 ? data[2] : 1) / 16;
    // The loops the limits let through, counted here by brute force.
    std::size_t short_loops = 0;
    for (const recon::BoundaryLoop& loop : before.loops) {
      double perimeter = 0, width = 0;
      for (std::size_t i = 0; i < loop.vertices.size(); ++i) {
        const recon::Vec3& a = mesh.vertices[loop.vertices[i]];
        perimeter += (mesh.vertices[loop.vertices[(i + 1) % loop.vertices.size()]] - a).norm();
        for (const std::uint32_t w : loop.vertices) {
          const double d = (mesh.vertices[w] - a).norm();
          width = d > width || std::isnan(d) ? d : width;  // NaN: too wide
        }
      }
      if (opt.max_perimeter_spacings > 0 && !(perimeter <= 10.0 * static_cast<double>(spacing[0])))
        continue;
      if (opt.max_width > 0 && !(width <= opt.max_width * (1 + 1e-12))) continue;
      ++short_loops;
    }
    const std::vector<recon::Vec3> vertices = mesh.vertices;
    const recon::FillStats stats = recon::fill_holes(mesh, opt, spacing);
    if (stats.filled > short_loops) __builtin_trap();  // a loop too long or wide was filled
    if (mesh.vertices.size() != vertices.size() + stats.vertices) __builtin_trap();
    if (!opt.refine && stats.vertices != 0) __builtin_trap();
    for (std::size_t v = 0; v < vertices.size(); ++v)  // bitwise: NaN coordinates stay NaN
      if (std::memcmp(&mesh.vertices[v], &vertices[v], sizeof(recon::Vec3)) != 0) __builtin_trap();
    const recon::MeshReport after = recon::analyze(mesh);
    const bool clean = before.non_manifold_edges == 0 && before.non_manifold_vertices == 0 &&
                       before.orientation_consistent;
    if (!clean && stats.filled != 0) __builtin_trap();  // only clean meshes are touched
    if (clean) {
      if (after.non_manifold_edges != 0 || after.non_manifold_vertices != 0 ||
          !after.orientation_consistent)
        __builtin_trap();
      if (after.boundary_loops + stats.filled != before.boundary_loops) __builtin_trap();
      if (recon::find_self_intersections(mesh, 0, old_triangles).pairs != 0) __builtin_trap();
      // The loops left open because their patch crosses the mesh, untangled where a few
      // triangles reach through them: the mesh stays clean, with as many components, as many
      // vertices used but the few of a widened removal dropped (and closed up), and exactly the
      // loops it closed fewer.
      if (stats.crossing > 0 && !opt.refine && opt.max_perimeter_spacings > 0) {
        const std::size_t old_vertices = mesh.vertices.size();
        const recon::UntangleStats u = recon::untangle_gaps(mesh, opt, spacing, stats);
        const recon::MeshReport untangled = recon::analyze(mesh);
        if (untangled.non_manifold_edges != 0 || untangled.non_manifold_vertices != 0 ||
            !untangled.orientation_consistent || untangled.components != after.components ||
            untangled.referenced_vertices + u.dropped.size() != after.referenced_vertices ||
            mesh.vertices.size() + u.dropped.size() != old_vertices ||
            u.dropped.size() > recon::kUntangleMaxDropped * u.widened ||
            u.renumber.size() != (u.dropped.empty() ? 0 : old_vertices) ||
            untangled.boundary_loops + u.closed != after.boundary_loops ||
            (u.closed == 0) != (u.removed == 0))
          __builtin_trap();
      }
    }
  } catch (const scanmesh::Error&) {
    // malformed input: the expected way to reject it
  }
  return 0;
}
