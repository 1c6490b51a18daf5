// Generic Modbus sensor: register decoding tables (incl. the Baumer manual example), map
// validation, request planning, the TOML profile, and the device against the Modbus emulators
// (TCP on 127.0.0.1 and RTU over a pty) with every injected fault.
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/modbus_sensor/codec.hpp"
#include "scanmesh/drivers/modbus_sensor/device.hpp"
#include "scanmesh/drivers/modbus_sensor/profile.hpp"
#include "scanmesh/drivers/transports/modbus_bus.hpp"
#include "scanmesh/sim/emulators/modbus_emulator.hpp"
#include "support/sensor_harness.hpp"
#include "support/temp_dir.hpp"

using namespace std::chrono_literals;
using namespace scanmesh::drivers;
using namespace scanmesh::drivers::modbus_sensor;
using scanmesh::sim::ModbusFaults;
using scanmesh::sim::ModbusTcpEmulator;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

RegisterField field(std::string name, std::uint16_t address, FieldType type,
                    WordOrder order = WordOrder::kLowFirst, double scale = 1, double offset = 0,
                    int bit = -1) {
  return {std::move(name), RegisterKind::kInput, address, type, order, scale, offset, bit};
}

using Collector = scanmesh::test::SensorCollector;
using scanmesh::test::wait_until;

SensorOptions fast_options(std::string name = "om0") {
  return scanmesh::test::fast_sensor_options(std::move(name), 150ms);
}

RegisterBusFactory tcp_factory(int port) {
  return scanmesh::test::tcp_modbus_factory("om0", port, 150ms);
}

std::string baumer_profile_path() {
  return (std::filesystem::path(__FILE__).parent_path() / ".." / ".." / "config" / "devices" /
          "baumer-om30.toml")
      .lexically_normal()
      .string();
}

}  // namespace

TEST_CASE("modbus codec: field decoding table", "[drivers][modbus]") {
  struct Case {
    const char* legend;
    RegisterField f;
    std::vector<std::uint16_t> regs;
    double expected;
  };
  const Case cases[] = {
      {"u16", field("quality", 0, FieldType::kU16), {0xFFFF}, 65535},
      {"i16 negative", field("quality", 0, FieldType::kI16), {0xFFFE}, -2},
      {"u32 low word first", field("distance", 0, FieldType::kU32), {0x5678, 0x1234}, 0x12345678},
      {"u32 high word first",
       field("distance", 0, FieldType::kU32, WordOrder::kHighFirst),
       {0x1234, 0x5678},
       0x12345678},
      {"i32 high first -123456 (Leadshine style)",
       field("distance", 0, FieldType::kI32, WordOrder::kHighFirst),
       {0xFFFE, 0x1DC0},
       -123456},
      {"i32 low first -1", field("distance", 0, FieldType::kI32), {0xFFFF, 0xFFFF}, -1},
      {"u16 scale+offset",
       field("distance", 0, FieldType::kU16, WordOrder::kLowFirst, 0.01, 5),
       {1234},
       17.34},
      {"bit 1 set", field("alarm", 0, FieldType::kU16, WordOrder::kLowFirst, 1, 0, 1), {0x0003}, 1},
      {"bit 1 clear",
       field("alarm", 0, FieldType::kU16, WordOrder::kLowFirst, 1, 0, 1),
       {0x0001},
       0},
      {"bit 17 of u32",
       field("alarm", 0, FieldType::kU32, WordOrder::kLowFirst, 1, 0, 17),
       {0x0000, 0x0002},
       1},
  };
  for (const auto& c : cases) {
    INFO(c.legend);
    CHECK(decode_field(c.f, c.regs) == Approx(c.expected));
    std::vector<std::uint16_t> back(c.regs.size());
    encode_field(c.f, c.expected, back);
    CHECK(decode_field(c.f, back) == Approx(c.expected));
  }
  // Too few registers: NaN, never a read past the end.
  CHECK(std::isnan(
      decode_field(field("distance", 0, FieldType::kF32), std::vector<std::uint16_t>{0x7C37})));
}

TEST_CASE("modbus codec: Baumer manual example 202=0x7C37 203=0x428B is 69.7426 mm",
          "[drivers][modbus]") {
  const RegisterMap map = baumer_om30_map();
  const RegisterField* d = map.find("distance");
  REQUIRE(d != nullptr);
  const std::vector<std::uint16_t> regs = {0x7C37, 0x428B};
  CHECK(decode_field(*d, regs) == Approx(69.7426).margin(1e-4));
  // Read high word first by mistake, it would be garbage: the word order matters.
  RegisterField wrong = *d;
  wrong.word_order = WordOrder::kHighFirst;
  CHECK(std::abs(decode_field(wrong, regs) - 69.7426) > 1);
}

TEST_CASE("modbus codec: Baumer map plans one 13-register FC04 request and decodes status",
          "[drivers][modbus]") {
  const MapDecoder dec(baumer_om30_map());
  REQUIRE(dec.blocks().size() == 1);
  CHECK(dec.blocks()[0].kind == RegisterKind::kInput);
  CHECK(dec.blocks()[0].address == 200);
  CHECK(dec.blocks()[0].count == 13);
  CHECK(dec.image_size() == 13);

  auto image = [](std::uint16_t quality, std::uint16_t outputs, std::uint16_t lo,
                  std::uint16_t hi) {
    std::vector<std::uint16_t> im(13, 0);
    im[0] = quality;
    im[1] = outputs;
    im[2] = lo;
    im[3] = hi;
    im[9] = 12;      // 209-210: 12 s
    im[11] = 34567;  // 211-212: 34567 us
    return im;
  };
  struct Case {
    const char* legend;
    std::vector<std::uint16_t> im;
    SensorStatus status;
    std::uint32_t code;
  };
  const Case cases[] = {
      {"ok", image(0, 1, 0x7C37, 0x428B), SensorStatus::kOk, 0},
      {"weak quality still ok", image(1, 0, 0x7C37, 0x428B), SensorStatus::kOk, 0},
      {"critical quality -> alarm", image(2, 0, 0x7C37, 0x428B), SensorStatus::kAlarm, 2},
      {"alarm bit -> alarm, code = outputs", image(0, 3, 0x7C37, 0x428B), SensorStatus::kAlarm, 3},
      {"NaN distance -> no target", image(2, 0, 0x0000, 0x7FC0), SensorStatus::kNoTarget, 0},
      {"+inf distance -> no target", image(2, 0, 0x0000, 0x7F80), SensorStatus::kNoTarget, 0},
  };
  for (const auto& c : cases) {
    INFO(c.legend);
    const Measurement m = dec.decode(c.im);
    CHECK(m.status == c.status);
    CHECK(m.device_code == c.code);
    if (c.status == SensorStatus::kOk) {
      CHECK(m.value_mm == Approx(69.7426).margin(1e-4));
    } else {
      CHECK(std::isnan(m.value_mm));
    }
    REQUIRE(m.t_device.has_value());
    CHECK(m.t_device->ns == 12'034'567'000LL);
  }
}

TEST_CASE("modbus codec: a device timestamp too large for int64 nanoseconds is dropped, not "
          "overflowed",
          "[drivers][modbus]") {
  // A fuzzer found 2.3e9 s plus 8.5e15 us (a scaled u32 field) overflowing the nanosecond sum.
  RegisterMap m;
  m.fields = {field("distance", 0, FieldType::kF32), field("timestamp_s", 2, FieldType::kU32),
              field("timestamp_us", 4, FieldType::kU32, WordOrder::kLowFirst, 2e6)};
  const MapDecoder dec(m);
  auto image = [](std::uint32_t s, std::uint32_t us) {
    return std::vector<std::uint16_t>{0x7C37, 0x428B, static_cast<std::uint16_t>(s & 0xFFFF),
                                      static_cast<std::uint16_t>(s >> 16),
                                      static_cast<std::uint16_t>(us & 0xFFFF),
                                      static_cast<std::uint16_t>(us >> 16)};
  };
  const Measurement bad = dec.decode(image(2'307'492'233U, 4'234'644'142U));
  CHECK(bad.status == SensorStatus::kOk);
  CHECK_FALSE(bad.t_device.has_value());
  // About 124 years of seconds still give a timestamp, to the nanosecond.
  const Measurement far = dec.decode(image(3'900'000'000U, 5));
  REQUIRE(far.t_device.has_value());
  CHECK(far.t_device->ns == 3'900'000'000'000'000'000LL + 10'000'000'000LL);
}

TEST_CASE("modbus codec: request planning merges gaps, splits kinds and far fields",
          "[drivers][modbus]") {
  RegisterMap m;
  m.fields = {field("distance", 10, FieldType::kF32), field("quality", 5, FieldType::kU16),
              field("status", 200, FieldType::kU16)};
  RegisterField holding = field("alarm", 11, FieldType::kU16);
  holding.kind = RegisterKind::kHolding;
  m.fields.push_back(holding);
  const MapDecoder dec(m);
  REQUIRE(dec.blocks().size() == 3);
  CHECK((dec.blocks()[0].address == 11 && dec.blocks()[0].count == 1 &&
         dec.blocks()[0].kind == RegisterKind::kHolding));
  CHECK((dec.blocks()[1].address == 5 && dec.blocks()[1].count == 7));
  CHECK((dec.blocks()[2].address == 200 && dec.blocks()[2].count == 1));
  // A 125-register limit: a far field in the same kind starts a new block.
  RegisterMap wide;
  wide.max_gap = 100;
  wide.fields = {field("distance", 0, FieldType::kF32), field("quality", 99, FieldType::kU16),
                 field("status", 124, FieldType::kU32)};
  const MapDecoder dw(wide);
  REQUIRE(dw.blocks().size() == 2);
  CHECK(dw.blocks()[0].count == 100);
  CHECK((dw.blocks()[1].address == 124 && dw.blocks()[1].count == 2));
}

TEST_CASE("modbus codec: map validation reports every bad field at once", "[drivers][modbus]") {
  RegisterMap m;
  m.profile = "bad";
  m.fields = {field("quality", 0, FieldType::kU16, WordOrder::kLowFirst, 0),
              field("quality", 1, FieldType::kF32, WordOrder::kLowFirst, 1, kNaN, 3),
              field("distanse", 65535, FieldType::kU32)};
  try {
    m.validate();
    FAIL("accepted");
  } catch (const scanmesh::ConfigError& e) {
    const std::string msg = e.what();
    CHECK_THAT(msg, Catch::StartsWith("register map bad: "));
    CHECK_THAT(msg, Catch::Contains("field 1 (quality): scale must be finite and non-zero"));
    CHECK_THAT(msg, Catch::Contains("field 2 (quality): duplicate name"));
    CHECK_THAT(msg, Catch::Contains("field 2 (quality): offset must be finite"));
    CHECK_THAT(msg, Catch::Contains("field 2 (quality): bit needs an integer type"));
    CHECK_THAT(msg, Catch::Contains("field 3 (distanse): unknown name"));
    CHECK_THAT(msg, Catch::Contains("field 3 (distanse): address + size exceeds 65535"));
    CHECK_THAT(msg, Catch::Contains("no \"distance\" field"));
  }
  CHECK_NOTHROW(baumer_om30_map().validate());
  CHECK(decode_string(scanmesh::sim::pack_register_string("Baumer", 16)) == "Baumer");
  CHECK(decode_string(std::vector<std::uint16_t>{0x4F4D, 0x3330, 0x2020}) == "OM30");
}

TEST_CASE("modbus profile: the shipped baumer-om30.toml equals the built-in map",
          "[drivers][modbus]") {
  const RegisterMap file = load_register_map_profile(baumer_profile_path());
  const RegisterMap built = baumer_om30_map();
  CHECK(file.profile == "baumer-om30");
  REQUIRE(file.fields.size() == built.fields.size());
  for (std::size_t i = 0; i < built.fields.size(); ++i) {
    INFO(built.fields[i].name);
    CHECK(file.fields[i].name == built.fields[i].name);
    CHECK(file.fields[i].kind == built.fields[i].kind);
    CHECK(file.fields[i].address == built.fields[i].address);
    CHECK(file.fields[i].type == built.fields[i].type);
    CHECK(file.fields[i].word_order == built.fields[i].word_order);
    CHECK(file.fields[i].scale == built.fields[i].scale);
    CHECK(file.fields[i].offset == built.fields[i].offset);
    CHECK(file.fields[i].bit == built.fields[i].bit);
  }
  for (auto [a, b] :
       {std::pair{&file.vendor, &built.vendor}, std::pair{&file.model, &built.model},
        std::pair{&file.serial, &built.serial}, std::pair{&file.firmware, &built.firmware}}) {
    REQUIRE(a->has_value());
    CHECK((*a)->address == (*b)->address);
    CHECK((*a)->count == (*b)->count);
  }
  CHECK(file.quality_critical == built.quality_critical);
}

TEST_CASE("modbus profile: errors name the file and every bad key", "[drivers][modbus]") {
  scanmesh::test::TempDir dir;
  const std::string path = (dir / "bad.toml").string();
  {
    std::ofstream f(path);
    f << "max_gap = 500\nspeed = 3\n[identity]\nvendor = { address = 0 }\n"
         "[[field]]\nname = \"distance\"\naddress = 202\ntype = \"f64\"\n"
         "[[field]]\nname = \"quality\"\naddress = \"x\"\ntype = \"u16\"\nword_order = \"le\"\n";
  }
  try {
    (void)load_register_map_profile(path);
    FAIL("accepted");
  } catch (const scanmesh::ConfigError& e) {
    const std::string msg = e.what();
    CHECK_THAT(msg, Catch::StartsWith(path + ": "));
    CHECK_THAT(msg, Catch::Contains("max_gap: must be in 0 .. 100"));
    CHECK_THAT(msg, Catch::Contains("speed: unknown key"));
    CHECK_THAT(msg, Catch::Contains("identity.vendor.count: missing"));
    CHECK_THAT(msg, Catch::Contains("field[1].type: unknown type \"f64\""));
    CHECK_THAT(msg, Catch::Contains("field[2].address: must be a number"));
    CHECK_THAT(msg, Catch::Contains("field[2].word_order"));
  }
  {
    std::ofstream f(path);
    f << "[[field]\nname = ";
  }
  CHECK_THROWS_WITH(load_register_map_profile(path), Catch::StartsWith(path + ":1:"));
  CHECK_THROWS_AS(load_register_map_profile((dir / "missing.toml").string()),
                  scanmesh::ConfigError);
}

TEST_CASE("modbus sensor device: Baumer OM30 over TCP, values, identity, wire requests",
          "[drivers][modbus]") {
  ModbusTcpEmulator emu(scanmesh::sim::scripted_values({10.5, 20.25, kNaN, 30.0}),
                        scanmesh::sim::baumer_om30_image(), 1, 0);
  scanmesh::sim::write_baumer_om30_identity(emu, "Baumer Electric AG", "OM30-P0100.HV.YUN",
                                            "12345678", "1.2.3");
  emu.start();
  const int port = emu.port();
  Device dev(fast_options(), tcp_factory(port), baumer_om30_map());
  dev.open();
  CHECK(dev.state() == DeviceState::kOpen);
  const DeviceIdentity id = dev.identify();
  CHECK(id.vendor == "Baumer Electric AG");
  CHECK(id.model == "OM30-P0100.HV.YUN");
  CHECK(id.serial == "12345678");
  CHECK(id.firmware == "1.2.3");
  CHECK(dev.capabilities().device_clock);
  CHECK_FALSE(dev.capabilities().streaming);

  const auto opened = emu.requests();
  REQUIRE(opened.size() == 5);  // 4 identity strings + one measurement read
  CHECK((opened[0].function == 4 && opened[0].address == 0 && opened[0].count == 16));
  CHECK((opened[1].address == 32 && opened[1].count == 26));
  CHECK((opened[2].address == 95 && opened[2].count == 10));
  CHECK((opened[3].address == 110 && opened[3].count == 5));
  CHECK((opened[4].function == 4 && opened[4].address == 200 && opened[4].count == 13));

  Collector c;
  dev.start(c.callbacks());
  REQUIRE(wait_until([&] { return c.count() >= 8; }));
  scanmesh::test::stop_and_check_quiet(dev, c);

  const auto samples = c.copy();
  // The emulator took measurement 0 during open() (not for the identity reads); samples
  // continue the script from 1.
  const double script[] = {10.5, 20.25, kNaN, 30.0};
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const double want = script[(i + 1) % 4];
    INFO("sample " << i);
    CHECK(samples[i].seq == i);
    if (std::isnan(want)) {
      CHECK(samples[i].status == SensorStatus::kNoTarget);
      CHECK(std::isnan(samples[i].value_mm));
    } else {
      CHECK(samples[i].status == SensorStatus::kOk);
      CHECK(samples[i].value_mm == Approx(want));
    }
    REQUIRE(samples[i].t_device.has_value());
    CHECK(samples[i].t_device->ns == static_cast<std::int64_t>(i + 1) * 1'000'000);
    if (i > 0) CHECK(samples[i].t_host >= samples[i - 1].t_host);
  }
  for (const auto& r : emu.requests()) {
    CHECK(r.function == 4);
    CHECK(r.unit == 1);
  }
  const auto st = dev.stats();
  CHECK(st.samples == samples.size());
  CHECK(st.error_replies == 0);
  CHECK(st.timeouts == 0);
}

TEST_CASE("modbus sensor device: exceptions, late replies, silence, vanish; then recovery",
          "[drivers][modbus]") {
  ModbusTcpEmulator emu(scanmesh::sim::scripted_values({42.0}), scanmesh::sim::baumer_om30_image(),
                        1, 0);
  emu.start();
  const int port = emu.port();
  Device dev(fast_options(), tcp_factory(port), baumer_om30_map());
  dev.open();
  Collector c;
  dev.start(c.callbacks());
  REQUIRE(wait_until([&] { return c.count() >= 3; }));

  SECTION("exception replies are counted, give no sample, and stop when the fault stops") {
    emu.set_faults(ModbusFaults{4, 0ms, false});
    REQUIRE(wait_until([&] { return dev.stats().error_replies >= 3; }));
    const auto n = c.count();
    std::this_thread::sleep_for(20ms);
    CHECK(c.count() == n);
    emu.set_faults({});
    REQUIRE(wait_until([&] { return c.count() >= n + 3; }));
    CHECK(dev.state() == DeviceState::kAcquiring);
  }
  SECTION("a late reply is a timeout; recovery without becoming lost") {
    emu.set_faults(ModbusFaults{0, 250ms, false});
    REQUIRE(wait_until([&] { return dev.stats().timeouts >= 1; }));
    emu.set_faults({});
    const auto n = c.count();
    REQUIRE(wait_until([&] { return c.count() >= n + 3; }));
  }
  SECTION("silence -> kLost after timeouts_until_lost, then back to kAcquiring") {
    emu.set_faults(ModbusFaults{0, 0ms, true});
    REQUIRE(wait_until([&] { return c.saw(DeviceState::kLost); }));
    CHECK(dev.stats().timeouts >= 3);
    CHECK_THAT(c.reason(DeviceState::kLost), Catch::StartsWith("om0: lost: 3 consecutive"));
    emu.set_faults({});
    REQUIRE(wait_until([&] { return dev.stats().reconnects >= 1; }));
    CHECK(dev.state() == DeviceState::kAcquiring);
    const auto n = c.count();
    REQUIRE(wait_until([&] { return c.count() >= n + 3; }));
  }
  SECTION("the server vanishes -> kLost at once; it reappears -> reconnect") {
    emu.vanish();
    REQUIRE(wait_until([&] { return dev.state() == DeviceState::kLost; }));
    CHECK_THAT(c.reason(DeviceState::kLost), Catch::Contains("om0") && Catch::Contains("lost"));
    std::this_thread::sleep_for(100ms);  // a few refused reconnection attempts
    CHECK(dev.stats().reconnects == 0);
    emu.reappear();
    REQUIRE(wait_until([&] { return dev.stats().reconnects >= 1; }));
    const auto n = c.count();
    REQUIRE(wait_until([&] { return c.count() >= n + 3; }));
    CHECK(dev.state() == DeviceState::kAcquiring);
  }
  dev.stop();
  for (const auto& s : c.copy()) {
    CHECK(s.status == SensorStatus::kOk);  // nothing corrupt was ever delivered
    CHECK(s.value_mm == Approx(42.0));
  }
  const auto samples = c.copy();
  for (std::size_t i = 1; i < samples.size(); ++i) CHECK(samples[i].seq == samples[i - 1].seq + 1);
}

TEST_CASE("modbus sensor device: open() errors name the device and the operation",
          "[drivers][modbus]") {
  ModbusTcpEmulator emu(scanmesh::sim::scripted_values({1.0}), scanmesh::sim::baumer_om30_image(),
                        1, 0);
  emu.start();
  const int port = emu.port();
  emu.set_faults(ModbusFaults{2, 0ms, false});
  Device dev(fast_options(), tcp_factory(port), baumer_om30_map());
  try {
    dev.open();
    FAIL("opened");
  } catch (const DeviceError& e) {
    CHECK(e.kind() == DeviceErrorKind::kProtocol);
    CHECK_THAT(std::string(e.what()), Catch::StartsWith("om0 (tcp 127.0.0.1:"));
    CHECK_THAT(e.operation(), Catch::StartsWith("identify: FC04"));
    CHECK_THAT(e.detail(), Catch::Contains("Illegal data address"));
  }
  emu.vanish();
  CHECK_THROWS_AS(dev.open(), DeviceError);
  // An invalid map is a ConfigError at construction.
  RegisterMap bad;
  CHECK_THROWS_AS(Device(fast_options(), nullptr, bad), scanmesh::ConfigError);
}

TEST_CASE("modbus sensor device: Baumer OM30 over RTU on a pty", "[drivers][modbus]") {
  scanmesh::test::TempDir dir;
  const std::string link = (dir / "ttyOM30").string();
  scanmesh::sim::ModbusRtuEmulator emu(link, scanmesh::sim::scripted_values({5.0, 6.0}),
                                       scanmesh::sim::baumer_om30_image(), 1);
  scanmesh::sim::write_baumer_om30_identity(emu, "Baumer", "OM30", "42", "2.0");
  emu.start();
  Device dev(
      fast_options(), [link] { return open_modbus_rtu("om0", link, 115200, 'N', 8, 1, 1, 150ms); },
      load_register_map_profile(baumer_profile_path()));
  dev.open();
  CHECK(dev.identify().model == "OM30");
  Collector c;
  dev.start(c.callbacks());
  REQUIRE(wait_until([&] { return c.count() >= 4; }));
  emu.vanish();
  REQUIRE(wait_until([&] { return dev.state() == DeviceState::kLost; }));
  emu.reappear();
  REQUIRE(wait_until([&] { return dev.stats().reconnects >= 1; }));
  const auto n = c.count();
  REQUIRE(wait_until([&] { return c.count() >= n + 2; }));
  dev.stop();
  for (const auto& s : c.copy()) {
    CHECK(s.status == SensorStatus::kOk);
    CHECK((s.value_mm == Approx(5.0) || s.value_mm == Approx(6.0)));
  }
}
