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

#include <memory>
#include <mutex>
#include <string>

#include "scanmesh/drivers/byte_stream.hpp"
#include "scanmesh/drivers/device_support.hpp"
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

class Device final : public DisplacementSensor {
 public:
  Device(SensorOptions options, ByteStreamFactory transport);
  /// Throws ConfigError for an invalid option.
  Device(SensorOptions options, ByteStreamFactory transport, LkgOptions lkg);
  ~Device() override;

  const std::string& name() const override { return options_.name; }
  void open() override;
  void close() noexcept override;
  void start(SensorCallbacks callbacks) override;
  void stop() noexcept override;

  DeviceIdentity identify() const override { return identity_; }
  SensorCapabilities capabilities() const override;
  DeviceState state() const override { return state_.get(); }
  DeviceStats stats() const override { return stats_.snapshot(); }

 private:
  enum class Outcome { kSample, kError, kTimeout };
  /// Poll mode: one M0 round trip. Auto mode: reads until at least one record of our OUT
  /// arrived. Samples go to the callback when emit_samples; detail explains a non-sample.
  Outcome acquire_one(bool emit_samples, std::string& detail);
  void emit(SensorSample& sample);
  void run(Worker& worker);
  void lose(const std::string& reason);
  bool reconnect(Worker& worker, Backoff& backoff);
  SensorSample to_sample(const Reading& reading, Timestamp t_host) const;
  std::string where() const;

  SensorOptions options_;
  ByteStreamFactory factory_;
  LkgOptions lkg_;
  DeviceIdentity identity_;
  std::unique_ptr<ByteStream> transport_;  // used by the worker while running
  Decoder decoder_;
  SequenceTracker seq_;
  AtomicStats stats_;
  StateCell state_;
  SensorCallbacks callbacks_;
  Worker worker_;
  bool running_ = false;
};

}  // namespace scanmesh::drivers::keyence_lkg
