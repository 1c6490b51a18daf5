// scanalyze registration files (.conf): one `bmesh FILE tx ty tz qx qy qz qw` line per scan,
// mapping each scan into the common (world) frame.
// SPDX-License-Identifier: MIT
#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "detail.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/meshio/meshio.hpp"

namespace scanmesh::meshio {

Eigen::Vector3d ConfEntry::to_world(const Eigen::Vector3d& p) const {
  // scanalyze stores the rotation of the conjugate quaternion: world = R^T p + t
  // (see shared/data/README.md, "Registration"). Eigen's constructor takes (w, x, y, z).
  Eigen::Quaterniond q(quaternion[3], quaternion[0], quaternion[1], quaternion[2]);
  const double norm = q.norm();
  if (!(norm > 0.0) || !std::isfinite(norm)) return p + translation;  // parse_conf rejects these
  q.coeffs() /= norm;
  return q.toRotationMatrix().transpose() * p + translation;
}

std::vector<ConfEntry> parse_conf(std::string_view text, std::string_view name,
                                  const std::filesystem::path& base_dir) {
  std::vector<ConfEntry> entries;
  detail::LineReader lines(text);
  std::string_view line;
  while (lines.next(line)) {
    detail::Tokenizer tok(line);
    const std::string_view key = tok.next();
    if (key.empty() || key.front() == '#' || key == "camera") continue;
    if (key != "bmesh" && key != "mesh") {
      detail::fail_line(name, lines.line_number(),
                        "unknown statement " + detail::quote(key) + " (expected camera or bmesh)");
    }
    const std::string_view file = tok.next();
    if (file.empty()) {
      detail::fail_line(name, lines.line_number(), "expected 'bmesh FILE tx ty tz qx qy qz qw'");
    }
    double v[7];
    for (int i = 0; i < 7; ++i) {
      const std::string_view t = tok.next();
      if (t.empty()) {
        detail::fail_line(name, lines.line_number(),
                          "expected 7 numbers (tx ty tz qx qy qz qw) after the file name, found " +
                              std::to_string(i));
      }
      const detail::NumberStatus s = detail::parse_double_token(t, v[i]);
      if (s != detail::NumberStatus::kOk) {
        detail::fail_line(name, lines.line_number(), detail::describe(s, t));
      }
    }
    ConfEntry e;
    const std::filesystem::path f{std::string(file)};
    e.file = f.is_absolute() ? f : base_dir / f;
    e.translation = Eigen::Vector3d(v[0], v[1], v[2]);
    e.quaternion = Eigen::Vector4d(v[3], v[4], v[5], v[6]);
    const double qn = e.quaternion.norm();
    if (!(qn > 1e-12) || !std::isfinite(qn)) {
      detail::fail_line(name, lines.line_number(), "rotation quaternion has zero length");
    }
    entries.push_back(std::move(e));
  }
  return entries;
}

std::vector<ConfEntry> read_conf(const std::filesystem::path& file) {
  return parse_conf(detail::load_file(file), file.string(), file.parent_path());
}

}  // namespace scanmesh::meshio
