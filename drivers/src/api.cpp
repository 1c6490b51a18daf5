// Out-of-line parts of the drivers API: clock, enum names, DeviceError.
// SPDX-License-Identifier: MIT
#include <chrono>

#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/register_bus.hpp"
#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::drivers {

Timestamp monotonic_now() {
  return {std::chrono::duration_cast<std::chrono::nanoseconds>(
              std::chrono::steady_clock::now().time_since_epoch())
              .count()};
}

std::string_view to_string(SensorStatus status) {
  switch (status) {
    case SensorStatus::kOk:
      return "ok";
    case SensorStatus::kNoTarget:
      return "no_target";
    case SensorStatus::kOverRange:
      return "over_range";
    case SensorStatus::kAlarm:
      return "alarm";
    case SensorStatus::kDeviceError:
      return "device_error";
  }
  return "unknown";
}

std::optional<SensorStatus> sensor_status_from_string(std::string_view word) {
  for (auto s : {SensorStatus::kOk, SensorStatus::kNoTarget, SensorStatus::kOverRange,
                 SensorStatus::kAlarm, SensorStatus::kDeviceError}) {
    if (to_string(s) == word) return s;
  }
  return std::nullopt;
}

std::string_view to_string(StageStatus status) {
  switch (status) {
    case StageStatus::kIdle:
      return "idle";
    case StageStatus::kMoving:
      return "moving";
    case StageStatus::kHoming:
      return "homing";
    case StageStatus::kAlarm:
      return "alarm";
    case StageStatus::kLost:
      return "lost";
  }
  return "unknown";
}

std::optional<StageStatus> stage_status_from_string(std::string_view word) {
  for (auto s : {StageStatus::kIdle, StageStatus::kMoving, StageStatus::kHoming,
                 StageStatus::kAlarm, StageStatus::kLost}) {
    if (to_string(s) == word) return s;
  }
  return std::nullopt;
}

std::string_view to_string(DeviceState state) {
  switch (state) {
    case DeviceState::kClosed:
      return "closed";
    case DeviceState::kOpen:
      return "open";
    case DeviceState::kAcquiring:
      return "acquiring";
    case DeviceState::kLost:
      return "lost";
  }
  return "unknown";
}

std::string_view to_string(DeviceErrorKind kind) {
  switch (kind) {
    case DeviceErrorKind::kTimeout:
      return "timeout";
    case DeviceErrorKind::kDisconnected:
      return "disconnected";
    case DeviceErrorKind::kProtocol:
      return "protocol";
    case DeviceErrorKind::kIo:
      return "io";
    case DeviceErrorKind::kNotFound:
      return "not_found";
  }
  return "unknown";
}

void RegisterBus::select_unit(int unit) {
  throw DeviceError(DeviceErrorKind::kProtocol, name(), "select unit " + std::to_string(unit),
                    "this bus serves one unit only");
}

DeviceError::DeviceError(DeviceErrorKind kind, std::string device, std::string operation,
                         std::string detail)
    : Error(device + ": " + operation + ": " + detail),
      kind_(kind),
      device_(std::move(device)),
      operation_(std::move(operation)),
      detail_(std::move(detail)) {}

}  // namespace scanmesh::drivers
