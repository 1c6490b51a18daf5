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

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "scanmesh/drivers/common/sensor_lifecycle.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/modbus_sensor/codec.hpp"
#include "scanmesh/drivers/register_bus.hpp"

namespace scanmesh::drivers::modbus_sensor {

/// open() opens the bus, reads the identity strings the map has, and reads the measurement block
/// once; it throws DeviceError "<name>: <operation>: <detail>". The worker polls at
/// poll_interval (a fixed rate: a slow poll shortens the next pause).
class Device final : public SensorLifecycle {
 public:
  /// Validates the map (throws ConfigError). `transport` opens the bus (and reopens it after a
  /// loss); it throws DeviceError.
  Device(SensorOptions options, RegisterBusFactory transport, RegisterMap map);
  ~Device() override;

  SensorCapabilities capabilities() const override;

 private:
  /// One poll: reads every block; throws DeviceError from the bus.
  Measurement poll_once();
  [[noreturn]] void rethrow_named(const DeviceError& e, const std::string& operation) const;

  // ---- SensorLifecycle hooks ----
  void open_device() override;
  /// Reopens the bus; back when it answers one poll.
  bool reconnect_once() override;
  Step acquire(std::string& timeout_detail) override;
  void drop_transport() noexcept override { bus_.reset(); }
  bool has_transport() const override { return bus_ != nullptr; }
  std::string lost_after_timeouts(int count, const std::string& detail) const override;
  void on_start() override { next_poll_ = std::chrono::steady_clock::now(); }
  void on_reconnected() override { next_poll_ = std::chrono::steady_clock::now(); }
  bool pause(Worker& worker) override;

  RegisterBusFactory transport_;
  MapDecoder decoder_;
  std::unique_ptr<RegisterBus> bus_;  // used by open() and then only by the worker
  std::vector<std::uint16_t> image_;
  std::chrono::steady_clock::time_point next_poll_;  // worker only
};

}  // namespace scanmesh::drivers::modbus_sensor
