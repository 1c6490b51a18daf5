// Locating the shared real scans (SCANMESH_DATA) from tests and benchmarks.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdlib>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>

namespace scanmesh::test {

/// The file `rel` under $SCANMESH_DATA. Returns nullopt when SCANMESH_DATA is unset (the test
/// then has nothing to check); throws when it is set but the file is missing, so CI fails loudly.
inline std::optional<std::filesystem::path> shared_file(const std::string& rel) {
  const char* root = std::getenv("SCANMESH_DATA");
  if (root == nullptr || *root == '\0') return std::nullopt;
  std::filesystem::path p = std::filesystem::path(root) / rel;
  if (!std::filesystem::is_regular_file(p)) {
    throw std::runtime_error("SCANMESH_DATA is set to '" + std::string(root) +
                             "' but the scan '" + rel + "' is missing there");
  }
  return p;
}

}  // namespace scanmesh::test
