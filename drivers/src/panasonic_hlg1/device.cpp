// Panasonic HL-G1 device: the RMD protocol hooks of PolledSerialSensor (see
// panasonic_hlg1/device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/panasonic_hlg1/device.hpp"

#include <string>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::panasonic_hlg1 {

namespace {

std::string two_digits(int v) { return std::to_string(v / 10) + std::to_string(v % 10); }

}  // namespace

Device::Device(SensorOptions options, ByteStreamFactory transport)
    : Device(std::move(options), std::move(transport), HlG1Options{}) {}

Device::Device(SensorOptions options, ByteStreamFactory transport, HlG1Options hlg1)
    : PolledSerialSensor(std::move(options), std::move(transport)), hlg1_(hlg1) {
  if (hlg1_.unit < 0 || hlg1_.unit > 99)
    throw ConfigError(this->options().name + ": panasonic-hlg1 unit must be 0..99");
  check_options();
  // Requests carry a real BCC unless send_bcc is off (`**` is documented as accepted too).
  request_ = ReadMeasurement::encode(hlg1_.unit, hlg1_.send_bcc);
}

Device::~Device() { close(); }  // stops the worker before decoder_ goes away

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

std::string Device::open_operation() const { return "RMD (unit " + two_digits(hlg1_.unit) + ")"; }

DeviceIdentity Device::device_identity() const {
  // No identity command is documented: one valid RMD reply identifies the sensor.
  return DeviceIdentity{"Panasonic", "HL-G1", "", ""};
}

void Device::feed(std::span<const std::uint8_t> bytes, Timestamp t_host, Exchange& exchange) {
  decoder_.feed(
      bytes,
      [&](const Reply& reply) {
        // Strict request/response; on RS-485 other heads' replies are not ours.
        if (exchange.done() || reply.unit != hlg1_.unit) return;
        if (reply.kind == ReplyKind::kError) {
          exchange.error_reply("error reply !" + two_digits(reply.error_code) + " (" +
                               std::string(error_text(reply.error_code)) + ")");
          return;
        }
        if (!reply.has_value) return;  // an answer to some other command
        // RMD values have no status field: every valid RMD reply is a kOk sample.
        SensorSample s;
        s.t_host = t_host;
        s.status = SensorStatus::kOk;
        s.value_mm = reply.value_mm();
        exchange.sample(s);
      },
      // A wrong BCC is malformed too: counted, no sample.
      [&](const char* why) { exchange.malformed(why); });
}

}  // namespace scanmesh::drivers::panasonic_hlg1
