// The libmodbus transport (open_modbus_tcp / open_modbus_rtu) against the Modbus emulators:
// reads, writes, exceptions, timeouts, refused connections, a server vanishing, RTU over a pty.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/transports/modbus_bus.hpp"
#include "scanmesh/sim/emulators/modbus_emulator.hpp"
#include "support/temp_dir.hpp"

using namespace std::chrono_literals;
using scanmesh::drivers::DeviceError;
using scanmesh::drivers::DeviceErrorKind;
using scanmesh::drivers::RegisterKind;
using scanmesh::sim::ModbusFaults;
using scanmesh::sim::ModbusRtuEmulator;
using scanmesh::sim::ModbusTcpEmulator;

namespace {

ModbusTcpEmulator plain_tcp() {
  return ModbusTcpEmulator(scanmesh::sim::scripted_values({1.0}), {}, 1, 0);
}

DeviceErrorKind kind_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const DeviceError& e) {
    return e.kind();
  }
  FAIL("no DeviceError thrown");
  return DeviceErrorKind::kIo;
}

}  // namespace

TEST_CASE("modbus tcp: FC04/FC03 reads, FC06/FC16 writes", "[drivers][modbus]") {
  ModbusTcpEmulator emu(scanmesh::sim::scripted_values({1.0}), {}, 1, 0);
  const std::vector<std::uint16_t> ir = {10, 11, 12, 0xFFFF};
  emu.set_input_registers(200, ir);
  emu.start();
  REQUIRE(emu.port() > 0);
  auto bus = scanmesh::drivers::open_modbus_tcp("om0", "127.0.0.1", emu.port(), 1, 500ms);
  CHECK(bus->name() == "om0 (tcp 127.0.0.1:" + std::to_string(emu.port()) + ")");

  std::vector<std::uint16_t> got(4);
  bus->read_registers(RegisterKind::kInput, 200, got);
  CHECK(got == ir);

  const std::uint16_t one = 4660;
  bus->write_registers(100, std::span(&one, 1));
  const std::vector<std::uint16_t> several = {1, 2, 3};
  bus->write_registers(0x6200 % 2048, several);
  std::vector<std::uint16_t> back(1);
  bus->read_registers(RegisterKind::kHolding, 100, back);
  CHECK(back[0] == 4660);
  CHECK(emu.holding_registers(0x6200 % 2048, 3) == several);

  const auto reqs = emu.requests();
  REQUIRE(reqs.size() == 4);
  CHECK((reqs[0].function == 4 && reqs[0].address == 200 && reqs[0].count == 4));
  CHECK((reqs[1].function == 6 && reqs[1].address == 100 && reqs[1].count == 1));
  CHECK((reqs[2].function == 16 && reqs[2].count == 3));
  CHECK((reqs[3].function == 3 && reqs[3].address == 100 && reqs[3].count == 1));
  CHECK(reqs[0].unit == 1);

  // Out-of-spec counts are refused before anything goes on the wire.
  std::vector<std::uint16_t> too_many(126);
  CHECK(kind_of([&] { bus->read_registers(RegisterKind::kInput, 0, too_many); }) ==
        DeviceErrorKind::kProtocol);
  CHECK(emu.requests().size() == 4);
}

TEST_CASE("modbus tcp: an exception reply is kProtocol naming the exception", "[drivers][modbus]") {
  auto emu = plain_tcp();
  emu.start();
  auto bus = scanmesh::drivers::open_modbus_tcp("om0", "127.0.0.1", emu.port(), 1, 500ms);
  emu.set_faults(ModbusFaults{4, 0ms, false});
  std::vector<std::uint16_t> got(2);
  try {
    bus->read_registers(RegisterKind::kInput, 202, got);
    FAIL("no exception");
  } catch (const DeviceError& e) {
    CHECK(e.kind() == DeviceErrorKind::kProtocol);
    CHECK(e.device() == bus->name());
    CHECK_THAT(e.operation(), Catch::Contains("FC04"));
    CHECK_THAT(e.detail(), Catch::Contains("Modbus exception 4") &&
                               Catch::Contains("Slave device or server failure"));
  }
  emu.set_faults(ModbusFaults{2, 0ms, false});
  CHECK(kind_of([&] { bus->read_registers(RegisterKind::kInput, 202, got); }) ==
        DeviceErrorKind::kProtocol);
  // The device still answers once the fault is gone.
  emu.set_faults({});
  emu.set_input_registers(202, std::vector<std::uint16_t>{0x7C37, 0x428B});
  bus->read_registers(RegisterKind::kInput, 202, got);
  CHECK(got == std::vector<std::uint16_t>{0x7C37, 0x428B});
}

TEST_CASE("modbus tcp: a late reply is kTimeout and never taken for a later answer",
          "[drivers][modbus]") {
  auto emu = plain_tcp();
  emu.set_input_registers(10, std::vector<std::uint16_t>{111});
  emu.start();
  auto bus = scanmesh::drivers::open_modbus_tcp("om0", "127.0.0.1", emu.port(), 1, 100ms);
  emu.set_faults(ModbusFaults{0, 300ms, false});
  std::vector<std::uint16_t> got(1);
  const auto t0 = std::chrono::steady_clock::now();
  CHECK(kind_of([&] { bus->read_registers(RegisterKind::kInput, 10, got); }) ==
        DeviceErrorKind::kTimeout);
  CHECK(std::chrono::steady_clock::now() - t0 < 290ms);
  // The late reply (111) is still on its way; no later request may take it for its answer.
  // (The emulator is busy with the old request for a while: retry until it answers.)
  emu.set_faults({});
  emu.set_input_registers(10, std::vector<std::uint16_t>{222});
  int ok = 0;
  for (int i = 0; i < 20 && ok < 3; ++i) {
    try {
      got[0] = 0;
      bus->read_registers(RegisterKind::kInput, 10, got);
      CHECK(got[0] == 222);
      ++ok;
    } catch (const DeviceError& e) {
      CHECK(e.kind() == DeviceErrorKind::kTimeout);
    }
  }
  CHECK(ok == 3);

  emu.set_faults(ModbusFaults{0, 0ms, true});  // silent
  CHECK(kind_of([&] { bus->read_registers(RegisterKind::kInput, 10, got); }) ==
        DeviceErrorKind::kTimeout);
}

TEST_CASE("modbus tcp: refused connection and a vanishing server are kDisconnected",
          "[drivers][modbus]") {
  auto emu = plain_tcp();
  emu.start();
  const int port = emu.port();
  auto bus = scanmesh::drivers::open_modbus_tcp("om0", "127.0.0.1", port, 1, 300ms);
  std::vector<std::uint16_t> got(1);
  bus->read_registers(RegisterKind::kInput, 0, got);

  emu.vanish();
  CHECK(kind_of([&] { bus->read_registers(RegisterKind::kInput, 0, got); }) ==
        DeviceErrorKind::kDisconnected);
  try {
    (void)scanmesh::drivers::open_modbus_tcp("om0", "127.0.0.1", port, 1, 300ms);
    FAIL("connected to a vanished server");
  } catch (const DeviceError& e) {
    CHECK(e.kind() == DeviceErrorKind::kDisconnected);
    CHECK(e.operation() == "connect");
    CHECK_THAT(e.detail(), Catch::Contains("refused"));
    CHECK_THAT(std::string(e.what()), Catch::StartsWith("om0 (tcp 127.0.0.1:"));
  }
  emu.reappear();
  CHECK(emu.port() == port);
  auto bus2 = scanmesh::drivers::open_modbus_tcp("om0", "127.0.0.1", port, 1, 300ms);
  bus2->read_registers(RegisterKind::kInput, 0, got);
  CHECK(emu.connections() == 2);
}

TEST_CASE("modbus rtu over a pty: reads, writes, wrong unit, vanish", "[drivers][modbus]") {
  scanmesh::test::TempDir dir;
  const std::string link = (dir / "ttyOM").string();
  ModbusRtuEmulator emu(link, scanmesh::sim::scripted_values({1.0}), {}, 7);
  emu.set_input_registers(200, std::vector<std::uint16_t>{0, 1, 0x7C37, 0x428B});
  emu.start();

  auto bus = scanmesh::drivers::open_modbus_rtu("om0", link, 115200, 'N', 8, 1, 7, 200ms);
  CHECK(bus->name() == "om0 (" + link + ")");
  std::vector<std::uint16_t> got(4);
  bus->read_registers(RegisterKind::kInput, 200, got);
  CHECK(got == std::vector<std::uint16_t>{0, 1, 0x7C37, 0x428B});
  const std::vector<std::uint16_t> w = {5, 6};
  bus->write_registers(180, w);
  CHECK(emu.holding_registers(180, 2) == w);
  const auto reqs = emu.requests();
  REQUIRE(reqs.size() == 2);
  CHECK(
      (reqs[0].unit == 7 && reqs[0].function == 4 && reqs[0].address == 200 && reqs[0].count == 4));
  CHECK((reqs[1].function == 16 && reqs[1].address == 180));

  // Another unit on the bus does not answer: a timeout.
  auto other = scanmesh::drivers::open_modbus_rtu("om1", link, 115200, 'N', 8, 1, 3, 100ms);
  bus.reset();
  CHECK(kind_of([&] { other->read_registers(RegisterKind::kInput, 200, got); }) ==
        DeviceErrorKind::kTimeout);
  other.reset();

  bus = scanmesh::drivers::open_modbus_rtu("om0", link, 115200, 'N', 8, 1, 7, 200ms);
  emu.vanish();
  const auto k = kind_of([&] { bus->read_registers(RegisterKind::kInput, 200, got); });
  CHECK((k == DeviceErrorKind::kDisconnected || k == DeviceErrorKind::kTimeout));
  bus.reset();
  CHECK(kind_of([&] {
          (void)scanmesh::drivers::open_modbus_rtu("om0", link, 115200, 'N', 8, 1, 7, 200ms);
        }) == DeviceErrorKind::kNotFound);
  emu.reappear();
  bus = scanmesh::drivers::open_modbus_rtu("om0", link, 115200, 'N', 8, 1, 7, 200ms);
  bus->read_registers(RegisterKind::kInput, 200, got);
  CHECK(got[2] == 0x7C37);
}
