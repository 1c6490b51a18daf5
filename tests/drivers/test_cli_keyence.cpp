// `scanmesh device read` end to end: the real binary opens the real serial transport on the pty
// of a KEYENCE LK-G emulator running in this test process.
// SPDX-License-Identifier: MIT
#ifdef SCANMESH_EXE
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "scanmesh/sim/emulators/keyence_lkg.hpp"
#include "support/json_lines.hpp"
#include "support/process.hpp"
#include "support/temp_dir.hpp"

using namespace std::chrono_literals;
using nlohmann::json;
using scanmesh::test::json_lines;
using scanmesh::test::run_program;
using scanmesh::test::TempDir;

TEST_CASE("device read: N samples from an LK-G emulator as JSON lines", "[drivers][cli]") {
  TempDir dir;
  const double inf = std::numeric_limits<double>::infinity();
  scanmesh::sim::KeyenceLkgEmulator emu((dir / "lkg").string(),
                                        scanmesh::sim::scripted_values({1.2345, -0.012, inf}));
  emu.start();
  const auto r = run_program(SCANMESH_EXE, dir,
                             {"device", "read", "--driver", "keyence-lkg", "--port", emu.port(),
                              "--samples", "6", "--json"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  const auto lines = json_lines(r.out);
  REQUIRE(lines.size() == 6);
  std::int64_t last_t = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const json& j = lines[i];
    CHECK(j.at("seq").get<std::uint64_t>() == i);
    CHECK(j.at("t_host_ns").get<std::int64_t>() > last_t);
    last_t = j.at("t_host_ns").get<std::int64_t>();
    REQUIRE(j.contains("value_mm"));
    REQUIRE(j.contains("status"));
  }
  // The emulator measured 1.2345, -0.012, over range, 1.2345, ... in the order it was asked.
  int ok = 0, over = 0;
  for (const json& j : lines) {
    if (j["status"] == "ok") {
      ++ok;
      const double v = j["value_mm"].get<double>();
      CHECK((std::abs(v - 1.2345) < 1e-9 || std::abs(v + 0.012) < 1e-9));
    } else {
      CHECK(j["status"] == "over_range");
      CHECK(j["value_mm"].is_null());
      ++over;
    }
  }
  CHECK(ok == 4);
  CHECK(over == 2);
  // Only measurement requests went over the wire (plus whatever open() sent to identify).
  CHECK(emu.received().find("M0\r") != std::string::npos);
}

TEST_CASE("device read: a device that does not answer is exit status 5 within seconds",
          "[drivers][cli]") {
  TempDir dir;
  scanmesh::sim::KeyenceLkgEmulator emu((dir / "lkg").string(),
                                        scanmesh::sim::scripted_values({1.0}));
  emu.set_faults({.silent = true});
  emu.start();
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = run_program(SCANMESH_EXE, dir,
                             {"device", "read", "--driver", "keyence-lkg", "--port", emu.port(),
                              "--samples", "3", "--json"});
  const auto dt = std::chrono::steady_clock::now() - t0;
  INFO(r.out << r.err);
  CHECK(r.status == 5);
  CHECK(dt < 10s);
  CHECK(r.out.empty());
  CHECK(r.err.find("keyence-lkg") != std::string::npos);
  CHECK(r.err.find(emu.port()) != std::string::npos);
}

TEST_CASE("device read: usage errors are exit status 2", "[drivers][cli]") {
  TempDir dir;
  auto r = run_program(SCANMESH_EXE, dir,
                       {"device", "read", "--driver", "no-such", "--port", "/dev/null",
                        "--samples", "1"});
  CHECK(r.status == 2);
  CHECK(r.err.find("keyence-lkg") != std::string::npos);  // lists the known drivers
  r = run_program(SCANMESH_EXE, dir, {"device", "read", "--driver", "keyence-lkg", "--samples", "1"});
  CHECK(r.status == 2);
  r = run_program(SCANMESH_EXE, dir,
                  {"device", "read", "--driver", "keyence-lkg", "--port", "x", "--tcp",
                   "127.0.0.1:502", "--samples", "1"});
  CHECK(r.status == 2);
}

TEST_CASE("devices: lists serial ports as JSON", "[drivers][cli]") {
  TempDir dir;
  const auto r = run_program(SCANMESH_EXE, dir, {"devices", "--json"});
  REQUIRE(r.status == 0);
  const json j = json::parse(r.out);
  REQUIRE(j.at("serial_ports").is_array());
  REQUIRE(j.at("usb_devices").is_array());
  for (const json& p : j["serial_ports"]) {
    CHECK(p.at("path").get<std::string>().rfind("/dev/", 0) == 0);
  }
}
#endif
