// Tests of the Panasonic HL-G1 driver: codec tables, and the device against its pty emulator
// over the real serial transport, with every injected fault.
// SPDX-License-Identifier: MIT
#include <unistd.h>

#include <atomic>
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/panasonic_hlg1/codec.hpp"
#include "scanmesh/drivers/panasonic_hlg1/device.hpp"
#include "scanmesh/drivers/transports/serial_stream.hpp"
#include "scanmesh/sim/emulators/panasonic_hlg1.hpp"

namespace hlg1 = scanmesh::drivers::panasonic_hlg1;
using scanmesh::drivers::DeviceError;
using scanmesh::drivers::DeviceErrorKind;
using scanmesh::drivers::DeviceState;
using scanmesh::drivers::SensorCallbacks;
using scanmesh::drivers::SensorOptions;
using scanmesh::drivers::SensorSample;
using scanmesh::drivers::SensorStatus;
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

struct Decoded {
  std::vector<std::string> replies;
  std::vector<std::string> malformed;
};

Decoded decode_chunks(const std::vector<std::string>& chunks) {
  hlg1::Decoder decoder;
  Decoded out;
  for (const auto& c : chunks)
    decoder.feed(
        std::string_view(c), [&](const hlg1::Reply& r) { out.replies.push_back(describe(r)); },
        [&](const char* why) { out.malformed.emplace_back(why); });
  return out;
}

Decoded decode(const std::string& bytes) { return decode_chunks({bytes}); }

// ---- device helpers ----

class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = std::filesystem::temp_directory_path() /
            ("scanmesh-hlg1-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

struct Collector {
  std::mutex mutex;
  std::vector<SensorSample> samples;
  std::vector<std::pair<DeviceState, std::string>> states;

  SensorCallbacks callbacks() {
    return {[this](const SensorSample& s) {
              std::lock_guard lock(mutex);
              samples.push_back(s);
            },
            [this](DeviceState st, const std::string& reason) {
              std::lock_guard lock(mutex);
              states.emplace_back(st, reason);
            }};
  }
  std::size_t count() {
    std::lock_guard lock(mutex);
    return samples.size();
  }
  std::vector<SensorSample> copy() {
    std::lock_guard lock(mutex);
    return samples;
  }
  bool saw(DeviceState st, const std::string& needle = "") {
    std::lock_guard lock(mutex);
    for (const auto& [s, reason] : states)
      if (s == st && reason.find(needle) != std::string::npos) return true;
    return false;
  }
  std::string state_log() {
    std::lock_guard lock(mutex);
    std::string out;
    for (const auto& [s, reason] : states)
      out += std::string(scanmesh::drivers::to_string(s)) + ": " + reason + "\n";
    return out;
  }
};

template <class Pred>
bool wait_until(Pred pred, std::chrono::milliseconds limit = 4000ms) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(5ms);
  }
  return pred();
}

SensorOptions fast_options() {
  SensorOptions o;
  o.name = "hlg0";
  o.poll_interval = 2ms;
  o.timeout = 100ms;
  o.timeouts_until_lost = 3;
  o.backoff_initial = 20ms;
  o.backoff_max = 200ms;
  return o;
}

scanmesh::drivers::ByteStreamFactory serial_factory(const std::string& link) {
  return [link] {
    return scanmesh::drivers::open_serial_stream("hlg0", {link, hlg1::kDefaultBaud});
  };
}

bool all_in(const std::vector<SensorSample>& samples, std::size_t from,
            const std::vector<double>& allowed) {
  for (std::size_t i = from; i < samples.size(); ++i) {
    if (samples[i].status != SensorStatus::kOk) return false;
    bool found = false;
    for (double a : allowed) found = found || std::fabs(samples[i].value_mm - a) < 1e-9;
    if (!found) return false;
  }
  return true;
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
  struct Case {
    const char* legend;
    std::string input;
    std::vector<std::string> replies;
    std::size_t malformed;
  };
  const std::string rmd = framed("%01$RMD+0025000");
  const std::vector<Case> cases = {
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
  for (const auto& c : cases) {
    INFO(c.legend);
    const Decoded d = decode(c.input);
    CHECK(d.replies == c.replies);
    CHECK(d.malformed.size() == c.malformed);
  }
  hlg1::Reply r;
  REQUIRE(hlg1::parse_reply("%03$RMD-0123456**", r) == nullptr);
  CHECK(r.value_mm() == Approx(-12.3456));  // the manual's example
  REQUIRE(hlg1::parse_reply("%01$RMD+0025000**", r) == nullptr);
  CHECK(r.value_mm() == Approx(2.5));
}

TEST_CASE("panasonic_hlg1 codec: split at every byte boundary", "[drivers][panasonic_hlg1]") {
  const std::string stream = framed("%01$RMD+0025000") + framed("%01!42") + "%03$RMD-0123456**\r" +
                             framed("%01$RSP+00001");
  const Decoded whole = decode(stream);
  REQUIRE(whole.replies.size() == 4);
  REQUIRE(whole.malformed.empty());
  for (std::size_t a = 0; a <= stream.size(); ++a) {
    INFO("split at " << a);
    const Decoded d = decode_chunks({stream.substr(0, a), stream.substr(a)});
    CHECK(d.replies == whole.replies);
    CHECK(d.malformed.empty());
  }
  std::vector<std::string> bytes;
  for (char c : stream) bytes.emplace_back(1, c);
  CHECK(decode_chunks(bytes).replies == whole.replies);
}

// ======================= device against the emulator =======================

TEST_CASE("panasonic_hlg1 device: scripted values, sequence numbers, wire bytes",
          "[drivers][panasonic_hlg1]") {
  TempDir dir;
  const std::string link = dir.file("tty");
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

  Collector collector;
  device.start(collector.callbacks());
  REQUIRE(wait_until([&] { return collector.count() >= 10; }));
  device.stop();
  const std::size_t after_stop = collector.count();
  std::this_thread::sleep_for(30ms);
  CHECK(collector.count() == after_stop);

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
  const std::string link = dir.file("tty");
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
  Collector collector;
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
  const std::string link = dir.file("tty");
  const std::vector<double> script = {1.0, 2.0, 3.0, 4.5};
  scanmesh::sim::PanasonicHlg1Emulator emulator(link, scanmesh::sim::scripted_values(script));
  emulator.start();
  hlg1::Device device(fast_options(), serial_factory(link));
  device.open();
  Collector collector;
  device.start(collector.callbacks());
  REQUIRE(wait_until([&] { return collector.count() >= 3; }));

  auto resumes = [&](std::size_t more) {
    const std::size_t n = collector.count();
    return wait_until([&] { return collector.count() >= n + more; });
  };
  auto quiet = [&] {  // no new sample (but the one in flight) while a fault is active
    const std::size_t n = collector.count();
    std::this_thread::sleep_for(50ms);
    return collector.count() <= n + 1;
  };

  SECTION("garbage before every reply") {
    emulator.set_faults({.garbage_before_reply = true});
    const auto before = device.stats().malformed;
    REQUIRE(wait_until([&] { return device.stats().malformed >= before + 3; }));
    CHECK(resumes(3));
  }
  SECTION("every byte written alone") {
    emulator.set_faults({.split_every_byte = true});
    CHECK(resumes(5));
    CHECK(device.stats().malformed == 0);
  }
  SECTION("bad BCC") {
    emulator.set_faults({.bad_checksum = true});
    REQUIRE(wait_until([&] { return device.stats().malformed >= 3; }));
    CHECK(quiet());
    emulator.set_faults({});
    CHECK(resumes(3));
  }
  SECTION("error replies") {
    emulator.set_faults({.error_reply = true});
    REQUIRE(wait_until([&] { return device.stats().error_replies >= 3; }));
    CHECK(quiet());
    emulator.set_faults({});
    CHECK(resumes(3));
  }
  SECTION("replies later than the timeout") {
    emulator.set_faults({.reply_delay = 250ms});
    REQUIRE(wait_until([&] { return device.stats().timeouts >= 2; }));
    emulator.set_faults({});
    CHECK(resumes(3));
  }
  SECTION("silent sensor: lost, then back") {
    emulator.set_faults({.silent = true});
    REQUIRE(wait_until([&] { return device.state() == DeviceState::kLost; }));
    CHECK(device.stats().timeouts >= 3);
    CHECK(collector.saw(DeviceState::kLost, "hlg0"));
    CHECK(collector.saw(DeviceState::kLost, "RMD: no reply within 100 ms"));
    emulator.set_faults({});
    REQUIRE(wait_until([&] { return device.state() == DeviceState::kAcquiring; }));
    CHECK(device.stats().reconnects >= 1);
    CHECK(resumes(3));
  }
  SECTION("port vanishes, then reappears") {
    emulator.vanish();
    REQUIRE(wait_until([&] { return device.state() == DeviceState::kLost; }));
    CHECK(collector.saw(DeviceState::kLost, "hlg0"));
    std::this_thread::sleep_for(100ms);
    emulator.reappear();
    REQUIRE(wait_until([&] { return device.state() == DeviceState::kAcquiring; }));
    CHECK(device.stats().reconnects >= 1);
    CHECK(resumes(3));
  }
  device.stop();
  INFO(collector.state_log());
  const auto samples = collector.copy();
  CHECK(all_in(samples, 0, script));
  for (std::size_t k = 1; k < samples.size(); ++k) CHECK(samples[k].seq == samples[k - 1].seq + 1);
}
