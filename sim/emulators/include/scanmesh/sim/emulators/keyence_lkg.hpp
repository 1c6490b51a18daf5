// KEYENCE LK-G controller emulator on a pty: answers M0 / MS / Q0 / R0 from a ValueSource and
// pushes timed auto-output records on a tick (PROTOCOLS.md §1.1).
// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <chrono>
#include <string>
#include <string_view>

#include "scanmesh/sim/emulators/serial_emulator.hpp"

namespace scanmesh::sim {

struct KeyenceLkgEmulatorOptions {
  /// Digits after the decimal point of value fields (the controller's unit setting). 0..5.
  int decimals = 4;
  /// Period of the timed auto-output records (0 = the emulator never pushes records).
  std::chrono::microseconds auto_output_period{0};
  /// Whether auto output is on at start (set_auto_output() switches it).
  bool auto_output = false;
  /// Code of the ER reply the error_reply fault produces (01 = status error).
  int error_code = 1;
};

/// Emulated LK-G controller. Commands end in CR (LF is ignored); the reply header repeats the
/// command as received. Behaviour:
/// - M0 -> `M0,<OUT1>,<OUT2>` (both OUTs show the same measurement);
/// - MS -> `MS,00,<OUT1>,00,<OUT2>` ([unverified] layout, see the driver's codec.hpp);
/// - Q0 / R0 -> echo; between them (setting mode) M0/MS answer `ER,<cmd>,01`;
/// - anything else -> `ER,<cmd>,00`.
/// Values: kOk as fixed width, over range `+FFFFFFF`/`-FFFFFFF`, no target as dashes, alarm or
/// device error as `XXXXXXXX`. Faults: error_reply answers M0/MS with `ER,<cmd>,<error_code>`;
/// bad_checksum has no meaning here (the protocol has no checksum) and is ignored.
class KeyenceLkgEmulator final : public SerialEmulator {
 public:
  KeyenceLkgEmulator(std::string link_path, ValueSource values,
                     KeyenceLkgEmulatorOptions options = {});
  ~KeyenceLkgEmulator() override;

  /// Switches the timed auto output on or off (needs auto_output_period > 0).
  void set_auto_output(bool on) { auto_output_.store(on); }
  bool setting_mode() const { return setting_mode_.load(); }

  /// Formats one value field as the controller does (8 characters).
  static std::string format_value(const drivers::SensorSample& sample, int decimals);

 protected:
  std::string on_input(std::string_view bytes) override;
  std::string on_tick() override;
  std::chrono::microseconds tick_interval() const override { return options_.auto_output_period; }

 private:
  std::string answer(std::string_view command);

  KeyenceLkgEmulatorOptions options_;
  std::atomic<bool> auto_output_;
  std::atomic<bool> setting_mode_{false};
  std::string pending_;  // partial command (emulator thread only)
};

}  // namespace scanmesh::sim
