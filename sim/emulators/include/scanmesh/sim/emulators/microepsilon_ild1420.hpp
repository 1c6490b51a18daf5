// Emulator of a Micro-Epsilon optoNCDT ILD1420 on a pty: streams binary L/M/H output blocks on a
// 1 ms tick and answers the ASCII commands (GETINFO, OUTPUT ..., ...) with "->" prompts.
// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "scanmesh/sim/emulators/serial_emulator.hpp"

namespace scanmesh::sim {

/// Settings of the emulated sensor.
struct Ild1420EmulatorOptions {
  double measuring_range_mm = 10;      ///< reported by GETINFO and used for the scaling
  bool report_measuring_range = true;  ///< false: GETINFO has no "Measuring range" line
  /// Words of an output block: 'd' distance, 'c' 18-bit counter, 'l'/'h' timestamp low/high
  /// word (10 µs ticks). Default "d". Must match the driver's BlockLayout.
  std::string layout = "d";
  int blocks_per_tick = 1;  ///< blocks per 1 ms tick (1 = 1 kHz, 10 = 10 kHz), 1 .. 100
  /// When set, measurements come from here instead of the plain ValueSource, each at its own
  /// instant: the blocks of a tick are taken one period (1 ms / blocks_per_tick) apart, the last
  /// one at the tick (never later than now, never earlier than the previous one plus a period
  /// unless that is in the future). The timestamp words then carry that instant.
  TimedValueSource timed_values;
  bool streaming = true;    ///< output on at power-up (OUTPUT RS422)
  std::string name = "ILD1420-10";
  std::string serial = "1234567";
  std::string article = "4120123";
  std::string version = "001.002.003";
};

/// Faults (SerialFaults): garbage_before_reply and split_every_byte apply to replies and stream
/// alike (base class); bad_checksum drops the M byte of every 5th value (broken marker
/// sequence); error_reply answers every command with "E200 Unknown command"-style errors;
/// silent/reply_delay/vanish as in the base. Error-code values come from the ValueSource: NaN
/// -> 262076 (no peak), -inf -> 262077, +inf -> 262078, kDeviceError/kAlarm -> 262082 (laser
/// off) unless the sample carries a device_code.
class MicroEpsilonIld1420Emulator final : public SerialEmulator {
 public:
  MicroEpsilonIld1420Emulator(std::string link_path, ValueSource values,
                              Ild1420EmulatorOptions options = {});
  ~MicroEpsilonIld1420Emulator() override;

  bool streaming() const { return streaming_.load(); }
  /// Commands received (without CR), in order.
  std::vector<std::string> commands() const;
  /// Encodes one word as the L, M, H bytes (first: block-start flag clear).
  static std::string encode_word(std::uint32_t word, bool first);
  /// Distance -> 16-bit raw value (d = (1.02 x / 65520 - 0.01) MR).
  static std::uint32_t raw_distance(double value_mm, double measuring_range_mm);

 protected:
  std::string on_input(std::string_view bytes) override;
  std::string on_tick() override;
  std::chrono::microseconds tick_interval() const override { return std::chrono::milliseconds(1); }

 private:
  std::string answer(const std::string& command);
  std::string block(std::optional<drivers::Timestamp> measured);

  Ild1420EmulatorOptions options_;
  std::string line_;
  std::atomic<bool> streaming_;
  mutable std::mutex mutex_;
  std::vector<std::string> commands_;
  std::uint32_t counter_ = 0;
  std::uint64_t ticks_10us_ = 0;
  std::int64_t device_ns_ = 0;  // the device clock, ns (free-running, or measurement instants)
  std::optional<drivers::Timestamp> clock_origin_, last_measured_;
  std::uint64_t values_sent_ = 0;
};

}  // namespace scanmesh::sim
