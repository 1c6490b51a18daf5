// The meshing stage from a scan's recorded "meshing" parameters.
// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstdlib>

#include "scanmesh/acquisition/meshers.hpp"
#include "scanmesh/common/error.hpp"

namespace scanmesh::acq {

std::unique_ptr<Mesher> make_mesher(const nlohmann::json& meshing) {
  if (!meshing.is_object()) throw ConfigError("meshing parameters must be a JSON object");
  recon::ReconstructOptions ro;
  const nlohmann::json cube = meshing.contains("cube") ? meshing["cube"] : nlohmann::json("auto");
  double size = 0;
  if (cube.is_number()) {
    size = cube.get<double>();
  } else if (cube.is_string() && cube.get<std::string>() != "auto") {
    const std::string text = cube.get<std::string>();
    char* end = nullptr;
    size = std::strtod(text.c_str(), &end);
    if (text.empty() || end != text.c_str() + text.size()) size = -1;
  } else if (!cube.is_string()) {
    size = -1;
  }
  if (size != 0) {
    if (!std::isfinite(size) || size <= 0)
      throw ConfigError("cube must be 'auto' or a positive size in mm, got " + cube.dump());
    ro.cube_mode = recon::ReconstructOptions::CubeMode::kFixed;
    ro.cube_mm = size;
  }
  const std::string mesher = meshing.value("mesher", std::string("incremental"));
  if (mesher == "batch") return std::make_unique<BatchMesher>(ro);
  if (mesher != "incremental")
    throw ConfigError("mesher must be 'incremental' or 'batch', got '" + mesher + "'");
  recon::IncrementalOptions io;
  io.reconstruct = ro;
  return std::make_unique<IncrementalMesher>(io);
}

}  // namespace scanmesh::acq
