// KEYENCE IL amplifier behind a DL-RS1A, over RS-232C: polls M0, reports lost/recovered states
// and reconnects through its transport factory.
// SPDX-License-Identifier: MIT
//
// Models: IL-1000/1050/1500/1550 amplifiers with IL-S025/030/065/100/300/600/2000 heads, via
// DL-RS1A (one Device per amplifier; several Devices cannot share one port, so use one per
// DL-RS1A and pick the amplifier with `amplifier`).
// Document: KEYENCE DL-RS1A/IL User Manual p. 9; DL-RS1A User Manual pp. 8, 10
// (PROTOCOLS.md §1.2).
// Transport: ByteStream (RS-232C 8N1; 9600..115200 baud, default 38400).
// Quirks:
// - Strict request/response; requests end in CR LF (CR alone is accepted too), replies in CR LF.
// - Identification: the IL data numbers that would identify head/amplifier are not in the
//   protocol notes, so open() identifies the unit by one valid M0 reply (which also shows how
//   many amplifiers are connected). DeviceIdentity: vendor "KEYENCE", model "IL (DL-RS1A)",
//   empty serial and firmware.
// - Value format per head (±**.***, ±***.**, ±****.*): the point comes with the field;
//   value_scale converts other unit settings.
// - [unverified] over range / alarm fields as on the LK-G (see codec.hpp).
// - No device clock: t_device stays empty.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "scanmesh/drivers/byte_stream.hpp"
#include "scanmesh/drivers/common/polled_sensor.hpp"
#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/keyence_il/codec.hpp"

namespace scanmesh::drivers::keyence_il {

/// Factory default of the DL-RS1A and the fastest rate it supports.
inline constexpr unsigned kDefaultBaud = 38400;
inline constexpr unsigned kMaxBaud = 115200;

/// IL specific options.
struct IlOptions {
  /// Which amplifier's value this Device delivers: its position in the M0 reply (ID00 = 0).
  /// Default 0; valid 0..15.
  int amplifier = 0;
  /// mm per unit of the transmitted number. Default 1.0 (values in mm with their decimal
  /// point, as in the documented head formats). Use the digit weight (0.001 / 0.01 / 0.1 for
  /// the ±**.*** / ±***.** / ±****.* heads) if the unit sends no point, 0.001 for µm.
  /// Valid: > 0 and <= 1000.
  double value_scale = 1.0;
};

class Device final : public PolledSerialSensor {
 public:
  Device(SensorOptions options, ByteStreamFactory transport);
  /// Throws ConfigError for an invalid option.
  Device(SensorOptions options, ByteStreamFactory transport, IlOptions il);
  ~Device() override;

  SensorCapabilities capabilities() const override;

 private:
  std::string_view request() const override { return M0::encode(); }
  std::string operation() const override { return "M0"; }
  DeviceIdentity device_identity() const override;
  void feed(std::span<const std::uint8_t> bytes, Timestamp t_host, Exchange& exchange) override;
  void reset_codec() override { decoder_.reset(); }

  IlOptions il_;
  Decoder decoder_;
};

}  // namespace scanmesh::drivers::keyence_il
