// PolledSerialSensor: open/identify, one exchange per worker step and reconnecting over a
// ByteStream for the request/response ASCII sensor drivers (see common/polled_sensor.hpp).
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
  owner_.counters().error_replies.fetch_add(1);
  detail_ = std::move(detail);
  if (outcome_ != Outcome::kSample) outcome_ = Outcome::kError;
  done_ = !owner_.streaming();
}

void PolledSerialSensor::Exchange::malformed(std::string_view why) {
  owner_.counters().malformed.fetch_add(1);
  if (!owner_.streaming() && !done_) {
    detail_ = "malformed reply: ";
    detail_ += why;
    outcome_ = Outcome::kError;
    done_ = true;
  }
}

void PolledSerialSensor::Exchange::invalid(std::string detail) {
  owner_.counters().malformed.fetch_add(1);
  if (done_) return;
  detail_ = std::move(detail);
  if (outcome_ != Outcome::kSample) outcome_ = Outcome::kError;
  done_ = !owner_.streaming();
}

// ---- PolledSerialSensor ----

PolledSerialSensor::PolledSerialSensor(SensorOptions options, ByteStreamFactory transport,
                                       std::size_t read_buffer)
    : SensorLifecycle(std::move(options)),
      factory_(std::move(transport)),
      read_buffer_(std::clamp<std::size_t>(read_buffer, 1, kMaxReadBuffer)) {}

PolledSerialSensor::~PolledSerialSensor() { close(); }

void PolledSerialSensor::check_options() const {
  const SensorOptions& o = options();
  if (o.timeout < std::chrono::milliseconds(1) || o.timeout > std::chrono::seconds(60))
    throw ConfigError(o.name + ": timeout must be 1 ms .. 60 s");
  if (o.timeouts_until_lost < 1) throw ConfigError(o.name + ": timeouts_until_lost must be >= 1");
  if (!factory_) throw ConfigError(o.name + ": no transport factory");
}

std::string PolledSerialSensor::where() const {
  return transport_ ? transport_->name() : options().name;
}

void PolledSerialSensor::open_device() {
  transport_ = factory_();  // throws DeviceError naming the device and the port
  const std::string port = transport_->name();
  std::string detail;
  transport_->discard_input();
  reset_codec();
  const Outcome outcome = exchange(false, detail);
  if (outcome != Outcome::kSample) {
    throw DeviceError(
        outcome == Outcome::kTimeout ? DeviceErrorKind::kTimeout : DeviceErrorKind::kProtocol, port,
        open_operation(), detail);
  }
  set_identity(device_identity());
}

void PolledSerialSensor::emit(SensorSample& sample) {
  sample.seq = sequence().next();
  deliver(sample);
}

PolledSerialSensor::Outcome PolledSerialSensor::exchange(bool emit, std::string& detail) {
  const std::string_view req = request();
  const bool poll = !req.empty();
  const std::chrono::milliseconds timeout = options().timeout;
  const auto deadline = Clock::now() + timeout;
  // Strict request/response: the next request only after the reply (or the timeout).
  if (poll) transport_->write_all(req, timeout);
  std::uint8_t storage[kMaxReadBuffer];
  const std::span<std::uint8_t> buffer(storage, read_buffer_);
  Exchange ex(*this, emit);
  for (;;) {
    const auto now = Clock::now();
    if (now >= deadline) {
      detail = std::string(poll ? "no reply" : "no record") + " within " + ms_text(timeout);
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

bool PolledSerialSensor::reconnect_once() {
  transport_ = factory_();
  transport_->discard_input();
  reset_codec();
  std::string detail;
  // An error reply is an answer too; only silence keeps the device lost.
  return exchange(false, detail) != Outcome::kTimeout;
}

PolledSerialSensor::Step PolledSerialSensor::acquire(std::string& timeout_detail) {
  return exchange(true, timeout_detail) == Outcome::kTimeout ? Step::kTimeout : Step::kAnswered;
}

void PolledSerialSensor::on_timeout() {
  transport_->discard_input();  // a late reply must not pass for the next one
  reset_codec();
}

std::string PolledSerialSensor::lost_after_timeouts(int count, const std::string& detail) const {
  return where() + ": " + operation() + ": " + detail + ", " + std::to_string(count) +
         " times in a row";
}

bool PolledSerialSensor::pause(Worker& worker) {
  const auto interval = options().poll_interval;
  if (streaming() || interval.count() <= 0) return true;
  return worker.sleep_for(interval);
}

}  // namespace scanmesh::drivers
