// Modbus transport on libmodbus: the RAII owner of a modbus_t and the RegisterBus it implements,
// over Modbus TCP or Modbus RTU (serial lines and pseudo-terminals).
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include "scanmesh/drivers/register_bus.hpp"

struct _modbus;  // libmodbus' context type (modbus_t); its header stays out of our headers

namespace scanmesh::drivers {

/// Move-only owner of one libmodbus context: modbus_close() then modbus_free() on destruction.
/// Threading: a libmodbus context is blocking and not thread-safe. Each device owns one and
/// uses it only from its own worker thread (STYLE.md §5.3).
class ModbusContext {
 public:
  ModbusContext() = default;
  explicit ModbusContext(_modbus* ctx) noexcept : ctx_(ctx) {}
  ModbusContext(ModbusContext&& other) noexcept;
  ModbusContext& operator=(ModbusContext&& other) noexcept;
  ModbusContext(const ModbusContext&) = delete;
  ModbusContext& operator=(const ModbusContext&) = delete;
  ~ModbusContext();

  _modbus* get() const noexcept { return ctx_; }
  explicit operator bool() const noexcept { return ctx_ != nullptr; }

 private:
  void reset() noexcept;
  _modbus* ctx_ = nullptr;
};

/// Opens a Modbus TCP connection to host:port and talks to `unit` (1..247; 255 for gateways
/// that ignore it). `timeout` is the response timeout of every request (1 ms .. 60 s).
/// Throws DeviceError naming `device`: kDisconnected when the connection is refused,
/// kTimeout, kIo otherwise, each with libmodbus' own message.
/// Recovery: after a request timed out, the next request first reconnects the TCP socket, so a
/// late reply can never be taken for the answer to a later request.
std::unique_ptr<RegisterBus> open_modbus_tcp(const std::string& device, const std::string& host,
                                             int port, int unit, std::chrono::milliseconds timeout);

/// Opens a Modbus RTU line on `path` (e.g. /dev/ttyUSB0, or a pty). parity is 'N', 'E' or 'O';
/// data_bits 5..8; stop_bits 1 or 2. Pseudo-terminals only accept 8N1 (enabling parity on a
/// pty fails in tcsetattr, PROTOCOLS.md §6): exercise parity only on real adapters.
/// Throws DeviceError naming `device`: kNotFound when the path does not exist, kIo otherwise.
/// Recovery: RTU has no transaction id, so after a timeout the next request first waits one
/// response timeout and flushes the line, so that a late reply is discarded, not misread.
std::unique_ptr<RegisterBus> open_modbus_rtu(const std::string& device, const std::string& path,
                                             int baud, char parity, int data_bits, int stop_bits,
                                             int unit, std::chrono::milliseconds timeout);

}  // namespace scanmesh::drivers
