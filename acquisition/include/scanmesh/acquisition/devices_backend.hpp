// The scan backend over real device drivers: one displacement sensor and one motion stage (any
// drivers of those families, built by the drivers' factory or handed in), and a scan program of
// absolute moves the stage runs while the sensor streams. Nothing in it knows of simulation: the
// same code drives a real scanner and the protocol emulators.
// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "scanmesh/acquisition/backend.hpp"
#include "scanmesh/acquisition/scan_program.hpp"
#include "scanmesh/drivers/factory.hpp"
#include "scanmesh/drivers/motion_stage.hpp"

namespace scanmesh::acq {

struct DevicesBackendOptions {
  /// A move that has not ended this long after its nominal time fails the scan. Default 10 s.
  std::chrono::milliseconds move_slack{10000};
  /// Feed of the return to a scan line's start after a pause, mm/min, > 0. Default 3000.
  double reposition_feed_mm_min = 3000;
  /// Shown by devices() (the factory fills them in).
  std::string sensor_driver, sensor_port, stage_driver, stage_port;
};

/// Runs `program` on the stage while the sensor streams. Sensor samples go to device 0 from the
/// first move to the end of the last (not while paused); every stage report goes to the pipeline
/// (the accumulator joins them by their timestamps). pause() is a halt of the stage (a feed hold
/// then a flush of its queue); resume() returns to the start of the interrupted scan line and
/// runs it again, so a pause, a lost device or a lost stage leaves no gap in the coverage.
/// Moves are issued one at a time (each waits for the stage to stand): the interrupted move is
/// always known. Device state changes are reported as the drivers report them.
class DevicesBackend final : public ScanBackend {
 public:
  /// Throws ConfigError for a bad program or model (no sensor, no stage, null devices).
  DevicesBackend(std::unique_ptr<drivers::DisplacementSensor> sensor,
                 std::unique_ptr<drivers::MotionStage> stage, ScannerModel model,
                 ScanProgram program, DevicesBackendOptions options = {});
  ~DevicesBackend() override;

  std::string_view kind() const override { return "devices"; }
  ScannerModel model() const override { return model_; }
  std::vector<DeviceStatus> devices() const override;
  void start(SampleInput& input) override;
  void pause() override;
  void resume() override;
  void stop() noexcept override;

  /// Moves finished so far (re-runs after pauses count again), and pauses carried out.
  std::uint64_t moves_done() const { return moves_done_.load(); }
  std::uint64_t halts() const { return halts_.load(); }

 private:
  enum class Wait { kDone, kPaused, kStopped };
  void run(std::stop_token stop, SampleInput& input);
  /// Issues one move and waits for its end; kPaused when a pause (or a lost stage) broke it off.
  Wait run_move(std::stop_token& stop, const ScanMove& move);
  /// Waits while paused (the stage halted); false when stopped.
  bool hold(std::stop_token& stop);
  bool paused() const;
  void set_reason(bool sensor, const std::string& reason);

  std::unique_ptr<drivers::DisplacementSensor> sensor_;
  std::unique_ptr<drivers::MotionStage> stage_;
  ScannerModel model_;
  ScanProgram program_;
  DevicesBackendOptions options_;

  mutable std::mutex mutex_;  // guards the pause flag and the reasons
  std::condition_variable cv_;
  bool pause_requested_ = false;
  std::string sensor_reason_, stage_reason_;
  std::atomic<bool> forwarding_{false};  // sensor samples go to the pipeline
  std::atomic<bool> running_{false};
  std::atomic<bool> motion_done_{false};  // the program ran to its end: nothing to halt
  std::atomic<std::uint64_t> moves_done_{0}, halts_{0};
  std::jthread program_thread_;
};

/// Builds the sensor and the stage with the drivers' factory (not opened yet) and the backend
/// over them. `model.sensors[0].name` and `model.stage` name the devices in every message.
/// Throws ConfigError for an unknown driver or a bad combination.
std::unique_ptr<DevicesBackend> make_devices_backend(const drivers::SensorConfig& sensor,
                                                     const drivers::StageConfig& stage,
                                                     ScannerModel model, ScanProgram program,
                                                     DevicesBackendOptions options = {});

}  // namespace scanmesh::acq
