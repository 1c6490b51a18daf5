// Modbus device emulators: a libmodbus server on 127.0.0.1 (Modbus TCP) and on a pseudo-terminal
// (Modbus RTU), serving a register image whose measurement registers are refreshed from a
// ValueSource on every read, with injectable faults (exceptions, late or missing replies, the
// server vanishing and coming back). Includes the Baumer OM20/OM30 register image.
// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "scanmesh/sim/emulators/serial_emulator.hpp"

namespace scanmesh::sim {

/// Faults a Modbus emulator can inject.
struct ModbusFaults {
  /// Answer every request with this Modbus exception code (0 = none; 4 = slave device failure,
  /// 2 = illegal data address, ...).
  int exception = 0;
  std::chrono::milliseconds reply_delay{0};  ///< answer this late
  bool silent = false;                       ///< read requests, answer nothing
};

/// One request the emulator received (for wire-level assertions).
struct ModbusRequest {
  int unit = 0;
  int function = 0;           ///< 3, 4, 6, 16, ...
  std::uint16_t address = 0;  ///< 0-based PDU address
  std::uint16_t count = 0;    ///< registers (1 for FC06)
};

/// Writes one measurement into the register tables (input, holding).
using ModbusImageWriter =
    std::function<void(std::span<std::uint16_t> input, std::span<std::uint16_t> holding,
                       const drivers::SensorSample& sample)>;

/// How the measurement registers are refreshed: on every read request (FC03/FC04) whose range
/// overlaps [first, first + count) of the table `function` reads (0 = either table), the
/// emulator takes the next value from its ValueSource and calls write() before replying.
/// Reads elsewhere (identity strings) take no measurement. An empty write = a static image.
struct ModbusImage {
  ModbusImageWriter write;
  int function = 0;  ///< 3 (holding), 4 (input) or 0 (both)
  std::uint16_t first = 0;
  std::uint32_t count = 65536;
};

/// Register tables of one unit (spans into the handler's own storage).
struct ModbusTables {
  std::span<std::uint16_t> input;
  std::span<std::uint16_t> holding;
};

/// Device behaviour plugged into a Modbus emulator instead of the measurement image: per-unit
/// tables, refreshed before a request is answered and told about every write after it (the
/// written values are then in the table). Called on the emulator thread under its lock.
class ModbusHandler {
 public:
  virtual ~ModbusHandler() = default;
  /// The tables of `unit`; an empty holding span: no such unit (the request gets no answer).
  virtual ModbusTables tables(int unit) = 0;
  virtual void before_reply(const ModbusRequest& request) { (void)request; }
  virtual void after_write(const ModbusRequest& request) { (void)request; }
};

/// Common part: register image (input and holding tables, 2048 registers each, PDU addresses
/// 0..2047), faults, request log and the server thread. One client connection at a time.
class ModbusEmulator {
 public:
  static constexpr std::size_t kRegisters = 2048;

  ModbusEmulator(ValueSource values, ModbusImage image, int unit);
  virtual ~ModbusEmulator();
  ModbusEmulator(const ModbusEmulator&) = delete;
  ModbusEmulator& operator=(const ModbusEmulator&) = delete;

  /// Starts serving (throws scanmesh::Error when the server cannot be set up).
  void start();
  void stop() noexcept;
  /// Closes the connection / port and stops serving: the client sees the device vanish.
  void vanish();
  /// Serves again on the same port / link path.
  void reappear();

  void set_faults(const ModbusFaults& faults);
  ModbusFaults faults() const;
  void set_input_registers(std::uint16_t address, std::span<const std::uint16_t> values);
  void set_holding_registers(std::uint16_t address, std::span<const std::uint16_t> values);
  std::vector<std::uint16_t> input_registers(std::uint16_t address, std::size_t count) const;
  std::vector<std::uint16_t> holding_registers(std::uint16_t address, std::size_t count) const;
  std::vector<ModbusRequest> requests() const;
  /// Serves `handler`'s tables instead of the image (set before start()).
  void set_handler(std::shared_ptr<ModbusHandler> handler) { handler_ = std::move(handler); }
  /// Measurements taken from the value source.
  std::uint64_t measurements() const { return measurements_.load(); }
  /// Client connections accepted (TCP) so far.
  std::uint64_t connections() const { return connections_.load(); }

 protected:
  /// Transport-specific server loop (runs on the emulator thread).
  virtual void serve(std::stop_token stop) = 0;
  /// Sets up the listening side (called by start()/reappear() on the caller's thread).
  virtual void open_server() = 0;
  virtual void close_server() noexcept = 0;
  /// Handles one received request of `length` bytes with libmodbus context `ctx` (a modbus_t*);
  /// applies the faults, refreshes the measurement, logs and replies.
  void handle(void* ctx, const std::uint8_t* request, int length, std::stop_token& stop);

  int unit_;
  std::atomic<std::uint64_t> connections_{0};

 private:
  ValueSource values_;
  ModbusImage image_;
  mutable std::mutex mutex_;  // guards the tables, faults_ and requests_
  std::vector<std::uint16_t> input_;
  std::vector<std::uint16_t> holding_;
  ModbusFaults faults_;
  std::vector<ModbusRequest> requests_;
  std::shared_ptr<ModbusHandler> handler_;
  std::atomic<std::uint64_t> measurements_{0};
  std::jthread thread_;
};

/// Modbus TCP server on 127.0.0.1. port 0 = an ephemeral port (port() tells which, and it is
/// kept across vanish()/reappear()).
class ModbusTcpEmulator final : public ModbusEmulator {
 public:
  ModbusTcpEmulator(ValueSource values, ModbusImage image, int unit = 1, int port = 0);
  ~ModbusTcpEmulator() override;
  int port() const { return port_; }

 protected:
  void serve(std::stop_token stop) override;
  void open_server() override;
  void close_server() noexcept override;

 private:
  int port_;
  void* ctx_ = nullptr;  // modbus_t*
  int listen_fd_ = -1;
};

/// Modbus RTU server on the master side of a pty pair; the driver opens link_path (8N1; parity
/// cannot be set on a pty). libmodbus serves through the master fd (modbus_set_socket).
class ModbusRtuEmulator final : public ModbusEmulator {
 public:
  ModbusRtuEmulator(std::string link_path, ValueSource values, ModbusImage image, int unit = 1);
  ~ModbusRtuEmulator() override;
  const std::string& port() const { return link_path_; }

 protected:
  void serve(std::stop_token stop) override;
  void open_server() override;
  void close_server() noexcept override;

 private:
  std::string link_path_;
  std::vector<PtyPair> pty_;  // zero or one
  void* ctx_ = nullptr;       // modbus_t*
};

/// Baumer OM20/OM30 register image (PROTOCOLS.md §1.5), refreshed by FC04 reads overlapping
/// IR 200..212. The measurement writer sets IR 200
/// quality (0 ok, 2 critical for no target), 201 outputs (bit 1 alarm for kAlarm/kDeviceError),
/// 202-203 distance float32 low word first (NaN for no target, +-inf over range), 204-205 rate
/// float32 (measurement_rate_hz), 209-212 timestamp s / µs (u32 low word first) from
/// sample.t_device or, without one, from a 1 ms-per-measurement counter.
ModbusImage baumer_om30_image(double measurement_rate_hz = 1000.0);
/// Fills the identity strings (IR 0 vendor, 32 product, 95 serial, 110 firmware; 2 characters
/// per register, high byte first).
void write_baumer_om30_identity(ModbusEmulator& emulator, const std::string& vendor,
                                const std::string& product, const std::string& serial,
                                const std::string& firmware);
/// Packs a string into registers, 2 characters each, high byte first, NUL padded.
std::vector<std::uint16_t> pack_register_string(const std::string& text, std::size_t registers);

}  // namespace scanmesh::sim
