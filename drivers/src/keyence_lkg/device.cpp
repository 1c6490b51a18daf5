// KEYENCE LK-G device: the acquisition loop over a ByteStream (see keyence_lkg/device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/keyence_lkg/device.hpp"

#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::keyence_lkg {

namespace {

using Clock = std::chrono::steady_clock;

std::string ms_text(std::chrono::milliseconds d) { return std::to_string(d.count()) + " ms"; }

}  // namespace

Device::Device(SensorOptions options, ByteStreamFactory transport)
    : Device(std::move(options), std::move(transport), LkgOptions{}) {}

Device::Device(SensorOptions options, ByteStreamFactory transport, LkgOptions lkg)
    : options_(std::move(options)), factory_(std::move(transport)), lkg_(lkg) {
  if (lkg_.out != 1 && lkg_.out != 2)
    throw ConfigError(options_.name + ": keyence-lkg out must be 1 or 2");
  if (!(lkg_.value_scale > 0 && lkg_.value_scale <= 1000))
    throw ConfigError(options_.name + ": keyence-lkg value_scale must be > 0 and <= 1000");
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
  // Over RS-232C at 115200 baud (8N1: 11520 bytes/s) the fastest delivery is the auto-output
  // stream, 12 bytes per record ("T1,+01.2345" CR): 960 records/s. Polling M0 is slower
  // (24 bytes per round trip plus the ~3 ms response time). Range and resolution depend on the
  // head and the unit setting: unknown to the driver.
  c.max_rate_hz = kMaxBaud / 10.0 / 12.0;
  c.device_clock = false;
  c.streaming = lkg_.acquisition == Acquisition::kAutoOutput;
  return c;
}

std::string Device::where() const { return transport_ ? transport_->name() : options_.name; }

void Device::open() {
  if (running_) return;
  transport_.reset();
  transport_ = factory_();  // throws DeviceError naming the device and the port
  const std::string port = transport_->name();
  const char* operation = lkg_.acquisition == Acquisition::kPoll ? "M0" : "auto output";
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
        operation, detail);
  }
  identity_ = DeviceIdentity{"KEYENCE", "LK-G", "", ""};
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
  worker_.start([this](Worker& w) { run(w); },
                [this](const std::exception& e) {
                  // Last resort: run() catches everything itself.
                  lose(options_.name + ": worker stopped: " + e.what());
                });
}

void Device::stop() noexcept {
  if (!running_) return;
  worker_.stop();
  running_ = false;
  // No callback after stop(): the state change is not reported.
  state_.set(transport_ ? DeviceState::kOpen : DeviceState::kLost, "", nullptr);
}

SensorSample Device::to_sample(const Reading& reading, Timestamp t_host) const {
  SensorSample s;
  s.t_host = t_host;
  s.status = reading.status;
  s.value_mm = reading.status == SensorStatus::kOk ? reading.value * lkg_.value_scale
                                                   : std::numeric_limits<double>::quiet_NaN();
  return s;
}

void Device::emit(SensorSample& sample) {
  sample.seq = seq_.next();
  stats_.samples.fetch_add(1);
  if (callbacks_.on_sample) callbacks_.on_sample(sample);
}

Device::Outcome Device::acquire_one(bool emit_samples, std::string& detail) {
  const bool poll = lkg_.acquisition == Acquisition::kPoll;
  const auto deadline = Clock::now() + options_.timeout;
  if (poll) transport_->write_all(M0::encode(), options_.timeout);
  std::uint8_t buffer[512];
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
    bool done = false;
    Outcome outcome = Outcome::kTimeout;
    decoder_.feed(
        std::span<const std::uint8_t>(buffer, n),
        [&](const Reply& reply) {
          // Strict request/response: anything after the answer to our M0 is stale.
          if (done) return;
          if (reply.kind == ReplyKind::kError) {
            stats_.error_replies.fetch_add(1);
            const int code = reply.error_code;
            detail = "error reply ER," + std::string(reply.error_command_view()) + "," +
                     std::to_string(code / 10) + std::to_string(code % 10) + " (" +
                     std::string(error_text(code)) + ")";
            if (outcome != Outcome::kSample) outcome = Outcome::kError;
            done = poll;
            return;
          }
          const bool ours = poll ? (reply.kind == ReplyKind::kM0 && reply.count >= lkg_.out)
                                 : (reply.kind == ReplyKind::kAutoOutput && reply.out == lkg_.out);
          if (!ours) return;
          const Reading& r =
              poll ? reply.readings[static_cast<std::size_t>(lkg_.out - 1)] : reply.readings[0];
          SensorSample sample = to_sample(r, t_host);
          outcome = Outcome::kSample;
          done = poll;
          // Streaming: every record of a chunk is a sample. Polling: the one answer.
          if (emit_samples) emit(sample);
        },
        [&](const char* why) {
          stats_.malformed.fetch_add(1);
          if (poll && !done) {
            detail = std::string("malformed reply: ") + why;
            outcome = Outcome::kError;
            done = true;
          }
        });
    if (done || outcome == Outcome::kSample) return outcome;
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
    // The port opening is not enough (a silent device keeps its port): it must answer too.
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
  const bool poll = lkg_.acquisition == Acquisition::kPoll;
  int consecutive_timeouts = 0;
  while (!worker.stop_requested()) {
    if (!transport_) {
      reconnect(worker, backoff);
      consecutive_timeouts = 0;
      continue;
    }
    try {
      std::string detail;
      const Outcome outcome = acquire_one(true, detail);
      if (outcome == Outcome::kTimeout) {
        stats_.timeouts.fetch_add(1);
        transport_->discard_input();  // a late reply must not pass for the next one
        decoder_.reset();
        if (++consecutive_timeouts >= options_.timeouts_until_lost) {
          lose(where() + ": " + (poll ? "M0: " : "auto output: ") + detail + ", " +
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

}  // namespace scanmesh::drivers::keyence_lkg
