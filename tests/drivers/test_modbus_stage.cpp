// Modbus drive stages: register maps from register arrays (both word orders, scaling, negative
// positions, status bits, alarm names), the shipped profiles, and the driver against the drive
// emulator over Modbus TCP (XYZ Leadshine-style gantry) and RTU on a pty (Delta-style turntable).
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <cmath>
#include <map>
#include <numbers>
#include <set>
#include <thread>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/modbus_stage/codec.hpp"
#include "scanmesh/drivers/modbus_stage/device.hpp"
#include "scanmesh/drivers/modbus_stage/profile.hpp"
#include "scanmesh/drivers/transports/modbus_bus.hpp"
#include "scanmesh/sim/emulators/modbus_stage.hpp"
#include "support/process.hpp"
#include "support/stage_harness.hpp"

using namespace std::chrono_literals;
namespace drv = scanmesh::drivers;
namespace ms = scanmesh::drivers::modbus_stage;
using drv::StageAxis;
using drv::StageStatus;

TEST_CASE("modbus stage codec: 32-bit values in both word orders, negative, scaled", "[drivers][modbus_stage]") {
  const std::uint16_t high_first[] = {0xFFFE, 0x1DC0};  // -123456
  const std::uint16_t low_first[] = {0x1DC0, 0xFFFE};
  CHECK(ms::decode_value(ms::RegisterType::kI32, ms::WordOrder::kHighFirst, high_first) == -123456);
  CHECK(ms::decode_value(ms::RegisterType::kI32, ms::WordOrder::kLowFirst, low_first) == -123456);
  CHECK(ms::decode_value(ms::RegisterType::kU32, ms::WordOrder::kHighFirst, high_first) ==
        4294843840LL);
  // Delta's example: reading 0x0200 x2 gives 00B1 1F40 = 0x1F4000B1 (low word first).
  const std::uint16_t delta[] = {0x00B1, 0x1F40};
  CHECK(ms::decode_value(ms::RegisterType::kU32, ms::WordOrder::kLowFirst, delta) == 0x1F4000B1);
  const std::uint16_t minus_one[] = {0xFFFF};
  CHECK(ms::decode_value(ms::RegisterType::kI16, ms::WordOrder::kLowFirst, minus_one) == -1);
  std::uint16_t out[2];
  ms::encode_value(ms::RegisterType::kI32, ms::WordOrder::kHighFirst, 10000, out);
  CHECK((out[0] == 0x0000 && out[1] == 0x2710));  // the manual's 00 00 27 10
  ms::encode_value(ms::RegisterType::kI32, ms::WordOrder::kLowFirst, 3000, out);
  CHECK((out[0] == 0x0BB8 && out[1] == 0x0000));  // Delta's FC16 0BB8 0000 = 3000
  const ms::AxisMap axis{StageAxis::kX, 1, 2000, 0, 0};
  CHECK(ms::counts_to_units(axis, -123456) == Approx(-61.728));
  CHECK(ms::units_to_counts(axis, -61.728) == -123456);
  CHECK_THROWS_AS(ms::units_to_counts(axis, 2e6), scanmesh::ConfigError);
}

TEST_CASE("modbus stage codec: command writes and axis decoding", "[drivers][modbus_stage]") {
  const ms::StageRegisterMap lead = ms::leadshine_pr_map();
  // The PR0 block: mode, position high/low, rpm, ramp ms, ramp ms, dwell, trigger.
  const auto regs = ms::encode_write(lead, lead.move[0], 10000, 10.0, 1000.0);
  REQUIRE(regs.size() == 8);
  CHECK(regs == std::vector<std::uint16_t>{0x0001, 0x0000, 0x2710, 120, 83, 83, 0, 0x0010});
  const auto plan = ms::plan_reads(lead);
  REQUIRE(plan.size() == 3);  // 0x1003, 0x2203, 0x602A: too far apart to merge
  std::vector<std::uint16_t> image(plan[0].count + plan[1].count + plan[2].count, 0);
  image[0] = (1 << 2) | (1 << 4);  // moving, homed
  image[1] = 0x180;
  image[2] = 0xFFFE;
  image[3] = 0x1DC0;
  ms::AxisReading r = ms::decode_axis(lead, lead.axes[0], plan, image);
  CHECK(r.position == Approx(-61.728));
  CHECK(r.moving);
  CHECK(r.homed);
  CHECK_FALSE(r.fault);
  CHECK(r.alarm_code == 0x180);
  CHECK(ms::alarm_text(lead, 0x180) == "Er180 position following error too large");
  CHECK(ms::alarm_text(lead, 0x999) == "alarm 2457");

  const ms::StageRegisterMap delta = ms::delta_asda_map();
  const auto dplan = ms::plan_reads(delta);
  // The image of a plan with the given registers set (address -> value).
  auto image_of = [&](std::map<int, std::uint16_t> values) {
    std::vector<std::uint16_t> img;
    for (const auto& b : dplan)
      for (int a = b.address; a < b.address + b.count; ++a) img.push_back(values[a]);
    return img;
  };
  // P0-09 = 25000 PUU (90 degrees), low word first; P0-46 TPOS clear: moving.
  r = ms::decode_axis(delta, delta.axes[0], dplan, image_of({{0x0012, 25000}, {0x0013, 0}}));
  CHECK(r.position == Approx(90.0).margin(1e-6));
  CHECK(r.moving);  // in_position bit clear
  r = ms::decode_axis(delta, delta.axes[0], dplan,
                      image_of({{0x0012, 0x9E58}, {0x0013, 0xFFFF}, {0x005C, 1 << 4}}));
  CHECK(r.position == Approx(-90.0).margin(1e-6));  // -25000, low word first
  CHECK_FALSE(r.moving);
  r = ms::decode_axis(delta, delta.axes[0], dplan, image_of({{0x005C, 1 << 6}, {0x0002, 9}}));
  CHECK(r.fault);
  CHECK(r.alarm_code == 9);
}

TEST_CASE("modbus stage profiles: the shipped files equal the built-in maps", "[drivers][modbus_stage]") {
  const std::string dir = std::string(SCANMESH_SOURCE_DIR) + "/config/devices/";
  for (const auto& [file, builtin] :
       {std::pair{"leadshine-pr.toml", ms::leadshine_pr_map()},
        std::pair{"delta-asda.toml", ms::delta_asda_map()}}) {
    INFO(file);
    const ms::StageRegisterMap m = ms::load_stage_profile(dir + file);
    CHECK(m.profile == builtin.profile);
    CHECK(m.word_order == builtin.word_order);
    CHECK(m.position.address == builtin.position.address);
    CHECK(m.status.address == builtin.status.address);
    CHECK(m.alarm_names == builtin.alarm_names);
    CHECK(m.axes.size() == builtin.axes.size());
    CHECK(m.axes[0].counts_per_unit == Approx(builtin.axes[0].counts_per_unit).epsilon(1e-7));
    CHECK(m.speed_scale == Approx(builtin.speed_scale).epsilon(1e-7));
    for (std::size_t k = 0; k < m.move.size(); ++k)
      CHECK(ms::encode_write(m, m.move[k], -5000, 10, 500) ==
            ms::encode_write(builtin, builtin.move[k], -5000, 10, 500));
  }
  scanmesh::test::TempDir tmp;
  const auto bad = (tmp / "bad.toml").string();
  scanmesh::test::spit(bad, "profile = \"x\"\nword_order = \"middle\"\nposition = { address = 70000, type = \"f64\" }\n"
                            "[[move]]\naddress = 1\nvalues = [\"sped\"]\n[[axis]]\nname = \"w\"\nunit = 300\n");
  try {
    ms::load_stage_profile(bad);
    FAIL("no error");
  } catch (const scanmesh::ConfigError& e) {
    const std::string msg = e.what();
    CHECK(msg.find(bad) != std::string::npos);
    CHECK(msg.find("word_order") != std::string::npos);
    CHECK(msg.find("position.address") != std::string::npos);
    CHECK(msg.find("unknown type \"f64\"") != std::string::npos);
    CHECK(msg.find("unknown placeholder \"sped\"") != std::string::npos);
    CHECK(msg.find("axis[1].name") != std::string::npos);
    CHECK(msg.find("status: missing") != std::string::npos);
  }
}

// ---------------------------------------------------------------------------------------------

namespace {

scanmesh::sim::StageMotionOptions fast_axes() {
  scanmesh::sim::StageMotionOptions o;
  o.limits.linear_velocity_mm_s = 400;
  o.limits.linear_accel_mm_s2 = 20000;
  o.homing_speed_mm_s = 200;
  return o;
}

struct TcpGantry {
  std::shared_ptr<scanmesh::sim::ModbusStageModel> model;
  scanmesh::sim::ModbusTcpEmulator emulator;
  ms::Device device;
  scanmesh::test::StageCollector collector;

  explicit TcpGantry(scanmesh::sim::StageMotionOptions motion = fast_axes())
      : model(std::make_shared<scanmesh::sim::ModbusStageModel>(
            scanmesh::sim::ModbusStageOptions{ms::leadshine_pr_map(), motion})),
        emulator(nullptr, {}, 1, 0),
        device(scanmesh::test::fast_stage_options("gantry"),
               [this] {
                 emulator.set_handler(model);
                 emulator.start();
                 return scanmesh::test::tcp_modbus_factory("gantry", emulator.port(), 150ms);
               }(),
               ms::leadshine_pr_map()) {
    device.open();
    device.start(collector.callbacks());
    REQUIRE(collector.wait_for(2));
  }
  ~TcpGantry() { device.close(); }
};

}  // namespace

TEST_CASE("modbus stage driver: an XYZ gantry over Modbus TCP", "[drivers][modbus_stage]") {
  auto motion = fast_axes();
  motion.start = {10, 20, -5, 0};
  TcpGantry g(motion);
  CHECK(g.device.identify().vendor == "Leadshine");
  auto r = g.device.status();
  CHECK(r.pose.x_mm == Approx(10).margin(1e-3));
  CHECK(r.pose.z_mm == Approx(-5).margin(1e-3));  // negative counts, high word first
  g.device.move_to({50.0, 40.0, -20.0, std::nullopt}, 6000);
  r = g.device.wait_idle(5s);
  REQUIRE(r.status == StageStatus::kIdle);
  CHECK(scanmesh::test::distance(r.pose, {50, 40, -20, 0}) < 1e-3);
  // The wire: one FC16 of 8 registers at 0x6200 per moving axis, on units 1, 2, 3.
  int block_writes = 0;
  std::set<int> units;
  for (const auto& q : g.emulator.requests())
    if (q.function == 16 && q.address == 0x6200 && q.count == 8) {
      ++block_writes;
      units.insert(q.unit);
    }
  CHECK(block_writes == 3);
  CHECK(units == std::set<int>{1, 2, 3});
  g.device.move_by({std::nullopt, -15.0, std::nullopt, std::nullopt}, 6000);
  CHECK(g.device.wait_idle(5s).pose.y_mm == Approx(25).margin(1e-3));

  SECTION("homing") {
    g.device.home();
    CHECK(g.device.status().status == StageStatus::kHoming);
    r = g.device.wait_idle(8s);
    CHECK(r.status == StageStatus::kIdle);
    CHECK(scanmesh::test::distance(r.pose, {0, 0, 0, 0}) < 1e-3);
  }
  SECTION("a drive alarm is reported by name, reset clears it") {
    g.model->raise_alarm(StageAxis::kY, 0x180);
    REQUIRE(scanmesh::test::wait_until([&] { return g.device.status().status == StageStatus::kAlarm; }));
    r = g.device.status();
    CHECK(r.alarm_code == 0x180);
    CHECK(r.alarm_text == "y: Er180 position following error too large");
    g.device.clear_alarm();
    CHECK(g.device.wait_idle(2s).status == StageStatus::kIdle);
  }
  SECTION("halt stops the axes where they are") {
    g.device.move_to({300.0, std::nullopt, std::nullopt, std::nullopt}, 600);
    REQUIRE(scanmesh::test::wait_until([&] { return g.device.status().pose.x_mm > 51; }));
    g.device.halt();
    r = g.device.wait_idle(2s);
    CHECK(r.status == StageStatus::kIdle);
    CHECK(r.pose.x_mm < 299);
  }
  SECTION("Modbus exceptions are error replies; silence is a loss, then a reconnect") {
    g.emulator.set_faults({.exception = 4});
    REQUIRE(scanmesh::test::wait_until([&] { return g.device.stats().error_replies >= 3; }));
    CHECK_THROWS_AS(g.device.move_to({1.0, {}, {}, {}}, 600), drv::DeviceError);
    g.emulator.set_faults({.silent = true});
    REQUIRE(scanmesh::test::wait_until([&] { return g.device.state() == drv::DeviceState::kLost; }));
    CHECK(g.collector.saw(drv::DeviceState::kLost, "gantry"));
    CHECK(g.collector.saw(drv::DeviceState::kLost, "consecutive timeouts"));
    g.emulator.set_faults({});
    REQUIRE(scanmesh::test::wait_until([&] { return g.device.state() == drv::DeviceState::kAcquiring; }));
    CHECK(g.collector.resumes(3));
  }
  SECTION("the server vanishes and comes back") {
    g.emulator.vanish();
    REQUIRE(scanmesh::test::wait_until([&] { return g.device.state() == drv::DeviceState::kLost; }));
    g.emulator.reappear();
    REQUIRE(scanmesh::test::wait_until([&] { return g.device.state() == drv::DeviceState::kAcquiring; }));
    CHECK(g.device.stats().reconnects >= 1);
    CHECK(g.collector.resumes(3));
  }
  g.device.stop();
  const std::size_t after = g.collector.count();
  std::this_thread::sleep_for(40ms);
  CHECK(g.collector.count() == after);
}

TEST_CASE("modbus stage driver: probing latches in the drives", "[drivers][modbus_stage][probe]") {
  auto motion = fast_axes();
  motion.probe.scene = scanmesh::test::part_scene("steps");
  motion.probe.tip_radius_mm = 1.0;
  motion.start = {10, 15, 20, 0};
  TcpGantry g(motion);
  SECTION("contact on the first step's top (z = 10)") {
    const auto r = g.device.probe_move({0, 0, -1, 20, 600});
    REQUIRE(r.outcome == drv::ProbeMoveResult::Outcome::kContact);
    CHECK(r.trigger.pose.z_mm == Approx(11.0).margin(2e-3));
    CHECK(r.trigger.pose.x_mm == Approx(10.0).margin(1e-3));
    REQUIRE(scanmesh::test::wait_until([&] { return g.collector.probes().size() == 1; }));
  }
  SECTION("no contact within the travel") {
    CHECK(g.device.probe_move({0, 0, -1, 5, 600}).outcome ==
          drv::ProbeMoveResult::Outcome::kNoContact);
  }
  SECTION("a probe that never triggers") {
    g.model->set_probe_never_triggers(true);
    CHECK(g.device.probe_move({0, 0, -1, 20, 1200}).outcome ==
          drv::ProbeMoveResult::Outcome::kNoContact);
  }
  SECTION("deflected before the move") {
    g.device.move_to({std::nullopt, std::nullopt, 10.5, std::nullopt}, 6000);
    g.device.wait_idle(3s);
    CHECK(g.device.probe_move({0, 0, -1, 5, 600}).outcome ==
          drv::ProbeMoveResult::Outcome::kTriggeredAtStart);
  }
}

TEST_CASE("modbus stage driver: a Delta-style turntable over Modbus RTU on a pty", "[drivers][modbus_stage]") {
  scanmesh::test::TempDir dir;
  auto motion = fast_axes();
  motion.limits.linear_velocity_mm_s = 360;  // deg/s for this drive
  motion.start = {0, 0, 0, std::numbers::pi / 4};
  auto model = std::make_shared<scanmesh::sim::ModbusStageModel>(
      scanmesh::sim::ModbusStageOptions{ms::delta_asda_map(), motion});
  scanmesh::sim::ModbusRtuEmulator emulator((dir / "rs485").string(), nullptr, {}, 1);
  emulator.set_handler(model);
  emulator.start();
  const std::string link = (dir / "rs485").string();
  ms::Device device(scanmesh::test::fast_stage_options("table", 200ms),
                    [link] { return drv::open_modbus_rtu("table", link, 115200, 'N', 8, 1, 1, 200ms); },
                    ms::delta_asda_map());
  scanmesh::test::StageCollector collector;
  device.open();
  device.start(collector.callbacks());
  REQUIRE(collector.wait_for(2));
  CHECK(device.status().pose.a_rad == Approx(std::numbers::pi / 4).margin(1e-4));
  // The init write selected the monitored value (P0-17 = 0) before anything else.
  const auto req = emulator.requests();
  REQUIRE(!req.empty());
  CHECK(req.front().function == 16);
  CHECK(req.front().address == 0x0022);
  device.move_to({std::nullopt, std::nullopt, std::nullopt, std::numbers::pi}, 360 * 60);
  const auto r = device.wait_idle(5s);
  CHECK(r.status == StageStatus::kIdle);
  CHECK(r.pose.a_rad == Approx(std::numbers::pi).margin(1e-4));
  model->raise_alarm(StageAxis::kA, 9);
  REQUIRE(scanmesh::test::wait_until([&] { return device.status().status == StageStatus::kAlarm; }));
  CHECK(device.status().alarm_text == "a: AL009 position control error too large");
  device.close();
}
