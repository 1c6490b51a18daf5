// Internal to recon: numbers in the options' error messages, as a user typed them ("%g": 10, not
// 10.000000 as std::to_string writes).
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdio>
#include <string>

namespace scanmesh::recon::detail {

inline std::string short_number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

}  // namespace scanmesh::recon::detail
