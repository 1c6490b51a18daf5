// KEYENCE LK-G displacement sensor over RS-232C: polls M0 (or reads the timed auto-output
// stream), reports lost/recovered states and reconnects through its transport factory.
// SPDX-License-Identifier: MIT
//
// Models: LK-G3000 / LK-G5000 controllers with LK-G / LK-H heads (one OUT per Device).
// Document: KEYENCE LK-G Series User Manual ch. 5 "RS-232C", pp. 5-5, 5-6, 5-24
// (PROTOCOLS.md §1.1).
// Transport: ByteStream (RS-232C 8N1; 9600..115200 baud, default 115200).
// Quirks:
// - Strict request/response: the next command only after the reply (or the timeout).
// - Identification: the protocol has no identity command. Q0/R0 (setting mode) would only
//   switch modes ([unverified] and it interrupts measuring), so open() identifies the device by
//   one successful M0 (poll mode) or by one auto-output record (streaming mode); DeviceIdentity
//   is vendor "KEYENCE", model "LK-G", empty serial and firmware.
// - Alarm (dashes / XXXXXXX) and over-range (+/-FFFFFFF) values become samples with status
//   kAlarm / kOverRange and value_mm NaN; ER replies are counted, never turned into samples.
// - A reply arriving after the timeout is discarded with the input buffer; it may still be
//   taken for the reply to the next M0 if it arrives later still (it is a real, slightly old
//   measurement then).
// - No device clock: t_device stays empty.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "scanmesh/drivers/byte_stream.hpp"
#include "scanmesh/drivers/common/polled_sensor.hpp"
#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/keyence_lkg/codec.hpp"

namespace scanmesh::drivers::keyence_lkg {

/// Factory default of the LK-G RS-232C port and the fastest rate it supports.
inline constexpr unsigned kDefaultBaud = 115200;
inline constexpr unsigned kMaxBaud = 115200;

enum class Acquisition {
  kPoll,        ///< send M0 every poll_interval and wait for the reply (default)
  kAutoOutput,  ///< the controller is set to timed auto output: just read the pushed records
};

/// LK-G specific options.
struct LkgOptions {
  /// Which OUT this Device delivers: 1 = OUT1 (default) or 2 = OUT2.
  int out = 1;
  Acquisition acquisition = Acquisition::kPoll;
  /// mm per unit of the transmitted number. Default 1.0 (the controller's unit setting is mm;
  /// the decimal point is part of the field). Use 0.001 when it outputs µm, or the weight of
  /// the last digit when the unit setting sends no decimal point. Valid: > 0 and <= 1000.
  double value_scale = 1.0;
};

class Device final : public PolledSerialSensor {
 public:
  Device(SensorOptions options, ByteStreamFactory transport);
  /// Throws ConfigError for an invalid option.
  Device(SensorOptions options, ByteStreamFactory transport, LkgOptions lkg);
  ~Device() override;

  SensorCapabilities capabilities() const override;

 private:
  /// Poll mode: M0. Auto mode: nothing (an exchange reads until at least one record of our OUT
  /// arrived).
  std::string_view request() const override;
  std::string operation() const override;
  DeviceIdentity device_identity() const override;
  void feed(std::span<const std::uint8_t> bytes, Timestamp t_host, Exchange& exchange) override;
  void reset_codec() override { decoder_.reset(); }
  SensorSample to_sample(const Reading& reading, Timestamp t_host) const;

  LkgOptions lkg_;
  Decoder decoder_;
};

}  // namespace scanmesh::drivers::keyence_lkg
