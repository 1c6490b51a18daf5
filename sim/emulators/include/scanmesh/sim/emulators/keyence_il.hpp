// KEYENCE DL-RS1A + IL amplifiers emulator on a pty: answers M0 / MS / SR from a ValueSource
// (PROTOCOLS.md §1.2).
// SPDX-License-Identifier: MIT
#pragma once

#include <string>
#include <string_view>

#include "scanmesh/sim/emulators/serial_emulator.hpp"

namespace scanmesh::sim {

struct KeyenceIlEmulatorOptions {
  /// Amplifiers behind the DL-RS1A (1..16). Amplifier 0 shows the value source; the others
  /// show the same value plus their index in mm (so a test can tell them apart).
  int amplifiers = 1;
  /// Digits after the point: 3 for ±**.*** heads (IL-030...), 2 for IL-300/600, 1 for IL-2000.
  int decimals = 3;
  /// Code of the ER reply of the error_reply fault.
  int error_code = 0;
};

/// Emulated DL-RS1A. Requests end in CR or CR LF (any other last byte of a line: `ER,<cmd>,00`
/// is not emulated: CR is the only line end); replies end in CR LF.
/// - M0 -> `M0,<v0>,<v1>...`; MS -> `MS,00,<v0>,00,<v1>...` (control output 00 for kOk,
///   [unverified] 08 for a reading without value);
/// - SR,<id>,<no> -> `SR,<id>,<no>,0` for an existing amplifier, else `ER,SR,22`;
/// - anything else -> `ER,<cmd>,00`.
/// Values: kOk as ±**.*** etc., [unverified] over range `±FFFFFF`, otherwise `XXXXXXX`.
/// Faults: error_reply answers M0/MS/SR with `ER,<cmd>,<error_code>`; bad_checksum is ignored
/// (the protocol has no checksum).
class KeyenceIlEmulator final : public SerialEmulator {
 public:
  KeyenceIlEmulator(std::string link_path, ValueSource values,
                    KeyenceIlEmulatorOptions options = {});
  ~KeyenceIlEmulator() override;

 protected:
  std::string on_input(std::string_view bytes) override;

 private:
  std::string answer(std::string_view request);
  std::string format(const drivers::SensorSample& s, int amplifier) const;

  KeyenceIlEmulatorOptions options_;
  std::string pending_;  // partial request (emulator thread only)
};

}  // namespace scanmesh::sim
