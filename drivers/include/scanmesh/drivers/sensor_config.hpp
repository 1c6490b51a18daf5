// Sensor configuration files: one [sensor] table in TOML naming the driver, the port and the
// timing options (config/sensors/*.toml are the shipped examples).
// SPDX-License-Identifier: MIT
#pragma once

#include <filesystem>
#include <string_view>

#include "scanmesh/drivers/factory.hpp"

namespace scanmesh::drivers {

/// Parses a sensor configuration. Keys of [sensor] (units and ranges):
///   driver              string, required: a registered driver name (displacement_drivers())
///   name                string, default = driver: the device name in every message
///   port | tcp          exactly one: serial path or usb:VID:PID[:SERIAL] | "HOST:PORT"
///   baud                integer 50..4000000, default: the driver's
///   parity              "none" (default), "even" or "odd"
///   measuring_range_mm  number, default 0 (ask the sensor): ILD1420 measuring range
///   unit                integer 0..247, Modbus unit id / RS-485 sensor number, default 1
///   profile             string: register-map profile (modbus-sensor), relative to the file
///   timeout_ms          integer 1..60000, default 500: reply timeout
///   poll_interval_ms    number 0..60000, default 0: pause between polls of polled sensors
///   timeouts_until_lost integer 1..100, default 3
///   backoff_initial_ms  integer 1..60000, default 100; backoff_max_ms 1..600000, default 5000
/// Throws ConfigError listing every problem at once, each as "<source>: sensor.<key>: ...".
SensorConfig parse_sensor_config(std::string_view toml_text, std::string_view source,
                                 const std::filesystem::path& base_dir = {});

/// Reads and parses a file (relative profile paths resolve against its directory).
SensorConfig load_sensor_config(const std::filesystem::path& file);

}  // namespace scanmesh::drivers
