// RegisterBus: the transport interface of Modbus devices (libmodbus owns the framing), plus the
// data-driven register map that turns registers into values.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>

namespace scanmesh::drivers {

/// Modbus register tables. Addresses are 0-based PDU addresses everywhere in this project.
enum class RegisterKind { kHolding, kInput };

/// One Modbus unit (slave) on a bus or behind a TCP address. Blocking; one worker thread.
class RegisterBus {
 public:
  virtual ~RegisterBus() = default;
  /// Reads out.size() consecutive registers (FC03 holding / FC04 input) or throws DeviceError
  /// (kTimeout, kDisconnected, kProtocol for a Modbus exception, with its name).
  virtual void read_registers(RegisterKind kind, std::uint16_t address,
                              std::span<std::uint16_t> out) = 0;
  /// Writes holding registers (FC06 for one, FC16 for several) or throws DeviceError.
  virtual void write_registers(std::uint16_t address, std::span<const std::uint16_t> values) = 0;
  virtual const std::string& name() const = 0;
  /// Addresses another unit on the same line from the next request on (several drives on one
  /// RS-485 line, a TCP gateway). Unit 1..247. Buses with one fixed unit throw DeviceError.
  virtual void select_unit(int unit);
};

using RegisterBusFactory = std::function<std::unique_ptr<RegisterBus>()>;

}  // namespace scanmesh::drivers
