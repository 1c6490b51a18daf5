// Tests of the Panasonic HL-G1 driver: codec tables, and the device against its pty emulator
// over the real serial transport, with every injected fault.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/panasonic_hlg1/codec.hpp"
#include "scanmesh/drivers/panasonic_hlg1/device.hpp"
#include "scanmesh/sim/emulators/panasonic_hlg1.hpp"
#include "support/codec_table.hpp"
#include "support/sensor_harness.hpp"

namespace hlg1 = scanmesh::drivers::panasonic_hlg1;
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

/// Appends the BCC (XOR from % to the end of the data, 2 hex digits) and CR, computed here
/// independently of the codec.
std::string framed(const std::string& body) {
  unsigned x = 0;
  for (char c : body) x ^= static_cast<unsigned char>(c);
  char hex[4];
  std::snprintf(hex, sizeof hex, "%02X", x);
  return body + hex + "\r";
}

std::string describe(const hlg1::Reply& r) {
  std::string s = std::to_string(r.unit);
  if (r.kind == hlg1::ReplyKind::kError) {
    s += " !";
    s += std::to_string(r.error_code);
  } else {
    s += ' ';
    s.append(r.command_view());
    if (r.has_value) {
      s += " v=";
      s += std::to_string(r.counts);
    } else if (r.data_size > 0) {
      s += " d=";
      s.append(r.data_view());
    }
  }
  if (!r.bcc_checked) s += " **";
  return s;
}

// ---- device helpers ----

SensorOptions fast_options() { return scanmesh::test::fast_sensor_options("hlg0"); }

scanmesh::drivers::ByteStreamFactory serial_factory(const std::string& link) {
  return scanmesh::test::pty_serial_factory("hlg0", link, hlg1::kDefaultBaud);
}

}  // namespace

// ======================= codec =======================

TEST_CASE("panasonic_hlg1 codec: requests", "[drivers][panasonic_hlg1]") {
  CHECK(hlg1::bcc("%01#RMD") == 0x5C);
  CHECK(hlg1::ReadMeasurement::encode(1) == "%01#RMD5C\r");
  CHECK(hlg1::ReadMeasurement::encode(3, false) == "%03#RMD**\r");  // documented example
  CHECK(hlg1::ReadSamplingCycle::encode(1, false) == "%01#RSP**\r");
  char buf[32];
  const std::size_t n = hlg1::encode_request(4, "WHA", "+0055000", true, buf);
  CHECK(std::string(buf, n) == framed("%04#WHA+0055000"));
  CHECK(hlg1::encode_request(100, "RMD", "", true, buf) == 0);
  CHECK(hlg1::encode_request(-1, "RMD", "", true, buf) == 0);
  CHECK(hlg1::encode_request(1, "RM", "", true, buf) == 0);
  CHECK(hlg1::encode_request(1, "RMD", std::string(40, '0'), true, buf) == 0);
  CHECK(hlg1::error_text(40) == "BCC error");
  CHECK(hlg1::error_text(41) == "format error");
  CHECK(hlg1::error_text(42) == "command not supported");
  CHECK(hlg1::error_text(60) == "parameter error");
  CHECK(hlg1::error_text(61) == "data error");
  CHECK(hlg1::error_text(7) == "undocumented error code");
}

TEST_CASE("panasonic_hlg1 codec table", "[drivers][panasonic_hlg1]") {
  const std::string rmd = framed("%01$RMD+0025000");
  const std::vector<scanmesh::test::CodecCase> cases = {
      {"RMD with BCC", rmd, {"1 RMD v=25000"}, 0},
      {"RMD doc example with **", "%03$RMD-0123456**\r", {"3 RMD v=-123456 **"}, 0},
      {"RMD zero", framed("%01$RMD+0000000"), {"1 RMD v=0"}, 0},
      {"RMD extremes",
       framed("%01$RMD-9999999") + framed("%01$RMD+9999999"),
       {"1 RMD v=-9999999", "1 RMD v=9999999"},
       0},
      {"lower-case hex BCC", "%01$RMD+00250084f\r", {"1 RMD v=25008"}, 0},
      {"RSP data reply", "%01$RSP+00001**\r", {"1 RSP d=+00001 **"}, 0},
      {"write acknowledged (no data)", framed("%04$WHA"), {"4 WHA"}, 0},
      {"unit 99", framed("%99$RMD+0000001"), {"99 RMD v=1"}, 0},
      {"error 40", framed("%01!40"), {"1 !40"}, 0},
      {"error 41", framed("%01!41"), {"1 !41"}, 0},
      {"error 42", framed("%01!42"), {"1 !42"}, 0},
      {"error 60", framed("%01!60"), {"1 !60"}, 0},
      {"error 61 with **", "%01!61**\r", {"1 !61 **"}, 0},
      {"CR LF", rmd + "\n", {"1 RMD v=25000"}, 0},
      {"two frames in one chunk", rmd + framed("%02!42"), {"1 RMD v=25000", "2 !42"}, 0},
      {"leading noise glued to the frame",
       std::string("\xFE\x13~#\x00", 5) + rmd,
       {"1 RMD v=25000"},
       1},
      {"garbage line before a frame", "xyz\r" + rmd, {"1 RMD v=25000"}, 1},
      {"bad BCC", "%01$RMD+002500000\r", {}, 1},
      {"BCC not hex", "%01$RMD+0025000G1\r", {}, 1},
      {"truncated (no CR yet)", "%01$RMD+00250", {}, 0},
      {"truncated frame", "%01$RMD+00250\r", {}, 1},
      {"truncated value, valid BCC", framed("%01$RMD+00250"), {}, 1},
      {"letter in value", framed("%01$RMD+00A5000"), {}, 1},
      {"value without sign", framed("%01$RMD00250000"), {}, 1},
      {"error code one digit", framed("%01!4"), {}, 1},
      {"unit not digits", framed("%0A$RMD+0025000"), {}, 1},
      {"request type character", framed("%01#RMD"), {}, 1},
      {"command lower case", framed("%01$rmd+0025000"), {}, 1},
      {"too short", "%01$**\r", {}, 1},
      {"over-long line", std::string(100, '%') + "\r" + rmd, {"1 RMD v=25000"}, 1},
  };
  scanmesh::test::check_codec_table<hlg1::Decoder>(cases, describe);
  hlg1::Reply r;
  REQUIRE(hlg1::parse_reply("%03$RMD-0123456**", r) == nullptr);
  CHECK(r.value_mm() == Approx(-12.3456));  // the manual's example
  REQUIRE(hlg1::parse_reply("%01$RMD+0025000**", r) == nullptr);
  CHECK(r.value_mm() == Approx(2.5));
}

TEST_CASE("panasonic_hlg1 codec: split at every byte boundary", "[drivers][panasonic_hlg1]") {
  const std::string stream = framed("%01$RMD+0025000") + framed("%01!42") + "%03$RMD-0123456**\r" +
                             framed("%01$RSP+00001");
  scanmesh::test::check_split_at_every_byte<hlg1::Decoder>(stream, 4, describe);
}

// ======================= device against the emulator =======================

TEST_CASE("panasonic_hlg1 device: scripted values, sequence numbers, wire bytes",
          "[drivers][panasonic_hlg1]") {
  TempDir dir;
  const std::string link = (dir / "tty").string();
  const std::vector<double> script = {2.5, -12.3456, 0.0001, 5.0};
  scanmesh::sim::PanasonicHlg1Emulator emulator(link, scanmesh::sim::scripted_values(script));
  emulator.start();

  hlg1::Device device(fast_options(), serial_factory(link));
  device.open();
  CHECK(device.state() == DeviceState::kOpen);
  CHECK(device.identify().vendor == "Panasonic");
  CHECK(device.identify().model == "HL-G1");
  CHECK(device.capabilities().resolution_mm == Approx(1e-4));
  CHECK(emulator.received() == "%01#RMD5C\r");

  SensorCollector collector;
  device.start(collector.callbacks());
  REQUIRE(collector.wait_for(10));
  scanmesh::test::stop_and_check_quiet(device, collector);

  const auto samples = collector.copy();
  for (std::size_t k = 0; k < samples.size(); ++k) {
    INFO("sample " << k);
    CHECK(samples[k].seq == k);
    CHECK(samples[k].status == SensorStatus::kOk);
    CHECK(samples[k].value_mm == Approx(script[(k + 1) % script.size()]).margin(1e-9));
    CHECK_FALSE(samples[k].t_device.has_value());
  }
  const std::string wire = emulator.received();
  const std::string request = "%01#RMD5C\r";
  REQUIRE(wire.size() % request.size() == 0);
  for (std::size_t i = 0; i < wire.size(); i += request.size())
    CHECK(wire.substr(i, request.size()) == request);
  const auto stats = device.stats();
  CHECK(stats.samples == samples.size());
  CHECK(stats.malformed == 0);
  CHECK(stats.error_replies == 0);
  CHECK(stats.timeouts == 0);
}

TEST_CASE("panasonic_hlg1 device: unit numbers, ** BCC, values without a reading",
          "[drivers][panasonic_hlg1]") {
  TempDir dir;
  const std::string link = (dir / "tty").string();
  scanmesh::sim::PanasonicHlg1Emulator emulator(
      link, scanmesh::sim::scripted_values({1.25, std::nan(""), 3.5}),
      {.unit = 7, .reply_bcc = false});
  emulator.start();
  {
    // Another unit on the bus: nobody answers.
    hlg1::Device other(fast_options(), serial_factory(link), {.unit = 8});
    try {
      other.open();
      FAIL("open() of an absent unit must throw");
    } catch (const DeviceError& e) {
      CHECK(e.kind() == DeviceErrorKind::kTimeout);
      const std::string what = e.what();
      CHECK(what.find("hlg0 (" + link + "): RMD (unit 08): no reply within 100 ms") !=
            std::string::npos);
    }
  }
  hlg1::Device device(fast_options(), serial_factory(link), {.unit = 7, .send_bcc = false});
  device.open();
  SensorCollector collector;
  device.start(collector.callbacks());
  REQUIRE(wait_until([&] { return collector.count() >= 6 && device.stats().error_replies >= 3; }));
  device.stop();
  CHECK(emulator.received().substr(0, 20) == "%08#RMD55\r%07#RMD**\r");
  // No target comes back as an error reply: never a sample with a made-up value.
  for (const auto& s : collector.copy())
    CHECK((s.value_mm == Approx(1.25) || s.value_mm == Approx(3.5)));
  CHECK_THROWS_AS(hlg1::Device(fast_options(), serial_factory(link), {.unit = 100}),
                  scanmesh::ConfigError);
}

TEST_CASE("panasonic_hlg1 device: injected faults are reported and recovered from",
          "[drivers][panasonic_hlg1]") {
  TempDir dir;
  const std::string link = (dir / "tty").string();
  const std::vector<double> script = {1.0, 2.0, 3.0, 4.5};
  scanmesh::sim::PanasonicHlg1Emulator emulator(link, scanmesh::sim::scripted_values(script));
  emulator.start();
  hlg1::Device device(fast_options(), serial_factory(link));
  device.open();
  scanmesh::test::check_fault_recovery(
      emulator, device, {"hlg0", "silent sensor: lost, then back", "RMD: no reply within 100 ms"},
      script, [&](SensorCollector& collector) {
        SECTION("bad BCC") {
          emulator.set_faults({.bad_checksum = true});
          REQUIRE(wait_until([&] { return device.stats().malformed >= 3; }));
          CHECK(collector.quiet());
          emulator.set_faults({});
          CHECK(collector.resumes(3));
        }
      });
}
