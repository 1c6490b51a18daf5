// Sensor configuration files: every shipped example loads, and bad files report every problem
// at once with the file and the key.
// SPDX-License-Identifier: MIT
#ifdef SCANMESH_ALL_DRIVERS  // needs the full driver registry
#include <catch2/catch.hpp>
#include <filesystem>
#include <string>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/sensor_config.hpp"

namespace fs = std::filesystem;
using namespace scanmesh::drivers;

TEST_CASE("every shipped sensor configuration loads", "[drivers][config]") {
  const fs::path dir = fs::path(SCANMESH_SOURCE_DIR) / "config" / "sensors";
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() != ".toml") continue;
    INFO(e.path());
    const SensorConfig c = load_sensor_config(e.path());
    CHECK_FALSE(c.driver.empty());
    CHECK(c.port.empty() != c.tcp.empty());
    if (!c.profile.empty()) CHECK(fs::exists(c.profile));
    CHECK_NOTHROW(make_displacement_sensor(c));
    ++n;
  }
  CHECK(n >= 5);
}

TEST_CASE("sensor configuration values and defaults", "[drivers][config]") {
  const SensorConfig c = parse_sensor_config(R"(
[sensor]
driver = "keyence-lkg"
port = "/dev/ttyUSB3"
baud = 57600
timeout_ms = 250
poll_interval_ms = 1.5
)",
                                             "t.toml");
  CHECK(c.driver == "keyence-lkg");
  CHECK(c.options.name == "keyence-lkg");
  CHECK(c.port == "/dev/ttyUSB3");
  CHECK(c.baud == 57600);
  CHECK(c.options.timeout == std::chrono::milliseconds(250));
  CHECK(c.options.poll_interval == std::chrono::microseconds(1500));
  CHECK(c.options.timeouts_until_lost == 3);
}

TEST_CASE("a bad sensor configuration lists every problem", "[drivers][config]") {
  try {
    parse_sensor_config(R"(
[sensor]
driver = "lk-g"
port = "/dev/ttyUSB0"
tcp = "10.0.0.1:502"
baud = "fast"
unit = 400
colour = "red"
)",
                        "bad.toml");
    FAIL("accepted");
  } catch (const scanmesh::ConfigError& e) {
    const std::string msg = e.what();
    CHECK(msg.find("bad.toml: sensor.driver: unknown driver 'lk-g'") != std::string::npos);
    CHECK(msg.find("sensor.port: give exactly one of port and tcp") != std::string::npos);
    CHECK(msg.find("sensor.baud: must be an integer") != std::string::npos);
    CHECK(msg.find("sensor.unit: must be in [0, 247], got 400") != std::string::npos);
    CHECK(msg.find("sensor.colour: unknown key") != std::string::npos);
  }
  try {
    parse_sensor_config("[sensor\ndriver=1", "broken.toml");
    FAIL("accepted");
  } catch (const scanmesh::ConfigError& e) {
    CHECK(std::string(e.what()).rfind("broken.toml:1:", 0) == 0);
  }
  CHECK_THROWS_AS(parse_sensor_config("[other]\n", "x.toml"), scanmesh::ConfigError);
}
#endif
