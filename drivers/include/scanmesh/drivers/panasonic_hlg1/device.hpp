// Panasonic HL-G1 displacement sensor over RS-422/RS-485: polls RMD, reports lost/recovered
// states and reconnects through its transport factory.
// SPDX-License-Identifier: MIT
//
// Models: Panasonic HL-G1 series (HL-G103/105/108/112/125 heads); one Device per unit number.
// Document: HL-G1 manual ch. 4 §4-2, pp. 4-6 .. 4-9 (PROTOCOLS.md §1.4).
// Transport: ByteStream (RS-422, or RS-485 with several heads on one bus: the unit number
// selects the head); 8N1, 9600..115200 baud, default 38400.
// Quirks:
// - Strict request/response; replies carry the unit number, a reply for another unit is ignored.
// - Identification: no identity command is documented; open() identifies the sensor by one
//   valid RMD reply. DeviceIdentity: vendor "Panasonic", model "HL-G1", empty serial/firmware.
// - Requests carry a real BCC by default (send_bcc); `**` is also documented as accepted.
// - A reply with a wrong BCC is malformed (counted, no sample); `!` error replies are counted.
// - RMD values have no status field: every valid RMD reply is a kOk sample. The protocol
//   excerpt documents no RMD encoding for "no target"; such a condition has to come back as an
//   error reply (which is what the emulator does) and then yields no sample.
// - No device clock: t_device stays empty.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "scanmesh/drivers/byte_stream.hpp"
#include "scanmesh/drivers/common/polled_sensor.hpp"
#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/panasonic_hlg1/codec.hpp"

namespace scanmesh::drivers::panasonic_hlg1 {

/// Factory default of the HL-G1 serial port and the fastest rate it supports.
inline constexpr unsigned kDefaultBaud = 38400;
inline constexpr unsigned kMaxBaud = 115200;

/// HL-G1 specific options.
struct HlG1Options {
  /// Unit (sensor) number on the bus. Default 1; valid 0..99.
  int unit = 1;
  /// Send a computed BCC (default) or `**` in its place.
  bool send_bcc = true;
};

class Device final : public PolledSerialSensor {
 public:
  Device(SensorOptions options, ByteStreamFactory transport);
  /// Throws ConfigError for an invalid option.
  Device(SensorOptions options, ByteStreamFactory transport, HlG1Options hlg1);
  ~Device() override;

  SensorCapabilities capabilities() const override;

 private:
  std::string_view request() const override { return request_; }
  std::string operation() const override { return "RMD"; }
  std::string open_operation() const override;
  DeviceIdentity device_identity() const override;
  void feed(std::span<const std::uint8_t> bytes, Timestamp t_host, Exchange& exchange) override;
  void reset_codec() override { decoder_.reset(); }

  HlG1Options hlg1_;
  std::string request_;  // the encoded RMD request
  Decoder decoder_;
};

}  // namespace scanmesh::drivers::panasonic_hlg1
