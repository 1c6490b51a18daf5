// Device class of the generic Modbus register-mapped sensor (see device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/modbus_sensor/device.hpp"

#include <cmath>
#include <limits>
#include <utility>

#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::modbus_sensor {

Device::Device(SensorOptions options, RegisterBusFactory transport, RegisterMap map)
    : options_(std::move(options)), transport_(std::move(transport)), decoder_(std::move(map)) {
  image_.resize(decoder_.image_size());
}

Device::~Device() { close(); }

void Device::rethrow_named(const DeviceError& e, const std::string& operation) const {
  throw DeviceError(e.kind(), e.device().empty() ? options_.name : e.device(),
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

void Device::open() {
  close();
  bus_ = transport_();
  if (!bus_) {
    throw DeviceError(DeviceErrorKind::kIo, options_.name, "open", "transport factory failed");
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
  {
    std::lock_guard lock(identity_mutex_);
    identity_ = std::move(id);
  }
  state_.set(DeviceState::kOpen, "", nullptr);
}

void Device::close() noexcept {
  stop();
  bus_.reset();
  state_.set(DeviceState::kClosed, "", nullptr);
}

void Device::start(SensorCallbacks callbacks) {
  stop();
  if (!bus_) throw DeviceError(DeviceErrorKind::kIo, options_.name, "start", "device not open");
  callbacks_ = std::move(callbacks);
  running_ = true;
  state_.set(DeviceState::kAcquiring, options_.name + ": acquiring", &callbacks_);
  worker_.start([this](Worker& w) { run(w); },
                [this](const std::exception& e) {
                  // Nothing escapes the worker: an unexpected error ends acquisition as a state.
                  state_.set(DeviceState::kLost, options_.name + ": worker stopped: " + e.what(),
                             &callbacks_);
                });
}

void Device::stop() noexcept {
  if (!running_) return;
  worker_.stop();
  running_ = false;
  state_.set(bus_ ? DeviceState::kOpen : DeviceState::kClosed, "", nullptr);
}

bool Device::reconnect(Worker& worker, const std::string& reason) {
  bus_.reset();
  state_.set(DeviceState::kLost, options_.name + ": lost: " + reason, &callbacks_);
  Backoff backoff(options_.backoff_initial, options_.backoff_max);
  while (true) {
    if (!worker.sleep_for(backoff.next())) return false;
    try {
      bus_ = transport_();
      if (!bus_) continue;
      (void)poll_once();
    } catch (const DeviceError&) {
      bus_.reset();
      continue;
    }
    stats_.reconnects.fetch_add(1);
    seq_.resync();
    state_.set(DeviceState::kAcquiring, options_.name + ": reconnected", &callbacks_);
    return true;
  }
}

void Device::run(Worker& worker) {
  int consecutive_timeouts = 0;
  auto next_poll = std::chrono::steady_clock::now();
  while (!worker.stop_requested()) {
    std::string lost_reason;
    try {
      const Measurement m = poll_once();
      consecutive_timeouts = 0;
      SensorSample s;
      s.t_host = monotonic_now();
      s.seq = seq_.next();
      s.t_device = m.t_device;
      s.status = m.status;
      s.value_mm =
          m.status == SensorStatus::kOk ? m.value_mm : std::numeric_limits<double>::quiet_NaN();
      s.device_code = m.device_code;
      stats_.samples.fetch_add(1);
      if (callbacks_.on_sample) callbacks_.on_sample(s);
    } catch (const DeviceError& e) {
      switch (e.kind()) {
        case DeviceErrorKind::kTimeout:
          stats_.timeouts.fetch_add(1);
          if (++consecutive_timeouts >= options_.timeouts_until_lost) {
            lost_reason =
                std::to_string(consecutive_timeouts) + " consecutive timeouts (" + e.what() + ")";
          }
          break;
        case DeviceErrorKind::kProtocol:
          // Modbus exception or invalid reply: counted, no sample, the device still answers.
          stats_.error_replies.fetch_add(1);
          consecutive_timeouts = 0;
          break;
        default:
          lost_reason = e.what();
          break;
      }
    }
    if (!lost_reason.empty()) {
      consecutive_timeouts = 0;
      if (!reconnect(worker, lost_reason)) return;
      next_poll = std::chrono::steady_clock::now();
      continue;
    }
    if (options_.poll_interval.count() > 0) {
      const auto now = std::chrono::steady_clock::now();
      next_poll += options_.poll_interval;
      if (next_poll < now) next_poll = now;
      if (!worker.sleep_for(next_poll - now)) return;
    }
  }
}

DeviceIdentity Device::identify() const {
  std::lock_guard lock(identity_mutex_);
  return identity_;
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
