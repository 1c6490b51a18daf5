// Device class of the generic Modbus register-mapped displacement sensor: polls the map's
// fields over a RegisterBus and delivers SensorSamples (see codec.hpp for the map and models).
// SPDX-License-Identifier: MIT
//
// Models: Baumer OM20/OM30 (built-in map) and any sensor described by a RegisterMap.
// Vendor document: Baumer OM20/OM30 RS485 with Modbus RTU, Operating Manual V1, pp. 13, 14, 23,
//   45 (PROTOCOLS.md §1.5).
// Transport: RegisterBus from a RegisterBusFactory (libmodbus RTU or TCP, modbus_bus.hpp). The
//   bus is blocking and used only from this device's worker thread (and from open()).
// Quirks: see codec.hpp (low word first, no partial multi-register reads, 2 characters per
//   identity register). Modbus exceptions and invalid replies count as error_replies (libmodbus
//   owns the framing, so there is no separate "malformed" class); no sample is made from them.
#pragma once

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "scanmesh/drivers/device_support.hpp"
#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/modbus_sensor/codec.hpp"
#include "scanmesh/drivers/register_bus.hpp"

namespace scanmesh::drivers::modbus_sensor {

class Device final : public DisplacementSensor {
 public:
  /// Validates the map (throws ConfigError). `transport` opens the bus (and reopens it after a
  /// loss); it throws DeviceError.
  Device(SensorOptions options, RegisterBusFactory transport, RegisterMap map);
  ~Device() override;

  const std::string& name() const override { return options_.name; }
  /// Opens the bus, reads the identity strings the map has, and reads the measurement block
  /// once. Throws DeviceError "<name>: <operation>: <detail>".
  void open() override;
  void close() noexcept override;
  void start(SensorCallbacks callbacks) override;
  void stop() noexcept override;

  DeviceIdentity identify() const override;
  SensorCapabilities capabilities() const override;
  DeviceState state() const override { return state_.get(); }
  DeviceStats stats() const override { return stats_.snapshot(); }

 private:
  void run(Worker& worker);
  /// One poll: reads every block; throws DeviceError from the bus.
  Measurement poll_once();
  /// Drops the bus and reopens it with backoff until it answers; false when stopped.
  bool reconnect(Worker& worker, const std::string& reason);
  [[noreturn]] void rethrow_named(const DeviceError& e, const std::string& operation) const;

  SensorOptions options_;
  RegisterBusFactory transport_;
  MapDecoder decoder_;
  std::unique_ptr<RegisterBus> bus_;  // used by open() and then only by the worker
  std::vector<std::uint16_t> image_;
  mutable std::mutex identity_mutex_;
  DeviceIdentity identity_;
  SensorCallbacks callbacks_;
  SequenceTracker seq_;
  AtomicStats stats_;
  StateCell state_;
  Worker worker_;
  bool running_ = false;
};

}  // namespace scanmesh::drivers::modbus_sensor
