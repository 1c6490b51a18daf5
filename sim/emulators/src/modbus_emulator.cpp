// Modbus TCP / RTU emulators on libmodbus and the Baumer OM20/OM30 register image
// (see modbus_emulator.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/modbus_emulator.hpp"

#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>

#include "scanmesh/common/error.hpp"

namespace scanmesh::sim {

namespace {

modbus_t* mb(void* p) { return static_cast<modbus_t*>(p); }

bool wait_readable(int fd, int timeout_ms) {
  pollfd p{fd, POLLIN, 0};
  return ::poll(&p, 1, timeout_ms) > 0 && (p.revents & (POLLIN | POLLHUP | POLLERR));
}

void put_u32_low_first(std::span<std::uint16_t> regs, std::size_t at, std::uint32_t v) {
  regs[at] = static_cast<std::uint16_t>(v & 0xFFFF);
  regs[at + 1] = static_cast<std::uint16_t>(v >> 16);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// ModbusEmulator

ModbusEmulator::ModbusEmulator(ValueSource values, ModbusImage image, int unit)
    : unit_(unit),
      values_(std::move(values)),
      image_(std::move(image)),
      input_(kRegisters, 0),
      holding_(kRegisters, 0) {}

ModbusEmulator::~ModbusEmulator() = default;  // subclasses stop() in their destructors

void ModbusEmulator::start() {
  stop();
  open_server();
  thread_ = std::jthread([this](std::stop_token st) { serve(st); });
}

void ModbusEmulator::stop() noexcept {
  if (thread_.joinable()) {
    thread_.request_stop();
    thread_.join();
  }
  close_server();
}

void ModbusEmulator::vanish() { stop(); }

void ModbusEmulator::reappear() { start(); }

void ModbusEmulator::set_faults(const ModbusFaults& faults) {
  std::lock_guard lock(mutex_);
  faults_ = faults;
}

ModbusFaults ModbusEmulator::faults() const {
  std::lock_guard lock(mutex_);
  return faults_;
}

void ModbusEmulator::set_input_registers(std::uint16_t address,
                                         std::span<const std::uint16_t> values) {
  std::lock_guard lock(mutex_);
  for (std::size_t i = 0; i < values.size() && address + i < kRegisters; ++i)
    input_[address + i] = values[i];
}

void ModbusEmulator::set_holding_registers(std::uint16_t address,
                                           std::span<const std::uint16_t> values) {
  std::lock_guard lock(mutex_);
  for (std::size_t i = 0; i < values.size() && address + i < kRegisters; ++i)
    holding_[address + i] = values[i];
}

std::vector<std::uint16_t> ModbusEmulator::input_registers(std::uint16_t address,
                                                           std::size_t count) const {
  std::lock_guard lock(mutex_);
  std::vector<std::uint16_t> out;
  for (std::size_t i = 0; i < count && address + i < kRegisters; ++i)
    out.push_back(input_[address + i]);
  return out;
}

std::vector<std::uint16_t> ModbusEmulator::holding_registers(std::uint16_t address,
                                                             std::size_t count) const {
  std::lock_guard lock(mutex_);
  std::vector<std::uint16_t> out;
  for (std::size_t i = 0; i < count && address + i < kRegisters; ++i)
    out.push_back(holding_[address + i]);
  return out;
}

std::vector<ModbusRequest> ModbusEmulator::requests() const {
  std::lock_guard lock(mutex_);
  return requests_;
}

void ModbusEmulator::handle(void* ctx, const std::uint8_t* req, int length, std::stop_token& stop) {
  const int hl = modbus_get_header_length(mb(ctx));
  if (length < hl + 1) return;
  ModbusRequest r;
  r.unit = req[hl - 1];
  r.function = req[hl];
  if (length >= hl + 5) {
    r.address = static_cast<std::uint16_t>((req[hl + 1] << 8) | req[hl + 2]);
    r.count = r.function == 6 ? 1 : static_cast<std::uint16_t>((req[hl + 3] << 8) | req[hl + 4]);
  }
  ModbusFaults f;
  {
    std::lock_guard lock(mutex_);
    requests_.push_back(r);
    f = faults_;
  }
  if (f.silent) return;
  if (f.reply_delay.count() > 0) {
    const auto until = std::chrono::steady_clock::now() + f.reply_delay;
    while (std::chrono::steady_clock::now() < until && !stop.stop_requested())
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    if (stop.stop_requested()) return;
  }
  if (f.exception != 0) {
    modbus_reply_exception(mb(ctx), req, static_cast<unsigned>(f.exception));
    return;
  }
  const bool is_read = r.function == 3 || r.function == 4;
  const bool measure = is_read && image_.write && values_ &&
                       (image_.function == 0 || image_.function == r.function) &&
                       r.address < image_.first + image_.count &&
                       r.address + r.count > image_.first;
  drivers::SensorSample sample;
  if (measure) {
    measurements_.fetch_add(1);
    sample = values_();
  }
  std::lock_guard lock(mutex_);
  if (handler_) {
    const ModbusTables t = handler_->tables(r.unit);
    if (t.holding.empty()) return;  // no such unit on the line: no answer
    handler_->before_reply(r);
    modbus_mapping_t map{};
    map.nb_registers = static_cast<int>(t.holding.size());
    map.tab_registers = t.holding.data();
    map.nb_input_registers = static_cast<int>(t.input.size());
    map.tab_input_registers = t.input.data();
    modbus_reply(mb(ctx), req, length, &map);
    if (r.function == 6 || r.function == 16) handler_->after_write(r);
    return;
  }
  if (measure) image_.write(input_, holding_, sample);
  modbus_mapping_t map{};
  map.nb_registers = static_cast<int>(kRegisters);
  map.tab_registers = holding_.data();
  map.nb_input_registers = static_cast<int>(kRegisters);
  map.tab_input_registers = input_.data();
  modbus_reply(mb(ctx), req, length, &map);
}

// ---------------------------------------------------------------------------------------------
// ModbusTcpEmulator

ModbusTcpEmulator::ModbusTcpEmulator(ValueSource values, ModbusImage image, int unit, int port)
    : ModbusEmulator(std::move(values), std::move(image), unit), port_(port) {}

ModbusTcpEmulator::~ModbusTcpEmulator() { stop(); }

void ModbusTcpEmulator::open_server() {
  close_server();
  modbus_t* ctx = modbus_new_tcp("127.0.0.1", port_);
  if (ctx == nullptr) throw Error(std::string("modbus tcp emulator: ") + modbus_strerror(errno));
  modbus_set_slave(ctx, unit_);
  const int fd = modbus_tcp_listen(ctx, 4);
  if (fd == -1) {
    const std::string msg = modbus_strerror(errno);
    modbus_free(ctx);
    throw Error("modbus tcp emulator: listen on 127.0.0.1:" + std::to_string(port_) + ": " + msg);
  }
  sockaddr_in addr{};
  socklen_t len = sizeof addr;
  if (::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0)
    port_ = ntohs(addr.sin_port);  // the ephemeral port, kept for reappear()
  ctx_ = ctx;
  listen_fd_ = fd;
}

void ModbusTcpEmulator::close_server() noexcept {
  if (listen_fd_ >= 0) ::close(listen_fd_);
  listen_fd_ = -1;
  if (ctx_ != nullptr) {
    modbus_close(mb(ctx_));  // the client socket, if one is still set
    modbus_free(mb(ctx_));
  }
  ctx_ = nullptr;
}

void ModbusTcpEmulator::serve(std::stop_token stop) {
  modbus_t* ctx = mb(ctx_);
  int listen_fd = listen_fd_;
  std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
  while (!stop.stop_requested()) {
    if (!wait_readable(listen_fd, 20)) continue;
    const int s = modbus_tcp_accept(ctx, &listen_fd);
    if (s == -1) continue;
    connections_.fetch_add(1);
    while (!stop.stop_requested()) {
      if (!wait_readable(s, 20)) continue;
      const int rc = modbus_receive(ctx, query);
      if (rc > 0) {
        handle(ctx, query, rc, stop);
      } else if (rc == -1) {
        break;  // the client closed the connection (or sent garbage): wait for the next one
      }
    }
    ::close(s);
    modbus_set_socket(ctx, -1);
  }
}

// ---------------------------------------------------------------------------------------------
// ModbusRtuEmulator

ModbusRtuEmulator::ModbusRtuEmulator(std::string link_path, ValueSource values, ModbusImage image,
                                     int unit)
    : ModbusEmulator(std::move(values), std::move(image), unit), link_path_(std::move(link_path)) {}

ModbusRtuEmulator::~ModbusRtuEmulator() { stop(); }

void ModbusRtuEmulator::open_server() {
  close_server();
  pty_.emplace_back(link_path_);
  // The context is never connected: libmodbus reads and writes the pty master we hand it.
  modbus_t* ctx = modbus_new_rtu(link_path_.c_str(), 115200, 'N', 8, 1);
  if (ctx == nullptr) {
    pty_.clear();
    throw Error(std::string("modbus rtu emulator: ") + modbus_strerror(errno));
  }
  modbus_set_slave(ctx, unit_);
  modbus_set_socket(ctx, pty_.front().master_fd());
  ctx_ = ctx;
}

void ModbusRtuEmulator::close_server() noexcept {
  if (ctx_ != nullptr) {
    modbus_set_socket(mb(ctx_), -1);  // the fd belongs to the PtyPair
    modbus_free(mb(ctx_));
  }
  ctx_ = nullptr;
  pty_.clear();
}

void ModbusRtuEmulator::serve(std::stop_token stop) {
  modbus_t* ctx = mb(ctx_);
  const int fd = modbus_get_socket(ctx);
  std::uint8_t query[MODBUS_RTU_MAX_ADU_LENGTH];
  while (!stop.stop_requested()) {
    if (!wait_readable(fd, 20)) continue;
    const int rc = modbus_receive(ctx, query);
    if (rc > 0) {
      handle(ctx, query, rc, stop);
    } else if (rc == -1) {
      modbus_flush(ctx);  // bad CRC or a torn frame: drop what is buffered
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Baumer OM20/OM30 image

ModbusImage baumer_om30_image(double measurement_rate_hz) {
  std::uint64_t n = 0;
  ModbusImage image;
  image.function = 4;
  image.first = 200;
  image.count = 13;
  image.write = [measurement_rate_hz, n](std::span<std::uint16_t> input, std::span<std::uint16_t>,
                                         const drivers::SensorSample& s) mutable {
    using drivers::SensorStatus;
    std::uint16_t quality = 0;
    std::uint16_t outputs = 0x0001;  // bit 0: switching output (not used by the driver)
    float distance = static_cast<float>(s.value_mm);
    switch (s.status) {
      case SensorStatus::kOk:
        break;
      case SensorStatus::kNoTarget:
        quality = 2;
        distance = std::numeric_limits<float>::quiet_NaN();
        break;
      case SensorStatus::kOverRange:
        quality = 2;
        distance = s.value_mm < 0 ? -std::numeric_limits<float>::infinity()
                                  : std::numeric_limits<float>::infinity();
        break;
      case SensorStatus::kAlarm:
      case SensorStatus::kDeviceError:
        quality = 1;
        outputs |= 0x0002;  // bit 1: alarm
        if (!std::isfinite(distance)) distance = 0;
        break;
    }
    input[200] = quality;
    input[201] = outputs;
    put_u32_low_first(input, 202, std::bit_cast<std::uint32_t>(distance));
    put_u32_low_first(input, 204,
                      std::bit_cast<std::uint32_t>(static_cast<float>(measurement_rate_hz)));
    input[206] = 100;                    // exposure reserve
    put_u32_low_first(input, 207, 500);  // response delay, µs
    std::uint64_t us = 0;
    if (s.t_device) {
      us = static_cast<std::uint64_t>(std::max<std::int64_t>(0, s.t_device->ns / 1000));
    } else {
      us = n * 1000;  // 1 ms per measurement
    }
    ++n;
    put_u32_low_first(input, 209, static_cast<std::uint32_t>(us / 1000000));
    put_u32_low_first(input, 211, static_cast<std::uint32_t>(us % 1000000));
  };
  return image;
}

std::vector<std::uint16_t> pack_register_string(const std::string& text, std::size_t registers) {
  std::vector<std::uint16_t> regs(registers, 0);
  for (std::size_t i = 0; i < text.size() && i / 2 < registers; ++i) {
    const auto c = static_cast<std::uint8_t>(text[i]);
    regs[i / 2] |= static_cast<std::uint16_t>(i % 2 == 0 ? c << 8 : c);
  }
  return regs;
}

void write_baumer_om30_identity(ModbusEmulator& emulator, const std::string& vendor,
                                const std::string& product, const std::string& serial,
                                const std::string& firmware) {
  emulator.set_input_registers(0, pack_register_string(vendor, 16));
  emulator.set_input_registers(32, pack_register_string(product, 26));
  emulator.set_input_registers(95, pack_register_string(serial, 10));
  emulator.set_input_registers(110, pack_register_string(firmware, 5));
}

}  // namespace scanmesh::sim
