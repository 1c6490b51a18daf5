// The function table of the media module (scanmesh_profiler_media), shared by the module and
// Media::load(). Both are built from this tree with one compiler, so C++ types cross it.
// SPDX-License-Identifier: MIT
#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <string>

#include "scanmesh/drivers/profiler/frame_source.hpp"

namespace scanmesh::drivers::profiler {

/// Bumped whenever the table changes.
inline constexpr int kMediaAbi = 1;

struct MediaApi {
  int abi;
  /// The image as stored (any depth); false with `error` set.
  bool (*read_image)(const std::string& path, cv::Mat& out, std::string& error);
  bool (*write_image)(const std::string& path, const cv::Mat& image, std::string& error);
  /// A cv::VideoCapture source; null with `error` set (and `not_found` when nothing is there).
  std::unique_ptr<FrameSource> (*open_capture)(const std::string& spec,
                                               const SourceSettings& settings, std::string& error,
                                               bool& not_found);
};

}  // namespace scanmesh::drivers::profiler

/// The module's one exported symbol.
extern "C" const scanmesh::drivers::profiler::MediaApi* scanmesh_profiler_media_api();
