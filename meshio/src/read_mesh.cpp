// read_mesh(), read_points_and_faces(): load a triangle mesh file, picking the parser by
// extension.
// SPDX-License-Identifier: MIT
#include <string>

#include "detail.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"

namespace scanmesh::meshio {

recon::Mesh read_mesh(const std::filesystem::path& file) {
  const std::string ext = detail::lower_extension(file);
  const std::string name = file.string();
  if (ext == ".ply") return parse_ply(detail::load_file(file), name);
  if (ext == ".stl") return parse_stl(detail::load_file(file), name);
  if (ext == ".obj") return parse_obj(detail::load_file(file), name);
  detail::require_readable(file);
  throw InputError(name + ": unknown mesh file extension '" + ext +
                   "' (expected .ply, .stl or .obj)");
}

recon::Mesh read_points_and_faces(const std::filesystem::path& file) {
  const std::string ext = detail::lower_extension(file);
  if (ext == ".ply" || ext == ".stl" || ext == ".obj") {
    try {
      return read_mesh(file);
    } catch (const InputError&) {
      // The faces are unusable; read_points below reads the points alone or names their fault.
    }
  }
  return recon::Mesh{read_points(file).points, {}};
}

}  // namespace scanmesh::meshio
