// libFuzzer entry point for the meshio parsers: the first byte picks the format, the rest is the
// file content. Only scanmesh::Error (malformed input) is an expected outcome.
// SPDX-License-Identifier: MIT
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string_view bytes(reinterpret_cast<const char*>(data + 1), size - 1);
  namespace meshio = scanmesh::meshio;
  try {
    switch (data[0] % 5) {
      case 0:
        (void)meshio::parse_xyz(bytes, "fuzz.xyz");
        break;
      case 1:
        (void)meshio::parse_ply(bytes, "fuzz.ply");
        break;
      case 2:
        (void)meshio::parse_stl(bytes, "fuzz.stl");
        break;
      case 3:
        (void)meshio::parse_obj(bytes, "fuzz.obj");
        break;
      default: {
        const auto entries = meshio::parse_conf(bytes, "fuzz.conf", "/base");
        // Exercise the transform too: it must stay finite for every accepted entry.
        for (const auto& e : entries) {
          const Eigen::Vector3d w = e.to_world(Eigen::Vector3d(1, 2, 3));
          if (!w.allFinite()) __builtin_trap();
        }
        break;
      }
    }
  } catch (const scanmesh::Error&) {
    // malformed input: the expected way to reject it
  }
  return 0;
}
