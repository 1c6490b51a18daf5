// Panasonic HL-G1 emulator on a pty: answers MEWTOCOL-style `%nn#RMD` / `RSP` requests for one
// unit number from a ValueSource (PROTOCOLS.md §1.4).
// SPDX-License-Identifier: MIT
#pragma once

#include <string>
#include <string_view>

#include "scanmesh/sim/emulators/serial_emulator.hpp"

namespace scanmesh::sim {

struct PanasonicHlg1EmulatorOptions {
  int unit = 1;           ///< the unit number this head answers to (00..99)
  bool reply_bcc = true;  ///< send a computed BCC (false: `**`)
  int error_code = 61;    ///< code of the `!` reply of the error_reply fault
  /// Code answered to RMD when the value source has no value (no target, over range): the
  /// protocol excerpt documents no RMD encoding for it, so the emulator reports an error.
  int no_value_code = 61;
};

/// Emulated HL-G1 head. Requests `%<unit>#<cmd><data><BCC|**>` CR; a request with a wrong BCC
/// gets `!40` (BCC error), one for another unit gets no answer (RS-485 bus), an unknown command
/// `!42`. RMD -> `%<unit>$RMD<sign><7 digits, 0.1 µm><BCC>`; RSP -> `%<unit>$RSP+00001<BCC>`.
/// Faults: bad_checksum corrupts the reply BCC; error_reply answers `!<error_code>`.
class PanasonicHlg1Emulator final : public SerialEmulator {
 public:
  PanasonicHlg1Emulator(std::string link_path, ValueSource values,
                        PanasonicHlg1EmulatorOptions options = {});
  ~PanasonicHlg1Emulator() override;

 protected:
  std::string on_input(std::string_view bytes) override;

 private:
  std::string answer(std::string_view request);
  std::string frame(std::string body, const SerialFaults& faults) const;

  PanasonicHlg1EmulatorOptions options_;
  std::string pending_;  // partial request (emulator thread only)
};

}  // namespace scanmesh::sim
