// scanmesh_profiler_media: the one place that links OpenCV's imgcodecs and videoio. Image files
// (cv::imread / cv::imwrite) and cv::VideoCapture sources: V4L2 cameras by index or path, video
// files, image sequence patterns. Loaded on demand by Media::load().
// SPDX-License-Identifier: MIT
#include <sys/stat.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <string>

#include "media_api.hpp"

namespace scanmesh::drivers::profiler {
namespace {

/// OpenCV logs its own warnings when an open fails; we report the failure ourselves.
class QuietOpenCv {
 public:
  QuietOpenCv()
      : previous_(cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT)) {}
  ~QuietOpenCv() { cv::utils::logging::setLogLevel(previous_); }
  QuietOpenCv(const QuietOpenCv&) = delete;
  QuietOpenCv& operator=(const QuietOpenCv&) = delete;

 private:
  cv::utils::logging::LogLevel previous_;
};

bool is_index(const std::string& s) {
  if (s.empty() || s.size() > 3) return false;
  for (char c : s)
    if (c < '0' || c > '9') return false;
  return true;
}

bool exists(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0;
}

Timestamp now() {
  return {std::chrono::duration_cast<std::chrono::nanoseconds>(
              std::chrono::steady_clock::now().time_since_epoch())
              .count()};
}

class CaptureSource final : public FrameSource {
 public:
  CaptureSource(cv::VideoCapture cap, bool live, bool exposure_set, bool gain_set)
      : cap_(std::move(cap)), live_(live), exposure_set_(exposure_set), gain_set_(gain_set) {
    fps_ = cap_.get(cv::CAP_PROP_FPS);
    if (!std::isfinite(fps_) || fps_ < 0) fps_ = 0;
  }

  ReadStatus read(cv::Mat& frame, FrameMeta& meta) override {
    bool ok = false;
    try {
      ok = cap_.read(frame);
    } catch (const cv::Exception& e) {
      error_ = e.what();
      return live_ ? ReadStatus::kNoFrame : ReadStatus::kBadFrame;
    }
    meta = FrameMeta{};
    meta.t_host = now();
    if (!ok || frame.empty()) {
      error_ = live_ ? "no frame from the camera" : "";
      return live_ ? ReadStatus::kNoFrame : ReadStatus::kEnd;
    }
    if (live_) {
      // V4L2: the buffer's timestamp (CLOCK_MONOTONIC) in ms, and exposure_absolute in units
      // of 100 us [unverified: no camera in CI].
      const double ms = cap_.get(cv::CAP_PROP_POS_MSEC);
      if (std::isfinite(ms) && ms > 0) meta.t_device = Timestamp{static_cast<std::int64_t>(ms * 1e6)};
      const double exposure = cap_.get(cv::CAP_PROP_EXPOSURE);
      if (std::isfinite(exposure) && exposure > 0) meta.exposure_us = exposure * 100;
      const double gain = cap_.get(cv::CAP_PROP_GAIN);
      if (std::isfinite(gain) && gain >= 0) meta.gain = gain;
    }
    return ReadStatus::kFrame;
  }
  bool live() const override { return live_; }
  std::string error() const override { return error_; }
  double fps() const override { return fps_; }
  bool exposure_set() const override { return exposure_set_; }
  bool gain_set() const override { return gain_set_; }

 private:
  cv::VideoCapture cap_;
  bool live_;
  bool exposure_set_;
  bool gain_set_;
  double fps_ = 0;
  std::string error_;
};

bool read_image(const std::string& path, cv::Mat& out, std::string& error) {
  try {
    QuietOpenCv quiet;
    out = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    error = e.what();
    return false;
  }
  if (out.empty()) {
    error = "not an image OpenCV can decode";
    return false;
  }
  return true;
}

bool write_image(const std::string& path, const cv::Mat& image, std::string& error) {
  try {
    QuietOpenCv quiet;
    if (cv::imwrite(path, image)) return true;
    error = "cv::imwrite failed";
  } catch (const cv::Exception& e) {
    error = e.what();
  }
  return false;
}

std::unique_ptr<FrameSource> open_capture(const std::string& spec, const SourceSettings& settings,
                                          std::string& error, bool& not_found) {
  QuietOpenCv quiet;
  not_found = false;
  cv::VideoCapture cap;
  bool live = false;
  try {
    if (is_index(spec)) {
      live = true;
      if (!exists("/dev/video" + spec)) {
        not_found = true;
        error = "no such camera (no /dev/video" + spec + ")";
        return nullptr;
      }
      cap.open(std::atoi(spec.c_str()), cv::CAP_V4L2);
    } else if (spec.rfind("/dev/", 0) == 0) {
      live = true;
      if (!exists(spec)) {
        not_found = true;
        error = "no such camera";
        return nullptr;
      }
      cap.open(spec, cv::CAP_V4L2);
    } else {
      if (spec.find('%') == std::string::npos && !exists(spec)) {
        not_found = true;
        error = "no such file";
        return nullptr;
      }
      cap.open(spec, spec.find('%') == std::string::npos ? cv::CAP_ANY : cv::CAP_IMAGES);
    }
  } catch (const cv::Exception& e) {
    error = e.what();
    return nullptr;
  }
  if (!cap.isOpened()) {
    error = live ? "cannot open the camera (busy, or not a capture device)"
                 : "cannot open as a video or an image sequence";
    return nullptr;
  }
  bool exposure_set = false;
  bool gain_set = false;
  if (live) {
    if (settings.width > 0) cap.set(cv::CAP_PROP_FRAME_WIDTH, settings.width);
    if (settings.height > 0) cap.set(cv::CAP_PROP_FRAME_HEIGHT, settings.height);
    if (settings.exposure_us) {
      // V4L2: 1 = V4L2_EXPOSURE_MANUAL; exposure_absolute in 100 us [unverified].
      cap.set(cv::CAP_PROP_AUTO_EXPOSURE, 1);
      exposure_set = cap.set(cv::CAP_PROP_EXPOSURE, *settings.exposure_us / 100.0);
    }
    if (settings.gain) gain_set = cap.set(cv::CAP_PROP_GAIN, *settings.gain);
  }
  return std::make_unique<CaptureSource>(std::move(cap), live, exposure_set, gain_set);
}

constexpr MediaApi kApi{kMediaAbi, &read_image, &write_image, &open_capture};

}  // namespace
}  // namespace scanmesh::drivers::profiler

extern "C" __attribute__((visibility("default"))) const scanmesh::drivers::profiler::MediaApi*
scanmesh_profiler_media_api() {
  return &scanmesh::drivers::profiler::kApi;
}
