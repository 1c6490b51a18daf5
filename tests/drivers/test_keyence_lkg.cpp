// Tests of the KEYENCE LK-G driver: codec tables, and the device against its pty emulator over
// the real serial transport, with every injected fault.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/keyence_lkg/codec.hpp"
#include "scanmesh/drivers/keyence_lkg/device.hpp"
#include "scanmesh/drivers/transports/serial_stream.hpp"
#include "scanmesh/sim/emulators/keyence_lkg.hpp"
#include "support/codec_table.hpp"
#include "support/sensor_harness.hpp"

namespace lkg = scanmesh::drivers::keyence_lkg;
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

std::string describe(const lkg::Reply& r) {
  std::string s;
  switch (r.kind) {
    case lkg::ReplyKind::kM0:
      s = "M0";
      break;
    case lkg::ReplyKind::kMs:
      s = "MS";
      break;
    case lkg::ReplyKind::kEnterSetting:
      return "Q0";
    case lkg::ReplyKind::kExitSetting:
      return "R0";
    case lkg::ReplyKind::kAutoOutput:
      s = "T";
      s += std::to_string(r.out);
      break;
    case lkg::ReplyKind::kError:
      s = "ER ";  // (appends, not operator+: GCC 12 -Wrestrict false positive)
      s.append(r.error_command_view());
      s += ' ';
      s += std::to_string(r.error_code);
      return s;
  }
  for (std::size_t i = 0; i < r.count; ++i) {
    if (r.kind == lkg::ReplyKind::kMs) {
      s += " [";
      s.append(r.status[i].data(), 2);
      s += ']';
    }
    s += ' ';
    s += scanmesh::test::describe_reading(r.readings[i]);
  }
  return s;
}

// ---- device helpers ----

SensorOptions fast_options() { return scanmesh::test::fast_sensor_options("lkg0"); }

scanmesh::drivers::ByteStreamFactory serial_factory(const std::string& link) {
  return scanmesh::test::pty_serial_factory("lkg0", link, lkg::kDefaultBaud);
}

}  // namespace

// ======================= codec =======================

TEST_CASE("keyence_lkg codec table", "[drivers][keyence_lkg]") {
  const std::vector<scanmesh::test::CodecCase> cases = {
      {"M0 two values", "M0,+01.2345,-00.0120\r", {"M0 ok:1.2345 ok:-0.012"}, 0},
      {"M0 lower-case echo", "m0,+01.2345,-00.0120\r", {"M0 ok:1.2345 ok:-0.012"}, 0},
      {"M0 other decimal point", "M0,+1234.56,-0001.20\r", {"M0 ok:1234.56 ok:-1.2"}, 0},
      {"M0 no decimal point", "M0,+0012345,-0000001\r", {"M0 ok:12345 ok:-1"}, 0},
      {"M0 one OUT", "M0,+01.2345\r", {"M0 ok:1.2345"}, 0},
      {"M0 CR LF", "M0,+01.2345,+00.0000\r\n", {"M0 ok:1.2345 ok:0"}, 0},
      {"over range both sides", "M0,+FFFFFFF,-FFFFFFF\r", {"M0 over_range over_range"}, 0},
      {"alarm dashes and X", "M0,--------,XXXXXXXX\r", {"M0 alarm alarm"}, 0},
      {"alarm 7 dashes, signed X", "M0,-------,+XXXXXXX\r", {"M0 alarm alarm"}, 0},
      {"MS with status", "MS,00,+01.2345,01,-FFFFFFF\r", {"MS [00] ok:1.2345 [01] over_range"}, 0},
      {"Q0 echo", "Q0\r", {"Q0"}, 0},
      {"R0 echo", "r0\r", {"R0"}, 0},
      {"auto output OUT1", "T1,+01.2345\r", {"T1 ok:1.2345"}, 0},
      {"auto output OUT2 alarm", "T2,XXXXXXXX\r", {"T2 alarm"}, 0},
      {"error 00", "ER,M0,00\r", {"ER M0 0"}, 0},
      {"error 01", "ER,M0,01\r", {"ER M0 1"}, 0},
      {"error 20", "ER,Q0,20\r", {"ER Q0 20"}, 0},
      {"error 21", "ER,MS,21\r", {"ER MS 21"}, 0},
      {"error 22", "ER,SW,22\r", {"ER SW 22"}, 0},
      {"error 88", "ER,M0,88\r", {"ER M0 88"}, 0},
      {"error 99", "ER,M0,99\r", {"ER M0 99"}, 0},
      {"two replies in one chunk",
       "M0,+01.0000,+02.0000\rT1,-03.5000\r",
       {"M0 ok:1 ok:2", "T1 ok:-3.5"},
       0},
      {"leading noise glued to the reply",
       std::string("\xFE\x13~#\x00M0,+01.2345,+00.0000\r", 27),
       {"M0 ok:1.2345 ok:0"},
       1},
      {"garbage line before a reply", "zz%$\rM0,+01.2345,+00.0000\r", {"M0 ok:1.2345 ok:0"}, 1},
      {"truncated (no CR yet)", "M0,+01.23", {}, 0},
      {"truncated value field", "M0,+01.23\r", {}, 1},
      {"letter in value", "M0,+01.2A45,+00.0000\r", {}, 1},
      {"two points", "M0,+1.2.345,+00.0000\r", {}, 1},
      {"missing sign", "M0,001.2345,+00.0000\r", {}, 1},
      {"trailing comma", "M0,+01.2345,\r", {}, 1},
      {"three values", "M0,+01.2345,+01.2345,+01.2345\r", {}, 1},
      {"empty M0", "M0,\r", {}, 1},
      {"ER code one digit", "ER,M0,1\r", {}, 1},
      {"ER code not digits", "ER,M0,xx\r", {}, 1},
      {"MS status missing value", "MS,00\r", {}, 1},
      {"unknown header", "ZZ,1\r", {}, 1},
      {"over-long line", std::string(100, 'A') + "\rQ0\r", {"Q0"}, 1},
      {"blank lines only", "\r\n\r\n", {}, 0},
  };
  scanmesh::test::check_codec_table<lkg::Decoder>(cases, describe);
}

TEST_CASE("keyence_lkg codec: split at every byte boundary", "[drivers][keyence_lkg]") {
  const std::string stream = "M0,+01.2345,-00.0120\rER,M0,01\rT2,+FFFFFFF\rMS,00,--------\r";
  scanmesh::test::check_split_at_every_byte<lkg::Decoder>(stream, 4, describe);
}

TEST_CASE("keyence_lkg codec: error texts and value formatting", "[drivers][keyence_lkg]") {
  CHECK(lkg::error_text(0) == "command error");
  CHECK(lkg::error_text(1) == "status error (wrong mode)");
  CHECK(lkg::error_text(20) == "command length error");
  CHECK(lkg::error_text(21) == "parameter count error");
  CHECK(lkg::error_text(22) == "invalid parameter");
  CHECK(lkg::error_text(88) == "timeout error");
  CHECK(lkg::error_text(99) == "other error");
  CHECK(lkg::error_text(42) == "undocumented error code");

  struct F {
    double v;
    int decimals;
    const char* text;
  };
  for (const F& f :
       {F{1.2345, 4, "+01.2345"}, F{-0.012, 4, "-00.0120"}, F{1234.56, 2, "+1234.56"},
        F{-1.2, 4, "-01.2000"}, F{100.0, 4, "+FFFFFFF"}, F{-1e9, 4, "-FFFFFFF"},
        F{12345, 0, "+0012345"}, F{std::numeric_limits<double>::infinity(), 4, "+FFFFFFF"},
        F{std::numeric_limits<double>::quiet_NaN(), 4, "XXXXXXXX"}}) {
    char out[lkg::kValueWidth];
    lkg::format_value(f.v, f.decimals, out);
    CHECK(std::string(out, lkg::kValueWidth) == f.text);
    lkg::Reading r;
    CHECK(lkg::parse_value(std::string_view(out, lkg::kValueWidth), r));
  }
  CHECK(lkg::M0::encode() == "M0\r");
  CHECK(lkg::Ms::encode() == "MS\r");
  CHECK(lkg::EnterSetting::encode() == "Q0\r");
  CHECK(lkg::ExitSetting::encode() == "R0\r");
}

// ======================= device against the emulator =======================

TEST_CASE("keyence_lkg device: scripted values, sequence numbers, wire bytes",
          "[drivers][keyence_lkg]") {
  TempDir dir;
  const std::string link = (dir / "tty").string();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<double> script = {1.2345, -0.012, std::nan(""), inf, -inf, 2.5};
  scanmesh::sim::KeyenceLkgEmulator emulator(link, scanmesh::sim::scripted_values(script));
  emulator.start();

  lkg::Device device(fast_options(), serial_factory(link));
  device.open();
  CHECK(device.state() == DeviceState::kOpen);
  CHECK(device.identify().vendor == "KEYENCE");
  CHECK(device.identify().model == "LK-G");
  CHECK(device.identify().serial.empty());
  CHECK(device.capabilities().max_rate_hz > 0);
  CHECK_FALSE(device.capabilities().streaming);
  CHECK(emulator.received() == "M0\r");  // identification: one M0

  SensorCollector collector;
  device.start(collector.callbacks());
  REQUIRE(collector.wait_for(13));
  scanmesh::test::stop_and_check_quiet(device, collector);

  const auto samples = collector.copy();
  // open() took measurement 0; sample k is measurement k + 1.
  for (std::size_t k = 0; k < samples.size(); ++k) {
    INFO("sample " << k);
    const double want = script[(k + 1) % script.size()];
    CHECK(samples[k].seq == k);
    CHECK(samples[k].index == 0);
    CHECK_FALSE(samples[k].t_device.has_value());
    if (k > 0) CHECK(samples[k].t_host >= samples[k - 1].t_host);
    if (std::isnan(want)) {
      CHECK(samples[k].status == SensorStatus::kAlarm);  // dashes
      CHECK(std::isnan(samples[k].value_mm));
    } else if (std::isinf(want)) {
      CHECK(samples[k].status == SensorStatus::kOverRange);
      CHECK(std::isnan(samples[k].value_mm));
    } else {
      CHECK(samples[k].status == SensorStatus::kOk);
      CHECK(samples[k].value_mm == Approx(want).margin(1e-9));
    }
  }
  // Bytes on the wire: only M0 CR, one per measurement.
  const std::string wire = emulator.received();
  REQUIRE(wire.size() % 3 == 0);
  for (std::size_t i = 0; i < wire.size(); i += 3) CHECK(wire.substr(i, 3) == "M0\r");
  CHECK(wire.size() / 3 == emulator.measurements());
  const auto stats = device.stats();
  CHECK(stats.samples == samples.size());
  CHECK(stats.malformed == 0);
  CHECK(stats.error_replies == 0);
  CHECK(stats.timeouts == 0);
  device.close();
  CHECK(device.state() == DeviceState::kClosed);
}

TEST_CASE("keyence_lkg device: OUT2 and value_scale", "[drivers][keyence_lkg]") {
  TempDir dir;
  const std::string link = (dir / "tty").string();
  scanmesh::sim::KeyenceLkgEmulator emulator(link, scanmesh::sim::scripted_values({1234.5}),
                                             {.decimals = 1});
  emulator.start();
  lkg::Device device(fast_options(), serial_factory(link), {.out = 2, .value_scale = 0.001});
  device.open();
  SensorCollector collector;
  device.start(collector.callbacks());
  REQUIRE(collector.wait_for(3));
  device.stop();
  for (const auto& s : collector.copy()) CHECK(s.value_mm == Approx(1.2345));
  CHECK_THROWS_AS(lkg::Device(fast_options(), serial_factory(link), {.out = 3}),
                  scanmesh::ConfigError);
  CHECK_THROWS_AS(lkg::Device(fast_options(), serial_factory(link), {.value_scale = 0}),
                  scanmesh::ConfigError);
}

TEST_CASE("keyence_lkg device: open errors name the device and the operation",
          "[drivers][keyence_lkg]") {
  TempDir dir;
  const std::string link = (dir / "tty").string();
  {
    lkg::Device device(fast_options(), serial_factory(link));
    try {
      device.open();
      FAIL("open() without a port must throw");
    } catch (const DeviceError& e) {
      CHECK(e.kind() == DeviceErrorKind::kNotFound);
      CHECK(std::string(e.what()).find("lkg0") != std::string::npos);
    }
  }
  scanmesh::sim::KeyenceLkgEmulator emulator(link, scanmesh::sim::scripted_values({1.0}));
  emulator.set_faults({.silent = true});
  emulator.start();
  {
    lkg::Device device(fast_options(), serial_factory(link));
    try {
      device.open();
      FAIL("open() of a silent device must throw");
    } catch (const DeviceError& e) {
      CHECK(e.kind() == DeviceErrorKind::kTimeout);
      const std::string what = e.what();
      CHECK(what.find("lkg0 (" + link + ")") != std::string::npos);
      CHECK(what.find("M0: no reply within 100 ms") != std::string::npos);
    }
    CHECK(device.state() == DeviceState::kClosed);
  }
  // Setting mode (Q0 sent by someone else): M0 is refused with a status error.
  emulator.set_faults({});
  {
    auto raw = scanmesh::drivers::open_serial_stream("raw", {link, lkg::kDefaultBaud});
    raw->write_all(std::string_view("Q0\r"), 200ms);
    REQUIRE(wait_until([&] { return emulator.setting_mode(); }));
  }
  {
    lkg::Device device(fast_options(), serial_factory(link));
    try {
      device.open();
      FAIL("open() in setting mode must throw");
    } catch (const DeviceError& e) {
      CHECK(e.kind() == DeviceErrorKind::kProtocol);
      CHECK(std::string(e.what()).find("ER,M0,01 (status error") != std::string::npos);
    }
  }
}

TEST_CASE("keyence_lkg device: injected faults are reported and recovered from",
          "[drivers][keyence_lkg]") {
  TempDir dir;
  const std::string link = (dir / "tty").string();
  const std::vector<double> script = {1.0, 2.0, 3.0, 4.5};
  scanmesh::sim::KeyenceLkgEmulator emulator(link, scanmesh::sim::scripted_values(script));
  emulator.start();
  lkg::Device device(fast_options(), serial_factory(link));
  device.open();
  scanmesh::test::check_fault_recovery(
      emulator, device, {"lkg0", "silent device: lost, then back", "no reply within 100 ms"},
      script);
}

TEST_CASE("keyence_lkg device: auto-output streaming mode", "[drivers][keyence_lkg]") {
  TempDir dir;
  const std::string link = (dir / "tty").string();
  const std::vector<double> script = {0.5, -0.25, std::nan(""), 7.125};
  scanmesh::sim::KeyenceLkgEmulator emulator(
      link, scanmesh::sim::scripted_values(script),
      {.auto_output_period = std::chrono::microseconds(2000), .auto_output = true});
  emulator.start();
  lkg::Device device(fast_options(), serial_factory(link),
                     {.acquisition = lkg::Acquisition::kAutoOutput});
  device.open();
  CHECK(device.capabilities().streaming);
  SensorCollector collector;
  device.start(collector.callbacks());
  REQUIRE(collector.wait_for(20));

  // The stream stops: timeouts, lost; it comes back: acquiring again.
  emulator.set_auto_output(false);
  REQUIRE(wait_until([&] { return device.state() == DeviceState::kLost; }));
  CHECK(collector.saw(DeviceState::kLost, "auto output: no record within 100 ms"));
  emulator.set_auto_output(true);
  REQUIRE(wait_until([&] { return device.state() == DeviceState::kAcquiring; }));
  const std::size_t n = collector.count();
  REQUIRE(collector.wait_for(n + 10));
  device.stop();

  CHECK(emulator.received().empty());  // streaming: the driver never sends anything
  const auto samples = collector.copy();
  for (std::size_t k = 0; k < samples.size(); ++k) {
    INFO("sample " << k);
    if (k > 0) CHECK(samples[k].seq == samples[k - 1].seq + 1);
    const auto& s = samples[k];
    if (s.status == SensorStatus::kAlarm) {
      CHECK(std::isnan(s.value_mm));
    } else {
      REQUIRE(s.status == SensorStatus::kOk);
      CHECK((s.value_mm == 0.5 || s.value_mm == -0.25 || s.value_mm == 7.125));
    }
  }
  // Consecutive samples follow the script (records are never lost inside one connection).
  std::size_t in_order = 0;
  for (std::size_t k = 1; k < 20; ++k) {
    auto idx = [&](const SensorSample& s) -> int {
      if (s.status != SensorStatus::kOk) return 2;
      return s.value_mm == 0.5 ? 0 : s.value_mm == -0.25 ? 1 : 3;
    };
    if ((idx(samples[k - 1]) + 1) % 4 == idx(samples[k])) ++in_order;
  }
  CHECK(in_order == 19);
}
