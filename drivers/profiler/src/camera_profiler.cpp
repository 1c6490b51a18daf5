// CameraProfiler: lifecycle, worker loop and the frame-to-profile path (see
// camera_profiler.hpp; the lifecycle follows common/sensor_lifecycle.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/profiler/camera_profiler.hpp"

#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::profiler {

namespace {

std::string size_text(cv::Size s) { return std::to_string(s.width) + "x" + std::to_string(s.height); }

}  // namespace

std::vector<std::string> ProfilerConfig::problems() const {
  std::vector<std::string> p;
  if (options.name.empty()) p.push_back("name must not be empty");
  if (options.timeout < std::chrono::milliseconds(1) || options.timeout > std::chrono::seconds(60))
    p.push_back("timeout must be 1 ms .. 60 s");
  if (options.timeouts_until_lost < 1) p.push_back("timeouts_until_lost must be >= 1");
  if (options.backoff_initial <= std::chrono::milliseconds(0) ||
      options.backoff_max < options.backoff_initial)
    p.push_back("backoff: initial > 0 and max >= initial");
  if (laser_off_every < 0 || laser_off_every == 1)
    p.push_back("laser_off_every must be 0 (none) or >= 2, got " + std::to_string(laser_off_every));
  for (auto& s : camera_problems(calibration.camera)) p.push_back("calibration: " + s);
  for (auto& s : plane_problems(calibration.plane)) p.push_back("calibration: " + s);
  for (auto& s : extraction.problems()) p.push_back("extraction: " + s);
  if (!(min_z_mm < max_z_mm)) p.push_back("min_z_mm must be below max_z_mm");
  return p;
}

CameraProfiler::CameraProfiler(ProfilerConfig config, FrameSourceFactory factory)
    : config_(std::move(config)), factory_(std::move(factory)), extractor_([&] {
        auto p = config_.problems();
        if (!factory_) p.push_back("no frame source");
        if (!p.empty()) {
          std::string msg = config_.options.name + ": profiler configuration:";
          for (const auto& s : p) msg += " " + s + ";";
          msg.pop_back();
          throw ConfigError(msg);
        }
        return config_.extraction;
      }()) {}

CameraProfiler::~CameraProfiler() { close(); }

FrameSourceFactory CameraProfiler::media_factory(const Media& media, const ProfilerConfig& config) {
  SourceSettings settings = config.settings;
  settings.timeout = config.options.timeout;
  return [media, source = config.source, settings, name = config.options.name] {
    return media.open_source(source, settings, name);
  };
}

std::string CameraProfiler::who() const {
  return config_.source.empty() ? config_.options.name
                                : config_.options.name + " (" + config_.source + ")";
}

void CameraProfiler::connect() {
  std::unique_ptr<FrameSource> src = factory_();
  if (!src) throw DeviceError(DeviceErrorKind::kIo, who(), "open", "no frame source");
  cv::Mat frame;
  FrameMeta meta;
  for (int bad = 0;;) {
    const ReadStatus st = src->read(frame, meta);
    if (st == ReadStatus::kFrame) break;
    if (st == ReadStatus::kEnd)
      throw DeviceError(DeviceErrorKind::kProtocol, who(), "open", "the source has no frames");
    if (st == ReadStatus::kNoFrame)
      throw DeviceError(DeviceErrorKind::kTimeout, who(), "open",
                        src->error().empty() ? "no frame" : src->error());
    stats_.malformed.fetch_add(1);
    if (++bad >= 3) throw DeviceError(DeviceErrorKind::kProtocol, who(), "open", src->error());
  }
  const CameraIntrinsics& cam = config_.calibration.camera;
  if (frame.size() != cam.size) {
    const std::string cal = config_.calibration.source.empty() ? std::string("the calibration")
                                                                : config_.calibration.source;
    throw DeviceError(DeviceErrorKind::kProtocol, who(), "open",
                      "frames are " + size_text(frame.size()) + " but " + cal + " is for a " +
                          size_text(cam.size) + " camera");
  }
  if (frame.depth() != CV_8U)
    throw DeviceError(DeviceErrorKind::kProtocol, who(), "open",
                      "frames of " + std::to_string(8 * frame.elemSize1()) +
                          "-bit samples; 8-bit only");
  {
    std::lock_guard lock(caps_mutex_);
    caps_.width_px = static_cast<std::uint32_t>(frame.cols);
    caps_.height_px = static_cast<std::uint32_t>(frame.rows);
    caps_.points_per_profile = static_cast<std::uint32_t>(
        config_.extraction.axis == LineAxis::kColumns ? frame.cols : frame.rows);
    caps_.max_rate_hz = src->fps();
    caps_.exposure_control = src->exposure_set();
    caps_.gain_control = src->gain_set();
    caps_.live = src->live();
    caps_.device_clock = meta.t_device.has_value();
  }
  source_ = std::move(src);
  pending_ = frame;
  pending_meta_ = meta;
  has_pending_ = true;
  frame_index_ = 0;
  background_.release();
}

void CameraProfiler::open() {
  if (running_) return;  // open and acquiring already (or reconnecting on its own)
  source_.reset();
  has_pending_ = false;
  if (!triangulator_)
    triangulator_ = std::make_unique<Triangulator>(
        config_.calibration.camera, config_.calibration.plane, config_.extraction.axis,
        config_.min_z_mm, config_.max_z_mm);
  connect();
  state_.set(DeviceState::kOpen, "", nullptr);
}

void CameraProfiler::close() noexcept {
  stop();
  source_.reset();
  has_pending_ = false;
  state_.set(DeviceState::kClosed, "", nullptr);
}

void CameraProfiler::start(ProfilerCallbacks callbacks) {
  if (running_) return;
  if (state_.get() == DeviceState::kClosed)
    throw DeviceError(DeviceErrorKind::kProtocol, config_.options.name, "start", "open() first");
  callbacks_ = std::move(callbacks);
  state_callbacks_ = SensorCallbacks{};
  state_callbacks_.on_state = callbacks_.on_state;
  running_ = true;
  state_.set(source_ ? DeviceState::kAcquiring : DeviceState::kLost,
             config_.options.name + (source_ ? ": acquiring" : ": lost: reconnecting"),
             &state_callbacks_);
  worker_.start([this](Worker& w) { run(w); },
                [this](const std::exception& e) {
                  source_.reset();
                  state_.set(DeviceState::kLost,
                             config_.options.name + ": worker stopped: " + e.what(),
                             &state_callbacks_);
                });
}

void CameraProfiler::stop() noexcept {
  if (!running_) return;
  worker_.stop();
  running_ = false;
  // No callback after stop(): the state change is not reported.
  state_.set(source_ ? DeviceState::kOpen : DeviceState::kLost, "", nullptr);
}

DeviceIdentity CameraProfiler::identify() const {
  return DeviceIdentity{"", "camera + line laser", config_.source, ""};
}

ProfilerCapabilities CameraProfiler::capabilities() const {
  std::lock_guard lock(caps_mutex_);
  return caps_;
}

void CameraProfiler::lose(const std::string& reason) {
  source_.reset();
  has_pending_ = false;
  state_.set(DeviceState::kLost, config_.options.name + ": lost: " + reason, &state_callbacks_);
}

bool CameraProfiler::process(const cv::Mat& frame, const FrameMeta& meta) {
  if (frame.size() != config_.calibration.camera.size || frame.depth() != CV_8U) {
    stats_.malformed.fetch_add(1);
    return false;
  }
  try {
    single_channel(frame, config_.channel, channel_);
  } catch (const ConfigError&) {
    stats_.malformed.fetch_add(1);
    return false;
  }
  const int every = config_.laser_off_every;
  if (every > 0 && frame_index_ % static_cast<std::uint64_t>(every) == 0) {
    channel_.copyTo(background_);
    return true;
  }
  extractor_.extract(channel_, background_, positions_);
  triangulator_->triangulate(positions_, profile_.points);
  profile_.seq = seq_.next();
  profile_.t_host = meta.t_host;
  profile_.t_device = meta.t_device;
  profile_.exposure_us = meta.exposure_us;
  profile_.gain = meta.gain;
  stats_.samples.fetch_add(1);
  if (callbacks_.on_profile) callbacks_.on_profile(profile_);
  return true;
}

void CameraProfiler::run(Worker& worker) {
  Backoff backoff(config_.options.backoff_initial, config_.options.backoff_max);
  int misses = 0;
  cv::Mat frame;
  while (!worker.stop_requested()) {
    if (!source_) {
      if (!worker.sleep_for(backoff.next())) return;
      try {
        connect();
      } catch (const std::exception&) {
        continue;  // one failed attempt: try again after the next delay
      }
      backoff.reset();
      misses = 0;
      stats_.reconnects.fetch_add(1);
      state_.set(DeviceState::kAcquiring, config_.options.name + ": reconnected",
                 &state_callbacks_);
      continue;
    }
    FrameMeta meta;
    ReadStatus st = ReadStatus::kFrame;
    if (has_pending_) {
      frame = pending_;
      meta = pending_meta_;
      has_pending_ = false;
      pending_.release();
    } else {
      try {
        st = source_->read(frame, meta);
      } catch (const std::exception& e) {
        lose(e.what());
        continue;
      }
    }
    switch (st) {
      case ReadStatus::kFrame:
        misses = 0;
        try {
          process(frame, meta);
        } catch (const std::exception&) {
          stats_.malformed.fetch_add(1);  // a frame the extraction refused: skipped
        }
        ++frame_index_;
        break;
      case ReadStatus::kBadFrame:
        stats_.malformed.fetch_add(1);
        ++frame_index_;
        break;
      case ReadStatus::kNoFrame:
        stats_.timeouts.fetch_add(1);
        if (++misses >= config_.options.timeouts_until_lost) {
          lose("no frame " + std::to_string(misses) + " times in a row" +
               (source_->error().empty() ? "" : ": " + source_->error()));
          misses = 0;
        }
        break;
      case ReadStatus::kEnd: {
        // A finite source (files) does not come back: the worker ends, the state says why.
        const std::string reason = who() + ": lost: end of the source after " +
                                   std::to_string(frame_index_) + " frames";
        source_.reset();
        state_.set(DeviceState::kLost, reason, &state_callbacks_);
        return;
      }
    }
  }
}

}  // namespace scanmesh::drivers::profiler
