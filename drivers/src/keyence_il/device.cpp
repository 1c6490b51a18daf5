// KEYENCE IL / DL-RS1A device: the M0 polling loop over a ByteStream (see keyence_il/device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/keyence_il/device.hpp"

#include <chrono>
#include <limits>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::keyence_il {

namespace {

using Clock = std::chrono::steady_clock;

std::string ms_text(std::chrono::milliseconds d) { return std::to_string(d.count()) + " ms"; }

std::string two_digits(int v) { return std::to_string(v / 10) + std::to_string(v % 10); }

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

Device::Device(SensorOptions options, ByteStreamFactory transport)
    : Device(std::move(options), std::move(transport), IlOptions{}) {}

Device::Device(SensorOptions options, ByteStreamFactory transport, IlOptions il)
    : options_(std::move(options)), factory_(std::move(transport)), il_(il) {
  if (il_.amplifier < 0 || il_.amplifier >= static_cast<int>(kMaxAmplifiers))
    throw ConfigError(options_.name + ": keyence-il amplifier must be 0..15");
  if (!(il_.value_scale > 0 && il_.value_scale <= 1000))
    throw ConfigError(options_.name + ": keyence-il value_scale must be > 0 and <= 1000");
  if (options_.timeout < std::chrono::milliseconds(1) ||
      options_.timeout > std::chrono::seconds(60))
    throw ConfigError(options_.name + ": timeout must be 1 ms .. 60 s");
  if (options_.timeouts_until_lost < 1)
    throw ConfigError(options_.name + ": timeouts_until_lost must be >= 1");
  if (!factory_) throw ConfigError(options_.name + ": no transport factory");
}

Device::~Device() { close(); }

SensorCapabilities Device::capabilities() const {
  SensorCapabilities c;
  // Strict request/response at 115200 baud (11520 bytes/s): 4 request + 12 reply bytes per M0
  // round trip with one amplifier ("M0,+12.345" CR LF), 720 values/s. Range and
  // resolution depend on the head (IL-S025 .. IL-2000): unknown to the driver.
  c.max_rate_hz = kMaxBaud / 10.0 / 16.0;
  c.device_clock = false;
  c.streaming = false;
  return c;
}

std::string Device::where() const { return transport_ ? transport_->name() : options_.name; }

void Device::open() {
  if (running_) return;
  transport_.reset();
  transport_ = factory_();  // throws DeviceError naming the device and the port
  const std::string port = transport_->name();
  std::string detail;
  Outcome outcome;
  try {
    transport_->discard_input();
    decoder_.reset();
    outcome = acquire_one(false, detail);
  } catch (...) {
    transport_.reset();
    throw;
  }
  if (outcome != Outcome::kSample) {
    transport_.reset();
    throw DeviceError(
        outcome == Outcome::kTimeout ? DeviceErrorKind::kTimeout : DeviceErrorKind::kProtocol, port,
        "M0", detail);
  }
  identity_ = DeviceIdentity{"KEYENCE", "IL (DL-RS1A)", "", ""};
  state_.set(DeviceState::kOpen, "", nullptr);
}

void Device::close() noexcept {
  stop();
  transport_.reset();
  state_.set(DeviceState::kClosed, "", nullptr);
}

void Device::start(SensorCallbacks callbacks) {
  if (running_) return;
  if (state_.get() == DeviceState::kClosed)
    throw DeviceError(DeviceErrorKind::kProtocol, options_.name, "start", "open() first");
  callbacks_ = std::move(callbacks);
  running_ = true;
  state_.set(transport_ ? DeviceState::kAcquiring : DeviceState::kLost, "start", &callbacks_);
  worker_.start(
      [this](Worker& w) { run(w); },
      [this](const std::exception& e) { lose(options_.name + ": worker stopped: " + e.what()); });
}

void Device::stop() noexcept {
  if (!running_) return;
  worker_.stop();
  running_ = false;
  state_.set(transport_ ? DeviceState::kOpen : DeviceState::kLost, "", nullptr);
}

Device::Outcome Device::acquire_one(bool emit_sample, std::string& detail) {
  const auto deadline = Clock::now() + options_.timeout;
  transport_->write_all(M0::encode(), options_.timeout);
  std::uint8_t buffer[256];
  for (;;) {
    const auto now = Clock::now();
    if (now >= deadline) {
      detail = "no reply within " + ms_text(options_.timeout);
      return Outcome::kTimeout;
    }
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - now);
    const std::size_t n = transport_->read_some(buffer, left);
    if (n == 0) continue;
    const Timestamp t_host = monotonic_now();
    bool done = false;
    Outcome outcome = Outcome::kTimeout;
    decoder_.feed(
        std::span<const std::uint8_t>(buffer, n),
        [&](const Reply& reply) {
          // Strict request/response: anything after the answer to our M0 is stale.
          if (done) return;
          if (reply.kind == ReplyKind::kError) {
            stats_.error_replies.fetch_add(1);
            detail = "error reply ER," + std::string(reply.command_view()) + "," +
                     two_digits(reply.error_code) + " (" +
                     std::string(error_text(reply.error_code)) + ")";
            outcome = Outcome::kError;
            done = true;
            return;
          }
          if (reply.kind != ReplyKind::kM0) return;  // DR records, stale SR answers
          const auto amp = static_cast<std::size_t>(il_.amplifier);
          done = true;
          if (reply.count <= amp) {
            stats_.malformed.fetch_add(1);
            detail = "M0 reply has " + std::to_string(reply.count) + " values, amplifier " +
                     std::to_string(amp) + " missing";
            outcome = Outcome::kError;
            return;
          }
          const Reading& r = reply.readings[amp];
          SensorSample s;
          s.t_host = t_host;
          s.status = r.status;
          s.value_mm = r.status == SensorStatus::kOk ? r.value * il_.value_scale : kNaN;
          outcome = Outcome::kSample;
          if (emit_sample) {
            s.seq = seq_.next();
            stats_.samples.fetch_add(1);
            if (callbacks_.on_sample) callbacks_.on_sample(s);
          }
        },
        [&](const char* why) {
          stats_.malformed.fetch_add(1);
          if (!done) {
            detail = std::string("malformed reply: ") + why;
            outcome = Outcome::kError;
            done = true;
          }
        });
    if (done) return outcome;
  }
}

void Device::lose(const std::string& reason) {
  transport_.reset();
  decoder_.reset();
  state_.set(DeviceState::kLost, reason, &callbacks_);
}

bool Device::reconnect(Worker& worker, Backoff& backoff) {
  if (!worker.sleep_for(backoff.next())) return false;
  try {
    transport_ = factory_();
    transport_->discard_input();
    decoder_.reset();
    std::string detail;
    // The port opening is not enough (a silent unit keeps its port): it must answer too.
    if (acquire_one(false, detail) == Outcome::kTimeout) {
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

void Device::run(Worker& worker) {
  Backoff backoff(options_.backoff_initial, options_.backoff_max);
  int consecutive_timeouts = 0;
  while (!worker.stop_requested()) {
    if (!transport_) {
      reconnect(worker, backoff);
      consecutive_timeouts = 0;
      continue;
    }
    try {
      std::string detail;
      if (acquire_one(true, detail) == Outcome::kTimeout) {
        stats_.timeouts.fetch_add(1);
        transport_->discard_input();  // a late reply must not pass for the next one
        decoder_.reset();
        if (++consecutive_timeouts >= options_.timeouts_until_lost) {
          lose(where() + ": M0: " + detail + ", " + std::to_string(consecutive_timeouts) +
               " times in a row");
          consecutive_timeouts = 0;
          continue;
        }
      } else {
        consecutive_timeouts = 0;
      }
    } catch (const std::exception& e) {
      // DeviceError kDisconnected (port gone) or a write timeout: the unit is lost.
      lose(e.what());
      consecutive_timeouts = 0;
      continue;
    }
    if (options_.poll_interval.count() > 0 && !worker.sleep_for(options_.poll_interval)) break;
  }
}

}  // namespace scanmesh::drivers::keyence_il
