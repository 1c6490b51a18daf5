// Device class of the Micro-Epsilon ILD1420 (see device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/microepsilon_ild1420/device.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::microepsilon_ild1420 {

namespace {
constexpr std::size_t kReadChunk = 4096;
}

Device::Device(SensorOptions options, ByteStreamFactory transport, Options ild)
    : SensorLifecycle(std::move(options), 18),
      transport_(std::move(transport)),
      ild_(std::move(ild)),
      decoder_(ild_.layout.values.size()),
      buffer_(kReadChunk) {
  std::string problems;
  if (const std::string why = ild_.layout.check(); !why.empty()) problems += "layout: " + why;
  if (!(ild_.measuring_range_mm >= 0) || !std::isfinite(ild_.measuring_range_mm))
    problems += std::string(problems.empty() ? "" : "; ") + "measuring_range_mm must be >= 0";
  if (!problems.empty()) throw ConfigError(name() + ": " + problems);
  scaling_.measuring_range_mm = ild_.measuring_range_mm;
  scaling_.mastering = ild_.mastering;
}

Device::~Device() { close(); }

Reply Device::command(const Command& cmd, bool stream_after) {
  const std::chrono::milliseconds timeout = options().timeout;
  replies_.reset();
  stream_->write_all(cmd.encode(), timeout);
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (true) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      throw DeviceError(DeviceErrorKind::kTimeout, stream_->name(), cmd.text,
                        "no reply within " + std::to_string(timeout.count()) + " ms");
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

void Device::start_output() {
  const Reply r = command(output(OutputTarget::kRs422), true);
  if (!r.ok()) counters().error_replies.fetch_add(1);
}

void Device::open_device() {
  stream_ = transport_();
  if (!stream_) throw DeviceError(DeviceErrorKind::kIo, name(), "open", "no transport");
  const Reply off = command(output(OutputTarget::kNone), false);
  if (!off.ok()) {
    counters().error_replies.fetch_add(1);
    throw DeviceError(DeviceErrorKind::kProtocol, stream_->name(), "OUTPUT NONE", off.error);
  }
  stream_->discard_input();  // values sent before the sensor obeyed
  Info info;
  try {
    const Reply r = command(get_info(), false);
    if (r.ok()) {
      info = parse_info(r);
    } else {
      counters().error_replies.fetch_add(1);
      if (ild_.measuring_range_mm <= 0)
        throw DeviceError(DeviceErrorKind::kProtocol, stream_->name(), "GETINFO", r.error);
    }
  } catch (const DeviceError& e) {
    // Without GETINFO the configured measuring range is enough to decode the stream.
    if (e.kind() != DeviceErrorKind::kTimeout || ild_.measuring_range_mm <= 0) throw;
    counters().timeouts.fetch_add(1);
  }
  const double mr = info.measuring_range_mm > 0 ? info.measuring_range_mm : ild_.measuring_range_mm;
  if (mr <= 0) {
    throw DeviceError(DeviceErrorKind::kProtocol, stream_->name(), "GETINFO",
                      "no \"Measuring range\" in the reply and none configured");
  }
  scaling_.measuring_range_mm = mr;
  if (info.identity.model.empty()) info.identity.vendor = "Micro-Epsilon";
  set_identity(std::move(info.identity));
}

void Device::on_start() {
  decoder_.reset();
  need_output_ = true;
}

void Device::deliver(std::span<const std::uint8_t> bytes, Timestamp t_host) {
  if (bytes.empty()) return;
  decoder_.feed(bytes, [&](const RawBlock& block) {
    const DecodedBlock d = decode_block(block, ild_.layout, scaling_);
    SensorSample s;
    s.t_host = t_host;
    s.seq = d.counter ? sequence().next(*d.counter) : sequence().next();
    s.t_device = d.t_device;
    s.status = d.status;
    s.value_mm = d.value_mm;
    s.device_code = d.device_code;
    SensorLifecycle::deliver(s);
  });
  counters().malformed.store(decoder_.malformed());
  counters().gaps.store(sequence().gaps());
}

bool Device::reconnect_once() {
  stream_ = transport_();
  if (!stream_) return false;
  decoder_.reset();
  // Back only when the sensor answers: (re)start its output.
  start_output();
  need_output_ = false;
  return true;
}

Device::Step Device::acquire(std::string& timeout_detail) {
  try {
    if (need_output_) {
      start_output();
      need_output_ = false;
      return Step::kAnswered;
    }
    const std::size_t n = stream_->read_some(buffer_, options().timeout);
    if (n == 0) return Step::kTimeout;
    deliver(std::span(buffer_).first(n), monotonic_now());
    return Step::kAnswered;
  } catch (const DeviceError& e) {
    if (e.kind() != DeviceErrorKind::kTimeout) throw;
    timeout_detail = e.what();  // counted like silence; the loss reason is the error's text
    return Step::kTimeout;
  }
}

std::string Device::lost_after_timeouts(int count, const std::string& detail) const {
  if (!detail.empty()) return detail;
  return "no data for " + std::to_string(count) + " x " +
         std::to_string(options().timeout.count()) + " ms";
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
