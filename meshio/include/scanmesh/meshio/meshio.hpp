// Reading point clouds and meshes, writing meshes. Every reader reports malformed input as
// scanmesh::InputError naming the file, the line (text) or byte offset (binary) and the problem.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::meshio {

/// Reads the points of any supported file, chosen by extension (case-insensitive):
/// .xyz .txt .csv .asc (x y z per line; separators space, tab, comma, semicolon; extra columns and
/// '#' comments ignored), .ply (vertices), .stl (unique vertices), .obj ('v' lines).
/// Throws InputError (unreadable, malformed, unknown extension).
recon::PointCloud read_points(const std::filesystem::path& file);

/// Reads a triangle mesh: .ply (face lists, triangulated as fans; tristrips with -1 restarts),
/// .stl (ascii or binary; coincident vertices merged exactly), .obj (faces with v/vt/vn forms,
/// negative indices, polygons triangulated as fans). Throws InputError.
recon::Mesh read_mesh(const std::filesystem::path& file);

/// The points of any file read_points takes, with the faces when it is a mesh (.ply .stl .obj)
/// whose faces parse (as read_mesh); a point file, a mesh without faces or one whose faces do
/// not parse gives its points with no triangles (faces that do not parse do not spoil the
/// points). Throws InputError as read_points does.
recon::Mesh read_points_and_faces(const std::filesystem::path& file);

/// In-memory parsers used by the file readers, the tests and the fuzz targets. `name` is used in
/// error messages only.
recon::PointCloud parse_xyz(std::string_view text, std::string_view name);
recon::Mesh parse_ply(std::string_view bytes, std::string_view name);  // vertices + faces
recon::Mesh parse_stl(std::string_view bytes, std::string_view name);
recon::Mesh parse_obj(std::string_view text, std::string_view name);

/// What a PLY file holds beside its points and faces, for readers that want it.
struct PlyExtras {
  /// Header lines skipped because their keyword is unknown (real raw scans bend the format:
  /// some Stanford range scans carry a line 'bye'), each as "FILE:LINE: unknown header line
  /// 'bye' skipped". The readers never refuse a file for such a line.
  std::vector<std::string> warnings;
  /// A range scan's rows (`range_grid` with `obj_info num_cols N`): the vertex indices of each
  /// row of the grid, in column order (empty rows kept); empty without a range grid.
  std::vector<std::vector<std::uint32_t>> range_rows;
};
recon::Mesh parse_ply(std::string_view bytes, std::string_view name, PlyExtras& extras);
/// read_mesh of a .ply, with its extras. Throws InputError.
recon::Mesh read_ply(const std::filesystem::path& file, PlyExtras& extras);

/// One entry of a scanalyze registration file: `bmesh FILE tx ty tz qx qy qz qw`.
struct ConfEntry {
  std::filesystem::path file;                 ///< resolved against the .conf's directory
  Eigen::Vector3d translation{0, 0, 0};       ///< t
  Eigen::Vector4d quaternion{0, 0, 0, 1};     ///< (x, y, z, w) as in the file
  /// world = R^T p + t, with R the rotation matrix of the unit quaternion.
  [[nodiscard]] Eigen::Vector3d to_world(const Eigen::Vector3d& p) const;
};
std::vector<ConfEntry> parse_conf(std::string_view text, std::string_view name,
                                  const std::filesystem::path& base_dir);
std::vector<ConfEntry> read_conf(const std::filesystem::path& file);

struct WriteOptions {
  bool ascii_stl = false;  ///< STL only: text instead of binary
};

/// Whether float coordinates hold this mesh: rounding to float (2^-24 of the largest coordinate)
/// moves no vertex by more than 1e-4 of the mean edge length. False for a part far from the
/// origin at a fine spacing; write_mesh then keeps double precision where the format allows.
bool float_holds(const recon::Mesh& mesh);

struct WriteReport {
  /// The format stores float32 (binary STL) and float cannot hold this mesh (float_holds).
  bool float_rounds_mesh = false;
};

/// The mesh formats write_mesh writes, by extension in any case: .stl, .ply, .obj.
bool writes_mesh_extension(const std::filesystem::path& file);

/// Writes by extension: .stl (binary unless ascii_stl), .ply (binary little endian), .obj.
/// Coordinates are float (PLY `float`, 9 significant digits in text) when float_holds(mesh),
/// otherwise double (PLY `double`, 17 digits in text); binary STL is float by its format, and
/// the report says when that rounds the mesh.
/// Writes to a temporary file beside the target and renames it into place, so no partial file
/// is ever left under the final name. Throws OutputError naming the file and the OS error.
WriteReport write_mesh(const recon::Mesh& mesh, const std::filesystem::path& file,
                       const WriteOptions& options = {});

/// The point files write_points_xyz writes, by extension in any case: .xyz, .txt, .asc (the
/// whitespace-separated text read_points reads).
bool writes_points_extension(const std::filesystem::path& file);

/// Writes points as "x y z\n" text (%.9g), atomically like write_mesh. Throws OutputError for
/// an extension writes_points_extension does not take.
void write_points_xyz(const std::vector<recon::Vec3>& points, const std::filesystem::path& file);

}  // namespace scanmesh::meshio
