// The driver registry (factory.hpp): one registration line per driver in kDrivers below.
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/factory.hpp"

#include <charconv>
#include <utility>

#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/grbl/device.hpp"
#include "scanmesh/drivers/ippdme/device.hpp"
#include "scanmesh/drivers/modbus_stage/device.hpp"
#include "scanmesh/drivers/modbus_stage/profile.hpp"
#include "scanmesh/drivers/transports/tcp_stream.hpp"
#include "scanmesh/drivers/keyence_il/device.hpp"
#include "scanmesh/drivers/keyence_lkg/device.hpp"
#include "scanmesh/drivers/microepsilon_ild1420/device.hpp"
#include "scanmesh/drivers/modbus_sensor/device.hpp"
#include "scanmesh/drivers/modbus_sensor/profile.hpp"
#include "scanmesh/drivers/panasonic_hlg1/device.hpp"
#include "scanmesh/drivers/transports/modbus_bus.hpp"
#include "scanmesh/drivers/transports/discovery.hpp"
#include "scanmesh/drivers/transports/serial_stream.hpp"

namespace scanmesh::drivers {

namespace {

/// A serial transport factory: resolves usb: identities at every (re)open, since the adapter
/// may come back under another /dev/ttyUSBn after being unplugged.
ByteStreamFactory serial_factory(const SensorConfig& c, unsigned default_baud) {
  if (c.port.empty())
    throw ConfigError(c.options.name + ": driver " + c.driver + " needs --port (a serial port)");
  SerialSettings s;
  s.baud = c.baud ? c.baud : default_baud;
  s.parity = c.parity;
  return [name = c.options.name, spec = c.port, s]() mutable {
    s.path = parse_usb_identity(spec) ? resolve_serial_port(spec, list_serial_ports()) : spec;
    return open_serial_stream(name, s);
  };
}

/// HOST and PORT of a "HOST:PORT" address (ConfigError naming the device otherwise).
std::pair<std::string, int> split_tcp(const std::string& name, const std::string& tcp) {
  const auto colon = tcp.rfind(':');
  int port = 0;
  const char* end = tcp.data() + tcp.size();
  if (colon == std::string::npos || colon == 0 ||
      std::from_chars(tcp.data() + colon + 1, end, port).ptr != end || port < 1 || port > 65535)
    throw ConfigError(name + ": --tcp must be HOST:PORT (port 1..65535), got '" + tcp + "'");
  return {tcp.substr(0, colon), port};
}

ByteStreamFactory stage_serial_factory(const StageConfig& c, unsigned default_baud) {
  if (c.port.empty())
    throw ConfigError(c.options.name + ": driver " + c.driver + " needs --port (a serial port)");
  SerialSettings s;
  s.baud = c.baud ? c.baud : default_baud;
  s.parity = c.parity;
  return [name = c.options.name, spec = c.port, s]() mutable {
    s.path = parse_usb_identity(spec) ? resolve_serial_port(spec, list_serial_ports()) : spec;
    return open_serial_stream(name, s);
  };
}

std::unique_ptr<MotionStage> make_grbl(const StageConfig& c) {
  grbl::Options o;
  o.rotary_a = c.rotary_a;
  return std::make_unique<grbl::Device>(c.options, stage_serial_factory(c, grbl::kDefaultBaud), o);
}

std::unique_ptr<MotionStage> make_modbus_stage(const StageConfig& c) {
  modbus_stage::StageRegisterMap map = c.profile.empty()
                                           ? modbus_stage::leadshine_pr_map()
                                           : modbus_stage::load_stage_profile(c.profile);
  const std::string name = c.options.name;
  if (c.unit >= 0) {
    if (map.axes.size() != 1)
      throw ConfigError(name + ": --unit applies to a single-axis profile; profile " + map.profile +
                        " has " + std::to_string(map.axes.size()) + " axes (set their units in "
                        "its [[axis]] tables)");
    map.axes[0].unit = c.unit;
  }
  const int unit = map.axes.front().unit;
  const auto timeout = c.options.timeout;
  RegisterBusFactory bus;
  if (!c.tcp.empty()) {
    auto [host, port] = split_tcp(name, c.tcp);
    bus = [name, host, port, unit, timeout] { return open_modbus_tcp(name, host, port, unit, timeout); };
  } else if (!c.port.empty()) {
    const int baud = static_cast<int>(c.baud ? c.baud : 19200);
    bus = [name, spec = c.port, baud, parity = c.parity, unit, timeout] {
      const std::string path =
          parse_usb_identity(spec) ? resolve_serial_port(spec, list_serial_ports()) : spec;
      return open_modbus_rtu(name, path, baud, parity, 8, 1, unit, timeout);
    };
  } else {
    throw ConfigError(name + ": driver modbus-stage needs --tcp HOST:PORT or --port PATH");
  }
  return std::make_unique<modbus_stage::Device>(c.options, std::move(bus), std::move(map));
}

std::unique_ptr<MotionStage> make_ippdme(const StageConfig& c) {
  if (c.tcp.empty())
    throw ConfigError(c.options.name + ": driver ippdme needs --tcp HOST:PORT (I++ DME is TCP)");
  auto [host, port] = split_tcp(c.options.name, c.tcp);
  const auto timeout = c.options.timeout;
  ByteStreamFactory stream = [name = c.options.name, host, port, timeout] {
    return open_tcp_stream(name, host, port, timeout);
  };
  return std::make_unique<ippdme::Device>(c.options, std::move(stream));
}

std::unique_ptr<DisplacementSensor> make_keyence_lkg(const SensorConfig& c) {
  return std::make_unique<keyence_lkg::Device>(c.options,
                                               serial_factory(c, keyence_lkg::kDefaultBaud));
}

std::unique_ptr<DisplacementSensor> make_keyence_il(const SensorConfig& c) {
  return std::make_unique<keyence_il::Device>(c.options,
                                              serial_factory(c, keyence_il::kDefaultBaud));
}

std::unique_ptr<DisplacementSensor> make_panasonic_hlg1(const SensorConfig& c) {
  panasonic_hlg1::HlG1Options o;
  if (c.unit >= 0) o.unit = c.unit;
  return std::make_unique<panasonic_hlg1::Device>(
      c.options, serial_factory(c, panasonic_hlg1::kDefaultBaud), o);
}

std::unique_ptr<DisplacementSensor> make_microepsilon_ild1420(const SensorConfig& c) {
  microepsilon_ild1420::Options o;
  o.measuring_range_mm = c.measuring_range_mm;
  return std::make_unique<microepsilon_ild1420::Device>(
      c.options, serial_factory(c, microepsilon_ild1420::kDefaultBaud), o);
}

std::unique_ptr<DisplacementSensor> make_modbus_sensor(const SensorConfig& c) {
  modbus_sensor::RegisterMap map = c.profile.empty()
                                       ? modbus_sensor::baumer_om30_map()
                                       : modbus_sensor::load_register_map_profile(c.profile);
  const int unit = c.unit >= 0 ? c.unit : 1;
  const auto timeout = c.options.timeout;
  const std::string name = c.options.name;
  RegisterBusFactory bus;
  if (!c.tcp.empty()) {
    const auto colon = c.tcp.rfind(':');
    int port = 0;
    const char* end = c.tcp.data() + c.tcp.size();
    if (colon == std::string::npos || colon == 0 ||
        std::from_chars(c.tcp.data() + colon + 1, end, port).ptr != end || port < 1 ||
        port > 65535)
      throw ConfigError(name + ": --tcp must be HOST:PORT (port 1..65535), got '" + c.tcp + "'");
    bus = [name, host = c.tcp.substr(0, colon), port, unit, timeout] {
      return open_modbus_tcp(name, host, port, unit, timeout);
    };
  } else if (!c.port.empty()) {
    const int baud = static_cast<int>(c.baud ? c.baud : 19200);
    bus = [name, spec = c.port, baud, parity = c.parity, unit, timeout] {
      const std::string path =
          parse_usb_identity(spec) ? resolve_serial_port(spec, list_serial_ports()) : spec;
      return open_modbus_rtu(name, path, baud, parity, 8, 1, unit, timeout);
    };
  } else {
    throw ConfigError(name + ": driver modbus-sensor needs --tcp HOST:PORT or --port PATH");
  }
  return std::make_unique<modbus_sensor::Device>(c.options, std::move(bus), std::move(map));
}

struct Registration {
  DriverInfo info;
  std::unique_ptr<DisplacementSensor> (*make)(const SensorConfig&);
};

// One line per driver.
const Registration kDrivers[] = {
    {{"keyence-lkg", "KEYENCE LK-G3000/LK-G5000", "serial RS-232C", keyence_lkg::kDefaultBaud},
     &make_keyence_lkg},
    {{"keyence-il", "KEYENCE IL series via DL-RS1A", "serial RS-232C", keyence_il::kDefaultBaud},
     &make_keyence_il},
    {{"panasonic-hlg1", "Panasonic HL-G1", "serial RS-422/RS-485", panasonic_hlg1::kDefaultBaud},
     &make_panasonic_hlg1},
    {{"microepsilon-ild1420", "Micro-Epsilon optoNCDT ILD1420 (1320/1220)", "serial RS422",
      microepsilon_ild1420::kDefaultBaud},
     &make_microepsilon_ild1420},
    {{"modbus-sensor", "Modbus register-mapped sensors (Baumer OM20/OM30 profile built in)",
      "Modbus RTU or TCP", 19200},
     &make_modbus_sensor},
};

struct StageRegistration {
  DriverInfo info;
  std::unique_ptr<MotionStage> (*make)(const StageConfig&);
};

// One line per stage driver.
const StageRegistration kStageDrivers[] = {
    {{"grbl", "Grbl 1.1 / grblHAL G-code controllers (stages, turntables)", "serial",
      grbl::kDefaultBaud},
     &make_grbl},
    {{"modbus-stage", "Modbus servo/stepper drives (Leadshine PR, Delta ASDA profiles)",
      "Modbus RTU or TCP", 19200},
     &make_modbus_stage},
    {{"ippdme", "CMM controllers speaking I++ DME (VDMA 8722)", "TCP", 0}, &make_ippdme},
};

}  // namespace

std::vector<DriverInfo> stage_drivers() {
  std::vector<DriverInfo> out;
  for (const auto& r : kStageDrivers) out.push_back(r.info);
  return out;
}

std::unique_ptr<MotionStage> make_motion_stage(const StageConfig& config) {
  for (const auto& r : kStageDrivers)
    if (r.info.name == config.driver) return r.make(config);
  std::string known;
  for (const auto& d : stage_drivers()) known += (known.empty() ? "" : ", ") + d.name;
  throw ConfigError("unknown stage driver '" + config.driver + "' (known: " + known + ")");
}

std::vector<DriverInfo> displacement_drivers() {
  std::vector<DriverInfo> out;
  for (const auto& r : kDrivers) out.push_back(r.info);
  return out;
}

std::unique_ptr<DisplacementSensor> make_displacement_sensor(const SensorConfig& config) {
  for (const auto& r : kDrivers)
    if (r.info.name == config.driver) return r.make(config);
  std::string known;
  for (const auto& d : displacement_drivers()) known += (known.empty() ? "" : ", ") + d.name;
  throw ConfigError("unknown driver '" + config.driver + "' (known: " + known + ")");
}

}  // namespace scanmesh::drivers
