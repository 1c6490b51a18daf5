// Micro-Epsilon ILD1420: binary stream codec tables (valid blocks, garbage, every split point,
// two blocks per chunk, corrupted marker bits, truncation, every error code, reserve zones,
// mastering), the ASCII reply parser with interleaved binary values, GETINFO, and the device
// against its pty emulator with every injected fault.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/microepsilon_ild1420/codec.hpp"
#include "scanmesh/drivers/microepsilon_ild1420/device.hpp"
#include "scanmesh/drivers/transports/serial_stream.hpp"
#include "scanmesh/sim/emulators/microepsilon_ild1420.hpp"
#include "support/sensor_harness.hpp"
#include "support/temp_dir.hpp"

using namespace std::chrono_literals;
using namespace scanmesh::drivers;
using namespace scanmesh::drivers::microepsilon_ild1420;
using scanmesh::sim::MicroEpsilonIld1420Emulator;
using scanmesh::sim::SerialFaults;

namespace {

using Bytes = std::vector<std::uint8_t>;

Bytes word(std::uint32_t w, bool first = true) {
  const auto a = encode_word(w, first);
  return Bytes(a.begin(), a.end());
}
Bytes cat(std::initializer_list<Bytes> parts) {
  Bytes out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}
Bytes text(std::string_view s) { return Bytes(s.begin(), s.end()); }
/// A block of words, the first with the block-start flag.
Bytes block(std::initializer_list<std::uint32_t> words) {
  Bytes out;
  bool first = true;
  for (auto w : words) {
    const auto b = word(w, first);
    out.insert(out.end(), b.begin(), b.end());
    first = false;
  }
  return out;
}

std::vector<RawBlock> decode_all(StreamDecoder& d, const Bytes& bytes) {
  std::vector<RawBlock> out;
  d.feed(bytes, [&](const RawBlock& b) { out.push_back(b); });
  return out;
}
std::vector<std::uint32_t> words_of(const std::vector<RawBlock>& blocks) {
  std::vector<std::uint32_t> out;
  for (const auto& b : blocks)
    for (int i = 0; i < b.count; ++i) out.push_back(b.words[i]);
  return out;
}

using Collector = scanmesh::test::SensorCollector;
using scanmesh::test::wait_until;

SensorOptions fast_options() { return scanmesh::test::fast_sensor_options("ild0", 150ms); }

ByteStreamFactory serial_factory(const std::string& link) {
  return scanmesh::test::pty_serial_factory("ild0", link, 921600);  // 8N1
}

}  // namespace

TEST_CASE("ild1420 codec: binary stream table", "[drivers][microepsilon]") {
  struct Case {
    const char* legend;
    std::size_t per_block;
    Bytes input;
    std::vector<std::uint32_t> words;  // decoded words of complete blocks, in order
    std::uint64_t malformed;
  };
  const Case cases[] = {
      {"one distance value", 1, word(32760), {32760}, 0},
      {"18-bit error code", 1, word(262076), {262076}, 0},
      {"two values in one chunk", 1, cat({word(1), word(65520)}), {1, 65520}, 0},
      {"leading garbage (ASCII and H-shaped bytes)",
       1,
       cat({text("\xFE\x13~#"), Bytes{0x00}, word(4242)}),
       {4242},
       1},
      {"leading lone M and H bytes", 1, cat({Bytes{0x55, 0xC3}, word(7)}), {7}, 1},
      {"dropped M byte: value lost, next one fine",
       1,
       cat({Bytes{word(100)[0], word(100)[2]}, word(200)}),
       {200},
       1},
      {"dropped L byte", 1, cat({Bytes{word(100)[1], word(100)[2]}, word(200)}), {200}, 1},
      {"corrupted marker (H byte turned into an L)",
       1,
       cat({Bytes{word(100)[0], word(100)[1], 0x05}, word(300)}),
       {300},
       1},
      {"truncated value: nothing yet", 1, Bytes{word(100)[0], word(100)[1]}, {}, 0},
      {"4-value block", 4, block({10, 20, 30, 40}), {10, 20, 30, 40}, 0},
      {"two 4-value blocks",
       4,
       cat({block({1, 2, 3, 4}), block({5, 6, 7, 8})}),
       {1, 2, 3, 4, 5, 6, 7, 8},
       0},
      {"block joined mid-way (additional values first) is skipped",
       4,
       cat({word(3, false), word(4, false), block({5, 6, 7, 8})}),
       {5, 6, 7, 8},
       2},
      {"short block (value lost inside)",
       4,
       cat({word(1, true), word(2, false), Bytes{0x01, 0x81}, word(4, false), block({5, 6, 7, 8})}),
       {5, 6, 7, 8},
       2},
      {"long block",
       2,
       cat({word(1, true), word(2, false), word(3, false), block({5, 6})}),
       {1, 2, 5, 6},
       1},
  };
  for (const auto& c : cases) {
    INFO(c.legend);
    StreamDecoder d(c.per_block);
    CHECK(words_of(decode_all(d, c.input)) == c.words);
    CHECK(d.malformed() == c.malformed);
  }
}

TEST_CASE("ild1420 codec: every split point of two blocks gives the same blocks",
          "[drivers][microepsilon]") {
  const Bytes stream =
      cat({text("\x13\x7E"), block({32760, 17, 0x1234, 0x0002}), block({643, 18, 0x1298, 2})});
  StreamDecoder whole(4);
  const auto expected = words_of(decode_all(whole, stream));
  REQUIRE(expected == std::vector<std::uint32_t>{32760, 17, 0x1234, 2, 643, 18, 0x1298, 2});
  for (std::size_t split = 0; split <= stream.size(); ++split) {
    for (std::size_t split2 = split; split2 <= stream.size(); split2 += 5) {
      StreamDecoder d(4);
      std::vector<RawBlock> got;
      auto sink = [&](const RawBlock& b) { got.push_back(b); };
      d.feed(std::span(stream).first(split), sink);
      d.feed(std::span(stream).subspan(split, split2 - split), sink);
      d.feed(std::span(stream).subspan(split2), sink);
      INFO("split at " << split << " and " << split2);
      CHECK(words_of(got) == expected);
      CHECK(d.malformed() == whole.malformed());
    }
  }
  // One byte at a time.
  StreamDecoder d(4);
  std::vector<RawBlock> got;
  for (auto b : stream) d.feed(std::span(&b, 1), [&](const RawBlock& r) { got.push_back(r); });
  CHECK(words_of(got) == expected);
}

TEST_CASE("ild1420 codec: scaling, reserve zones, mastering and every error code",
          "[drivers][microepsilon]") {
  const Scaling mr10{10, false};
  struct Case {
    const char* legend;
    std::uint32_t raw;
    SensorStatus status;
    double value_mm;  // NaN = no value
  };
  const double nan = std::nan("");
  const Case cases[] = {
      {"mid range x=32760 -> 5 mm", 32760, SensorStatus::kOk, 5.0},
      {"start of range x=643", 643, SensorStatus::kOk, (1.02 * 643 / 65520 - 0.01) * 10},
      {"end of range x=64877", 64877, SensorStatus::kOk, (1.02 * 64877 / 65520 - 0.01) * 10},
      {"SMR reserve x=100: kept, flagged by value only", 100, SensorStatus::kOk,
       (1.02 * 100 / 65520 - 0.01) * 10},
      {"EMR reserve x=65520", 65520, SensorStatus::kOk, 10.1},
      {"not a distance, not a code", 70000, SensorStatus::kDeviceError, nan},
      {"262075 data rate too high", 262075, SensorStatus::kDeviceError, nan},
      {"262076 no peak", 262076, SensorStatus::kNoTarget, nan},
      {"262077 peak before range", 262077, SensorStatus::kOverRange, nan},
      {"262078 peak after range", 262078, SensorStatus::kOverRange, nan},
      {"262079 (undocumented)", 262079, SensorStatus::kDeviceError, nan},
      {"262080 cannot be calculated", 262080, SensorStatus::kDeviceError, nan},
      {"262081 peak too large", 262081, SensorStatus::kDeviceError, nan},
      {"262082 laser off", 262082, SensorStatus::kDeviceError, nan},
  };
  for (const auto& c : cases) {
    INFO(c.legend);
    DecodedBlock out;
    decode_distance(c.raw, mr10, out);
    CHECK(out.status == c.status);
    if (std::isnan(c.value_mm)) {
      CHECK(std::isnan(out.value_mm));
      CHECK(out.device_code == c.raw);
    } else {
      CHECK(out.value_mm == Approx(c.value_mm).margin(1e-9));
      CHECK(out.device_code == 0);
      CHECK(encode_distance(out.value_mm, mr10) == c.raw);
    }
  }
  DecodedBlock m;
  decode_distance(100000, Scaling{50, true}, m);
  CHECK(m.status == SensorStatus::kOk);
  CHECK(m.value_mm == Approx((1.02 * 100000 / 65520 - 0.51) * 50));

  // A whole block with counter and timestamp words.
  RawBlock b;
  b.words = {32760, 262143, 0x5678, 0x0012};
  b.count = 4;
  const DecodedBlock d = decode_block(b, BlockLayout::distance_counter_timestamp(), mr10);
  CHECK(d.status == SensorStatus::kOk);
  CHECK(d.value_mm == Approx(5.0));
  CHECK(d.counter == 262143U);
  REQUIRE(d.t_device.has_value());
  CHECK(d.t_device->ns == ((0x12LL << 16) | 0x5678) * 10'000);
  CHECK(BlockLayout{}.check().empty());
  CHECK_FALSE(BlockLayout{{BlockValue::kCounter}}.check().empty());
  CHECK_FALSE(BlockLayout{{BlockValue::kDistance, BlockValue::kTimestampLow}}.check().empty());
}

TEST_CASE("ild1420 codec: commands and replies with interleaved binary values",
          "[drivers][microepsilon]") {
  CHECK(get_info().encode() == "GETINFO\r");
  CHECK(output(OutputTarget::kNone).encode() == "OUTPUT NONE\r");
  CHECK(output(OutputTarget::kRs422).encode() == "OUTPUT RS422\r");
  CHECK(meas_rate(0.25).encode() == "MEASRATE 0.25\r");

  const std::string info_text =
      "GETINFO\r\nName:     ILD1420-10\r\nSerial:   1234567\r\nArticle:  4120123\r\n"
      "Measuring range: 10.00mm\r\nVersion:  001.002.003\r\n->";
  auto parse = [](const Bytes& in, std::size_t chunk) {
    ReplyParser p;
    std::size_t i = 0;
    while (i < in.size() && !p.done()) {
      const std::size_t n = std::min(chunk, in.size() - i);
      i += p.feed(std::span(in).subspan(i, n));
    }
    if (!p.done()) p.flush();
    return p;
  };
  SECTION("plain reply, and GETINFO parsed") {
    const ReplyParser p = parse(text(info_text), 1000);
    REQUIRE(p.done());
    CHECK(p.reply().ok());
    const Info info = parse_info(p.reply());
    CHECK(info.identity.vendor == "Micro-Epsilon");
    CHECK(info.identity.model == "ILD1420-10");
    CHECK(info.identity.serial == "1234567");
    CHECK(info.identity.firmware == "001.002.003");
    CHECK(info.article == "4120123");
    CHECK(info.measuring_range_mm == 10.0);
  }
  SECTION("binary values between and inside reply lines, split at every byte") {
    Bytes in;
    const std::string t = info_text;
    for (std::size_t i = 0; i < t.size(); ++i) {
      in.push_back(static_cast<std::uint8_t>(t[i]));
      if (i % 7 == 3) {  // a value (whose L/M look like text: '0' + 'A')
        const Bytes w = word(0x30 | (0x01 << 6) | (0x05 << 12));
        in.insert(in.end(), w.begin(), w.end());
      }
    }
    for (std::size_t chunk : {std::size_t{1}, std::size_t{2}, std::size_t{5}, in.size()}) {
      INFO("chunk " << chunk);
      const ReplyParser p = parse(in, chunk);
      REQUIRE(p.done());
      const Info info = parse_info(p.reply());
      CHECK(info.identity.model == "ILD1420-10");
      CHECK(info.measuring_range_mm == 10.0);
      CHECK(p.reply().lines.size() == 6);
      CHECK(p.binary_bytes_removed() > 0);
    }
  }
  SECTION("errors and warnings") {
    const ReplyParser e = parse(text("MASTERMV MASTER 5\r\nE104 Timeout\r\n->"), 3);
    REQUIRE(e.done());
    CHECK_FALSE(e.reply().ok());
    CHECK(e.reply().error == "E104 Timeout");
    const ReplyParser w = parse(text("MEASRATE 4\r\nW320 value adjusted\r\n->"), 100);
    REQUIRE(w.done());
    CHECK(w.reply().ok());
    CHECK(w.reply().warnings == std::vector<std::string>{"W320 value adjusted"});
  }
  SECTION("the stream right after the prompt is handed back") {
    const Bytes in = cat({text("OUTPUT RS422\r\n->"), word(32760), word(100)});
    ReplyParser p;
    const std::size_t used = p.feed(in);
    REQUIRE(p.done());
    Bytes rest = p.take_after_prompt();
    rest.insert(rest.end(), in.begin() + static_cast<std::ptrdiff_t>(used), in.end());
    CHECK(rest == cat({word(32760), word(100)}));
  }
  SECTION("overlong line and a truncated reply") {
    ReplyParser p(16);
    p.feed(text(std::string(40, 'x') + "\r\nOK\r\n"));
    CHECK_FALSE(p.done());
    CHECK(p.overlong_lines() == 1);
    p.flush();
    CHECK_FALSE(p.done());
    p.feed(text("->"));
    p.flush();
    REQUIRE(p.done());
    CHECK(p.reply().lines == std::vector<std::string>{"OK"});
  }
}

TEST_CASE("ild1420 device: identity, values, exact commands on the wire",
          "[drivers][microepsilon]") {
  scanmesh::test::TempDir dir;
  const std::string link = (dir / "ttyILD").string();
  MicroEpsilonIld1420Emulator emu(link, scanmesh::sim::scripted_values({1.0, 2.5, 7.25}));
  emu.start();
  Device dev(fast_options(), serial_factory(link));
  dev.open();
  CHECK_FALSE(emu.streaming());
  CHECK(dev.identify().model == "ILD1420-10");
  CHECK(dev.identify().serial == "1234567");
  CHECK(dev.measuring_range_mm() == 10.0);
  CHECK(dev.capabilities().streaming);
  CHECK(dev.capabilities().max_rate_hz == 4000);
  Collector c;
  dev.start(c.callbacks());
  REQUIRE(wait_until([&] { return c.count() >= 30; }));
  scanmesh::test::stop_and_check_quiet(dev, c);
  CHECK(emu.received() == "OUTPUT NONE\rGETINFO\rOUTPUT RS422\r");
  const auto samples = c.copy();
  // Values quantised to 1.02 * 10 / 65520 mm; the script cycles 1.0, 2.5, 7.25.
  std::size_t k = 0;
  while (k < 3 && std::abs(samples[0].value_mm - std::vector<double>{1.0, 2.5, 7.25}[k]) > 1e-3)
    ++k;
  REQUIRE(k < 3);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    INFO(i);
    CHECK(samples[i].seq == i);
    CHECK(samples[i].status == SensorStatus::kOk);
    CHECK(samples[i].value_mm ==
          Approx(std::vector<double>{1.0, 2.5, 7.25}[(k + i) % 3]).margin(2e-4));
  }
  CHECK(dev.stats().malformed == 0);
}

TEST_CASE("ild1420 device: counter + timestamp blocks, gaps from dropped bytes",
          "[drivers][microepsilon]") {
  scanmesh::test::TempDir dir;
  const std::string link = (dir / "ttyILD").string();
  scanmesh::sim::Ild1420EmulatorOptions eo;
  eo.layout = "dclh";
  eo.measuring_range_mm = 50;
  MicroEpsilonIld1420Emulator emu(link, scanmesh::sim::scripted_values({12.5}), eo);
  emu.start();
  Options io;
  io.layout = BlockLayout::distance_counter_timestamp();
  Device dev(fast_options(), serial_factory(link), io);
  dev.open();
  CHECK(dev.measuring_range_mm() == 50.0);
  CHECK(dev.capabilities().device_clock);
  Collector c;
  dev.start(c.callbacks());
  REQUIRE(wait_until([&] { return c.count() >= 20; }));
  CHECK(dev.stats().gaps == 0);
  emu.set_faults(SerialFaults{false, false, true, false, false, 0ms});  // dropped M bytes
  REQUIRE(wait_until([&] { return dev.stats().gaps >= 3 && dev.stats().malformed >= 3; }));
  emu.set_faults({});
  const auto before = c.count();
  REQUIRE(wait_until([&] { return c.count() >= before + 10; }));
  dev.stop();
  const auto samples = c.copy();
  for (std::size_t i = 0; i < samples.size(); ++i) {
    INFO(i);
    CHECK(samples[i].status == SensorStatus::kOk);
    CHECK(samples[i].value_mm == Approx(12.5).margin(1e-3));
    REQUIRE(samples[i].t_device.has_value());
    if (i > 0) {
      CHECK(samples[i].seq > samples[i - 1].seq);
      // seq and the device clock advance together (1 ms per block), gaps included.
      CHECK((samples[i].t_device->ns - samples[i - 1].t_device->ns) ==
            static_cast<std::int64_t>(samples[i].seq - samples[i - 1].seq) * 1'000'000);
    }
  }
  CHECK(samples.back().seq + 1 == samples.size() + dev.stats().gaps);
}

TEST_CASE("ild1420 device: error-code values become statuses, never values",
          "[drivers][microepsilon]") {
  scanmesh::test::TempDir dir;
  const std::string link = (dir / "ttyILD").string();
  std::uint64_t i = 0;
  scanmesh::sim::ValueSource src = [i]() mutable {
    SensorSample s;
    switch (i++ % 5) {
      case 0:
        s.status = SensorStatus::kOk;
        s.value_mm = 3.0;
        break;
      case 1:
        s.status = SensorStatus::kNoTarget;
        break;
      case 2:
        s.status = SensorStatus::kOverRange;
        s.value_mm = INFINITY;
        break;
      case 3:
        s.status = SensorStatus::kDeviceError;
        s.device_code = 262075;
        break;
      default:
        s.status = SensorStatus::kOverRange;
        s.value_mm = -INFINITY;
        break;
    }
    return s;
  };
  MicroEpsilonIld1420Emulator emu(link, src);
  emu.start();
  Device dev(fast_options(), serial_factory(link));
  dev.open();
  Collector c;
  dev.start(c.callbacks());
  REQUIRE(wait_until([&] { return c.count() >= 25; }));
  dev.stop();
  int seen[5] = {};
  for (const auto& s : c.copy()) {
    if (s.status == SensorStatus::kOk) {
      CHECK(s.value_mm == Approx(3.0).margin(2e-4));
      ++seen[0];
      continue;
    }
    CHECK(std::isnan(s.value_mm));
    if (s.device_code == 262076) {
      CHECK(s.status == SensorStatus::kNoTarget);
      ++seen[1];
    }
    if (s.device_code == 262078) {
      CHECK(s.status == SensorStatus::kOverRange);
      ++seen[2];
    }
    if (s.device_code == 262075) {
      CHECK(s.status == SensorStatus::kDeviceError);
      ++seen[3];
    }
    if (s.device_code == 262077) {
      CHECK(s.status == SensorStatus::kOverRange);
      ++seen[4];
    }
  }
  for (int k = 0; k < 5; ++k) CHECK(seen[k] >= 4);
}

TEST_CASE("ild1420 device: garbage, split bytes, late and missing data, vanish; recovery",
          "[drivers][microepsilon]") {
  scanmesh::test::TempDir dir;
  const std::string link = (dir / "ttyILD").string();
  MicroEpsilonIld1420Emulator emu(link, scanmesh::sim::scripted_values({4.0}));
  emu.start();
  Device dev(fast_options(), serial_factory(link));
  dev.open();
  Collector c;
  dev.start(c.callbacks());
  REQUIRE(wait_until([&] { return c.count() >= 5; }));

  SECTION("garbage before every block: counted, values intact") {
    emu.set_faults(SerialFaults{true, false, false, false, false, 0ms});
    REQUIRE(wait_until([&] { return dev.stats().malformed >= 5; }));
    const auto n = c.count();
    REQUIRE(wait_until([&] { return c.count() >= n + 5; }));
  }
  SECTION("every byte in its own write") {
    emu.set_faults(SerialFaults{false, true, false, false, false, 0ms});
    const auto n = c.count();
    REQUIRE(wait_until([&] { return c.count() >= n + 20; }));
    CHECK(dev.stats().malformed == 0);
  }
  SECTION("data later than the timeout: timeouts, then lost, then back") {
    emu.set_faults(SerialFaults{false, false, false, false, false, 400ms});
    REQUIRE(wait_until([&] { return dev.stats().timeouts >= 1; }));
    emu.set_faults({});
    const auto n = c.count();
    REQUIRE(
        wait_until([&] { return c.count() >= n + 10 && dev.state() == DeviceState::kAcquiring; }));
  }
  SECTION("silence -> kLost, then reconnect when it talks again") {
    emu.set_faults(SerialFaults{false, false, false, false, true, 0ms});
    REQUIRE(wait_until([&] { return dev.state() == DeviceState::kLost; }));
    CHECK_THAT(c.reason(DeviceState::kLost),
               Catch::StartsWith("ild0: lost: no data for 3 x 150 ms"));
    CHECK(dev.stats().timeouts >= 3);
    emu.set_faults({});
    REQUIRE(wait_until([&] { return dev.stats().reconnects >= 1; }));
    const auto n = c.count();
    REQUIRE(wait_until([&] { return c.count() >= n + 10; }));
    CHECK(dev.state() == DeviceState::kAcquiring);
  }
  SECTION("the port vanishes and comes back") {
    emu.vanish();
    REQUIRE(wait_until([&] { return dev.state() == DeviceState::kLost; }));
    CHECK_THAT(c.reason(DeviceState::kLost), Catch::StartsWith("ild0: lost: ild0 ("));
    emu.reappear();
    REQUIRE(wait_until([&] { return dev.stats().reconnects >= 1; }));
    const auto n = c.count();
    REQUIRE(wait_until([&] { return c.count() >= n + 10; }));
  }
  dev.stop();
  const auto samples = c.copy();
  for (std::size_t i = 0; i < samples.size(); ++i) {
    CHECK(samples[i].status == SensorStatus::kOk);
    CHECK(samples[i].value_mm == Approx(4.0).margin(2e-4));
    if (i > 0) CHECK(samples[i].seq == samples[i - 1].seq + 1);
  }
}

TEST_CASE("ild1420 device: open() errors and the configured measuring range",
          "[drivers][microepsilon]") {
  scanmesh::test::TempDir dir;
  const std::string link = (dir / "ttyILD").string();
  scanmesh::sim::Ild1420EmulatorOptions eo;
  eo.report_measuring_range = false;
  MicroEpsilonIld1420Emulator emu(link, scanmesh::sim::scripted_values({2.0}), eo);
  emu.start();
  {
    Device dev(fast_options(), serial_factory(link));
    try {
      dev.open();
      FAIL("opened without a measuring range");
    } catch (const DeviceError& e) {
      CHECK(e.kind() == DeviceErrorKind::kProtocol);
      CHECK(e.operation() == "GETINFO");
      CHECK(e.device() == "ild0 (" + link + ")");
    }
  }
  Options io;
  io.measuring_range_mm = 25;
  {
    Device dev(fast_options(), serial_factory(link), io);
    dev.open();
    CHECK(dev.measuring_range_mm() == 25.0);
  }
  emu.set_faults(SerialFaults{false, false, false, true, false, 0ms});  // E... replies
  {
    Device dev(fast_options(), serial_factory(link), io);
    CHECK_THROWS_WITH(dev.open(), Catch::Contains("OUTPUT NONE: E200"));
  }
  emu.set_faults(SerialFaults{false, false, false, false, true, 0ms});  // silent
  {
    Device dev(fast_options(), serial_factory(link), io);
    CHECK_THROWS_WITH(dev.open(), "ild0 (" + link + "): OUTPUT NONE: no reply within 150 ms");
  }
  CHECK_THROWS_AS(Device(fast_options(), serial_factory(link), Options{-1, {}, false, 4000}),
                  scanmesh::ConfigError);
}
