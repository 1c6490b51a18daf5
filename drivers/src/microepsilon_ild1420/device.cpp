// Device class of the Micro-Epsilon ILD1420 (see device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/microepsilon_ild1420/device.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "scanmesh/common/error.hpp"

namespace scanmesh::drivers::microepsilon_ild1420 {

namespace {
constexpr std::size_t kReadChunk = 4096;
}

Device::Device(SensorOptions options, ByteStreamFactory transport, Options ild)
    : options_(std::move(options)),
      transport_(std::move(transport)),
      ild_(std::move(ild)),
      decoder_(ild_.layout.values.size()),
      buffer_(kReadChunk) {
  std::string problems;
  if (const std::string why = ild_.layout.check(); !why.empty()) problems += "layout: " + why;
  if (!(ild_.measuring_range_mm >= 0) || !std::isfinite(ild_.measuring_range_mm))
    problems += std::string(problems.empty() ? "" : "; ") + "measuring_range_mm must be >= 0";
  if (!problems.empty()) throw ConfigError(options_.name + ": " + problems);
  scaling_.measuring_range_mm = ild_.measuring_range_mm;
  scaling_.mastering = ild_.mastering;
}

Device::~Device() { close(); }

DeviceStats Device::stats() const { return stats_.snapshot(); }

Reply Device::command(const Command& cmd, bool stream_after) {
  replies_.reset();
  stream_->write_all(cmd.encode(), options_.timeout);
  const auto deadline = std::chrono::steady_clock::now() + options_.timeout;
  while (true) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      throw DeviceError(DeviceErrorKind::kTimeout, stream_->name(), cmd.text,
                        "no reply within " + std::to_string(options_.timeout.count()) + " ms");
    }
    // Short slices: a quiet line commits the look-behind bytes (the prompt's last characters).
    const std::size_t n = stream_->read_some(
        buffer_, std::clamp(left, std::chrono::milliseconds(1), std::chrono::milliseconds(5)));
    std::size_t used = 0;
    if (n == 0) {
      replies_.flush();
    } else {
      used = replies_.feed(std::span(buffer_).first(n));
    }
    if (replies_.done()) {
      if (stream_after) {
        const Timestamp now = monotonic_now();
        const std::vector<std::uint8_t> after = replies_.take_after_prompt();
        deliver(after, now);
        deliver(std::span(buffer_).subspan(used, n - used), now);
      }
      return replies_.reply();
    }
  }
}

void Device::open() {
  close();
  stream_ = transport_();
  if (!stream_) throw DeviceError(DeviceErrorKind::kIo, options_.name, "open", "no transport");
  try {
    const Reply off = command(output(OutputTarget::kNone), false);
    if (!off.ok()) {
      stats_.error_replies.fetch_add(1);
      throw DeviceError(DeviceErrorKind::kProtocol, stream_->name(), "OUTPUT NONE", off.error);
    }
    stream_->discard_input();  // values sent before the sensor obeyed
    Info info;
    try {
      const Reply r = command(get_info(), false);
      if (r.ok()) {
        info = parse_info(r);
      } else {
        stats_.error_replies.fetch_add(1);
        if (ild_.measuring_range_mm <= 0)
          throw DeviceError(DeviceErrorKind::kProtocol, stream_->name(), "GETINFO", r.error);
      }
    } catch (const DeviceError& e) {
      // Without GETINFO the configured measuring range is enough to decode the stream.
      if (e.kind() != DeviceErrorKind::kTimeout || ild_.measuring_range_mm <= 0) throw;
      stats_.timeouts.fetch_add(1);
    }
    const double mr =
        info.measuring_range_mm > 0 ? info.measuring_range_mm : ild_.measuring_range_mm;
    if (mr <= 0) {
      throw DeviceError(DeviceErrorKind::kProtocol, stream_->name(), "GETINFO",
                        "no \"Measuring range\" in the reply and none configured");
    }
    scaling_.measuring_range_mm = mr;
    if (info.identity.model.empty()) info.identity.vendor = "Micro-Epsilon";
    std::lock_guard lock(identity_mutex_);
    identity_ = std::move(info.identity);
  } catch (...) {
    stream_.reset();
    throw;
  }
  state_.set(DeviceState::kOpen, "", nullptr);
}

void Device::close() noexcept {
  stop();
  stream_.reset();
  state_.set(DeviceState::kClosed, "", nullptr);
}

void Device::start(SensorCallbacks callbacks) {
  stop();
  if (!stream_) throw DeviceError(DeviceErrorKind::kIo, options_.name, "start", "device not open");
  callbacks_ = std::move(callbacks);
  running_ = true;
  decoder_.reset();
  state_.set(DeviceState::kAcquiring, options_.name + ": acquiring", &callbacks_);
  worker_.start([this](Worker& w) { run(w); },
                [this](const std::exception& e) {
                  state_.set(DeviceState::kLost, options_.name + ": worker stopped: " + e.what(),
                             &callbacks_);
                });
}

void Device::stop() noexcept {
  if (!running_) return;
  worker_.stop();
  running_ = false;
  state_.set(stream_ ? DeviceState::kOpen : DeviceState::kClosed, "", nullptr);
}

void Device::deliver(std::span<const std::uint8_t> bytes, Timestamp t_host) {
  if (bytes.empty()) return;
  decoder_.feed(bytes, [&](const RawBlock& block) {
    const DecodedBlock d = decode_block(block, ild_.layout, scaling_);
    SensorSample s;
    s.t_host = t_host;
    s.seq = d.counter ? seq_.next(*d.counter) : seq_.next();
    s.t_device = d.t_device;
    s.status = d.status;
    s.value_mm = d.value_mm;
    s.device_code = d.device_code;
    stats_.samples.fetch_add(1);
    if (callbacks_.on_sample) callbacks_.on_sample(s);
  });
  stats_.malformed.store(decoder_.malformed());
  stats_.gaps.store(seq_.gaps());
}

bool Device::reconnect(Worker& worker, const std::string& reason) {
  stream_.reset();
  state_.set(DeviceState::kLost, options_.name + ": lost: " + reason, &callbacks_);
  Backoff backoff(options_.backoff_initial, options_.backoff_max);
  while (true) {
    if (!worker.sleep_for(backoff.next())) return false;
    try {
      stream_ = transport_();
      if (!stream_) continue;
      decoder_.reset();
      // Back only when the sensor answers: (re)start its output.
      const Reply r = command(output(OutputTarget::kRs422), true);
      if (!r.ok()) stats_.error_replies.fetch_add(1);
    } catch (const DeviceError&) {
      stream_.reset();
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
  bool need_output = true;
  while (!worker.stop_requested()) {
    std::string lost_reason;
    try {
      if (need_output) {
        const Reply r = command(output(OutputTarget::kRs422), true);
        if (!r.ok()) stats_.error_replies.fetch_add(1);
        need_output = false;
        consecutive_timeouts = 0;
      }
      const std::size_t n = stream_->read_some(buffer_, options_.timeout);
      if (n == 0) {
        stats_.timeouts.fetch_add(1);
        if (++consecutive_timeouts >= options_.timeouts_until_lost) {
          lost_reason = "no data for " + std::to_string(consecutive_timeouts) + " x " +
                        std::to_string(options_.timeout.count()) + " ms";
        }
      } else {
        consecutive_timeouts = 0;
        deliver(std::span(buffer_).first(n), monotonic_now());
      }
    } catch (const DeviceError& e) {
      if (e.kind() == DeviceErrorKind::kTimeout) {
        stats_.timeouts.fetch_add(1);
        if (++consecutive_timeouts >= options_.timeouts_until_lost) lost_reason = e.what();
      } else {
        lost_reason = e.what();
      }
    }
    if (!lost_reason.empty()) {
      consecutive_timeouts = 0;
      if (!reconnect(worker, lost_reason)) return;
      need_output = false;
    }
  }
}

DeviceIdentity Device::identify() const {
  std::lock_guard lock(identity_mutex_);
  return identity_;
}

SensorCapabilities Device::capabilities() const {
  SensorCapabilities c;
  c.max_rate_hz = ild_.max_rate_hz;
  c.range_min_mm = 0;
  c.range_max_mm = scaling_.measuring_range_mm;
  c.resolution_mm = 1.02 * scaling_.measuring_range_mm / 65520.0;
  c.device_clock = std::find(ild_.layout.values.begin(), ild_.layout.values.end(),
                             BlockValue::kTimestampLow) != ild_.layout.values.end();
  c.streaming = true;
  return c;
}

}  // namespace scanmesh::drivers::microepsilon_ild1420
