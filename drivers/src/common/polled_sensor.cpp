// PolledSerialSensor: open/identify, the worker loop, lost/reconnect and statistics shared by the
// request/response ASCII sensor drivers (see common/polled_sensor.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/common/polled_sensor.hpp"

#include <algorithm>
#include <chrono>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers {

namespace {

using Clock = std::chrono::steady_clock;

std::string ms_text(std::chrono::milliseconds d) { return std::to_string(d.count()) + " ms"; }

}  // namespace

// ---- Exchange ----

void PolledSerialSensor::Exchange::sample(SensorSample& sample) {
  outcome_ = Outcome::kSample;
  done_ = !owner_.streaming();
  // Streaming: every record of a chunk is a sample. Polling: the one answer.
  if (emit_) owner_.emit(sample);
}

void PolledSerialSensor::Exchange::error_reply(std::string detail) {
  owner_.stats_.error_replies.fetch_add(1);
  detail_ = std::move(detail);
  if (outcome_ != Outcome::kSample) outcome_ = Outcome::kError;
  done_ = !owner_.streaming();
}

void PolledSerialSensor::Exchange::malformed(std::string_view why) {
  owner_.stats_.malformed.fetch_add(1);
  if (!owner_.streaming() && !done_) {
    detail_ = "malformed reply: ";
    detail_ += why;
    outcome_ = Outcome::kError;
    done_ = true;
  }
}

void PolledSerialSensor::Exchange::invalid(std::string detail) {
  owner_.stats_.malformed.fetch_add(1);
  if (done_) return;
  detail_ = std::move(detail);
  if (outcome_ != Outcome::kSample) outcome_ = Outcome::kError;
  done_ = !owner_.streaming();
}

// ---- PolledSerialSensor ----

PolledSerialSensor::PolledSerialSensor(SensorOptions options, ByteStreamFactory transport,
                                       std::size_t read_buffer)
    : options_(std::move(options)),
      factory_(std::move(transport)),
      read_buffer_(std::clamp<std::size_t>(read_buffer, 1, kMaxReadBuffer)) {}

PolledSerialSensor::~PolledSerialSensor() { close(); }

void PolledSerialSensor::check_options() const {
  if (options_.timeout < std::chrono::milliseconds(1) ||
      options_.timeout > std::chrono::seconds(60))
    throw ConfigError(options_.name + ": timeout must be 1 ms .. 60 s");
  if (options_.timeouts_until_lost < 1)
    throw ConfigError(options_.name + ": timeouts_until_lost must be >= 1");
  if (!factory_) throw ConfigError(options_.name + ": no transport factory");
}

std::string PolledSerialSensor::where() const {
  return transport_ ? transport_->name() : options_.name;
}

void PolledSerialSensor::open() {
  if (running_) return;
  transport_.reset();
  transport_ = factory_();  // throws DeviceError naming the device and the port
  const std::string port = transport_->name();
  std::string detail;
  Outcome outcome;
  try {
    transport_->discard_input();
    reset_codec();
    outcome = exchange(false, detail);
  } catch (...) {
    transport_.reset();
    throw;
  }
  if (outcome != Outcome::kSample) {
    transport_.reset();
    throw DeviceError(
        outcome == Outcome::kTimeout ? DeviceErrorKind::kTimeout : DeviceErrorKind::kProtocol, port,
        open_operation(), detail);
  }
  identity_ = device_identity();
  state_.set(DeviceState::kOpen, "", nullptr);
}

void PolledSerialSensor::close() noexcept {
  stop();
  transport_.reset();
  state_.set(DeviceState::kClosed, "", nullptr);
}

void PolledSerialSensor::start(SensorCallbacks callbacks) {
  if (running_) return;
  if (state_.get() == DeviceState::kClosed)
    throw DeviceError(DeviceErrorKind::kProtocol, options_.name, "start", "open() first");
  callbacks_ = std::move(callbacks);
  running_ = true;
  state_.set(transport_ ? DeviceState::kAcquiring : DeviceState::kLost, "start", &callbacks_);
  worker_.start([this](Worker& w) { run(w); },
                [this](const std::exception& e) {
                  // Last resort: run() catches everything itself.
                  lose(options_.name + ": worker stopped: " + e.what());
                });
}

void PolledSerialSensor::stop() noexcept {
  if (!running_) return;
  worker_.stop();
  running_ = false;
  // No callback after stop(): the state change is not reported.
  state_.set(transport_ ? DeviceState::kOpen : DeviceState::kLost, "", nullptr);
}

void PolledSerialSensor::emit(SensorSample& sample) {
  sample.seq = seq_.next();
  stats_.samples.fetch_add(1);
  if (callbacks_.on_sample) callbacks_.on_sample(sample);
}

PolledSerialSensor::Outcome PolledSerialSensor::exchange(bool emit, std::string& detail) {
  const std::string_view req = request();
  const bool poll = !req.empty();
  const auto deadline = Clock::now() + options_.timeout;
  // Strict request/response: the next request only after the reply (or the timeout).
  if (poll) transport_->write_all(req, options_.timeout);
  std::uint8_t storage[kMaxReadBuffer];
  const std::span<std::uint8_t> buffer(storage, read_buffer_);
  Exchange ex(*this, emit);
  for (;;) {
    const auto now = Clock::now();
    if (now >= deadline) {
      detail =
          std::string(poll ? "no reply" : "no record") + " within " + ms_text(options_.timeout);
      return Outcome::kTimeout;
    }
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - now);
    const std::size_t n = transport_->read_some(buffer, left);
    if (n == 0) continue;
    const Timestamp t_host = monotonic_now();
    feed(buffer.first(n), t_host, ex);
    if (ex.done_ || ex.outcome_ == Outcome::kSample) {
      detail = std::move(ex.detail_);
      return ex.outcome_;
    }
  }
}

void PolledSerialSensor::lose(const std::string& reason) {
  transport_.reset();
  reset_codec();
  state_.set(DeviceState::kLost, reason, &callbacks_);
}

bool PolledSerialSensor::reconnect(Worker& worker, Backoff& backoff) {
  if (!worker.sleep_for(backoff.next())) return false;
  try {
    transport_ = factory_();
    transport_->discard_input();
    reset_codec();
    std::string detail;
    // The port opening is not enough (a silent device keeps its port): it must answer too.
    if (exchange(false, detail) == Outcome::kTimeout) {
      transport_.reset();
      return false;
    }
  } catch (const std::exception&) {
    transport_.reset();
    return false;
  }
  stats_.reconnects.fetch_add(1);
  backoff.reset();
  state_.set(DeviceState::kAcquiring, options_.name + ": reconnected", &callbacks_);
  return true;
}

void PolledSerialSensor::run(Worker& worker) {
  Backoff backoff(options_.backoff_initial, options_.backoff_max);
  const bool poll = !streaming();
  int consecutive_timeouts = 0;
  while (!worker.stop_requested()) {
    if (!transport_) {
      reconnect(worker, backoff);
      consecutive_timeouts = 0;
      continue;
    }
    try {
      std::string detail;
      if (exchange(true, detail) == Outcome::kTimeout) {
        stats_.timeouts.fetch_add(1);
        transport_->discard_input();  // a late reply must not pass for the next one
        reset_codec();
        if (++consecutive_timeouts >= options_.timeouts_until_lost) {
          lose(where() + ": " + operation() + ": " + detail + ", " +
               std::to_string(consecutive_timeouts) + " times in a row");
          consecutive_timeouts = 0;
          continue;
        }
      } else {
        consecutive_timeouts = 0;
      }
    } catch (const std::exception& e) {
      // DeviceError kDisconnected (port gone) or a write timeout: the device is lost.
      lose(e.what());
      consecutive_timeouts = 0;
      continue;
    }
    if (poll && options_.poll_interval.count() > 0 && !worker.sleep_for(options_.poll_interval))
      break;
  }
}

}  // namespace scanmesh::drivers
