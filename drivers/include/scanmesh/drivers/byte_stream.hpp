// ByteStream: the transport interface of byte-oriented devices (serial ports, USB bulk
// endpoints). Blocking calls with timeouts, used from one device worker thread.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>

namespace scanmesh::drivers {

class ByteStream {
 public:
  virtual ~ByteStream() = default;

  /// Writes every byte or throws DeviceError (kTimeout, kDisconnected, kIo).
  virtual void write_all(std::span<const std::uint8_t> bytes,
                         std::chrono::milliseconds timeout) = 0;
  /// Waits at most `timeout` for at least one byte and returns how many were read (0 on
  /// timeout). Throws DeviceError kDisconnected when the other end is gone.
  virtual std::size_t read_some(std::span<std::uint8_t> buffer,
                                std::chrono::milliseconds timeout) = 0;
  /// Discards whatever is buffered for reading (stale replies after a timeout).
  virtual void discard_input() = 0;
  /// Human-readable name for messages: the device name and the port ("lkg0 (/dev/ttyUSB0)").
  virtual const std::string& name() const = 0;

  void write_all(std::string_view text, std::chrono::milliseconds timeout) {
    write_all(std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()),
              timeout);
  }
};

/// Opens (or reopens, after a loss) the transport of one device. Throws DeviceError.
using ByteStreamFactory = std::function<std::unique_ptr<ByteStream>()>;

}  // namespace scanmesh::drivers
