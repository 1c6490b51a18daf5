// CameraProfiler: a camera and a line laser as a LineProfiler. Frames from a FrameSource (a
// camera, a video, image files, or frames in memory), the line extracted per column (or row),
// triangulated with the calibration, delivered as profiles on a worker thread.
// SPDX-License-Identifier: MIT
#pragma once

#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "scanmesh/drivers/device_support.hpp"
#include "scanmesh/drivers/line_profiler.hpp"
#include "scanmesh/drivers/profiler/camera.hpp"
#include "scanmesh/drivers/profiler/extraction.hpp"
#include "scanmesh/drivers/profiler/frame_source.hpp"
#include "scanmesh/drivers/profiler/media.hpp"

namespace scanmesh::drivers::profiler {

struct ProfilerConfig {
  ProfilerOptions options;
  std::string source;  ///< what the factory opens, named in messages ("/dev/video0", "frames/")
  SourceSettings settings;
  ExtractionOptions extraction;  ///< its axis says columns or rows
  FrameChannel channel = FrameChannel::kRed;
  /// 0: every frame is a laser frame. N >= 2: frames 0, N, 2N ... of the source (counted from
  /// its opening) are laser-off frames, subtracted from the N - 1 frames after each.
  int laser_off_every = 0;
  ProfilerCalibration calibration;
  double min_z_mm = 0;  ///< points outside [min_z_mm, max_z_mm] along the optical axis are
                        ///< kOverRange
  double max_z_mm = std::numeric_limits<double>::infinity();

  /// Every problem, one message each.
  std::vector<std::string> problems() const;
};

/// The device. Threading as every driver: open/close/start/stop from the owner's thread;
/// callbacks on the worker. Per frame it allocates nothing once the first profile is out (the
/// source's own decoding aside).
class CameraProfiler final : public LineProfiler {
 public:
  /// Validates the configuration (ConfigError listing every problem). `factory` makes the
  /// source at open() and at every reconnection.
  CameraProfiler(ProfilerConfig config, FrameSourceFactory factory);
  ~CameraProfiler() override;

  /// A factory opening config.source through the media module (Media::open_source).
  static FrameSourceFactory media_factory(const Media& media, const ProfilerConfig& config);

  const std::string& name() const override { return config_.options.name; }
  void open() override;
  void close() noexcept override;
  void start(ProfilerCallbacks callbacks) override;
  void stop() noexcept override;

  DeviceIdentity identify() const override;
  ProfilerCapabilities capabilities() const override;
  DeviceState state() const override { return state_.get(); }
  DeviceStats stats() const override { return stats_.snapshot(); }

 private:
  std::string who() const;
  /// Makes a source and reads its first frame into pending_ (throws DeviceError).
  void connect();
  void run(Worker& worker);
  void lose(const std::string& reason);
  /// One frame: a background, or a profile delivered. False when it was not usable.
  bool process(const cv::Mat& frame, const FrameMeta& meta);

  ProfilerConfig config_;
  FrameSourceFactory factory_;
  LineExtractor extractor_;
  std::unique_ptr<Triangulator> triangulator_;  ///< built at the first open()

  std::unique_ptr<FrameSource> source_;
  cv::Mat pending_;  ///< the first frame, read by connect(), processed first by the worker
  FrameMeta pending_meta_;
  bool has_pending_ = false;
  std::uint64_t frame_index_ = 0;  ///< frames of the current source (laser-off cadence)

  cv::Mat channel_, background_;
  std::vector<float> positions_;
  Profile profile_;

  mutable std::mutex caps_mutex_;
  ProfilerCapabilities caps_;
  ProfilerCallbacks callbacks_;
  SensorCallbacks state_callbacks_;  ///< on_state only (StateCell reports through it)
  SequenceTracker seq_;
  AtomicStats stats_;
  StateCell state_;
  Worker worker_;
  bool running_ = false;
};

}  // namespace scanmesh::drivers::profiler
