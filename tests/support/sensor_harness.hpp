// Device-against-emulator harness for the sensor driver tests: collects samples and state
// changes, waits with deadlines, opens a driver on an emulator's pty over the real serial
// transport (or on a Modbus TCP emulator), and runs the fault tests every request/response
// sensor must pass.
// SPDX-License-Identifier: MIT
#pragma once

#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "scanmesh/drivers/byte_stream.hpp"
#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/register_bus.hpp"
#include "scanmesh/drivers/transports/modbus_bus.hpp"
#include "scanmesh/drivers/transports/serial_stream.hpp"
#include "support/temp_dir.hpp"

namespace scanmesh::test {

using namespace std::chrono_literals;

/// Default deadline of every wait: generous, since the tests share the CPU with others.
inline constexpr std::chrono::milliseconds kWaitLimit = 4000ms;

/// Polls pred every 5 ms until it holds or the limit passed; returns its last value.
template <class Pred>
bool wait_until(Pred pred, std::chrono::milliseconds limit = kWaitLimit) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(5ms);
  }
  return pred();
}

/// Records what a driver delivers through its callbacks (called on the driver's worker thread).
class SensorCollector {
 public:
  drivers::SensorCallbacks callbacks() {
    return {[this](const drivers::SensorSample& s) {
              {
                std::lock_guard lock(mutex_);
                samples_.push_back(s);
              }
              cv_.notify_all();
            },
            [this](drivers::DeviceState st, const std::string& reason) {
              std::lock_guard lock(mutex_);
              states_.emplace_back(st, reason);
            }};
  }
  std::size_t count() {
    std::lock_guard lock(mutex_);
    return samples_.size();
  }
  std::vector<drivers::SensorSample> copy() {
    std::lock_guard lock(mutex_);
    return samples_;
  }
  /// Waits until at least n samples arrived; false after the limit.
  bool wait_for(std::size_t n, std::chrono::milliseconds limit = kWaitLimit) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, limit, [&] { return samples_.size() >= n; });
  }
  /// Waits for `more` samples beyond those already received.
  bool resumes(std::size_t more) { return wait_for(count() + more); }
  /// True when at most `in_flight` samples arrive within `period` (a fault is holding them).
  bool quiet(std::chrono::milliseconds period = 50ms, std::size_t in_flight = 1) {
    const std::size_t n = count();
    std::this_thread::sleep_for(period);
    return count() <= n + in_flight;
  }
  /// A state change to st whose reason contains needle.
  bool saw(drivers::DeviceState st, const std::string& needle = "") {
    std::lock_guard lock(mutex_);
    for (const auto& [s, reason] : states_)
      if (s == st && reason.find(needle) != std::string::npos) return true;
    return false;
  }
  /// Reason of the first change to st (empty when there was none).
  std::string reason(drivers::DeviceState st) {
    std::lock_guard lock(mutex_);
    for (const auto& [s, why] : states_)
      if (s == st) return why;
    return {};
  }
  std::string state_log() {
    std::lock_guard lock(mutex_);
    std::string out;
    for (const auto& [s, reason] : states_)
      out += std::string(drivers::to_string(s)) + ": " + reason + "\n";
    return out;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<drivers::SensorSample> samples_;
  std::vector<std::pair<drivers::DeviceState, std::string>> states_;
};

/// Short timeouts and backoff, so that loss and recovery happen within a test's patience.
inline drivers::SensorOptions fast_sensor_options(std::string name,
                                                  std::chrono::milliseconds timeout = 100ms) {
  drivers::SensorOptions o;
  o.name = std::move(name);
  o.poll_interval = 2ms;
  o.timeout = timeout;
  o.timeouts_until_lost = 3;
  o.backoff_initial = 20ms;
  o.backoff_max = 200ms;
  return o;
}

/// Opens the real serial transport on an emulator's pty link (again at every reconnection).
inline drivers::ByteStreamFactory pty_serial_factory(std::string device_name, std::string link,
                                                     unsigned baud) {
  return [device_name = std::move(device_name), link = std::move(link), baud] {
    return drivers::open_serial_stream(device_name, {link, baud});
  };
}

/// Opens a Modbus TCP connection to an emulator on 127.0.0.1 (again at every reconnection).
inline drivers::RegisterBusFactory tcp_modbus_factory(std::string device_name, int port,
                                                      std::chrono::milliseconds timeout,
                                                      int unit = 1) {
  return [device_name = std::move(device_name), port, timeout, unit] {
    return drivers::open_modbus_tcp(device_name, "127.0.0.1", port, unit, timeout);
  };
}

/// True when every sample from index `from` on is kOk with one of the allowed values.
inline bool all_in(const std::vector<drivers::SensorSample>& samples, std::size_t from,
                   const std::vector<double>& allowed) {
  for (std::size_t i = from; i < samples.size(); ++i) {
    if (samples[i].status != drivers::SensorStatus::kOk) return false;
    bool found = false;
    for (double a : allowed) found = found || std::fabs(samples[i].value_mm - a) < 1e-9;
    if (!found) return false;
  }
  return true;
}

/// Stops the device and checks that no sample callback runs after stop() returned.
inline void stop_and_check_quiet(drivers::DisplacementSensor& device, SensorCollector& collector) {
  device.stop();
  const std::size_t after_stop = collector.count();
  std::this_thread::sleep_for(30ms);
  CHECK(collector.count() == after_stop);  // no callback after stop()
}

/// How one driver names itself in the fault tests.
struct FaultTexts {
  std::string device_name;     ///< SensorOptions::name, expected in every lost reason
  std::string silent_section;  ///< SECTION name of the silent-device case
  std::string silent_reason;   ///< expected in the lost reason of the silent device
};

/// The faults every request/response serial sensor survives, one SECTION each: garbage before
/// every reply, every byte written alone, error replies, late replies, a silent device (lost,
/// then back) and the port vanishing and reappearing. The device is open and the emulator
/// started, running `script`; extra_sections adds the protocol's own faults (called with the
/// device running). Afterwards: no corrupt sample, ever, and gap-free sequence numbers.
template <class Emulator>
void check_fault_recovery(Emulator& emulator, drivers::DisplacementSensor& device,
                          const FaultTexts& texts, const std::vector<double>& script,
                          const std::function<void(SensorCollector&)>& extra_sections = {}) {
  using drivers::DeviceState;
  SensorCollector collector;
  device.start(collector.callbacks());
  REQUIRE(collector.wait_for(3));

  SECTION("garbage before every reply") {
    emulator.set_faults({.garbage_before_reply = true});
    const auto before = device.stats().malformed;
    REQUIRE(wait_until([&] { return device.stats().malformed >= before + 3; }));
    CHECK(collector.resumes(3));  // the codec resynchronises on the reply header
  }
  SECTION("every byte written alone") {
    emulator.set_faults({.split_every_byte = true});
    CHECK(collector.resumes(5));
    CHECK(device.stats().malformed == 0);
  }
  SECTION("error replies") {
    emulator.set_faults({.error_reply = true});
    REQUIRE(wait_until([&] { return device.stats().error_replies >= 3; }));
    CHECK(collector.quiet());  // at most the reply already in flight
    emulator.set_faults({});
    CHECK(collector.resumes(3));
  }
  SECTION("replies later than the timeout") {
    emulator.set_faults({.reply_delay = 250ms});
    REQUIRE(wait_until([&] { return device.stats().timeouts >= 2; }));
    emulator.set_faults({});
    CHECK(collector.resumes(3));
  }
  SECTION(texts.silent_section) {
    emulator.set_faults({.silent = true});
    REQUIRE(wait_until([&] { return device.state() == DeviceState::kLost; }));
    CHECK(device.stats().timeouts >= 3);
    CHECK(collector.saw(DeviceState::kLost, texts.device_name));
    CHECK(collector.saw(DeviceState::kLost, texts.silent_reason));
    emulator.set_faults({});
    REQUIRE(wait_until([&] { return device.state() == DeviceState::kAcquiring; }));
    CHECK(device.stats().reconnects >= 1);
    CHECK(collector.resumes(3));
  }
  SECTION("port vanishes, then reappears") {
    emulator.vanish();
    REQUIRE(wait_until([&] { return device.state() == DeviceState::kLost; }));
    CHECK(collector.saw(DeviceState::kLost, texts.device_name));
    std::this_thread::sleep_for(100ms);  // a few failed reopenings
    emulator.reappear();
    REQUIRE(wait_until([&] { return device.state() == DeviceState::kAcquiring; }));
    CHECK(device.stats().reconnects >= 1);
    CHECK(collector.resumes(3));
  }
  if (extra_sections) extra_sections(collector);
  device.stop();
  INFO(collector.state_log());
  const auto samples = collector.copy();
  CHECK(all_in(samples, 0, script));  // no corrupt sample, ever
  for (std::size_t k = 1; k < samples.size(); ++k) CHECK(samples[k].seq == samples[k - 1].seq + 1);
}

}  // namespace scanmesh::test
