// DisplacementSensor: the family interface of laser displacement (point) sensors
// (../shared/STYLE.md §5.1). Every driver of drivers/<name>/ implements it; the sim back end too.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::drivers {

/// What the device says it is (empty fields: the protocol has no way to ask).
struct DeviceIdentity {
  std::string vendor;
  std::string model;
  std::string serial;
  std::string firmware;
};

/// Static facts of a driver/model (from the protocol document, or read from the device).
struct SensorCapabilities {
  double max_rate_hz = 0;        ///< fastest rate the device can deliver samples
  double range_min_mm = 0;       ///< measuring range (0/0 when unknown)
  double range_max_mm = 0;
  double resolution_mm = 0;      ///< value quantum of the protocol (0 when unknown)
  bool device_clock = false;     ///< samples carry t_device
  bool streaming = false;        ///< the device pushes samples (otherwise the driver polls)
};

/// Lifecycle state. kLost: the device stopped answering or vanished; the driver reconnects
/// with bounded backoff on its own and returns to kAcquiring (or kOpen) when it is back.
enum class DeviceState { kClosed, kOpen, kAcquiring, kLost };
std::string_view to_string(DeviceState state);

/// Counters, readable from any thread (a snapshot).
struct DeviceStats {
  std::uint64_t samples = 0;          ///< delivered to the callback
  std::uint64_t gaps = 0;             ///< samples known to be lost (sequence/counter jumps)
  std::uint64_t malformed = 0;        ///< frames/replies rejected by the codec
  std::uint64_t error_replies = 0;    ///< error replies / Modbus exceptions from the device
  std::uint64_t timeouts = 0;         ///< requests that got no answer in time
  std::uint64_t reconnects = 0;       ///< successful reopenings after a loss
};

struct SensorCallbacks {
  /// Called on the driver's worker thread for every sample, in order. Must not block for long
  /// and must not throw (the daemon posts to its io thread).
  std::function<void(const SensorSample&)> on_sample;
  /// State changes with a reason ("timeout: no reply to M0 in 200 ms"). Optional.
  std::function<void(DeviceState, const std::string& reason)> on_state;
};

/// Common options of every displacement-sensor driver.
struct SensorOptions {
  std::string name = "sensor";  ///< device name in every message
  /// Poll interval for request/response sensors (0 = as fast as the device answers).
  std::chrono::microseconds poll_interval{0};
  /// Reply timeout of one request. Default 500 ms; valid 1 ms .. 60 s.
  std::chrono::milliseconds timeout{500};
  /// Consecutive timeouts after which the device counts as lost. Default 3.
  int timeouts_until_lost = 3;
  /// Reconnect backoff: first delay, doubled up to the maximum.
  std::chrono::milliseconds backoff_initial{100};
  std::chrono::milliseconds backoff_max{5000};
};

class DisplacementSensor {
 public:
  virtual ~DisplacementSensor() = default;

  virtual const std::string& name() const = 0;
  /// Opens the transport and identifies the device. Throws DeviceError (names the device).
  virtual void open() = 0;
  /// Stops acquisition and releases the transport. Never throws.
  virtual void close() noexcept = 0;
  /// Starts acquisition on the driver's own worker thread. Requires open().
  virtual void start(SensorCallbacks callbacks) = 0;
  /// Stops acquisition and joins the worker. Never throws; no callback runs after it returns.
  virtual void stop() noexcept = 0;

  /// Identity read during open().
  virtual DeviceIdentity identify() const = 0;
  virtual SensorCapabilities capabilities() const = 0;
  virtual DeviceState state() const = 0;
  virtual DeviceStats stats() const = 0;
};

}  // namespace scanmesh::drivers
