// The production serial transport (Boost.Asio serial_port) against the pty emulator base:
// bytes both ways, timeouts, the port vanishing and coming back, clear errors.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <chrono>
#include <filesystem>
#include <string>
#include <fstream>
#include <thread>

#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/transports/serial_stream.hpp"
#include "scanmesh/sim/emulators/serial_emulator.hpp"
#include "support/temp_dir.hpp"

using namespace std::chrono_literals;
using scanmesh::drivers::DeviceError;
using scanmesh::drivers::DeviceErrorKind;

namespace {

/// Answers every CR-terminated line with "<line>!\r" (a minimal line protocol).
class EchoEmulator final : public scanmesh::sim::SerialEmulator {
 public:
  explicit EchoEmulator(std::string path)
      : SerialEmulator(std::move(path), scanmesh::sim::scripted_values({1.0})) {}

 private:
  std::string on_input(std::string_view bytes) override {
    std::string out;
    for (char c : bytes) {
      if (c == '\r') {
        out += line_ + "!\r";
        line_.clear();
      } else {
        line_ += c;
      }
    }
    return out;
  }
  std::string line_;
};

/// Reads until `n` bytes arrived or `deadline` passed.
std::string read_n(scanmesh::drivers::ByteStream& s, std::size_t n,
                   std::chrono::milliseconds deadline = 2000ms) {
  std::string got;
  std::uint8_t buf[256];
  const auto end = std::chrono::steady_clock::now() + deadline;
  while (got.size() < n && std::chrono::steady_clock::now() < end) {
    const std::size_t k = s.read_some(buf, 50ms);
    got.append(reinterpret_cast<const char*>(buf), k);
  }
  return got;
}

}  // namespace

TEST_CASE("serial stream talks to a pty emulator both ways", "[drivers][serial]") {
  scanmesh::test::TempDir dir;
  EchoEmulator emu((dir.path() / "tty").string());
  emu.start();
  auto s = scanmesh::drivers::open_serial_stream("echo0", {emu.port(), 115200});
  CHECK(s->name() == "echo0 (" + emu.port() + ")");
  s->write_all(std::string_view("M0\rQ0\r"), 500ms);
  CHECK(read_n(*s, 8) == "M0!\rQ0!\r");
  CHECK(emu.received() == "M0\rQ0\r");

  SECTION("a read with nothing to read times out with 0 bytes") {
    std::uint8_t buf[16];
    const auto t0 = std::chrono::steady_clock::now();
    CHECK(s->read_some(buf, 60ms) == 0);
    const auto dt = std::chrono::steady_clock::now() - t0;
    CHECK(dt >= 55ms);
    CHECK(dt < 1s);
  }
  SECTION("replies split into single bytes arrive complete") {
    emu.set_faults({.split_every_byte = true});
    s->write_all(std::string_view("ABCDEFGH\r"), 500ms);
    CHECK(read_n(*s, 10) == "ABCDEFGH!\r");
  }
  SECTION("the port vanishing is kDisconnected, and it can be reopened when it is back") {
    emu.vanish();
    std::uint8_t buf[16];
    try {
      for (int i = 0; i < 20; ++i) s->read_some(buf, 50ms);
      FAIL("no error after the pty closed");
    } catch (const DeviceError& e) {
      CHECK(e.kind() == DeviceErrorKind::kDisconnected);
      CHECK(std::string(e.what()).find("echo0") != std::string::npos);
      CHECK(e.operation() == "read");
    }
    try {
      scanmesh::drivers::open_serial_stream("echo0", {emu.port(), 115200});
      FAIL("opened a vanished port");
    } catch (const DeviceError& e) {
      CHECK(e.kind() == DeviceErrorKind::kNotFound);
    }
    emu.reappear();
    auto again = scanmesh::drivers::open_serial_stream("echo0", {emu.port(), 115200});
    again->write_all(std::string_view("R0\r"), 500ms);
    CHECK(read_n(*again, 4) == "R0!\r");
  }
}

TEST_CASE("serial stream open errors name the device, the path and the OS reason",
          "[drivers][serial]") {
  scanmesh::test::TempDir dir;
  const std::string path = (dir.path() / "nothing").string();
  try {
    scanmesh::drivers::open_serial_stream("lkg0", {path, 9600});
    FAIL("opened a missing port");
  } catch (const DeviceError& e) {
    const std::string msg = e.what();
    CHECK(e.kind() == DeviceErrorKind::kNotFound);
    CHECK(msg.find("lkg0") != std::string::npos);
    CHECK(msg.find(path) != std::string::npos);
    CHECK(msg.find("open") != std::string::npos);
  }
  // A regular file is not a serial port: the OS refuses the termios calls.
  const std::string file = (dir.path() / "file").string();
  { std::ofstream(file) << "x"; }
  CHECK_THROWS_AS(scanmesh::drivers::open_serial_stream("lkg0", {file, 9600}), DeviceError);
}
