// Device class of the generic Modbus register-mapped sensor (see device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/modbus_sensor/device.hpp"

#include <cmath>
#include <limits>
#include <utility>

#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::modbus_sensor {

Device::Device(SensorOptions options, RegisterBusFactory transport, RegisterMap map)
    : SensorLifecycle(std::move(options)),
      transport_(std::move(transport)),
      decoder_(std::move(map)) {
  image_.resize(decoder_.image_size());
}

Device::~Device() { close(); }

void Device::rethrow_named(const DeviceError& e, const std::string& operation) const {
  throw DeviceError(e.kind(), e.device().empty() ? name() : e.device(),
                    operation + ": " + e.operation(), e.detail());
}

Measurement Device::poll_once() {
  std::size_t offset = 0;
  for (const RegisterBlock& b : decoder_.blocks()) {
    bus_->read_registers(b.kind, b.address, std::span(image_).subspan(offset, b.count));
    offset += b.count;
  }
  return decoder_.decode(image_);
}

void Device::open_device() {
  bus_ = transport_();
  if (!bus_) {
    throw DeviceError(DeviceErrorKind::kIo, name(), "open", "transport factory failed");
  }
  const RegisterMap& map = decoder_.map();
  DeviceIdentity id;
  const std::pair<const std::optional<RegisterString>*, std::string*> strings[] = {
      {&map.vendor, &id.vendor},
      {&map.model, &id.model},
      {&map.serial, &id.serial},
      {&map.firmware, &id.firmware}};
  std::vector<std::uint16_t> regs;
  try {
    for (const auto& [where, out] : strings) {
      if (!*where) continue;
      regs.assign((*where)->count, 0);
      bus_->read_registers((*where)->kind, (*where)->address, regs);
      *out = decode_string(regs);
    }
  } catch (const DeviceError& e) {
    bus_.reset();
    rethrow_named(e, "identify");
  }
  try {
    (void)poll_once();
  } catch (const DeviceError& e) {
    bus_.reset();
    rethrow_named(e, "first measurement");
  }
  set_identity(std::move(id));
}

bool Device::reconnect_once() {
  bus_ = transport_();
  if (!bus_) return false;
  (void)poll_once();
  return true;
}

Device::Step Device::acquire(std::string& timeout_detail) {
  try {
    const Measurement m = poll_once();
    SensorSample s;
    s.t_host = monotonic_now();
    s.seq = sequence().next();
    s.t_device = m.t_device;
    s.status = m.status;
    s.value_mm =
        m.status == SensorStatus::kOk ? m.value_mm : std::numeric_limits<double>::quiet_NaN();
    s.device_code = m.device_code;
    deliver(s);
  } catch (const DeviceError& e) {
    switch (e.kind()) {
      case DeviceErrorKind::kTimeout:
        timeout_detail = e.what();
        return Step::kTimeout;
      case DeviceErrorKind::kProtocol:
        // Modbus exception or invalid reply: counted, no sample, the device still answers.
        counters().error_replies.fetch_add(1);
        break;
      default:
        throw;  // the bus is gone: lost
    }
  }
  return Step::kAnswered;
}

std::string Device::lost_after_timeouts(int count, const std::string& detail) const {
  return std::to_string(count) + " consecutive timeouts (" + detail + ")";
}

bool Device::pause(Worker& worker) {
  if (options().poll_interval.count() <= 0) return true;
  const auto now = std::chrono::steady_clock::now();
  next_poll_ += options().poll_interval;
  if (next_poll_ < now) next_poll_ = now;
  return worker.sleep_for(next_poll_ - now);
}

SensorCapabilities Device::capabilities() const {
  const RegisterMap& map = decoder_.map();
  SensorCapabilities c;
  c.max_rate_hz = map.max_rate_hz;
  c.range_min_mm = map.range_min_mm;
  c.range_max_mm = map.range_max_mm;
  c.resolution_mm = 0;
  c.device_clock = map.find("timestamp_s") != nullptr;
  c.streaming = false;
  return c;
}

}  // namespace scanmesh::drivers::modbus_sensor
