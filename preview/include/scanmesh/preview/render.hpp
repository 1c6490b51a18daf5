// Preview and colour-mapped deviation pictures of a mesh, rendered with OpenCV (software
// z-buffer, flat shading). Used by `scanmesh deviation --png` and by the daemon's previews.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::preview {

struct RenderOptions {
  int width_px = 1024;
  int height_px = 768;
  /// View direction (from the camera towards the object); default an isometric view.
  recon::Vec3 view_dir{-1.0, -1.0, -1.0};
  recon::Vec3 up{0.0, 0.0, 1.0};
  std::string title;  ///< printed at the top left when not empty
  /// Triangles from this index on are drawn amber instead of grey: the patches hole filling
  /// appended (surface the scanner never measured). Default: none.
  std::size_t highlight_from = static_cast<std::size_t>(-1);
};

/// Grey shaded picture of the mesh (both triangle sides lit; back faces tinted so holes and
/// flipped triangles are visible; triangles from options.highlight_from on amber). Throws OutputError when the PNG cannot be written.
void render_mesh_png(const recon::Mesh& mesh, const std::filesystem::path& png,
                     const RenderOptions& options = {});

/// Colour-mapped deviation picture: each vertex carries a signed deviation, colours interpolate
/// over the triangles with a diverging map symmetric around zero (range +-limit; default the
/// 95th percentile of |value|) and a labelled colour bar, as inspection software shows it.
void render_deviation_png(const recon::Mesh& mesh, const std::vector<double>& vertex_values,
                          const std::filesystem::path& png, const RenderOptions& options = {},
                          std::optional<double> limit = std::nullopt);

/// PNG bytes (8-bit RGB, libpng) of a `width` x `height` picture given as rows of blue, green,
/// red bytes, `stride` bytes apart (OpenCV's layout). Throws OutputError when libpng fails.
std::vector<std::uint8_t> encode_png_bgr(const std::uint8_t* bgr, int width, int height,
                                         std::size_t stride);

}  // namespace scanmesh::preview
