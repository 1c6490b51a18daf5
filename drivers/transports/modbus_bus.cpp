// libmodbus wrapper: ModbusContext, the TCP/RTU RegisterBus, and the one function that turns
// libmodbus errors into DeviceError.
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/transports/modbus_bus.hpp"

#include <modbus/modbus.h>

#include <algorithm>
#include <cerrno>
#include <string>
#include <thread>
#include <utility>

#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers {

namespace {

/// The one translation of a libmodbus failure (errno after a -1 return) into our error type.
DeviceError modbus_error(const std::string& device, const std::string& operation, int err) {
  const std::string text = modbus_strerror(err);
  if (err == ETIMEDOUT) return {DeviceErrorKind::kTimeout, device, operation, text};
  if (err == ECONNREFUSED || err == ECONNRESET || err == EPIPE || err == EBADF || err == ENOTCONN ||
      err == ECONNABORTED || err == EHOSTUNREACH || err == ENETUNREACH || err == EIO ||
      err == ENXIO) {
    return {DeviceErrorKind::kDisconnected, device, operation, text};
  }
  if (err == ENOENT || err == ENODEV) return {DeviceErrorKind::kNotFound, device, operation, text};
  if (err >= EMBXILFUN && err <= EMBXGTAR) {
    return {DeviceErrorKind::kProtocol, device, operation,
            "Modbus exception " + std::to_string(err - MODBUS_ENOBASE) + ": " + text};
  }
  if (err >= EMBBADCRC && err <= EMBBADSLAVE) {
    return {DeviceErrorKind::kProtocol, device, operation, "invalid reply: " + text};
  }
  return {DeviceErrorKind::kIo, device, operation, text};
}

std::string range_text(const char* fc, std::uint16_t address, std::size_t count) {
  return std::string(fc) + " " + std::to_string(count) + " @" + std::to_string(address);
}

class ModbusBus final : public RegisterBus {
 public:
  ModbusBus(ModbusContext ctx, std::string name, bool tcp, std::chrono::milliseconds timeout)
      : ctx_(std::move(ctx)), name_(std::move(name)), tcp_(tcp), timeout_(timeout) {}

  void read_registers(RegisterKind kind, std::uint16_t address,
                      std::span<std::uint16_t> out) override {
    const char* fc =
        kind == RegisterKind::kInput ? "FC04 read input registers" : "FC03 read holding registers";
    // The operation text is built only on the error paths: a poll allocates nothing.
    auto op = [&] { return range_text(fc, address, out.size()); };
    if (out.empty() || out.size() > MODBUS_MAX_READ_REGISTERS)
      throw DeviceError(DeviceErrorKind::kProtocol, name_, op(), "count must be 1..125");
    if (dirty_) recover(op());
    const int n = static_cast<int>(out.size());
    const int rc = kind == RegisterKind::kInput
                       ? modbus_read_input_registers(ctx_.get(), address, n, out.data())
                       : modbus_read_registers(ctx_.get(), address, n, out.data());
    if (rc == -1) {
      const int err = errno;  // before building the message
      fail(op(), err);
    }
    if (rc != n) {
      throw DeviceError(DeviceErrorKind::kProtocol, name_, op(),
                        "got " + std::to_string(rc) + " registers");
    }
  }

  void write_registers(std::uint16_t address, std::span<const std::uint16_t> values) override {
    const bool single = values.size() == 1;
    const std::string op =
        range_text(single ? "FC06 write register" : "FC16 write registers", address, values.size());
    if (values.empty() || values.size() > MODBUS_MAX_WRITE_REGISTERS)
      throw DeviceError(DeviceErrorKind::kProtocol, name_, op, "count must be 1..123");
    recover(op);
    const int rc = single ? modbus_write_register(ctx_.get(), address, values[0])
                          : modbus_write_registers(ctx_.get(), address,
                                                   static_cast<int>(values.size()), values.data());
    if (rc == -1) fail(op, errno);
  }

  const std::string& name() const override { return name_; }

  void select_unit(int unit) override {
    if (unit < 1 || unit > 247 || modbus_set_slave(ctx_.get(), unit) == -1)
      throw DeviceError(DeviceErrorKind::kProtocol, name_, "select unit " + std::to_string(unit),
                        "unit must be 1..247");
  }

 private:
  [[noreturn]] void fail(const std::string& op, int err) {
    DeviceError e = modbus_error(name_, op, err);
    // A timed-out or garbled exchange may leave a late reply in flight: resynchronise first.
    if (e.kind() == DeviceErrorKind::kTimeout || (err >= EMBBADCRC && err <= EMBBADSLAVE))
      dirty_ = true;
    throw e;
  }

  void recover(const std::string& op) {
    if (!dirty_) return;
    if (tcp_) {
      // TCP: a fresh connection cannot carry the late reply of the old one.
      modbus_close(ctx_.get());
      if (modbus_connect(ctx_.get()) == -1) throw modbus_error(name_, op + " (reconnect)", errno);
    } else {
      // RTU: no transaction id. Let a late reply arrive, then throw it away.
      std::this_thread::sleep_for(timeout_);
      modbus_flush(ctx_.get());
    }
    dirty_ = false;
  }

  ModbusContext ctx_;
  std::string name_;
  bool tcp_;
  std::chrono::milliseconds timeout_;
  bool dirty_ = false;
};

void configure(const ModbusContext& ctx, const std::string& name, int unit,
               std::chrono::milliseconds timeout) {
  if (timeout.count() < 1 || timeout.count() > 60000)
    throw DeviceError(DeviceErrorKind::kIo, name, "configure", "timeout must be 1 ms .. 60 s");
  if (modbus_set_slave(ctx.get(), unit) == -1) throw modbus_error(name, "set unit id", errno);
  const auto ms = static_cast<std::uint32_t>(timeout.count());
  if (modbus_set_response_timeout(ctx.get(), ms / 1000, (ms % 1000) * 1000) == -1)
    throw modbus_error(name, "set response timeout", errno);
  // Gap between two bytes of one reply: generous but below the response timeout.
  const std::uint32_t byte_ms = std::max<std::uint32_t>(1, std::min<std::uint32_t>(ms, 50));
  if (modbus_set_byte_timeout(ctx.get(), byte_ms / 1000, (byte_ms % 1000) * 1000) == -1)
    throw modbus_error(name, "set byte timeout", errno);
}

}  // namespace

ModbusContext::ModbusContext(ModbusContext&& other) noexcept
    : ctx_(std::exchange(other.ctx_, nullptr)) {}

ModbusContext& ModbusContext::operator=(ModbusContext&& other) noexcept {
  if (this != &other) {
    reset();
    ctx_ = std::exchange(other.ctx_, nullptr);
  }
  return *this;
}

ModbusContext::~ModbusContext() { reset(); }

void ModbusContext::reset() noexcept {
  if (ctx_ != nullptr) {
    modbus_close(ctx_);
    modbus_free(ctx_);
    ctx_ = nullptr;
  }
}

std::unique_ptr<RegisterBus> open_modbus_tcp(const std::string& device, const std::string& host,
                                             int port, int unit,
                                             std::chrono::milliseconds timeout) {
  const std::string name = device + " (tcp " + host + ":" + std::to_string(port) + ")";
  ModbusContext ctx(modbus_new_tcp(host.c_str(), port));
  if (!ctx) throw modbus_error(name, "create TCP context", errno);
  configure(ctx, name, unit, timeout);
  if (modbus_connect(ctx.get()) == -1) throw modbus_error(name, "connect", errno);
  return std::make_unique<ModbusBus>(std::move(ctx), name, true, timeout);
}

std::unique_ptr<RegisterBus> open_modbus_rtu(const std::string& device, const std::string& path,
                                             int baud, char parity, int data_bits, int stop_bits,
                                             int unit, std::chrono::milliseconds timeout) {
  const std::string name = device + " (" + path + ")";
  ModbusContext ctx(modbus_new_rtu(path.c_str(), baud, parity, data_bits, stop_bits));
  if (!ctx) throw modbus_error(name, "create RTU context", errno);
  configure(ctx, name, unit, timeout);
  if (modbus_connect(ctx.get()) == -1) throw modbus_error(name, "open " + path, errno);
  return std::make_unique<ModbusBus>(std::move(ctx), name, false, timeout);
}

}  // namespace scanmesh::drivers
