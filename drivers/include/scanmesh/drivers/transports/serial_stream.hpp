// Serial byte stream on Boost.Asio's serial_port: termios underneath, so it drives real ttys
// (USB-serial adapters, RS-232/422/485 cards) and the pseudo-terminals the emulators hold alike.
// SPDX-License-Identifier: MIT
#pragma once

#include <memory>
#include <string>

#include "scanmesh/drivers/byte_stream.hpp"

namespace scanmesh::drivers {

/// Line settings. Defaults 8N1 at 9600 baud.
struct SerialSettings {
  std::string path;           ///< device path (/dev/ttyUSB0, a pty, or a resolved usb: identity)
  unsigned baud = 9600;       ///< 50 .. 4000000; any standard termios rate
  char parity = 'N';          ///< 'N', 'E' or 'O'
  unsigned data_bits = 8;     ///< 5 .. 8
  unsigned stop_bits = 1;     ///< 1 or 2
};

/// Opens the port (exclusively: TIOCEXCL) or throws DeviceError naming `device` and the path:
/// kNotFound when the path does not exist, kIo otherwise, with the OS's message.
std::unique_ptr<ByteStream> open_serial_stream(const std::string& device,
                                               const SerialSettings& settings);

}  // namespace scanmesh::drivers
