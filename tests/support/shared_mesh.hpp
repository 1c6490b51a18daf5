// A reference mesh from the shared real scans (SCANMESH_DATA), for Catch2 tests.
// SPDX-License-Identifier: MIT
#pragma once

#include <catch2/catch.hpp>
#include <optional>
#include <string>

#include "scanmesh/meshio/meshio.hpp"
#include "support/data.hpp"

namespace scanmesh::test {

/// The mesh `rel` under $SCANMESH_DATA; nullopt, with a warning that the test skips `what`, when
/// SCANMESH_DATA is unset. Throws (as shared_file does) when it is set but the file is missing.
inline std::optional<recon::Mesh> shared_mesh(const std::string& rel, const std::string& what) {
  const auto file = shared_file(rel);
  if (!file) {
    WARN("SCANMESH_DATA is not set: skipping " << what);
    return std::nullopt;
  }
  return meshio::read_mesh(*file);
}

}  // namespace scanmesh::test
