// Image files and cameras. OpenCV's imgcodecs and videoio load about 240 shared libraries
// (0.15-0.2 s and 65 MB per process), so they live in a module (scanmesh_profiler_media) that
// Media::load() opens only when a program reads images or cameras.
// SPDX-License-Identifier: MIT
#pragma once

#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "scanmesh/drivers/profiler/frame_source.hpp"

namespace scanmesh::drivers::profiler {

struct MediaApi;  // the module's function table (media_api.hpp)

/// A handle on the loaded module: cheap to copy, valid for the whole process (the module is
/// never unloaded).
class Media {
 public:
  /// Loads the module: the path built into the library, then the executable's folder, then the
  /// loader's search path. Throws Error naming the module and the loader's words.
  static Media load();

  /// The image as stored: CV_8UC1 or CV_8UC3 (BGR). Throws InputError naming the file (missing,
  /// unreadable, not an image, 16-bit or another depth).
  cv::Mat read_image(const std::filesystem::path& file) const;
  /// Writes an 8-bit image; the format follows the extension. Throws OutputError.
  void write_image(const std::filesystem::path& file, const cv::Mat& image) const;
  /// Opens a camera (an index "0", a V4L2 path "/dev/video0"), a video file or an image
  /// sequence pattern ("frames/%04d.png") through cv::VideoCapture, or a folder of images (read
  /// in name order). `device` names it in errors. Throws DeviceError (kNotFound for a missing
  /// camera, file or folder; kIo when it cannot be opened).
  std::unique_ptr<FrameSource> open_source(const std::string& spec, const SourceSettings& settings,
                                           const std::string& device) const;

 private:
  explicit Media(const MediaApi* api) : api_(api) {}
  const MediaApi* api_;
};

/// The image files of a folder in name order (extensions .png .jpg .jpeg .bmp .tif .tiff .pgm
/// .ppm .pnm, any case). Throws InputError naming the folder when it cannot be read or holds no
/// image.
std::vector<std::filesystem::path> list_images(const std::filesystem::path& dir);

}  // namespace scanmesh::drivers::profiler
