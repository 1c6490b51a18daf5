// Points written so that a benchmark's flagged run can be reproduced bit for bit.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdio>
#include <string>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::bench {

/// Writes the points to DIR/STEM.xyz (spaces, '%' and '/' in STEM as underscores) as x y z
/// lines with 17 significant digits (the doubles exactly; `scanmesh simulate` and the xyz writer
/// keep 9, enough for a sensor but not to reproduce a run bit for bit), and prints "saved FILE"
/// or "cannot write FILE".
inline void save_points_exact(const std::vector<recon::Vec3>& points, const std::string& dir,
                              std::string stem) {
  for (char& c : stem)
    if (c == ' ' || c == '%' || c == '/') c = '_';
  const std::string file = dir + "/" + stem + ".xyz";
  std::FILE* f = std::fopen(file.c_str(), "w");
  if (f == nullptr) {
    std::printf("  cannot write %s\n", file.c_str());
    return;
  }
  for (const recon::Vec3& p : points) std::fprintf(f, "%.17g %.17g %.17g\n", p.x(), p.y(), p.z());
  if (std::fclose(f) != 0)
    std::printf("  cannot write %s\n", file.c_str());
  else
    std::printf("  saved %s\n", file.c_str());
}

}  // namespace scanmesh::bench
