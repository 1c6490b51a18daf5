// Fixed-width decimal parsing shared by the ASCII sensor codecs.
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/common/line_framer.hpp"

#include <cmath>
#include <cstdint>

namespace scanmesh::drivers {

bool parse_fixed_decimal(std::string_view text, double& value) {
  std::size_t i = 0;
  bool negative = false;
  if (i < text.size() && (text[i] == '+' || text[i] == '-')) {
    negative = text[i] == '-';
    ++i;
  }
  std::int64_t mantissa = 0;
  int digits = 0;
  int decimals = -1;  // digits after '.', -1 = no point seen
  for (; i < text.size(); ++i) {
    const char c = text[i];
    if (c >= '0' && c <= '9') {
      if (digits >= 15) return false;
      mantissa = mantissa * 10 + (c - '0');
      ++digits;
      if (decimals >= 0) ++decimals;
    } else if (c == '.' && decimals < 0) {
      decimals = 0;
    } else {
      return false;
    }
  }
  if (digits == 0) return false;
  static constexpr double kPow10[] = {1, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7,
                                      1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15};
  double v = static_cast<double>(mantissa);
  if (decimals > 0) v /= kPow10[decimals];
  value = negative ? -v : v;
  return true;
}

}  // namespace scanmesh::drivers
