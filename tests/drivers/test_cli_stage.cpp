// `scanmesh stage` end to end: the real binary drives the GRBL emulator on a pty, the Modbus
// drive emulator over TCP (with the shipped profile) and the I++ DME server on 127.0.0.1; and
// `scanmesh devices` lists the stage drivers.
// SPDX-License-Identifier: MIT
#ifdef SCANMESH_EXE
#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "scanmesh/sim/emulators/grbl.hpp"
#include "scanmesh/sim/emulators/ippdme.hpp"
#include "scanmesh/sim/emulators/modbus_stage.hpp"
#include "support/process.hpp"
#include "support/stage_harness.hpp"

using nlohmann::json;
using scanmesh::test::run_program;
using scanmesh::test::TempDir;

TEST_CASE("stage: GRBL over a pty, status, move, jog, home, probe", "[drivers][cli][grbl]") {
  TempDir dir;
  scanmesh::sim::GrblEmulatorOptions o;
  o.motion.limits.linear_velocity_mm_s = 1000;
  o.motion.limits.linear_accel_mm_s2 = 20000;
  o.motion.start = {10, 15, 20, 0};
  o.motion.probe.scene = scanmesh::test::part_scene("steps");
  o.motion.probe.tip_radius_mm = 1;
  scanmesh::sim::GrblEmulator emu((dir / "grbl").string(), o);
  emu.start();
  const std::vector<std::string> base = {"--driver", "grbl", "--port", emu.port(), "--json"};
  auto stage = [&](std::vector<std::string> args) {
    args.insert(args.begin(), "stage");
    args.insert(args.end(), base.begin(), base.end());
    return run_program(SCANMESH_EXE, dir, args);
  };
  auto r = stage({"status"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  json j = json::parse(r.out);
  CHECK(j.at("status") == "idle");
  CHECK(j.at("position").at("x").get<double>() == Approx(10).margin(1e-3));
  CHECK(j.at("units").at("z") == "mm");
  r = stage({"move", "--x", "12.5", "--y", "15", "--feed", "6000"});
  REQUIRE(r.status == 0);
  CHECK(json::parse(r.out).at("position").at("x").get<double>() == Approx(12.5).margin(1e-3));
  r = stage({"jog", "--x", "-2.5", "--feed", "6000"});
  REQUIRE(r.status == 0);
  CHECK(json::parse(r.out).at("position").at("x").get<double>() == Approx(10).margin(1e-3));
  r = stage({"probe", "--from", "10,15,20", "--dir", "0,0,-1", "--travel", "20", "--tip-radius", "1",
             "--feed", "1200"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  j = json::parse(r.out);
  CHECK(j.at("outcome") == "point");
  CHECK(j.at("z_mm").get<double>() == Approx(10.0).margin(2e-3));  // the step's top
  CHECK(j.at("latched").at("z_mm").get<double>() == Approx(11.0).margin(2e-3));
  CHECK(j.at("compensated_by") == "tip_radius");
  r = stage({"probe", "--from", "10,15,20", "--dir", "0,0,-1", "--travel", "4"});
  REQUIRE(r.status == 0);
  CHECK(json::parse(r.out).at("outcome") == "no_contact");
  r = stage({"home"});
  REQUIRE(r.status == 0);
  CHECK(json::parse(r.out).at("position").at("z").get<double>() == Approx(0).margin(1e-3));
  const auto lines = emu.lines();
  CHECK(std::find(lines.begin(), lines.end(), "G90G1X12.5000Y15.0000F6000.0") != lines.end());
  CHECK(std::find(lines.begin(), lines.end(), "$J=G91X-2.5000F6000.0") != lines.end());
  CHECK(std::find(lines.begin(), lines.end(), "$H") != lines.end());
  // Nobody answers: exit status 5, naming the device.
  emu.set_faults({.silent = true});
  r = stage({"status", "--timeout", "100"});
  CHECK(r.status == 5);
  CHECK(r.err.find("grbl") != std::string::npos);
  CHECK(r.err.find("no reply within 100 ms") != std::string::npos);
}

TEST_CASE("stage: Modbus drives over TCP with the shipped profile", "[drivers][cli][modbus_stage]") {
  TempDir dir;
  scanmesh::sim::StageMotionOptions motion;
  motion.limits.linear_velocity_mm_s = 400;
  motion.limits.linear_accel_mm_s2 = 20000;
  auto model = std::make_shared<scanmesh::sim::ModbusStageModel>(scanmesh::sim::ModbusStageOptions{
      scanmesh::drivers::modbus_stage::leadshine_pr_map(), motion});
  scanmesh::sim::ModbusTcpEmulator emu(nullptr, {}, 1, 0);
  emu.set_handler(model);
  emu.start();
  const std::string tcp = "127.0.0.1:" + std::to_string(emu.port());
  const std::string profile = std::string(SCANMESH_SOURCE_DIR) + "/config/devices/leadshine-pr.toml";
  auto r = run_program(SCANMESH_EXE, dir,
                       {"stage", "move", "--driver", "modbus-stage", "--tcp", tcp, "--profile", profile,
                        "--x", "20", "--z", "-7.5", "--feed", "12000", "--json"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  const json j = json::parse(r.out);
  CHECK(j.at("status") == "idle");
  CHECK(j.at("position").at("x").get<double>() == Approx(20).margin(1e-3));
  CHECK(j.at("position").at("z").get<double>() == Approx(-7.5).margin(1e-3));
  r = run_program(SCANMESH_EXE, dir,
                  {"stage", "status", "--driver", "modbus-stage", "--tcp", tcp, "--profile", profile,
                   "--unit", "4"});
  CHECK(r.status == 2);  // --unit on a three-axis profile: a usage error naming it
  CHECK(r.err.find("single-axis") != std::string::npos);
  emu.vanish();
  r = run_program(SCANMESH_EXE, dir,
                  {"stage", "status", "--driver", "modbus-stage", "--tcp", tcp, "--timeout", "100"});
  CHECK(r.status == 5);
}

TEST_CASE("stage: an I++ DME CMM, probing compensated by the controller", "[drivers][cli][ippdme]") {
  TempDir dir;
  scanmesh::sim::IppDmeEmulatorOptions o;
  o.motion.limits.linear_velocity_mm_s = 500;
  o.motion.limits.linear_accel_mm_s2 = 10000;
  o.motion.start = {10, 15, 30, 0};
  o.motion.probe.scene = scanmesh::test::part_scene("steps");
  o.motion.probe.tip_radius_mm = 2;
  scanmesh::sim::IppDmeEmulator emu(o);
  emu.start();
  const std::string tcp = "127.0.0.1:" + std::to_string(emu.port());
  const auto r = run_program(SCANMESH_EXE, dir,
                             {"stage", "probe", "--driver", "ippdme", "--tcp", tcp, "--from",
                              "50,15,40", "--dir", "0,0,-1", "--travel", "12", "--json"});
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  const json j = json::parse(r.out);
  CHECK(j.at("outcome") == "point");
  CHECK(j.at("z_mm").get<double>() == Approx(30).margin(2e-3));  // the third step's top
  CHECK(j.at("compensated_by") == "controller");
  CHECK(j.at("normal").at(2).get<double>() == Approx(1));
}

TEST_CASE("devices lists the stage drivers", "[drivers][cli]") {
  TempDir dir;
  const auto r = run_program(SCANMESH_EXE, dir, {"devices", "--json"});
  REQUIRE(r.status == 0);
  std::vector<std::string> names;
  const json devices = json::parse(r.out);
  for (const auto& d : devices.at("stage_drivers")) names.push_back(d.at("driver").get<std::string>());
  CHECK(names == std::vector<std::string>{"grbl", "modbus-stage", "ippdme"});
}
#endif
