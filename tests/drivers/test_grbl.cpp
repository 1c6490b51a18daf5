// GRBL: codec tables from byte strings (status reports, ok/error, alarms, probe reports, messages,
// split at every byte), line encoding, and the driver against the GRBL emulator on a pty over
// the real serial transport (flow control, moves, jog, hold, halt, homing, alarms, probing,
// faults, reconnect, an external trajectory).
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <sstream>
#include <thread>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/grbl/codec.hpp"
#include "scanmesh/drivers/grbl/device.hpp"
#include "scanmesh/sim/emulators/grbl.hpp"
#include "support/codec_table.hpp"
#include "support/stage_harness.hpp"

using namespace std::chrono_literals;
namespace drv = scanmesh::drivers;
namespace grbl = scanmesh::drivers::grbl;
using drv::StageStatus;
using scanmesh::test::CodecCase;

namespace {

std::string axes_text(const grbl::AxisValues& a) {
  std::ostringstream o;
  for (int k = 0; k < a.count; ++k) o << (k ? "," : "") << a.v[k];
  return o.str();
}

std::string describe(const grbl::Reply& r) {
  switch (r.kind) {
    case grbl::ReplyKind::kOk:
      return "ok";
    case grbl::ReplyKind::kError:
      return "error:" + std::to_string(r.code);
    case grbl::ReplyKind::kAlarm:
      return "ALARM:" + std::to_string(r.code);
    case grbl::ReplyKind::kStatus: {
      const auto& s = r.status;
      std::string out = std::string(grbl::to_string(s.state));
      if (s.substate >= 0) out += ":" + std::to_string(s.substate);
      out += (s.machine_pos ? "|M:" : "|W:") + axes_text(s.pos);
      if (s.has_feed) {
        std::ostringstream o;
        o << "|F:" << s.feed << "," << s.spindle;
        out += o.str();
      }
      if (s.has_wco) out += "|WCO:" + axes_text(s.wco);
      if (s.has_buffer)
        out += "|Bf:" + std::to_string(s.planner_free) + "," + std::to_string(s.rx_free);
      if (s.line >= 0) out += "|Ln:" + std::to_string(s.line);
      if (s.has_pins) out += "|Pn:" + std::to_string(s.pins);
      if (s.has_overrides)
        out += "|Ov:" + std::to_string(s.overrides[0]) + "," + std::to_string(s.overrides[1]) +
               "," + std::to_string(s.overrides[2]);
      return out;
    }
    case grbl::ReplyKind::kProbe:
      return "PRB:" + axes_text(r.probe.pos) + (r.probe.success ? ":1" : ":0");
    case grbl::ReplyKind::kMessage:
      return "[" + std::string(r.tag) + "|" + std::string(r.text) + "]";
    case grbl::ReplyKind::kWelcome:
      return "welcome:" + std::string(r.text);
    case grbl::ReplyKind::kSetting:
      return "$" + std::to_string(r.code) + "=" + std::string(r.text);
    case grbl::ReplyKind::kStartup:
      return ">" + std::string(r.text);
  }
  return "?";
}

}  // namespace

TEST_CASE("grbl codec: every reply kind from byte strings", "[drivers][grbl]") {
  const std::vector<CodecCase> cases = {
      {"ok", "ok\r\n", {"ok"}, 0},
      {"error with its number", "error:9\r\n", {"error:9"}, 0},
      {"alarm push", "ALARM:1\r\n", {"ALARM:1"}, 0},
      {"idle report, 1.1 default fields", "<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:1.000,2.000,-3.500>\r\n",
       {"Idle|M:0,0,0|F:0,0|WCO:1,2,-3.5"}, 0},
      {"run report, negative positions, WPos, buffer, line",
       "<Run|WPos:-12.345,6.000,-0.001|Bf:15,128|Ln:42|FS:1500,0>\r\n",
       {"Run|W:-12.345,6,-0.001|F:1500,0|Bf:15,128|Ln:42"}, 0},
      {"four axes (rotary A in degrees), pins, overrides",
       "<Jog|MPos:1.000,2.000,3.000,90.000|F:500|Pn:XP|Ov:100,100,100>\r\n",
       {"Jog|M:1,2,3,90|F:500,0|Pn:17|Ov:100,100,100"}, 0},
      {"hold with substate", "<Hold:0|MPos:5.000,0.000,0.000|FS:0,0>\r\n", {"Hold:0|M:5,0,0|F:0,0"}, 0},
      {"door with substate", "<Door:1|MPos:5.000,0.000,0.000>\r\n", {"Door:1|M:5,0,0"}, 0},
      {"alarm and home states", "<Alarm|MPos:0.000,0.000,0.000>\r\n<Home|MPos:0.000,0.000,0.000>\r\n",
       {"Alarm|M:0,0,0", "Home|M:0,0,0"}, 0},
      {"grblHAL fields it does not know are skipped", "<Idle|MPos:1.000,2.000,3.000|FS:0,0|H:1,7|SD:0>\r\n",
       {"Idle|M:1,2,3|F:0,0"}, 0},
      {"probe contact", "[PRB:10.000,-2.500,11.000:1]\r\n", {"PRB:10,-2.5,11:1"}, 0},
      {"probe without contact", "[PRB:0.000,0.000,-10.000:0]\r\n", {"PRB:0,0,-10:0"}, 0},
      {"messages", "[MSG:Caution: Unlocked]\r\n[VER:1.1h.20190825:]\r\n[OPT:V,15,128]\r\n",
       {"[MSG|Caution: Unlocked]", "[VER|1.1h.20190825:]", "[OPT|V,15,128]"}, 0},
      {"Grbl 0.9 message without tag", "[Caution: Unlocked]\r\n", {"[|Caution: Unlocked]"}, 0},
      {"welcome banner", "\r\nGrbl 1.1h ['$' for help]\r\n", {"welcome:Grbl 1.1h ['$' for help]"}, 0},
      {"setting and startup line", "$10=1\r\n>G54G20:ok\r\n", {"$10=1", ">G54G20"}, 0},
      {"two replies in one chunk, LF only", "ok\nerror:20\n", {"ok", "error:20"}, 0},
      {"leading garbage glued to a reply", "~#ok\r\n", {"ok"}, 1},
      {"noise bytes are dropped by the framer", std::string("\xFE\x13ok\r\n", 6), {"ok"}, 0},
      {"truncated reply: nothing yet", "<Idle|MPos:0.000,0.0", {}, 0},
      {"status without '>'", "<Idle|MPos:0.000,0.000,0.000\r\n", {}, 1},
      {"unknown state", "<Walk|MPos:0.000,0.000,0.000>\r\n", {}, 1},
      {"bad number", "<Idle|MPos:0.0x0,0.000,0.000>\r\n", {}, 1},
      {"no position field", "<Idle|FS:0,0>\r\n", {}, 1},
      {"two position fields", "<Idle|MPos:0,0,0|WPos:0,0,0>\r\n", {}, 1},
      {"empty axis", "<Idle|MPos:1,,3>\r\n", {}, 1},
      {"too many axes", "<Idle|MPos:1,2,3,4,5,6,7>\r\n", {}, 1},
      {"substate on a state without one", "<Idle:1|MPos:0,0,0>\r\n", {}, 1},
      {"bad error code", "error:x\r\n", {}, 1},
      {"bad probe flag", "[PRB:1,2,3:2]\r\n", {}, 1},
      {"unknown reply", "hello\r\n", {}, 1},
  };
  scanmesh::test::check_codec_table<grbl::Decoder>(cases, describe);
}

TEST_CASE("grbl codec: a stream split at every byte decodes the same", "[drivers][grbl]") {
  const std::string stream =
      "ok\r\n<Run|MPos:-1.500,2.250,3.000,45.000|FS:600,0|Pn:P>\r\nerror:9\r\nALARM:5\r\n"
      "[PRB:1.000,2.000,3.000:0]\r\n[MSG:Reset to continue]\r\nGrbl 1.1h ['$' for help]\r\n";
  scanmesh::test::check_split_at_every_byte<grbl::Decoder>(stream, 7, describe);
}

TEST_CASE("grbl codec: lines sent and the tables of codes", "[drivers][grbl]") {
  CHECK(grbl::move_line(true, {10.0, -2.5, std::nullopt, std::nullopt}, 600) ==
        "G90G1X10.0000Y-2.5000F600.0\n");
  CHECK(grbl::move_line(false, {std::nullopt, std::nullopt, 1.0, 90.0}, 1000) ==
        "G91G1Z1.0000A90.0000F1000.0\n");
  CHECK(grbl::jog_line({5.0, std::nullopt, std::nullopt, std::nullopt}, 300) ==
        "$J=G91X5.0000F300.0\n");
  CHECK(grbl::probe_line({std::nullopt, std::nullopt, -10.0, std::nullopt}, 100) ==
        "G91G38.2Z-10.0000F100.0\n");
  CHECK_THROWS_AS(grbl::move_line(true, {}, 100), scanmesh::ConfigError);
  CHECK_THROWS_AS(grbl::move_line(true, {1.0, {}, {}, {}}, 0), scanmesh::ConfigError);
  CHECK_THROWS_AS(grbl::move_line(true, {std::nan(""), {}, {}, {}}, 10), scanmesh::ConfigError);
  CHECK_THROWS_AS(grbl::move_line(true, {1e70, 1e70, 1e70, 1e70}, 10), scanmesh::ConfigError);
  CHECK(grbl::error_text(9) == "G-code locked out during alarm or jog state.");
  CHECK(grbl::error_text(22) == "Feed rate has not yet been set or is undefined.");
  CHECK(grbl::alarm_text(1).substr(0, 21) == "Hard limit triggered.");
  CHECK(grbl::alarm_text(5).find("did not contact") != std::string_view::npos);
  CHECK(grbl::alarm_text(99) == "unknown alarm");
}

// ---------------------------------------------------------------------------------------------
// Driver against the emulator

namespace {

struct GrblBench {
  scanmesh::test::TempDir dir;
  scanmesh::sim::GrblEmulator emulator;
  grbl::Device device;
  scanmesh::test::StageCollector collector;

  explicit GrblBench(scanmesh::sim::GrblEmulatorOptions emu = {}, grbl::Options options = {},
                     std::chrono::milliseconds timeout = 400ms)
      : emulator((dir / "grbl").string(), std::move(emu)),
        device(scanmesh::test::fast_stage_options("grbl0", timeout),
               scanmesh::test::pty_serial_factory("grbl0", (dir / "grbl").string(), 115200),
               options) {
    emulator.start();
    device.open();
    device.start(collector.callbacks());
    REQUIRE(collector.wait_for(2));
  }
  ~GrblBench() { device.close(); }
};

scanmesh::sim::GrblEmulatorOptions fast_motion() {
  scanmesh::sim::GrblEmulatorOptions o;
  o.motion.limits.linear_velocity_mm_s = 2000;
  o.motion.limits.linear_accel_mm_s2 = 20000;
  o.motion.homing_speed_mm_s = 500;
  return o;
}

}  // namespace

TEST_CASE("grbl driver: identity, status reports, absolute and relative moves", "[drivers][grbl]") {
  GrblBench b(fast_motion());
  CHECK(b.device.identify().firmware == "1.1h.20190825:");
  CHECK(b.device.identify().vendor == "Grbl");
  CHECK(b.device.status().status == StageStatus::kIdle);
  b.device.move_to({10.0, 5.0, -2.0, std::nullopt}, 3000);
  auto r = b.device.wait_idle(4s);
  REQUIRE(r.status == StageStatus::kIdle);
  CHECK(r.pose.x_mm == Approx(10.0).margin(1e-3));
  CHECK(r.pose.y_mm == Approx(5.0).margin(1e-3));
  CHECK(r.pose.z_mm == Approx(-2.0).margin(1e-3));
  b.device.move_by({-4.0, std::nullopt, std::nullopt, std::nullopt}, 3000);
  r = b.device.wait_idle(4s);
  CHECK(r.pose.x_mm == Approx(6.0).margin(1e-3));
  // Bytes on the wire, as the emulator took them from its receive buffer.
  const auto lines = b.emulator.lines();
  CHECK(std::find(lines.begin(), lines.end(), "G90G1X10.0000Y5.0000Z-2.0000F3000.0") != lines.end());
  CHECK(std::find(lines.begin(), lines.end(), "G91G1X-4.0000F3000.0") != lines.end());
  // Reports: gap-free sequence, host times increasing, some of them while moving.
  const auto samples = b.collector.copy();
  bool saw_moving = false;
  for (std::size_t k = 1; k < samples.size(); ++k) {
    CHECK(samples[k].seq == samples[k - 1].seq + 1);
    CHECK(samples[k].t >= samples[k - 1].t);
    saw_moving = saw_moving || samples[k].status == StageStatus::kMoving;
  }
  CHECK(saw_moving);
  CHECK(b.device.stats().timeouts == 0);
}

TEST_CASE("grbl driver: character counting never overflows the receive buffer", "[drivers][grbl]") {
  auto emu = fast_motion();
  emu.rx_buffer_bytes = 64;  // the driver learns it from [OPT:V,15,64]
  emu.planner_blocks = 4;
  GrblBench b(emu);
  CHECK(b.device.rx_buffer_bytes() == 64);
  // Four threads pipeline 12 relative moves each: lines wait in the controller's buffer while the
  // planner is full, so only character counting keeps the buffer from overflowing.
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&] {
      for (int k = 0; k < 12; ++k) b.device.move_by({0.5, std::nullopt, std::nullopt, std::nullopt}, 6000);
    });
  for (auto& t : threads) t.join();
  const auto r = b.device.wait_idle(8s);
  CHECK(r.pose.x_mm == Approx(24.0).margin(1e-3));
  CHECK(b.emulator.rx_overflows() == 0);
  CHECK(b.emulator.max_rx_fill() <= 63);
  CHECK(b.emulator.max_rx_fill() > 22);  // more than one line was in flight
}

TEST_CASE("grbl driver: jog, feed hold, cycle start, halt", "[drivers][grbl]") {
  auto emu = fast_motion();
  emu.motion.limits.linear_velocity_mm_s = 50;
  GrblBench b(emu);
  SECTION("feed hold freezes the axes, cycle start finishes the move") {
    b.device.move_to({20.0, std::nullopt, std::nullopt, std::nullopt}, 3000);
    REQUIRE(scanmesh::test::wait_until([&] { return b.device.status().pose.x_mm > 1.0; }));
    b.device.feed_hold();
    REQUIRE(scanmesh::test::wait_until([&] { return !b.emulator.motion().moving(drv::monotonic_now()); }));
    const double held = b.emulator.motion().pose(drv::monotonic_now()).x_mm;
    CHECK(held < 20.0);
    CHECK(b.device.status().status == StageStatus::kMoving);  // Hold: a move still pending
    b.device.cycle_start();
    const auto r = b.device.wait_idle(4s);
    CHECK(r.pose.x_mm == Approx(20.0).margin(1e-3));
  }
  SECTION("halt during a jog keeps the position and accepts the next move") {
    b.device.jog({100.0, std::nullopt, std::nullopt, std::nullopt}, 3000);
    REQUIRE(scanmesh::test::wait_until([&] { return b.device.status().pose.x_mm > 1.0; }));
    b.device.halt();
    auto r = b.device.wait_idle(4s);
    CHECK(r.status == StageStatus::kIdle);
    CHECK(r.pose.x_mm < 100.0);
    CHECK(r.alarm_code == 0);
    b.device.move_to({0.0, std::nullopt, std::nullopt, std::nullopt}, 3000);
    r = b.device.wait_idle(6s);
    CHECK(r.pose.x_mm == Approx(0.0).margin(1e-3));
    const auto lines = b.emulator.lines();
    CHECK(std::find(lines.begin(), lines.end(), "$J=G91X100.0000F3000.0") != lines.end());
  }
}

TEST_CASE("grbl driver: homing lock, $H, alarms by number and meaning, error replies", "[drivers][grbl]") {
  auto emu = fast_motion();
  emu.homing_lock = true;
  emu.motion.start = {30, 20, 10, 0};
  emu.motion.home = {0, 0, 0, 0};
  GrblBench b(emu);
  CHECK(b.device.status().status == StageStatus::kAlarm);
  // Locked: G-code is refused with error:9 and its meaning.
  try {
    b.device.move_to({1.0, std::nullopt, std::nullopt, std::nullopt}, 1000);
    FAIL("no error");
  } catch (const drv::DeviceError& e) {
    CHECK(e.kind() == drv::DeviceErrorKind::kProtocol);
    CHECK(std::string(e.what()).find("error:9: G-code locked out") != std::string::npos);
    CHECK(std::string(e.what()).find("grbl0") != std::string::npos);
  }
  CHECK(b.device.stats().error_replies == 1);
  b.device.home();
  auto r = b.device.wait_idle(8s);
  REQUIRE(r.status == StageStatus::kIdle);
  CHECK(scanmesh::test::distance(r.pose, {0, 0, 0, 0}) < 1e-3);
  CHECK(b.device.stats().timeouts == 0);  // no report during homing is not a timeout

  b.emulator.raise_alarm(1);
  REQUIRE(scanmesh::test::wait_until([&] { return b.device.status().status == StageStatus::kAlarm; }));
  r = b.device.status();
  CHECK(r.alarm_code == 1);
  CHECK(r.alarm_text.find("Hard limit triggered") != std::string::npos);
  b.device.clear_alarm();
  r = b.device.wait_idle(2s);
  CHECK(r.status == StageStatus::kIdle);
  b.device.move_to({2.0, std::nullopt, std::nullopt, std::nullopt}, 3000);
  CHECK(b.device.wait_idle(4s).pose.x_mm == Approx(2.0).margin(1e-3));
}

TEST_CASE("grbl driver: G38.2 probing on the reference mesh", "[drivers][grbl][probe]") {
  auto emu = fast_motion();
  emu.motion.probe.scene = scanmesh::test::part_scene("steps");  // top of the first step: z = 10
  emu.motion.probe.tip_radius_mm = 1.0;
  emu.motion.start = {10, 15, 20, 0};
  GrblBench b(emu);
  SECTION("contact: the latched tip centre, also delivered to on_probe") {
    const auto r = b.device.probe_move({0, 0, -1, 20, 600});
    REQUIRE(r.outcome == drv::ProbeMoveResult::Outcome::kContact);
    CHECK(r.trigger.pose.z_mm == Approx(11.0).margin(2e-3));
    CHECK(r.trigger.pose.x_mm == Approx(10.0).margin(1e-3));
    REQUIRE(scanmesh::test::wait_until([&] { return b.collector.probes().size() == 1; }));
    CHECK(b.collector.probes()[0].pose.z_mm == Approx(11.0).margin(2e-3));
    const auto lines = b.emulator.lines();
    CHECK(std::find(lines.begin(), lines.end(), "G91G38.2Z-20.0000F600.0") != lines.end());
    CHECK(b.device.wait_idle(2s).status == StageStatus::kIdle);
  }
  SECTION("no contact within the travel: ALARM:5, unlocked again") {
    const auto r = b.device.probe_move({0, 0, -1, 5, 600});
    CHECK(r.outcome == drv::ProbeMoveResult::Outcome::kNoContact);
    CHECK(r.device_code == 5);
    CHECK(b.device.wait_idle(2s).status == StageStatus::kIdle);
    CHECK(b.collector.probes().empty());
  }
  SECTION("a probe that never triggers") {
    b.emulator.set_probe_never_triggers(true);
    const auto r = b.device.probe_move({0, 0, -1, 20, 600});
    CHECK(r.outcome == drv::ProbeMoveResult::Outcome::kNoContact);
  }
  SECTION("deflected before the move: ALARM:4") {
    b.device.move_to({std::nullopt, std::nullopt, 10.5, std::nullopt}, 3000);  // tip in the step
    b.device.wait_idle(2s);
    const auto r = b.device.probe_move({0, 0, -1, 5, 600});
    CHECK(r.outcome == drv::ProbeMoveResult::Outcome::kTriggeredAtStart);
    CHECK(r.device_code == 4);
  }
}

TEST_CASE("grbl driver: faults, loss and reconnect", "[drivers][grbl]") {
  GrblBench b(fast_motion());
  SECTION("garbage before every reply") {
    b.emulator.set_faults({.garbage_before_reply = true});
    REQUIRE(scanmesh::test::wait_until([&] { return b.device.stats().malformed >= 3; }));
    CHECK(b.collector.resumes(5));
    b.device.move_to({3.0, std::nullopt, std::nullopt, std::nullopt}, 3000);
    CHECK(b.device.wait_idle(4s).pose.x_mm == Approx(3.0).margin(1e-3));
  }
  SECTION("every byte written alone") {
    b.emulator.set_faults({.split_every_byte = true});
    CHECK(b.collector.resumes(5));
    CHECK(b.device.stats().malformed == 0);
  }
  SECTION("a silent controller is lost, then found again") {
    b.emulator.set_faults({.silent = true});
    REQUIRE(scanmesh::test::wait_until([&] { return b.device.state() == drv::DeviceState::kLost; }));
    CHECK(b.collector.saw(drv::DeviceState::kLost, "grbl0"));
    CHECK(b.collector.saw(drv::DeviceState::kLost, "no status report within 400 ms, 3 times"));
    CHECK(b.device.status().status == StageStatus::kLost);
    CHECK_THROWS_AS(b.device.move_to({1.0, {}, {}, {}}, 100), drv::DeviceError);
    b.emulator.set_faults({});
    REQUIRE(scanmesh::test::wait_until([&] { return b.device.state() == drv::DeviceState::kAcquiring; }));
    CHECK(b.device.stats().reconnects >= 1);
    CHECK(b.collector.resumes(3));
  }
  SECTION("the port vanishes and comes back") {
    b.emulator.vanish();
    REQUIRE(scanmesh::test::wait_until([&] { return b.device.state() == drv::DeviceState::kLost; }));
    std::this_thread::sleep_for(100ms);  // a few failed reopenings
    b.emulator.reappear();
    REQUIRE(scanmesh::test::wait_until([&] { return b.device.state() == drv::DeviceState::kAcquiring; }));
    CHECK(b.collector.resumes(3));
    b.device.move_to({1.0, std::nullopt, std::nullopt, std::nullopt}, 3000);
    CHECK(b.device.wait_idle(4s).pose.x_mm == Approx(1.0).margin(1e-3));
  }
  b.device.stop();
  const std::size_t after = b.collector.count();
  std::this_thread::sleep_for(40ms);
  CHECK(b.collector.count() == after);  // no callback after stop()
  const auto samples = b.collector.copy();
  for (std::size_t k = 1; k < samples.size(); ++k) CHECK(samples[k].seq == samples[k - 1].seq + 1);
}

TEST_CASE("grbl driver: WPos reports become machine positions, rotary A in radians", "[drivers][grbl]") {
  auto emu = fast_motion();
  emu.report_wpos = true;
  emu.rotary_a = true;
  emu.work_offset = {100, -50, 5, 0};
  emu.motion.start = {1, 2, 3, std::numbers::pi / 2};
  grbl::Options o;
  o.rotary_a = true;
  GrblBench b(emu, o);
  const auto r = b.device.status();
  CHECK(r.pose.x_mm == Approx(1.0).margin(1e-3));
  CHECK(r.pose.y_mm == Approx(2.0).margin(1e-3));
  CHECK(r.pose.z_mm == Approx(3.0).margin(1e-3));
  CHECK(r.pose.a_rad == Approx(std::numbers::pi / 2).margin(1e-4));
  b.device.move_to({std::nullopt, std::nullopt, std::nullopt, std::numbers::pi}, 36000);
  CHECK(b.device.wait_idle(4s).pose.a_rad == Approx(std::numbers::pi).margin(1e-4));
  const auto lines = b.emulator.lines();
  CHECK(std::find(lines.begin(), lines.end(), "G90G1A180.0000F36000.0") != lines.end());
}

TEST_CASE("grbl driver: the emulator's axes follow an external trajectory", "[drivers][grbl]") {
  GrblBench b(fast_motion());
  const drv::Timestamp t0 = drv::monotonic_now();
  auto path = [t0](drv::Timestamp t) {
    const double s = static_cast<double>((t - t0).count()) * 1e-9;
    return drv::StagePose{10.0 * s, 0.0, 0.0, 0.0};  // 10 mm/s along x
  };
  b.emulator.motion().follow(path, t0 + 400ms);
  const std::size_t first = b.collector.count();
  // The path ends at x = 4 (400 ms at 10 mm/s): wait for a report of the end.
  REQUIRE(scanmesh::test::wait_until([&] { return b.device.wait_idle(50ms).pose.x_mm > 3.9995; }));
  const auto samples = b.collector.copy();
  int checked = 0;
  for (std::size_t k = first; k < samples.size(); ++k) {
    const auto& s = samples[k];
    if (s.t > t0 + 390ms) break;
    // The report was made before the host received it (causality), and not long before (50 ms
    // of travel: generous, the machine is shared).
    const double expected = path(s.t).x_mm;
    CHECK(s.pose.x_mm <= expected + 1e-3);
    CHECK(s.pose.x_mm >= expected - 0.5);
    ++checked;
  }
  CHECK(checked >= 5);
  CHECK(b.device.status().pose.x_mm == Approx(4.0).margin(1e-3));
}
