// KEYENCE LK-G device: the M0 / auto-output protocol hooks of PolledSerialSensor (see
// keyence_lkg/device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/keyence_lkg/device.hpp"

#include <limits>
#include <string>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::keyence_lkg {

Device::Device(SensorOptions options, ByteStreamFactory transport)
    : Device(std::move(options), std::move(transport), LkgOptions{}) {}

Device::Device(SensorOptions options, ByteStreamFactory transport, LkgOptions lkg)
    : PolledSerialSensor(std::move(options), std::move(transport), 512), lkg_(lkg) {
  if (lkg_.out != 1 && lkg_.out != 2)
    throw ConfigError(this->options().name + ": keyence-lkg out must be 1 or 2");
  if (!(lkg_.value_scale > 0 && lkg_.value_scale <= 1000))
    throw ConfigError(this->options().name + ": keyence-lkg value_scale must be > 0 and <= 1000");
  check_options();
}

Device::~Device() { close(); }  // stops the worker before decoder_ goes away

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

std::string_view Device::request() const {
  // Auto output: the controller pushes records on its own, the driver never sends anything.
  return lkg_.acquisition == Acquisition::kPoll ? M0::encode() : std::string_view();
}

std::string Device::operation() const {
  return lkg_.acquisition == Acquisition::kPoll ? "M0" : "auto output";
}

DeviceIdentity Device::device_identity() const {
  // No identity command (Q0/R0 would only switch modes): one answer is the identification.
  return DeviceIdentity{"KEYENCE", "LK-G", "", ""};
}

SensorSample Device::to_sample(const Reading& reading, Timestamp t_host) const {
  SensorSample s;
  s.t_host = t_host;
  s.status = reading.status;
  s.value_mm = reading.status == SensorStatus::kOk ? reading.value * lkg_.value_scale
                                                   : std::numeric_limits<double>::quiet_NaN();
  return s;
}

void Device::feed(std::span<const std::uint8_t> bytes, Timestamp t_host, Exchange& exchange) {
  const bool poll = lkg_.acquisition == Acquisition::kPoll;
  decoder_.feed(
      bytes,
      [&](const Reply& reply) {
        // Strict request/response: anything after the answer to our M0 is stale.
        if (exchange.done()) return;
        if (reply.kind == ReplyKind::kError) {
          const int code = reply.error_code;
          exchange.error_reply("error reply ER," + std::string(reply.error_command_view()) + "," +
                               std::to_string(code / 10) + std::to_string(code % 10) + " (" +
                               std::string(error_text(code)) + ")");
          return;
        }
        const bool ours = poll ? (reply.kind == ReplyKind::kM0 && reply.count >= lkg_.out)
                               : (reply.kind == ReplyKind::kAutoOutput && reply.out == lkg_.out);
        if (!ours) return;
        const Reading& r =
            poll ? reply.readings[static_cast<std::size_t>(lkg_.out - 1)] : reply.readings[0];
        SensorSample sample = to_sample(r, t_host);
        exchange.sample(sample);
      },
      [&](const char* why) { exchange.malformed(why); });
}

}  // namespace scanmesh::drivers::keyence_lkg
