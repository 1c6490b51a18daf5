// I++ DME: reply framing from byte strings (every marker, data items, errors, events, split at
// every byte, garbage), command encoding, and the client against the I++ DME server emulator
// over TCP on 127.0.0.1 (session, moves with move reports, homing, PtMeas, AbortE, errors,
// bounded transactions, unknown tags, loss and reconnect).
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <cmath>
#include <sstream>
#include <thread>

#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/ippdme/codec.hpp"
#include "scanmesh/drivers/ippdme/device.hpp"
#include "scanmesh/drivers/transports/tcp_stream.hpp"
#include "scanmesh/sim/emulators/ippdme.hpp"
#include "support/codec_table.hpp"
#include "support/stage_harness.hpp"

using namespace std::chrono_literals;
namespace drv = scanmesh::drivers;
namespace ipp = scanmesh::drivers::ippdme;
using drv::StageStatus;
using scanmesh::test::CodecCase;

namespace {

std::string describe(const ipp::Reply& r) {
  std::ostringstream o;
  o << ipp::to_string(r.tag) << " ";
  switch (r.marker) {
    case ipp::Marker::kAck: o << "&"; break;
    case ipp::Marker::kComplete: o << "%"; break;
    case ipp::Marker::kError:
      o << "! " << r.severity << "," << r.code << "," << r.cause << "," << r.text;
      break;
    case ipp::Marker::kData:
      o << "#";
      for (int k = 0; k < r.item_count; ++k) {
        const auto& it = r.items[k];
        o << " " << it.name << "(";
        for (int a = 0; a < it.count; ++a) o << (a ? "," : "") << it.v[a];
        if (!it.text.empty()) o << "'" << it.text << "'";
        o << ")";
      }
      if (r.item_count == 0) o << " " << r.data;
      break;
  }
  return o.str();
}

}  // namespace

TEST_CASE("ippdme codec: replies from byte strings", "[drivers][ippdme]") {
  const std::vector<CodecCase> cases = {
      {"acknowledged", "00012 &\r\n", {"00012 &"}, 0},
      {"complete", "00012 %\r\n", {"00012 %"}, 0},
      {"position data", "00180 # X(75), Y(50), Z(40)\r\n", {"00180 # X(75) Y(50) Z(40)"}, 0},
      {"probed point with its normal, exponents, signs",
       "00007 # X(-1.5), Y(+2.25E1), Z(3e-2), IJK(0, 0.6, -0.8)\r\n",
       {"00007 # X(-1.5) Y(22.5) Z(0.03) IJK(0,0.6,-0.8)"}, 0},
      {"dotted property and a string", "00003 # Tool.A.Radius(1.5)\r\n00004 # DMEVersion(\"1.4.3\")\r\n",
       {"00003 # Tool.A.Radius(1.5)", "00004 # DMEVersion('1.4.3')"}, 0},
      {"move report on an event tag", "E0001 # X(1), Y(2), Z(3), R(90)\r\n",
       {"E0001 # X(1) Y(2) Z(3) R(90)"}, 0},
      {"error with severity, number, cause, text",
       "00009 ! Error(2, 1006, \"PtMeas\", \"Surface not found\")\r\n",
       {"00009 ! 2,1006,PtMeas,Surface not found"}, 0},
      {"unsolicited error event", "E0000 ! Error(3, 0500, \"Machine\", \"Emergency stop\")\r\n",
       {"E0000 ! 3,500,Machine,Emergency stop"}, 0},
      {"two replies in one chunk, LF only", "00001 &\n00001 %\n", {"00001 &", "00001 %"}, 0},
      {"leading garbage glued to a reply", "~#00001 &\r\n", {"00001 &"}, 1},
      {"truncated: nothing yet", "00001 # X(1.0", {}, 0},
      {"reserved tag 00000", "00000 &\r\n", {}, 1},
      {"no space at position 6", "00001&\r\n", {}, 1},
      {"unknown marker", "00001 ?\r\n", {}, 1},
      {"text after the ack", "00001 & x\r\n", {}, 1},
      {"bad number", "00001 # X(1.2.3)\r\n", {}, 1},
      {"number longer than 16 characters", "00001 # X(1.00000000000000000)\r\n", {}, 1},
      {"unterminated item", "00001 # X(1, Y(2)\r\n", {}, 1},
      {"bad error", "00001 ! Error(x, 1, \"a\", \"b\")\r\n", {}, 1},
      {"too many items", "00001 # A(1), B(1), C(1), D(1), E(1), F(1), G(1), H(1), I(1)\r\n", {}, 1},
  };
  scanmesh::test::check_codec_table<ipp::Decoder>(cases, describe);
  const std::string stream =
      "00001 &\r\n00002 # X(1.5), Y(-2), Z(3), IJK(0, 0, 1)\r\nE0001 # X(1), Y(2), Z(3)\r\n"
      "00003 ! Error(2, 1006, \"PtMeas\", \"Surface not found\")\r\n00002 %\r\n";
  scanmesh::test::check_split_at_every_byte<ipp::Decoder>(stream, 5, describe);
}

TEST_CASE("ippdme codec: numbers and command lines", "[drivers][ippdme]") {
  double v = 0;
  CHECK((ipp::parse_number("-12.5", v) && v == -12.5));
  CHECK((ipp::parse_number("1E3", v) && v == 1000));
  CHECK((ipp::parse_number(".5", v) && v == 0.5));  // NUMBER: [+-]?(\d+\.?\d*|\.\d+)
  CHECK_FALSE(ipp::parse_number("1e1000", v));   // exponents have at most 3 digits... and overflow
  CHECK(ipp::format_number(10.0) == "10");
  CHECK(ipp::format_number(-0.125) == "-0.125");
  CHECK(ipp::command_line({false, 12}, "GoTo(X(1), Y(2))") == "00012 GoTo(X(1), Y(2))\r\n");
  CHECK(ipp::command_line({true, 1}, "AbortE()") == "E0001 AbortE()\r\n");
  CHECK(ipp::error_text(1006) == "Surface not found");
  CHECK(ipp::error_text(6) == "Transaction aborted (Use ClearAllErrors To Continue)");
}

// ---------------------------------------------------------------------------------------------

namespace {

scanmesh::sim::IppDmeEmulatorOptions cmm_options() {
  scanmesh::sim::IppDmeEmulatorOptions o;
  o.motion.limits.linear_velocity_mm_s = 500;
  o.motion.limits.linear_accel_mm_s2 = 10000;
  o.motion.homing_speed_mm_s = 400;
  o.motion.probe.tip_radius_mm = 1.5;
  return o;
}

struct Cmm {
  scanmesh::sim::IppDmeEmulator emulator;
  ipp::Device device;
  scanmesh::test::StageCollector collector;

  explicit Cmm(scanmesh::sim::IppDmeEmulatorOptions o = cmm_options(), ipp::Options io = {})
      : emulator(std::move(o)),
        device(scanmesh::test::fast_stage_options("cmm"),
               [this] {
                 emulator.start();
                 return drv::ByteStreamFactory([port = emulator.port()] {
                   return drv::open_tcp_stream("cmm", "127.0.0.1", port, 150ms);
                 });
               }(),
               io) {
    device.open();
    device.start(collector.callbacks());
    REQUIRE(collector.wait_for(2));
  }
  ~Cmm() { device.close(); }
};

}  // namespace

TEST_CASE("ippdme driver: session, moves with move reports, homing", "[drivers][ippdme]") {
  auto o = cmm_options();
  o.motion.start = {100, 50, 20, 0};
  Cmm c(o);
  CHECK(c.device.identify().firmware == "1.4.3");
  CHECK(c.device.tip_radius_mm() == Approx(1.5));
  const auto lines = c.emulator.lines();
  REQUIRE(lines.size() >= 5);
  CHECK(lines[0] == "00001 StartSession()");
  CHECK(lines[1] == "00002 OnPtMeasReport(X(), Y(), Z(), IJK())");
  CHECK(lines[2] == "E0001 OnMoveReportE(Time(0.01), Dis(0), X(), Y(), Z())");
  auto r = c.device.status();
  CHECK(scanmesh::test::distance(r.pose, {100, 50, 20, 0}) < 1e-3);
  const std::size_t before = c.collector.count();
  c.device.move_to({150.0, std::nullopt, 0.0, std::nullopt}, 6000);
  r = c.device.wait_idle(5s);
  REQUIRE(r.status == StageStatus::kIdle);
  CHECK(scanmesh::test::distance(r.pose, {150, 50, 0, 0}) < 1e-3);
  // Reports while moving came from the move-report daemon.
  bool moving_report = false;
  for (const auto& s : c.collector.copy())
    if (s.seq >= before && s.status == StageStatus::kMoving && s.pose.x_mm > 100.5 &&
        s.pose.x_mm < 149.5)
      moving_report = true;
  CHECK(moving_report);
  const auto wire = c.emulator.lines();
  CHECK(std::find_if(wire.begin(), wire.end(), [](const std::string& l) {
          return l.find(" GoTo(X(150), Z(0))") == 5;
        }) != wire.end());
  c.device.home();
  CHECK(c.device.status().status == StageStatus::kHoming);
  r = c.device.wait_idle(5s);
  CHECK(r.status == StageStatus::kIdle);
  CHECK(scanmesh::test::distance(r.pose, {0, 0, 0, 0}) < 1e-3);
  CHECK(c.device.stats().timeouts == 0);
}

TEST_CASE("ippdme driver: PtMeas, compensated by the controller", "[drivers][ippdme][probe]") {
  auto o = cmm_options();
  o.motion.probe.scene = scanmesh::test::part_scene("steps");
  o.motion.start = {10, 15, 20, 0};
  Cmm c(o);
  SECTION("contact: surface point and normal, tip centre as the latch") {
    const auto r = c.device.probe_move({0, 0, -1, 20, 600});
    REQUIRE(r.outcome == drv::ProbeMoveResult::Outcome::kContact);
    REQUIRE(r.trigger.surface.has_value());
    CHECK(r.trigger.surface->z_mm == Approx(10.0).margin(2e-3));
    CHECK(r.trigger.surface->k == Approx(1.0));
    CHECK(r.trigger.pose.z_mm == Approx(11.5).margin(2e-3));
    CHECK(c.collector.probes().size() == 1);
    // Retract(-1): back at the start.
    CHECK(c.device.wait_idle(3s).pose.z_mm == Approx(20).margin(1e-3));
  }
  SECTION("no contact: 1006 Surface not found, cleared") {
    const auto r = c.device.probe_move({0, 0, -1, 5, 600});
    CHECK(r.outcome == drv::ProbeMoveResult::Outcome::kNoContact);
    CHECK(r.device_code == 1006);
    CHECK(c.device.wait_idle(2s).status == StageStatus::kIdle);
  }
  SECTION("a probe that never triggers") {
    c.emulator.set_probe_never_triggers(true);
    CHECK(c.device.probe_move({0, 0, -1, 20, 1200}).outcome ==
          drv::ProbeMoveResult::Outcome::kNoContact);
  }
  SECTION("deflected before the search: 1001 Illegal touch") {
    c.device.move_to({std::nullopt, std::nullopt, 10.5, std::nullopt}, 6000);
    c.device.wait_idle(3s);
    const auto r = c.device.probe_move({0, 0, -1, 4, 600});
    CHECK(r.outcome == drv::ProbeMoveResult::Outcome::kTriggeredAtStart);
    CHECK(r.device_code == 1001);
  }
}

TEST_CASE("ippdme driver: errors, AbortE, bounded transactions, unknown tags, faults",
          "[drivers][ippdme]") {
  ipp::Options io;
  io.max_in_flight = 2;
  Cmm c(cmm_options(), io);
  SECTION("an unsolicited machine error is an alarm until ClearAllErrors") {
    c.emulator.raise_error(500, 3);
    REQUIRE(scanmesh::test::wait_until([&] { return c.device.status().status == StageStatus::kAlarm; }));
    CHECK(c.device.status().alarm_code == 500);
    // Accepted (&), then refused: the machine waits for ClearAllErrors().
    c.device.move_to({1.0, std::nullopt, std::nullopt, std::nullopt}, 600);
    const auto refused = c.device.wait_idle(2s);
    CHECK(refused.status == StageStatus::kAlarm);
    CHECK(refused.alarm_code == 514);
    CHECK(refused.alarm_text.find("Use ClearAllErrors to continue") != std::string::npos);
    c.device.clear_alarm();
    c.device.move_to({1.0, std::nullopt, std::nullopt, std::nullopt}, 600);
    CHECK(c.device.wait_idle(3s).pose.x_mm == Approx(1.0).margin(1e-3));
  }
  SECTION("halt: AbortE overtakes a long move") {
    c.device.move_to({400.0, std::nullopt, std::nullopt, std::nullopt}, 600);
    REQUIRE(scanmesh::test::wait_until([&] { return c.device.status().pose.x_mm > 1; }));
    c.device.halt();
    const auto r = c.device.wait_idle(2s);
    CHECK(r.status == StageStatus::kIdle);
    CHECK(r.pose.x_mm < 399);
  }
  SECTION("transactions in flight stay within the bound") {
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
      threads.emplace_back([&, t] {
        c.device.move_by({std::nullopt, 1.0 + t, std::nullopt, std::nullopt}, 60000);
      });
    for (auto& t : threads) t.join();
    c.device.wait_idle(5s);
    CHECK(c.device.max_in_flight_seen() <= 2);
    CHECK(c.emulator.max_queued() <= 2);
  }
  SECTION("a reply for an unknown tag is counted, not trusted") {
    c.emulator.send_unknown_tag();
    REQUIRE(scanmesh::test::wait_until([&] { return c.device.unknown_tags() == 1; }));
    CHECK(c.device.stats().malformed >= 1);
    CHECK(c.collector.resumes(3));
  }
  SECTION("garbage before every line") {
    c.emulator.set_faults({.garbage_before_reply = true});
    REQUIRE(scanmesh::test::wait_until([&] { return c.device.stats().malformed >= 3; }));
    CHECK(c.collector.resumes(3));
  }
  SECTION("a silent server is lost, then found again") {
    c.emulator.set_faults({.silent = true});
    REQUIRE(scanmesh::test::wait_until([&] { return c.device.state() == drv::DeviceState::kLost; }));
    CHECK(c.collector.saw(drv::DeviceState::kLost, "cmm"));
    CHECK(c.collector.saw(drv::DeviceState::kLost, "Get: no reply within 150 ms"));
    c.emulator.set_faults({});
    REQUIRE(scanmesh::test::wait_until([&] { return c.device.state() == drv::DeviceState::kAcquiring; }));
    CHECK(c.collector.resumes(3));
  }
  SECTION("the connection is dropped; the driver reconnects and starts a new session") {
    c.emulator.drop_client();
    REQUIRE(scanmesh::test::wait_until([&] { return c.device.stats().reconnects >= 1; }));
    CHECK(c.collector.resumes(3));
    const auto lines = c.emulator.lines();
    CHECK(std::count(lines.begin(), lines.end(), "00001 StartSession()") +
              std::count_if(lines.begin(), lines.end(),
                            [](const std::string& l) { return l.find("StartSession()") != std::string::npos; }) >=
          2);
  }
  c.device.stop();
  const std::size_t after = c.collector.count();
  std::this_thread::sleep_for(40ms);
  CHECK(c.collector.count() == after);
}
