// read_mesh(): loads a triangle mesh file and picks the parser by extension.
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
  throw InputError(name + ": unknown mesh file extension '" + ext +
                   "' (expected .ply, .stl or .obj)");
}

}  // namespace scanmesh::meshio
