// `scanmesh device read --driver modbus-sensor` end to end: the real binary talks Modbus TCP and
// Modbus RTU (over a pty) to a Baumer OM30 emulator in this process, with the built-in map and
// with the shipped profile file.
// SPDX-License-Identifier: MIT
#ifdef SCANMESH_EXE
#include <catch2/catch.hpp>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "scanmesh/sim/emulators/modbus_emulator.hpp"
#include "support/json_lines.hpp"
#include "support/process.hpp"
#include "support/temp_dir.hpp"

using nlohmann::json;
using scanmesh::test::json_lines;
using scanmesh::test::run_program;
using scanmesh::test::TempDir;

namespace {

void check_values(const std::vector<json>& lines, std::size_t n) {
  REQUIRE(lines.size() == n);
  for (std::size_t i = 0; i < n; ++i) {
    CHECK(lines[i].at("seq").get<std::uint64_t>() == i);
    const auto& v = lines[i].at("value_mm");
    if (lines[i].at("status") == "ok") {
      const double x = v.get<double>();
      // float32 registers: the scripted 69.743 / 12.5 come back to float precision
      CHECK((std::abs(x - 69.743) < 1e-4 || std::abs(x - 12.5) < 1e-4));
    } else {
      CHECK(v.is_null());
      CHECK(lines[i].at("status") == "no_target");
    }
  }
}

}  // namespace

TEST_CASE("device read: Baumer OM30 over Modbus TCP", "[drivers][cli][modbus]") {
  TempDir dir;
  scanmesh::sim::ModbusTcpEmulator emu(
      scanmesh::sim::scripted_values({69.743, 12.5, std::nan("")}),
      scanmesh::sim::baumer_om30_image());
  emu.start();
  const std::string tcp = "127.0.0.1:" + std::to_string(emu.port());
  SECTION("built-in map") {
    const auto r = run_program(SCANMESH_EXE, dir,
                               {"device", "read", "--driver", "modbus-sensor", "--tcp", tcp,
                                "--samples", "7", "--json"});
    INFO(r.out << r.err);
    REQUIRE(r.status == 0);
    check_values(json_lines(r.out), 7);
  }
  SECTION("shipped profile file") {
    const auto r = run_program(
        SCANMESH_EXE, dir,
        {"device", "read", "--driver", "modbus-sensor", "--tcp", tcp, "--profile",
         std::string(SCANMESH_SOURCE_DIR) + "/config/devices/baumer-om30.toml", "--samples", "4",
         "--json"});
    INFO(r.out << r.err);
    REQUIRE(r.status == 0);
    check_values(json_lines(r.out), 4);
  }
  SECTION("a sensor configuration file, with the address overridden on the command line") {
    const auto r = run_program(
        SCANMESH_EXE, dir,
        {"device", "read", "--config",
         std::string(SCANMESH_SOURCE_DIR) + "/config/sensors/baumer-om30-tcp.toml", "--tcp", tcp,
         "--samples", "3", "--json"});
    INFO(r.out << r.err);
    REQUIRE(r.status == 0);
    check_values(json_lines(r.out), 3);
  }
  SECTION("nobody listening: exit status 5 naming the device and the address") {
    emu.vanish();
    const auto r = run_program(SCANMESH_EXE, dir,
                               {"device", "read", "--driver", "modbus-sensor", "--tcp", tcp,
                                "--samples", "1", "--json"});
    CHECK(r.status == 5);
    CHECK(r.err.find("modbus-sensor") != std::string::npos);
    CHECK(r.err.find(tcp.substr(0, tcp.find(':'))) != std::string::npos);
  }
}

TEST_CASE("device read: Baumer OM30 over Modbus RTU on a pty", "[drivers][cli][modbus]") {
  TempDir dir;
  scanmesh::sim::ModbusRtuEmulator emu((dir / "rs485").string(),
                                       scanmesh::sim::scripted_values({69.743, 12.5}),
                                       scanmesh::sim::baumer_om30_image());
  emu.start();
  const auto r = run_program(SCANMESH_EXE, dir,
                             {"device", "read", "--driver", "modbus-sensor", "--port", emu.port(),
                              "--baud", "115200", "--samples", "5", "--json"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  check_values(json_lines(r.out), 5);
}
#endif
