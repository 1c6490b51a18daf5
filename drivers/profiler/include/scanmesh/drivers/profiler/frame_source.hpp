// Where a profiler's frames come from: a camera, a video file, an image sequence, a folder of
// images, or (in tests) frames in memory. The interface the media module implements.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::drivers::profiler {

/// What came with a frame.
struct FrameMeta {
  Timestamp t_host;                   ///< host monotonic time the frame arrived
  std::optional<Timestamp> t_device;  ///< the camera's own time of the frame, if any
  std::optional<double> exposure_us;
  std::optional<double> gain;
};

/// Camera settings applied at opening where the camera allows (ignored by files).
struct SourceSettings {
  std::optional<double> exposure_us;  ///< manual exposure
  std::optional<double> gain;         ///< camera units
  int width = 0;                      ///< requested frame size (0: the camera's)
  int height = 0;
  std::chrono::milliseconds timeout{1000};  ///< longest wait for one frame
};

/// What one FrameSource::read() brought.
enum class ReadStatus : std::uint8_t {
  kFrame,     ///< a frame
  kEnd,       ///< a finite source is over
  kNoFrame,   ///< a live source gave none in time (or vanished): error() says why
  kBadFrame,  ///< a frame that cannot be decoded was skipped: error() says why
};

/// A stream of frames. Not thread-safe: one reader.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// The next frame (8-bit, 1 or 3 channels, BGR) into `frame`.
  virtual ReadStatus read(cv::Mat& frame, FrameMeta& meta) = 0;
  /// A camera (false: a finite source, which ends).
  virtual bool live() const = 0;
  /// Why the last read() failed.
  virtual std::string error() const = 0;
  /// Frames per second the source announces (0: unknown).
  virtual double fps() const { return 0; }
  /// Whether the camera accepted the requested exposure / gain.
  virtual bool exposure_set() const { return false; }
  virtual bool gain_set() const { return false; }
};

/// Makes a fresh source (at open() and at every reconnection); throws DeviceError.
using FrameSourceFactory = std::function<std::unique_ptr<FrameSource>()>;

/// Which channel of a colour frame carries the laser.
enum class FrameChannel : std::uint8_t { kRed, kGreen, kBlue, kGray };

/// The frame as one 8-bit channel: a 1-channel frame as it is (no copy), a 3-channel (BGR) frame's
/// `channel` (kGray: the luminance). Throws ConfigError for other types.
void single_channel(const cv::Mat& frame, FrameChannel channel, cv::Mat& out);

}  // namespace scanmesh::drivers::profiler
