// Tests of the KEYENCE IL / DL-RS1A driver: codec tables, and the device against its pty
// emulator over the real serial transport, with every injected fault.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/keyence_il/codec.hpp"
#include "scanmesh/drivers/keyence_il/device.hpp"
#include "scanmesh/sim/emulators/keyence_il.hpp"
#include "support/codec_table.hpp"
#include "support/sensor_harness.hpp"

namespace il = scanmesh::drivers::keyence_il;
using scanmesh::drivers::DeviceError;
using scanmesh::drivers::DeviceErrorKind;
using scanmesh::drivers::DeviceState;
using scanmesh::drivers::SensorOptions;
using scanmesh::drivers::SensorSample;
using scanmesh::drivers::SensorStatus;
using scanmesh::test::SensorCollector;
using scanmesh::test::TempDir;
using scanmesh::test::wait_until;
using namespace std::chrono_literals;

namespace {

// ---- codec helpers ----

std::string describe(const il::Reply& r) {
  std::string s;
  switch (r.kind) {
    case il::ReplyKind::kM0:
      s = "M0";
      break;
    case il::ReplyKind::kMs:
      s = "MS";
      break;
    case il::ReplyKind::kDr:
      s = "DR";
      break;
    case il::ReplyKind::kSr:
      s = "SR ";
      s += std::to_string(r.id);
      s += ' ';
      s += std::to_string(r.data_number);
      s += ' ';
      s.append(r.data_view());
      return s;
    case il::ReplyKind::kWriteAck:
      s.append(r.command_view());
      s += " ack ";
      s += std::to_string(r.data_number);
      return s;
    case il::ReplyKind::kError:
      s = "ER ";
      s.append(r.command_view());
      s += ' ';
      s += std::to_string(r.error_code);
      return s;
  }
  for (std::size_t i = 0; i < r.count; ++i) {
    if (r.kind != il::ReplyKind::kM0) {
      s += " [";
      s += std::to_string(r.control[i]);
      s += ']';
    }
    s += ' ';
    s += scanmesh::test::describe_reading(r.readings[i]);
  }
  return s;
}

// ---- device helpers ----

SensorOptions fast_options() { return scanmesh::test::fast_sensor_options("il0"); }

scanmesh::drivers::ByteStreamFactory serial_factory(const std::string& link) {
  return scanmesh::test::pty_serial_factory("il0", link, il::kDefaultBaud);
}

}  // namespace

// ======================= codec =======================

TEST_CASE("keyence_il codec table", "[drivers][keyence_il]") {
  std::string seventeen = "M0";
  for (int i = 0; i < 17; ++i) seventeen += ",+01.000";
  const std::vector<scanmesh::test::CodecCase> cases = {
      {"M0 one amplifier", "M0,+12.345\r\n", {"M0 ok:12.345"}, 0},
      {"M0 three head formats",
       "M0,+12.345,-123.45,+1234.5\r\n",
       {"M0 ok:12.345 ok:-123.45 ok:1234.5"},
       0},
      {"M0 no point", "M0,+012345\r\n", {"M0 ok:12345"}, 0},
      {"M0 CR only", "M0,-00.012\r", {"M0 ok:-0.012"}, 0},
      {"MS control outputs", "MS,00,+12.345,05,-00.012\r\n", {"MS [0] ok:12.345 [5] ok:-0.012"}, 0},
      {"DR record", "DR,01,+01.000\r\n", {"DR [1] ok:1"}, 0},
      {"SR data", "SR,00,037,+0012345\r\n", {"SR 0 37 +0012345"}, 0},
      {"SR 10 characters", "SR,15,999,ABCDEFGHIJ\r\n", {"SR 15 999 ABCDEFGHIJ"}, 0},
      {"SW acknowledged", "SW,01,065\r\n", {"SW ack 65"}, 0},
      {"AW acknowledged", "AW,065\r\n", {"AW ack 65"}, 0},
      {"error 00", "ER,M0,00\r\n", {"ER M0 0"}, 0},
      {"error 22 (read-only)", "ER,SW,22\r\n", {"ER SW 22"}, 0},
      {"over range", "M0,+FFFFFF,-FFFFFFF\r\n", {"M0 over_range over_range"}, 0},
      {"alarm", "M0,-------,XXXXXXX\r\n", {"M0 alarm alarm"}, 0},
      {"16 amplifiers",
       seventeen.substr(0, 2 + 16 * 8) + "\r\n",
       {"M0 ok:1 ok:1 ok:1 ok:1 ok:1 ok:1 ok:1 ok:1 ok:1 ok:1 ok:1 ok:1 ok:1 ok:1 ok:1 ok:1"},
       0},
      {"two replies in one chunk", "M0,+01.000\r\nER,MS,00\r\n", {"M0 ok:1", "ER MS 0"}, 0},
      {"leading noise glued to the reply",
       std::string("\xFE\x13~#\x00M0,+12.345\r\n", 17),
       {"M0 ok:12.345"},
       1},
      {"garbage line before a reply", "@@\r\nM0,+12.345\r\n", {"M0 ok:12.345"}, 1},
      {"truncated (no terminator yet)", "M0,+12.3", {}, 0},
      {"truncated value", "M0,+12.3\r\n", {}, 1},
      {"value too long", "M0,+12.3456\r\n", {}, 1},
      {"letter in value", "M0,+1A.345\r\n", {}, 1},
      {"missing sign", "M0,012.345\r\n", {}, 1},
      {"17 amplifiers", seventeen + "\r\n", {}, 1},
      {"MS control one digit", "MS,0,+12.345\r\n", {}, 1},
      {"MS value missing", "MS,00\r\n", {}, 1},
      {"trailing comma", "M0,+12.345,\r\n", {}, 1},
      {"ER code one digit", "ER,M0,0\r\n", {}, 1},
      {"SR data too long", "SR,00,037,ABCDEFGHIJK\r\n", {}, 1},
      {"SR ID one digit", "SR,0,037,1\r\n", {}, 1},
      {"SR data missing", "SR,00,037\r\n", {}, 1},
      {"unknown header", "QQ,1\r\n", {}, 1},
      {"over-long line", std::string(300, '1') + "\r\nM0,+12.345\r\n", {"M0 ok:12.345"}, 1},
  };
  scanmesh::test::check_codec_table<il::Decoder>(cases, describe);
  CHECK(il::M0::encode() == "M0\r\n");
  CHECK(il::Ms::encode() == "MS\r\n");
  CHECK(il::Sr::encode(1, 37) == "SR,01,037\r\n");
  CHECK(il::Sr::encode(100, 37).empty());
  CHECK(il::Sr::encode(1, 1000).empty());
  CHECK(il::error_text(0).find("command error") == 0);
  CHECK(il::error_text(22).find("invalid parameter") == 0);
  CHECK(il::error_text(5) == "undocumented error code");
}

TEST_CASE("keyence_il codec: split at every byte boundary", "[drivers][keyence_il]") {
  const std::string stream = "M0,+12.345,-123.45\r\nER,M0,00\r\nMS,01,+FFFFFF\r\nSR,00,037,+1\r\n";
  scanmesh::test::check_split_at_every_byte<il::Decoder>(stream, 4, describe);
}

// ======================= device against the emulator =======================

TEST_CASE("keyence_il device: scripted values, amplifier choice, wire bytes",
          "[drivers][keyence_il]") {
  TempDir dir;
  const std::string link = (dir / "tty").string();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<double> script = {1.234, -0.5, std::nan(""), inf, 7.0};
  scanmesh::sim::KeyenceIlEmulator emulator(link, scanmesh::sim::scripted_values(script),
                                            {.amplifiers = 3});
  emulator.start();

  il::Device device(fast_options(), serial_factory(link), {.amplifier = 2});
  device.open();
  CHECK(device.state() == DeviceState::kOpen);
  CHECK(device.identify().vendor == "KEYENCE");
  CHECK(device.identify().model == "IL (DL-RS1A)");
  CHECK(emulator.received() == "M0\r\n");

  SensorCollector collector;
  device.start(collector.callbacks());
  REQUIRE(collector.wait_for(11));
  scanmesh::test::stop_and_check_quiet(device, collector);

  const auto samples = collector.copy();
  for (std::size_t k = 0; k < samples.size(); ++k) {
    INFO("sample " << k);
    const double want = script[(k + 1) % script.size()];
    CHECK(samples[k].seq == k);
    if (std::isnan(want)) {
      CHECK(samples[k].status == SensorStatus::kAlarm);
      CHECK(std::isnan(samples[k].value_mm));
    } else if (std::isinf(want)) {
      CHECK(samples[k].status == SensorStatus::kOverRange);
      CHECK(std::isnan(samples[k].value_mm));
    } else {
      CHECK(samples[k].status == SensorStatus::kOk);
      CHECK(samples[k].value_mm == Approx(want + 2).margin(1e-9));  // amplifier 2
    }
  }
  const std::string wire = emulator.received();
  REQUIRE(wire.size() % 4 == 0);
  for (std::size_t i = 0; i < wire.size(); i += 4) CHECK(wire.substr(i, 4) == "M0\r\n");
  CHECK(device.stats().malformed == 0);
  CHECK(device.stats().samples == samples.size());
}

TEST_CASE("keyence_il device: open errors and options", "[drivers][keyence_il]") {
  TempDir dir;
  const std::string link = (dir / "tty").string();
  scanmesh::sim::KeyenceIlEmulator emulator(link, scanmesh::sim::scripted_values({1.0}),
                                            {.amplifiers = 2, .decimals = 2});
  emulator.start();
  {
    il::Device device(fast_options(), serial_factory(link), {.amplifier = 5});
    try {
      device.open();
      FAIL("open() for a missing amplifier must throw");
    } catch (const DeviceError& e) {
      CHECK(e.kind() == DeviceErrorKind::kProtocol);
      const std::string what = e.what();
      CHECK(what.find("il0 (" + link + "): M0: M0 reply has 2 values, amplifier 5 missing") !=
            std::string::npos);
    }
  }
  emulator.set_faults({.silent = true});
  {
    il::Device device(fast_options(), serial_factory(link));
    CHECK_THROWS_WITH(device.open(), Catch::Contains("M0: no reply within 100 ms"));
  }
  emulator.set_faults({});
  {
    il::Device device(fast_options(), serial_factory(link), {.value_scale = 0.001});
    device.open();
    SensorCollector collector;
    device.start(collector.callbacks());
    REQUIRE(collector.wait_for(2));
    device.stop();
    for (const auto& s : collector.copy()) CHECK(s.value_mm == Approx(0.001));
  }
  CHECK_THROWS_AS(il::Device(fast_options(), serial_factory(link), {.amplifier = 16}),
                  scanmesh::ConfigError);
  CHECK_THROWS_AS(il::Device(fast_options(), serial_factory(link), {.value_scale = -1}),
                  scanmesh::ConfigError);
}

TEST_CASE("keyence_il device: injected faults are reported and recovered from",
          "[drivers][keyence_il]") {
  TempDir dir;
  const std::string link = (dir / "tty").string();
  const std::vector<double> script = {1.0, 2.0, 3.0, 4.5};
  scanmesh::sim::KeyenceIlEmulator emulator(link, scanmesh::sim::scripted_values(script));
  emulator.start();
  il::Device device(fast_options(), serial_factory(link));
  device.open();
  scanmesh::test::check_fault_recovery(
      emulator, device, {"il0", "silent unit: lost, then back", "M0: no reply within 100 ms"},
      script);
}
