// libFuzzer entry point for the mesh topology code that `scanmesh inspect` and the hole filling
// run on meshes from outside: a mesh parsed from the bytes (first byte: OBJ, ASCII/binary STL or
// PLY) goes through analyze() and fill_holes(). Only scanmesh::Error is an expected outcome; a
// manifold, consistently oriented input must stay so after filling, with no more loops and the
// same genus.
// SPDX-License-Identifier: MIT
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/fill.hpp"

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
    recon::FillOptions opt;
    opt.max_edges = 64;
    const recon::FillStats stats = recon::fill_holes(mesh, opt);
    const recon::MeshReport after = recon::analyze(mesh);
    const bool clean = before.non_manifold_edges == 0 && before.non_manifold_vertices == 0 &&
                       before.orientation_consistent;
    if (!clean && stats.filled != 0) __builtin_trap();  // only clean meshes are touched
    if (clean) {
      if (after.non_manifold_edges != 0 || after.non_manifold_vertices != 0 ||
          !after.orientation_consistent)
        __builtin_trap();
      if (after.boundary_loops + stats.filled != before.boundary_loops) __builtin_trap();
    }
  } catch (const scanmesh::Error&) {
    // malformed input: the expected way to reject it
  }
  return 0;
}
