// SensorLifecycle: state, statistics, worker loop, lost/reconnect with backoff shared by every
// sensor driver (see common/sensor_lifecycle.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/common/sensor_lifecycle.hpp"

#include <utility>

#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers {

SensorLifecycle::SensorLifecycle(SensorOptions options, int counter_bits)
    : options_(std::move(options)), seq_(counter_bits) {}

void SensorLifecycle::set_identity(DeviceIdentity identity) {
  std::lock_guard lock(identity_mutex_);
  identity_ = std::move(identity);
}

DeviceIdentity SensorLifecycle::identify() const {
  std::lock_guard lock(identity_mutex_);
  return identity_;
}

void SensorLifecycle::deliver(const SensorSample& sample) {
  stats_.samples.fetch_add(1);
  if (callbacks_.on_sample) callbacks_.on_sample(sample);
}

void SensorLifecycle::open() {
  if (running_) return;  // open and acquiring already (or reconnecting on its own)
  drop_transport();
  try {
    open_device();
  } catch (...) {
    drop_transport();
    throw;
  }
  state_.set(DeviceState::kOpen, "", nullptr);
}

void SensorLifecycle::close() noexcept {
  stop();
  drop_transport();
  state_.set(DeviceState::kClosed, "", nullptr);
}

void SensorLifecycle::start(SensorCallbacks callbacks) {
  if (running_) return;
  if (state_.get() == DeviceState::kClosed)
    throw DeviceError(DeviceErrorKind::kProtocol, options_.name, "start", "open() first");
  callbacks_ = std::move(callbacks);
  running_ = true;
  on_start();
  // Started after a loss (no transport): the worker begins by reconnecting.
  state_.set(has_transport() ? DeviceState::kAcquiring : DeviceState::kLost,
             options_.name + (has_transport() ? ": acquiring" : ": lost: reconnecting"),
             &callbacks_);
  worker_.start([this](Worker& w) { run(w); },
                [this](const std::exception& e) {
                  // Nothing escapes the worker: an unexpected error ends acquisition as a state.
                  const std::string reason = options_.name + ": worker stopped: " + e.what();
                  drop_transport();
                  state_.set(DeviceState::kLost, reason, &callbacks_);
                });
}

void SensorLifecycle::stop() noexcept {
  if (!running_) return;
  worker_.stop();
  running_ = false;
  // No callback after stop(): the state change is not reported.
  state_.set(has_transport() ? DeviceState::kOpen : DeviceState::kLost, "", nullptr);
}

void SensorLifecycle::lose(const std::string& reason) {
  drop_transport();
  state_.set(DeviceState::kLost, options_.name + ": lost: " + reason, &callbacks_);
}

bool SensorLifecycle::reconnect() {
  try {
    // The transport opening is not enough (a silent device keeps its port): it must answer too.
    if (!reconnect_once()) {
      drop_transport();
      return false;
    }
  } catch (const std::exception&) {  // any failure is one failed attempt: try again later
    drop_transport();
    return false;
  }
  stats_.reconnects.fetch_add(1);
  seq_.resync();  // the device may have restarted its own sample counter
  state_.set(DeviceState::kAcquiring, options_.name + ": reconnected", &callbacks_);
  on_reconnected();
  return true;
}

void SensorLifecycle::run(Worker& worker) {
  Backoff backoff(options_.backoff_initial, options_.backoff_max);
  int consecutive_timeouts = 0;
  while (!worker.stop_requested()) {
    if (!has_transport()) {
      if (!worker.sleep_for(backoff.next())) return;
      if (reconnect()) backoff.reset();
      consecutive_timeouts = 0;
      continue;
    }
    try {
      std::string detail;
      if (acquire(detail) == Step::kTimeout) {
        stats_.timeouts.fetch_add(1);
        on_timeout();
        if (++consecutive_timeouts >= options_.timeouts_until_lost) {
          lose(lost_after_timeouts(consecutive_timeouts, detail));
          consecutive_timeouts = 0;
          continue;
        }
      } else {
        consecutive_timeouts = 0;
      }
    } catch (const std::exception& e) {
      // A DeviceError (port gone, write timeout ...) or anything unexpected: the device is lost
      // and the worker reconnects; nothing ends acquisition but stop().
      lose(e.what());
      consecutive_timeouts = 0;
      continue;
    }
    if (!pause(worker)) return;
  }
}

}  // namespace scanmesh::drivers
