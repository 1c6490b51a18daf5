// CameraProfiler as a device: lifecycle, states, statistics, profiles from frames in memory
// (rendered), laser-off frames, losses and reconnection, and the errors naming the device.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <opencv2/imgproc.hpp>
#include <thread>
#include <vector>

#include "profiler/scene.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/profiler/camera_profiler.hpp"
#include "scanmesh/drivers/profiler/media.hpp"

using namespace scanmesh;
using namespace std::chrono_literals;
namespace prof = scanmesh::drivers::profiler;
namespace drv = scanmesh::drivers;

namespace {

/// What a scripted source does on each read.
struct Step {
  prof::ReadStatus status = prof::ReadStatus::kFrame;
  cv::Mat frame;
};

/// A script shared by every source the factory makes (a reconnection continues it).
struct Script {
  std::mutex mutex;
  std::deque<Step> steps;
  bool live = true;
  int opened = 0;
  bool refuse_open = false;
};

class ScriptedSource final : public prof::FrameSource {
 public:
  explicit ScriptedSource(std::shared_ptr<Script> s) : s_(std::move(s)) {}
  prof::ReadStatus read(cv::Mat& frame, prof::FrameMeta& meta) override {
    std::unique_lock lock(s_->mutex);
    meta = prof::FrameMeta{};
    meta.t_host = drv::monotonic_now();
    if (s_->steps.empty()) {
      lock.unlock();
      if (s_->live) std::this_thread::sleep_for(2ms);  // a camera waiting for its next frame
      return s_->live ? prof::ReadStatus::kNoFrame : prof::ReadStatus::kEnd;
    }
    Step step = s_->steps.front();
    s_->steps.pop_front();
    frame = step.frame;
    meta.exposure_us = 500;
    return step.status;
  }
  bool live() const override { return s_->live; }
  std::string error() const override { return "scripted"; }

 private:
  std::shared_ptr<Script> s_;
};

prof::FrameSourceFactory scripted(std::shared_ptr<Script> s) {
  return [s] {
    std::lock_guard lock(s->mutex);
    if (s->refuse_open)
      throw drv::DeviceError(drv::DeviceErrorKind::kNotFound, "cam0", "open", "unplugged");
    ++s->opened;
    return std::make_unique<ScriptedSource>(s);
  };
}

/// Collects profiles (copies) and states, waits with deadlines.
class Collector {
 public:
  drv::ProfilerCallbacks callbacks() {
    return {[this](const drv::Profile& p) {
              {
                std::lock_guard lock(mutex_);
                profiles_.push_back(p);
              }
              cv_.notify_all();
            },
            [this](drv::DeviceState s, const std::string& reason) {
              {
                std::lock_guard lock(mutex_);
                states_.emplace_back(s, reason);
              }
              cv_.notify_all();
            }};
  }
  bool wait_profiles(std::size_t n) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, 5s, [&] { return profiles_.size() >= n; });
  }
  bool wait_state(drv::DeviceState s, std::size_t nth = 1) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, 5s, [&] {
      std::size_t k = 0;
      for (const auto& st : states_) k += st.first == s;
      return k >= nth;
    });
  }
  std::vector<drv::Profile> profiles() {
    std::lock_guard lock(mutex_);
    return profiles_;
  }
  std::vector<std::pair<drv::DeviceState, std::string>> states() {
    std::lock_guard lock(mutex_);
    return states_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<drv::Profile> profiles_;
  std::vector<std::pair<drv::DeviceState, std::string>> states_;
};

struct Frames {
  test::PartScene scene;
  std::vector<sim::LaserFrame> on;
  cv::Mat off;
  Frames() {
    for (double y : {15.0, 20.0, 25.0})
      on.push_back(sim::render_laser_frame(scene.bvh, test::part_from_camera(40, y),
                                           test::profiler_camera(), {test::profiler_laser()},
                                           test::noisy_look(static_cast<std::uint64_t>(y))));
    off = sim::render_laser_frame(scene.bvh, test::part_from_camera(40, 20), test::profiler_camera(),
                                  {}, test::noisy_look(99))
              .image;
  }
};

const Frames& frames() {
  static const Frames f;
  return f;
}

prof::ProfilerConfig config(const std::string& name = "cam0") {
  prof::ProfilerConfig c;
  c.options.name = name;
  c.options.backoff_initial = 5ms;
  c.options.backoff_max = 20ms;
  c.source = "scripted";
  c.calibration = test::true_calibration(test::profiler_camera(), test::profiler_laser());
  c.calibration.source = "cal.yml";
  return c;
}

}  // namespace

TEST_CASE("profiler device: lifecycle, profiles in order, no callback after stop",
          "[profiler]") {
  auto script = std::make_shared<Script>();
  script->live = false;
  for (int i = 0; i < 3; ++i) script->steps.push_back({prof::ReadStatus::kFrame, frames().on[i].image});
  prof::CameraProfiler dev(config(), scripted(script));
  CHECK(dev.state() == drv::DeviceState::kClosed);
  Collector col;
  CHECK_THROWS_WITH(dev.start(col.callbacks()), Catch::Contains("cam0") && Catch::Contains("open() first"));
  dev.open();
  CHECK(dev.state() == drv::DeviceState::kOpen);
  const auto caps = dev.capabilities();
  CHECK(caps.width_px == 640);
  CHECK(caps.height_px == 480);
  CHECK(caps.points_per_profile == 640);
  CHECK_FALSE(caps.live);
  dev.start(col.callbacks());
  REQUIRE(col.wait_profiles(3));
  REQUIRE(col.wait_state(drv::DeviceState::kLost));  // the files are over
  const auto profiles = col.profiles();
  REQUIRE(profiles.size() == 3);
  for (std::size_t i = 0; i < 3; ++i) {
    CHECK(profiles[i].seq == i);
    CHECK(profiles[i].points.size() == 640);
    CHECK(profiles[i].exposure_us == 500);
    CHECK(profiles[i].valid_count() > 150);
    if (i > 0) CHECK(profiles[i].t_host >= profiles[i - 1].t_host);
    // Every point is on the plane of the laser and in front of the camera, or an invalid marker.
    const auto& plane = config().calibration.plane;
    for (const auto& p : profiles[i].points) {
      if (!p.valid()) {
        CHECK(std::isnan(p.z_mm));
        continue;
      }
      CHECK(std::abs(plane.normal.dot(cv::Vec3d(p.x_mm, p.y_mm, p.z_mm)) - plane.distance_mm) < 1e-6);
      CHECK(p.z_mm > 200);
      CHECK(p.z_mm < 260);
    }
  }
  const auto states = col.states();
  REQUIRE(states.size() == 2);
  CHECK(states[0].first == drv::DeviceState::kAcquiring);
  CHECK_THAT(states[1].second, Catch::Contains("cam0 (scripted): lost: end of the source after 3 frames"));
  CHECK(dev.stats().samples == 3);
  dev.stop();
  CHECK(dev.state() == drv::DeviceState::kLost);
  const std::size_t after = col.profiles().size() + col.states().size();
  dev.close();
  CHECK(dev.state() == drv::DeviceState::kClosed);
  CHECK(col.profiles().size() + col.states().size() == after);
}

TEST_CASE("profiler device: a live source that goes silent is lost and comes back",
          "[profiler]") {
  auto script = std::make_shared<Script>();
  script->live = true;
  script->steps.push_back({prof::ReadStatus::kFrame, frames().on[0].image});
  script->steps.push_back({prof::ReadStatus::kFrame, frames().on[1].image});
  script->steps.push_back({prof::ReadStatus::kBadFrame, {}});
  script->steps.push_back({prof::ReadStatus::kFrame, cv::Mat(10, 10, CV_8UC1)});  // wrong size
  prof::CameraProfiler dev(config(), scripted(script));
  dev.open();
  Collector col;
  dev.start(col.callbacks());
  REQUIRE(col.wait_profiles(2));
  // The script is empty now: kNoFrame three times in a row, the device is lost; it reconnects
  // while the source keeps opening, and frames come again.
  REQUIRE(col.wait_state(drv::DeviceState::kLost));
  {
    std::lock_guard lock(script->mutex);
    script->steps.push_back({prof::ReadStatus::kFrame, frames().on[2].image});
    script->steps.push_back({prof::ReadStatus::kFrame, frames().on[0].image});
  }
  REQUIRE(col.wait_profiles(3));
  REQUIRE(col.wait_state(drv::DeviceState::kAcquiring, 2));
  dev.stop();
  const auto profiles = col.profiles();
  for (std::size_t i = 0; i < profiles.size(); ++i) CHECK(profiles[i].seq == i);
  const auto st = dev.stats();
  CHECK(st.malformed == 2);
  CHECK(st.timeouts >= 3);
  CHECK(st.reconnects >= 1);
  bool said_lost = false;
  for (const auto& [s, reason] : col.states())
    if (s == drv::DeviceState::kLost)
      said_lost = said_lost || reason.find("cam0: lost: no frame 3 times in a row") != std::string::npos;
  CHECK(said_lost);
  CHECK(script->opened >= 2);
}

TEST_CASE("profiler device: laser-off frames are subtracted from the frames after them",
          "[profiler]") {
  // A lamp in view, brighter than the line, in every frame: only subtraction finds the line.
  auto lamp = [](cv::Mat img) {
    img = img.clone();
    cv::rectangle(img, cv::Rect(0, 60, 640, 50), cv::Scalar(235), cv::FILLED);
    return img;
  };
  for (int every : {0, 2}) {
    auto script = std::make_shared<Script>();
    script->live = false;
    for (int i = 0; i < 2; ++i) {
      script->steps.push_back({prof::ReadStatus::kFrame, lamp(frames().off)});
      script->steps.push_back({prof::ReadStatus::kFrame, lamp(frames().on[1].image)});
    }
    prof::ProfilerConfig c = config();
    c.laser_off_every = every;
    prof::CameraProfiler dev(c, scripted(script));
    dev.open();
    Collector col;
    dev.start(col.callbacks());
    REQUIRE(col.wait_state(drv::DeviceState::kLost));
    dev.stop();
    const auto profiles = col.profiles();
    INFO("laser_off_every " << every);
    if (every == 0) {
      CHECK(profiles.size() == 4);  // every frame is a profile, and the lamp hides the line
      for (const auto& p : profiles) CHECK(p.valid_count() < 20);
    } else {
      REQUIRE(profiles.size() == 2);
      for (const auto& p : profiles) CHECK(p.valid_count() > 150);
    }
  }
}

TEST_CASE("profiler device: errors name the device and the file", "[profiler]") {
  // A calibration of another camera size.
  auto script = std::make_shared<Script>();
  script->live = false;
  cv::Mat big;
  cv::resize(frames().on[0].image, big, cv::Size(1280, 960));
  script->steps.push_back({prof::ReadStatus::kFrame, big});
  prof::CameraProfiler dev(config(), scripted(script));
  try {
    dev.open();
    FAIL("opened");
  } catch (const drv::DeviceError& e) {
    CHECK_THAT(e.what(), Catch::Contains("cam0 (scripted): open: frames are 1280x960 but cal.yml "
                                         "is for a 640x480 camera"));
  }
  // A missing camera, through the media module.
  const prof::Media media = prof::Media::load();
  prof::ProfilerConfig c = config("laser1");
  c.source = "/dev/video97";
  prof::CameraProfiler cam(c, prof::CameraProfiler::media_factory(media, c));
  try {
    cam.open();
    FAIL("opened a missing camera");
  } catch (const drv::DeviceError& e) {
    CHECK(e.kind() == drv::DeviceErrorKind::kNotFound);
    CHECK_THAT(e.what(), Catch::Contains("laser1 (/dev/video97): open: no such camera"));
  }
  c.source = std::string("7");
  prof::CameraProfiler by_index(c, prof::CameraProfiler::media_factory(media, c));
  CHECK_THROWS_WITH(by_index.open(), Catch::Contains("laser1 (7)") && Catch::Contains("no /dev/video7"));
  // A bad configuration: every problem at once.
  prof::ProfilerConfig bad = config();
  bad.laser_off_every = 1;
  bad.calibration.camera.matrix(0, 0) = -1;
  bad.options.timeout = 0ms;
  try {
    prof::CameraProfiler x(bad, scripted(script));
    FAIL("accepted");
  } catch (const ConfigError& e) {
    CHECK_THAT(e.what(), Catch::Contains("cam0") && Catch::Contains("laser_off_every") &&
                             Catch::Contains("focal") && Catch::Contains("timeout"));
  }
}
