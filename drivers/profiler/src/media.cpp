// Loading the media module, folders of images as frame sources, channel selection (see
// media.hpp, frame_source.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/profiler/media.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <system_error>

#include "media_api.hpp"
#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

#ifndef SCANMESH_PROFILER_MEDIA_MODULE
#define SCANMESH_PROFILER_MEDIA_MODULE "libscanmesh_profiler_media.so"
#endif

namespace scanmesh::drivers::profiler {

namespace fs = std::filesystem;

namespace {

constexpr const char* kModuleName = "libscanmesh_profiler_media.so";

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool is_image_file(const fs::path& p) {
  static constexpr const char* kExt[] = {".png", ".jpg", ".jpeg", ".bmp", ".tif",
                                         ".tiff", ".pgm", ".ppm", ".pnm"};
  const std::string ext = lower(p.extension().string());
  return std::any_of(std::begin(kExt), std::end(kExt), [&](const char* e) { return ext == e; });
}

/// A folder of images, read in name order; a file that does not decode is skipped (kBadFrame).
class FolderSource final : public FrameSource {
 public:
  FolderSource(Media media, std::vector<fs::path> files)
      : media_(media), files_(std::move(files)) {}
  ReadStatus read(cv::Mat& frame, FrameMeta& meta) override {
    if (next_ >= files_.size()) return ReadStatus::kEnd;
    const fs::path& file = files_[next_++];
    meta = FrameMeta{};
    try {
      frame = media_.read_image(file);
    } catch (const InputError& e) {
      error_ = e.what();
      return ReadStatus::kBadFrame;
    }
    meta.t_host = monotonic_now();
    return ReadStatus::kFrame;
  }
  bool live() const override { return false; }
  std::string error() const override { return error_; }

 private:
  Media media_;
  std::vector<fs::path> files_;
  std::size_t next_ = 0;
  std::string error_;
};

}  // namespace

Media Media::load() {
  std::string tried;
  std::vector<std::string> candidates{SCANMESH_PROFILER_MEDIA_MODULE};
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) candidates.push_back((exe.parent_path() / kModuleName).string());
  candidates.emplace_back(kModuleName);
  for (const auto& c : candidates) {
    // Never unloaded: OpenCV registers exit handlers inside it.
    void* handle = ::dlopen(c.c_str(), RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE);
    if (handle == nullptr) {
      const char* why = ::dlerror();
      tried += std::string(tried.empty() ? "" : "; ") + (why ? why : c);
      continue;
    }
    using Entry = const MediaApi* (*)();
    auto entry = reinterpret_cast<Entry>(::dlsym(handle, "scanmesh_profiler_media_api"));
    if (entry == nullptr) throw Error(c + ": not the scanmesh media module (no entry point)");
    const MediaApi* api = entry();
    if (api == nullptr || api->abi != kMediaAbi)
      throw Error(c + ": media module of another build (interface " +
                  std::to_string(api ? api->abi : -1) + ", expected " +
                  std::to_string(kMediaAbi) + ")");
    return Media(api);
  }
  throw Error("cannot load the image and camera module " + std::string(kModuleName) + ": " + tried);
}

cv::Mat Media::read_image(const fs::path& file) const {
  std::error_code ec;
  const auto status = fs::status(file, ec);
  if (ec || !fs::exists(status)) throw InputError(file.string() + ": cannot read: no such file");
  if (fs::is_directory(status)) throw InputError(file.string() + ": cannot read: is a folder");
  cv::Mat img;
  std::string error;
  if (!api_->read_image(file.string(), img, error))
    throw InputError(file.string() + ": cannot read the image: " + error);
  if (img.depth() != CV_8U || (img.channels() != 1 && img.channels() != 3 && img.channels() != 4))
    throw InputError(file.string() + ": " + std::to_string(img.channels()) +
                     "-channel image of " + std::to_string(8 * img.elemSize1()) +
                     "-bit samples; 8-bit grey or colour images only");
  if (img.channels() == 4) cv::cvtColor(img, img, cv::COLOR_BGRA2BGR);
  return img;
}

void Media::write_image(const fs::path& file, const cv::Mat& image) const {
  std::string error;
  if (!api_->write_image(file.string(), image, error))
    throw OutputError(file.string() + ": cannot write the image: " + error);
}

std::unique_ptr<FrameSource> Media::open_source(const std::string& spec,
                                                const SourceSettings& settings,
                                                const std::string& device) const {
  const std::string who = device + " (" + spec + ")";
  std::error_code ec;
  if (fs::is_directory(spec, ec)) {
    std::vector<fs::path> files;
    try {
      files = list_images(spec);
    } catch (const InputError& e) {
      throw DeviceError(DeviceErrorKind::kNotFound, who, "open", e.what());
    }
    return std::make_unique<FolderSource>(*this, std::move(files));
  }
  std::string error;
  bool not_found = false;
  auto source = api_->open_capture(spec, settings, error, not_found);
  if (!source)
    throw DeviceError(not_found ? DeviceErrorKind::kNotFound : DeviceErrorKind::kIo, who, "open",
                      error);
  return source;
}

std::vector<fs::path> list_images(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw InputError(dir.string() + ": cannot read the image folder: " +
                     (fs::exists(dir, ec) ? "not a folder" : "no such folder"));
  std::vector<fs::path> files;
  fs::directory_iterator it(dir, ec);
  if (ec) throw InputError(dir.string() + ": cannot read the image folder: " + ec.message());
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    if (ec) throw InputError(dir.string() + ": cannot read the image folder: " + ec.message());
    std::error_code fe;
    if (it->is_regular_file(fe) && is_image_file(it->path())) files.push_back(it->path());
  }
  if (files.empty())
    throw InputError(dir.string() +
                     ": no images in the folder (.png .jpg .jpeg .bmp .tif .tiff .pgm .ppm .pnm)");
  std::sort(files.begin(), files.end());
  return files;
}

void single_channel(const cv::Mat& frame, FrameChannel channel, cv::Mat& out) {
  if (frame.depth() != CV_8U) throw ConfigError("frame: 8-bit images only");
  if (frame.channels() == 1) {
    out = frame;
    return;
  }
  if (frame.channels() != 3) throw ConfigError("frame: 1 or 3 channels only");
  switch (channel) {
    case FrameChannel::kBlue:
      cv::extractChannel(frame, out, 0);
      break;
    case FrameChannel::kGreen:
      cv::extractChannel(frame, out, 1);
      break;
    case FrameChannel::kRed:
      cv::extractChannel(frame, out, 2);
      break;
    case FrameChannel::kGray:
      cv::cvtColor(frame, out, cv::COLOR_BGR2GRAY);
      break;
  }
}

}  // namespace scanmesh::drivers::profiler
