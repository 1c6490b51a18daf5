// Text point clouds (.xyz .txt .csv .asc) and read_points(), which picks the reader by extension.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cstring>
#include <string>

#include "detail.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"

namespace scanmesh::meshio {
namespace {

/// Column separators of the text point formats; '\r' makes CRLF files work unchanged.
constexpr bool is_separator(char c) {
  return c == ' ' || c == '\t' || c == ',' || c == ';' || c == '\r' || c == '\v' || c == '\f';
}

}  // namespace

recon::PointCloud parse_xyz(std::string_view text, std::string_view name) {
  recon::PointCloud cloud;
  const char* p = text.data();
  const char* const end = p + text.size();
  // A point needs at least "0 0 0\n" (6 bytes); reserving by the line count keeps the vector from
  // reallocating without ever reserving more than the text can hold.
  const auto lines = static_cast<std::size_t>(std::count(p, end, '\n')) + 1;
  cloud.points.reserve(std::min(lines, text.size() / 5 + 1));

  std::size_t line = 0;
  while (p < end) {
    ++line;
    const auto* nl =
        static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)));
    const char* const line_end = nl != nullptr ? nl : end;
    double xyz[3];
    int found = 0;
    const char* q = p;
    while (found < 3) {
      while (q < line_end && is_separator(*q)) ++q;
      if (q == line_end || *q == '#') break;
      const char* stop = nullptr;
      const detail::NumberStatus s = detail::parse_double(q, line_end, xyz[found], &stop);
      const bool token_ends = s != detail::NumberStatus::kNotANumber &&
                              (stop == line_end || is_separator(*stop) || *stop == '#');
      if (s != detail::NumberStatus::kOk || !token_ends) {
        const char* t = q;
        while (t < line_end && !is_separator(*t)) ++t;
        const std::string_view token(q, static_cast<std::size_t>(t - q));
        const auto status = token_ends ? s : detail::NumberStatus::kNotANumber;
        detail::fail_line(
            name, line,
            "column " + std::to_string(found + 1) + ": " + detail::describe(status, token));
      }
      q = stop;
      ++found;
    }
    if (found > 0 && found < 3) {
      detail::fail_line(name, line, "expected 3 numbers (x y z), found " + std::to_string(found));
    }
    if (found == 3) cloud.points.emplace_back(xyz[0], xyz[1], xyz[2]);
    p = nl != nullptr ? nl + 1 : end;
  }
  return cloud;
}

recon::PointCloud read_points(const std::filesystem::path& file) {
  const std::string ext = detail::lower_extension(file);
  const std::string name = file.string();
  if (ext == ".xyz" || ext == ".txt" || ext == ".csv" || ext == ".asc") {
    return parse_xyz(detail::load_file(file), name);
  }
  recon::PointCloud cloud;
  if (ext == ".ply") {
    cloud.points = detail::parse_ply(detail::load_file(file), name, true).vertices;
  } else if (ext == ".stl") {
    cloud.points = parse_stl(detail::load_file(file), name).vertices;
  } else if (ext == ".obj") {
    cloud.points = detail::parse_obj(detail::load_file(file), name, true).vertices;
  } else {
    detail::require_readable(file);
    throw InputError(name + ": unknown point file extension '" + ext +
                     "' (expected .xyz, .txt, .csv, .asc, .ply, .stl or .obj)");
  }
  return cloud;
}

}  // namespace scanmesh::meshio
