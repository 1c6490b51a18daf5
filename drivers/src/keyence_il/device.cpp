// KEYENCE IL / DL-RS1A device: the M0 protocol hooks of PolledSerialSensor (see
// keyence_il/device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/keyence_il/device.hpp"

#include <limits>
#include <string>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::keyence_il {

namespace {

std::string two_digits(int v) { return std::to_string(v / 10) + std::to_string(v % 10); }

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

Device::Device(SensorOptions options, ByteStreamFactory transport)
    : Device(std::move(options), std::move(transport), IlOptions{}) {}

Device::Device(SensorOptions options, ByteStreamFactory transport, IlOptions il)
    : PolledSerialSensor(std::move(options), std::move(transport)), il_(il) {
  if (il_.amplifier < 0 || il_.amplifier >= static_cast<int>(kMaxAmplifiers))
    throw ConfigError(this->options().name + ": keyence-il amplifier must be 0..15");
  if (!(il_.value_scale > 0 && il_.value_scale <= 1000))
    throw ConfigError(this->options().name + ": keyence-il value_scale must be > 0 and <= 1000");
  check_options();
}

Device::~Device() { close(); }  // stops the worker before decoder_ goes away

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

DeviceIdentity Device::device_identity() const {
  // No identification data numbers in the protocol notes: one valid M0 reply identifies the unit.
  return DeviceIdentity{"KEYENCE", "IL (DL-RS1A)", "", ""};
}

void Device::feed(std::span<const std::uint8_t> bytes, Timestamp t_host, Exchange& exchange) {
  decoder_.feed(
      bytes,
      [&](const Reply& reply) {
        // Strict request/response: anything after the answer to our M0 is stale.
        if (exchange.done()) return;
        if (reply.kind == ReplyKind::kError) {
          exchange.error_reply("error reply ER," + std::string(reply.command_view()) + "," +
                               two_digits(reply.error_code) + " (" +
                               std::string(error_text(reply.error_code)) + ")");
          return;
        }
        if (reply.kind != ReplyKind::kM0) return;  // DR records, stale SR answers
        const auto amp = static_cast<std::size_t>(il_.amplifier);
        if (reply.count <= amp) {
          exchange.invalid("M0 reply has " + std::to_string(reply.count) + " values, amplifier " +
                           std::to_string(amp) + " missing");
          return;
        }
        const Reading& r = reply.readings[amp];
        SensorSample s;
        s.t_host = t_host;
        s.status = r.status;
        s.value_mm = r.status == SensorStatus::kOk ? r.value * il_.value_scale : kNaN;
        exchange.sample(s);
      },
      [&](const char* why) { exchange.malformed(why); });
}

}  // namespace scanmesh::drivers::keyence_il
