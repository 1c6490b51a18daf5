// Panasonic HL-G1 device: the RMD polling loop over a ByteStream (see panasonic_hlg1/device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/panasonic_hlg1/device.hpp"

#include <chrono>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::panasonic_hlg1 {

namespace {

using Clock = std::chrono::steady_clock;

std::string ms_text(std::chrono::milliseconds d) { return std::to_string(d.count()) + " ms"; }

std::string two_digits(int v) { return std::to_string(v / 10) + std::to_string(v % 10); }

}  // namespace

Device::Device(SensorOptions options, ByteStreamFactory transport)
    : Device(std::move(options), std::move(transport), HlG1Options{}) {}

Device::Device(SensorOptions options, ByteStreamFactory transport, HlG1Options hlg1)
    : options_(std::move(options)), factory_(std::move(transport)), hlg1_(hlg1) {
  if (hlg1_.unit < 0 || hlg1_.unit > 99)
    throw ConfigError(options_.name + ": panasonic-hlg1 unit must be 0..99");
  if (options_.timeout < std::chrono::milliseconds(1) ||
      options_.timeout > std::chrono::seconds(60))
    throw ConfigError(options_.name + ": timeout must be 1 ms .. 60 s");
  if (options_.timeouts_until_lost < 1)
    throw ConfigError(options_.name + ": timeouts_until_lost must be >= 1");
  if (!factory_) throw ConfigError(options_.name + ": no transport factory");
  request_ = ReadMeasurement::encode(hlg1_.unit, hlg1_.send_bcc);
}

Device::~Device() { close(); }

SensorCapabilities Device::capabilities() const {
  SensorCapabilities c;
  // Strict request/response at 115200 baud (11520 bytes/s): 10 request + 18 reply bytes per
  // RMD round trip, about 411 values/s. The value quantum is 0.1 µm; the range depends on the
  // head (HL-G103 .. HL-G125), unknown to the driver.
  c.max_rate_hz = kMaxBaud / 10.0 / 28.0;
  c.resolution_mm = kMmPerCount;
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
        "RMD (unit " + two_digits(hlg1_.unit) + ")", detail);
  }
  identity_ = DeviceIdentity{"Panasonic", "HL-G1", "", ""};
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
  transport_->write_all(std::string_view(request_), options_.timeout);
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
          // Strict request/response; on RS-485 other heads' replies are not ours.
          if (done || reply.unit != hlg1_.unit) return;
          if (reply.kind == ReplyKind::kError) {
            stats_.error_replies.fetch_add(1);
            detail = "error reply !" + two_digits(reply.error_code) + " (" +
                     std::string(error_text(reply.error_code)) + ")";
            outcome = Outcome::kError;
            done = true;
            return;
          }
          if (!reply.has_value) return;  // an answer to some other command
          SensorSample s;
          s.t_host = t_host;
          s.status = SensorStatus::kOk;
          s.value_mm = reply.value_mm();
          outcome = Outcome::kSample;
          done = true;
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
    // The port opening is not enough (a silent sensor keeps its port): it must answer too.
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
          lose(where() + ": RMD: " + detail + ", " + std::to_string(consecutive_timeouts) +
               " times in a row");
          consecutive_timeouts = 0;
          continue;
        }
      } else {
        consecutive_timeouts = 0;
      }
    } catch (const std::exception& e) {
      // DeviceError kDisconnected (port gone) or a write timeout: the sensor is lost.
      lose(e.what());
      consecutive_timeouts = 0;
      continue;
    }
    if (options_.poll_interval.count() > 0 && !worker.sleep_for(options_.poll_interval)) break;
  }
}

}  // namespace scanmesh::drivers::panasonic_hlg1
