// The simulator's back end for the device layer: a DisplacementSensor that delivers the samples
// of a simulated (or recorded) scan as a real driver delivers them, on its own worker thread,
// live at the scan's own pace (or faster), so code above the drivers runs unchanged on sim.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include "scanmesh/drivers/device_support.hpp"
#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::sim {

struct SimulatedSensorOptions {
  std::string name = "sim";  ///< device name in messages
  /// Playback speed relative to the scan, > 0 (1: live; 10: ten times faster), or 0: as fast as
  /// the callback takes them. Default 1.
  double speed = 1;
};

/// Delivers `samples` (time-ordered, e.g. SimulatedScan::sensor) once. Each delivered sample
/// keeps its seq, status, value and device time; t_host becomes the host monotonic time of
/// delivery at speed > 0 (so it looks live), and stays the recorded time at speed 0. Sequence
/// gaps (measurements the simulation lost) are counted in stats().gaps. When every sample was
/// delivered the state stays kAcquiring with nothing more to come (like a sensor at rest).
class SimulatedSensor final : public drivers::DisplacementSensor {
 public:
  /// Throws ConfigError for a negative or non-finite speed.
  SimulatedSensor(std::vector<drivers::SensorSample> samples, SimulatedSensorOptions options = {});
  ~SimulatedSensor() override;

  const std::string& name() const override { return options_.name; }
  void open() override;
  void close() noexcept override;
  void start(drivers::SensorCallbacks callbacks) override;
  void stop() noexcept override;

  drivers::DeviceIdentity identify() const override;
  drivers::SensorCapabilities capabilities() const override;
  drivers::DeviceState state() const override { return state_.get(); }
  drivers::DeviceStats stats() const override { return stats_.snapshot(); }

  /// Samples delivered so far (all of them once done() is true).
  std::size_t delivered() const { return next_.load(); }
  bool done() const { return next_.load() >= samples_.size(); }

 private:
  void run(drivers::Worker& worker);

  std::vector<drivers::SensorSample> samples_;
  SimulatedSensorOptions options_;
  drivers::SensorCallbacks callbacks_;
  drivers::AtomicStats stats_;
  drivers::StateCell state_;
  drivers::Worker worker_;
  std::atomic<std::size_t> next_{0};
  bool running_ = false;
};

}  // namespace scanmesh::sim
