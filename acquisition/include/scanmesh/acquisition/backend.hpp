// What a scan's samples come from: a ScanBackend owns the devices (real drivers, the simulated
// scanner, or a recorded journal), runs the scan motion, and pushes every sample into the
// pipeline's SampleInput from its own threads. The pipeline knows nothing else of devices.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/acquisition/accumulator.hpp"
#include "scanmesh/acquisition/sensor_model.hpp"
#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::acq {

/// Where samples enter the pipeline. Thread-safe: any device thread may call it; calls from one
/// thread keep their order.
class SampleInput {
 public:
  virtual ~SampleInput() = default;
  /// Samples of sensor `device` (its index in ScannerModel::sensors), in device order.
  virtual void on_sensor(std::uint16_t device, std::span<const SensorSample> samples) = 0;
  virtual void on_stage(const StageSample& sample) = 0;
  virtual void on_probe(std::uint16_t device, const ProbeTrigger& trigger) = 0;
  /// A device changed state; `reason` names the device ("lkg0 (/dev/ttyUSB0): no reply ...").
  virtual void on_device_state(std::string_view device, drivers::DeviceState state,
                               std::string_view reason) = 0;
  /// The scan motion is complete: nothing more will come.
  virtual void on_end() = 0;
  /// The backend cannot go on (a device that cannot be reopened, a corrupt journal...).
  virtual void on_failure(std::string_view message) = 0;
};

/// The machine as acquisition needs it: every sensor's optics and calibrated mounting, in
/// device-index order, and the accumulator's timing.
struct ScannerModel {
  struct Sensor {
    std::string name;
    SensorConfig config;
    Calibration calibration;
  };
  std::vector<Sensor> sensors;
  std::string stage;  ///< the stage's device name ("" if none)
  AccumulatorConfig accumulator;
};

/// One device as `status` shows it.
struct DeviceStatus {
  std::string name;
  std::string kind;    ///< "sensor", "stage", "probe"
  std::string driver;  ///< factory name ("keyence-lkg", "grbl", "sim", "replay")
  std::string port;    ///< transport address, if any
  drivers::DeviceState state = drivers::DeviceState::kClosed;
  std::string reason;  ///< last state change's reason
  drivers::DeviceStats stats;
};

class ScanBackend {
 public:
  virtual ~ScanBackend() = default;
  virtual std::string_view kind() const = 0;  ///< "sim", "devices", "replay"
  virtual ScannerModel model() const = 0;
  virtual std::vector<DeviceStatus> devices() const = 0;
  /// Opens the devices, starts acquisition and the scan motion. Samples flow into `input` from
  /// the backend's threads until stop(). Throws scanmesh::Error naming the device on failure.
  virtual void start(SampleInput& input) = 0;
  /// Holds the motion (and the samples it would produce) / continues it.
  virtual void pause() = 0;
  virtual void resume() = 0;
  /// Stops motion and acquisition; nothing calls `input` after it returns. Never throws.
  virtual void stop() noexcept = 0;
};

}  // namespace scanmesh::acq
