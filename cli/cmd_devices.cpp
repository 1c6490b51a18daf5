// `scanmesh devices`: serial ports with their USB identity and USB devices.
// `scanmesh device read`: open one displacement sensor, read N samples, print them as JSON lines.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <iostream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/factory.hpp"
#include "scanmesh/drivers/sensor_config.hpp"
#include "scanmesh/drivers/transports/discovery.hpp"

namespace scanmesh::cli {

namespace {

using nlohmann::json;
namespace drv = scanmesh::drivers;

std::string hex4(std::uint16_t v) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%04x", v);
  return buf;
}

int run_devices(bool as_json) {
  const auto ports = drv::list_serial_ports();
  std::vector<drv::UsbDeviceInfo> usb;
  std::string usb_error;
  try {
    usb = drv::list_usb_devices();
  } catch (const drv::DeviceError& e) {
    usb_error = e.what();  // no usbfs (containers): still list the serial ports
  }
  if (as_json) {
    json out = {{"serial_ports", json::array()}, {"usb_devices", json::array()}};
    for (const auto& p : ports) {
      json j = {{"path", p.path}, {"transport", p.transport}, {"description", p.description}};
      if (p.usb_vid) {
        j["usb_vid_pid"] = hex4(*p.usb_vid) + ":" + hex4(*p.usb_pid);
        j["serial_number"] = p.usb_serial;
        j["manufacturer"] = p.usb_manufacturer;
        j["product"] = p.usb_product;
        j["spec"] = "usb:" + hex4(*p.usb_vid) + ":" + hex4(*p.usb_pid) +
                    (p.usb_serial.empty() ? "" : ":" + p.usb_serial);
      }
      out["serial_ports"].push_back(std::move(j));
    }
    for (const auto& d : usb) {
      out["usb_devices"].push_back({{"bus", d.bus},
                                    {"address", d.address},
                                    {"vid_pid", hex4(d.vid) + ":" + hex4(d.pid)},
                                    {"manufacturer", d.manufacturer},
                                    {"product", d.product},
                                    {"serial_number", d.serial}});
    }
    if (!usb_error.empty()) out["usb_error"] = usb_error;
    out["stage_drivers"] = json::array();
    for (const auto& d : drv::stage_drivers())
      out["stage_drivers"].push_back({{"driver", d.name},
                                      {"models", d.models},
                                      {"transport", d.transport},
                                      {"default_baud", d.default_baud}});
    std::cout << out.dump() << "\n";
    return kExitOk;
  }
  std::cout << "serial ports: " << ports.size() << "\n";
  for (const auto& p : ports) {
    std::cout << "  " << p.path << "  " << p.transport;
    if (p.usb_vid) {
      std::cout << "  usb:" << hex4(*p.usb_vid) << ":" << hex4(*p.usb_pid)
                << (p.usb_serial.empty() ? "" : ":" + p.usb_serial) << "  " << p.usb_product;
    } else if (!p.description.empty()) {
      std::cout << "  " << p.description;
    }
    std::cout << "\n";
  }
  std::cout << "usb devices: " << usb.size() << "\n";
  for (const auto& d : usb) {
    std::cout << "  bus " << int(d.bus) << " address " << int(d.address) << "  " << hex4(d.vid)
              << ":" << hex4(d.pid) << "  " << d.manufacturer << " " << d.product
              << (d.serial.empty() ? "" : "  serial " + d.serial) << "\n";
  }
  if (!usb_error.empty()) std::cout << "  (" << usb_error << ")\n";
  const auto stages = drv::stage_drivers();
  std::cout << "stage drivers: " << stages.size() << "\n";
  for (const auto& d : stages)
    std::cout << "  " << d.name << "  " << d.transport << "  " << d.models << "\n";
  return kExitOk;
}

struct ReadArgs {
  std::string config_file;  ///< --config: base configuration; flags given override it
  drv::SensorConfig config;
  std::vector<std::string> given;  ///< long names of the flags given on the command line
  std::uint64_t samples = 0;
  int timeout_ms = 500;
  double interval_ms = 0;
  bool json = false;
};

json sample_json(const drv::SensorSample& s) {
  json j = {{"seq", s.seq}, {"t_host_ns", s.t_host.ns}};
  if (s.t_device) j["t_device_ns"] = s.t_device->ns;
  if (s.status == drv::SensorStatus::kOk && std::isfinite(s.value_mm)) {
    j["value_mm"] = s.value_mm;
  } else {
    j["value_mm"] = nullptr;
  }
  j["status"] = std::string(drv::to_string(s.status));
  if (s.device_code != 0) j["device_code"] = s.device_code;
  return j;
}

bool given(const ReadArgs& a, const std::string& flag) {
  return std::find(a.given.begin(), a.given.end(), flag) != a.given.end();
}

int run_device_read(ReadArgs args) {
  if (!args.config_file.empty()) {
    drv::SensorConfig base = drv::load_sensor_config(args.config_file);
    const drv::SensorConfig& flags = args.config;
    if (given(args, "driver")) base.driver = flags.driver;
    if (given(args, "port")) {
      base.port = flags.port;
      base.tcp.clear();
    }
    if (given(args, "tcp")) {
      base.tcp = flags.tcp;
      base.port.clear();
    }
    if (given(args, "baud")) base.baud = flags.baud;
    if (given(args, "unit")) base.unit = flags.unit;
    if (given(args, "parity")) base.parity = flags.parity;
    if (given(args, "range-mm")) base.measuring_range_mm = flags.measuring_range_mm;
    if (given(args, "profile")) base.profile = flags.profile;
    if (given(args, "name")) base.options.name = flags.options.name;
    if (!given(args, "timeout")) args.timeout_ms = static_cast<int>(base.options.timeout.count());
    if (!given(args, "interval"))
      args.interval_ms = static_cast<double>(base.options.poll_interval.count()) / 1000.0;
    args.config = base;
  } else if (args.config.driver.empty()) {
    throw ConfigError("device read: --driver is required (or --config FILE)");
  }
  auto& cfg = args.config;
  if (cfg.port.empty() == cfg.tcp.empty())
    throw ConfigError("device read: give exactly one of --port PATH and --tcp HOST:PORT");
  if (args.timeout_ms < 1 || args.timeout_ms > 60000)
    throw ConfigError("device read: --timeout must be 1..60000 ms");
  if (cfg.options.name == "sensor") cfg.options.name = cfg.driver;
  cfg.options.timeout = std::chrono::milliseconds(args.timeout_ms);
  cfg.options.poll_interval =
      std::chrono::microseconds(static_cast<std::int64_t>(args.interval_ms * 1000));
  auto sensor = drv::make_displacement_sensor(cfg);
  sensor->open();  // throws DeviceError (exit 5) when the device does not answer

  std::mutex mutex;
  std::condition_variable cv;
  std::deque<drv::SensorSample> queue;
  std::string lost_reason;
  drv::SensorCallbacks callbacks;
  callbacks.on_sample = [&](const drv::SensorSample& s) {
    std::lock_guard lock(mutex);
    queue.push_back(s);
    cv.notify_one();
  };
  callbacks.on_state = [&](drv::DeviceState st, const std::string& reason) {
    if (st != drv::DeviceState::kLost) return;
    std::lock_guard lock(mutex);
    lost_reason = reason;
    cv.notify_one();
  };
  sensor->start(callbacks);
  // A device that answers open() and then goes quiet must not hang the command: give up when
  // no sample came for a few timeouts (at least 3 s).
  const auto quiet_limit = std::max(std::chrono::milliseconds(3000), cfg.options.timeout * 6);
  std::uint64_t printed = 0;
  int status = kExitOk;
  std::string failure;
  while (printed < args.samples) {
    std::unique_lock lock(mutex);
    if (!cv.wait_for(lock, quiet_limit, [&] { return !queue.empty() || !lost_reason.empty(); })) {
      failure = cfg.options.name + ": no sample for " + std::to_string(quiet_limit.count()) +
                " ms";
      status = kExitDevice;
      break;
    }
    if (queue.empty() && !lost_reason.empty()) {
      failure = lost_reason;
      status = kExitDevice;
      break;
    }
    while (!queue.empty() && printed < args.samples) {
      const drv::SensorSample s = queue.front();
      queue.pop_front();
      lock.unlock();
      if (args.json) {
        std::cout << sample_json(s).dump() << "\n";
      } else {
        std::cout << s.seq << "  " << s.t_host.ns << "  ";
        if (s.status == drv::SensorStatus::kOk)
          std::cout << s.value_mm << " mm\n";
        else
          std::cout << drv::to_string(s.status) << "\n";
      }
      ++printed;
      lock.lock();
    }
  }
  sensor->stop();
  const drv::DeviceStats st = sensor->stats();
  sensor->close();
  std::cout.flush();
  if (status != kExitOk) {
    std::cerr << "scanmesh: " << failure << " (after " << printed << " of " << args.samples
              << " samples)\n";
  }
  std::cerr << "scanmesh: " << cfg.options.name << ": " << st.samples << " samples, " << st.gaps
            << " gaps, " << st.malformed << " malformed, " << st.error_replies
            << " error replies, " << st.timeouts << " timeouts, " << st.reconnects
            << " reconnects\n";
  return status;
}

}  // namespace

void add_devices_command(CLI::App& app, Runner& run) {
  auto* devices = app.add_subcommand("devices", "List serial ports (with USB identity) and USB devices");
  auto as_json = std::make_shared<bool>(false);
  devices->add_flag("--json", *as_json, "One JSON object on stdout");
  devices->callback([&run, as_json] { run = [as_json] { return run_devices(*as_json); }; });

  auto* device = app.add_subcommand("device", "Talk to one device");
  device->require_subcommand(1);
  auto* read = device->add_subcommand("read", "Open one displacement sensor and read N samples");
  auto args = std::make_shared<ReadArgs>();
  std::string drivers_list;
  for (const auto& d : drv::displacement_drivers())
    drivers_list += (drivers_list.empty() ? "" : ", ") + d.name;
  read->add_option("--config", args->config_file,
                   "Sensor configuration file (TOML, see config/sensors/); flags override it")
      ->check(CLI::ExistingFile);
  read->add_option("--driver", args->config.driver, "Driver: " + drivers_list);
  read->add_option("--port", args->config.port, "Serial port path or usb:VID:PID[:SERIAL]");
  read->add_option("--tcp", args->config.tcp, "HOST:PORT of a Modbus TCP sensor");
  read->add_option("--baud", args->config.baud, "Baud rate (default: the driver's)");
  read->add_option("--unit", args->config.unit, "Modbus unit id / RS-485 sensor number");
  read->add_option("--parity", args->config.parity, "Serial parity N, E or O (default N)")
      ->check(CLI::IsMember({'N', 'E', 'O'}));
  read->add_option("--range-mm", args->config.measuring_range_mm,
                   "Measuring range in mm when the sensor does not report it (ILD1420)");
  read->add_option("--profile", args->config.profile,
                   "Register-map profile (TOML) for modbus-sensor (default: Baumer OM30)");
  read->add_option("--samples", args->samples, "Number of samples to read")
      ->required()
      ->check(kPositive);
  read->add_option("--name", args->config.options.name, "Device name used in messages");
  read->add_option("--timeout", args->timeout_ms, "Reply timeout in ms (default 500)");
  read->add_option("--interval", args->interval_ms,
                   "Poll interval in ms for polled sensors (default 0: as fast as it answers)");
  read->add_flag("--json", args->json, "One JSON object per sample and line");
  read->callback([&run, args, read] {
    for (const char* flag : {"driver", "port", "tcp", "baud", "unit", "parity", "range-mm",
                             "profile", "name", "timeout", "interval"})
      if (read->count(std::string("--") + flag) > 0) args->given.push_back(flag);
    run = [args] { return run_device_read(*args); };
  });
}

}  // namespace scanmesh::cli
