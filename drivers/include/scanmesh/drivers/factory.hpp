// The driver registry: builds a configured displacement sensor on its real transport, keyed by
// the `driver` string of the configuration (one registration line per driver in factory.cpp).
// SPDX-License-Identifier: MIT
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/motion_stage.hpp"

namespace scanmesh::drivers {

/// Where and how to reach one sensor. Exactly one of `port` and `tcp` is set.
struct SensorConfig {
  std::string driver;   ///< "keyence-lkg", "keyence-il", "panasonic-hlg1",
                        ///< "microepsilon-ild1420", "modbus-sensor"
  std::string port;     ///< serial device path or usb:VID:PID[:SERIAL] (resolved at each open)
  std::string tcp;      ///< HOST:PORT of a Modbus TCP device
  unsigned baud = 0;    ///< 0 = the driver's default rate
  char parity = 'N';    ///< serial parity 'N', 'E' or 'O' (8 data bits, 1 stop bit)
  int unit = -1;        ///< Modbus unit id / RS-485 sensor number; -1 = driver default (1)
  std::string profile;  ///< register-map profile file (modbus-sensor); empty = Baumer OM30
  /// Measuring range in mm for sensors whose values scale with it and that may not report it
  /// (microepsilon-ild1420: 10, 25, 50, 100, 200 or 500). 0 = ask the sensor.
  double measuring_range_mm = 0;
  SensorOptions options;  ///< name, timeouts, poll interval, backoff
};

struct DriverInfo {
  std::string name;         ///< the `driver` string
  std::string models;       ///< models covered
  std::string transport;    ///< "serial", "modbus-rtu/tcp"
  unsigned default_baud = 0;
};

/// Every registered driver, in registration order.
std::vector<DriverInfo> displacement_drivers();

/// Builds the device (not yet opened). Throws ConfigError for an unknown driver (listing the
/// known ones) or an unusable combination (a TCP address for a serial-only driver, ...).
std::unique_ptr<DisplacementSensor> make_displacement_sensor(const SensorConfig& config);

/// Where and how to reach one motion stage. Exactly one of `port` and `tcp` is set.
struct StageConfig {
  std::string driver;   ///< "grbl", "modbus-stage", "ippdme"
  std::string port;     ///< serial device path or usb:VID:PID[:SERIAL] (grbl, modbus-stage RTU)
  std::string tcp;      ///< HOST:PORT (modbus-stage over Modbus TCP, ippdme)
  unsigned baud = 0;    ///< 0 = the driver's default rate
  char parity = 'N';    ///< serial parity 'N', 'E' or 'O'
  int unit = -1;        ///< modbus-stage: the drive's unit for a single-axis profile; -1 = profile's
  std::string profile;  ///< modbus-stage register-map profile file; empty = Leadshine-style XYZ
  bool rotary_a = false;  ///< grbl: the controller has an A axis (a turntable)
  StageOptions options;   ///< name, poll interval, timeouts, backoff
};

/// Every registered stage driver, in registration order.
std::vector<DriverInfo> stage_drivers();

/// Builds the stage (not yet opened). Throws ConfigError for an unknown driver (listing the
/// known ones), a bad profile or an unusable combination.
std::unique_ptr<MotionStage> make_motion_stage(const StageConfig& config);

}  // namespace scanmesh::drivers
