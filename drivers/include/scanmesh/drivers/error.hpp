// DeviceError: the one error type of the device layer (../shared/STYLE.md §4).
// SPDX-License-Identifier: MIT
#pragma once

#include <string>
#include <string_view>

#include "scanmesh/common/error.hpp"

namespace scanmesh::drivers {

enum class DeviceErrorKind {
  kTimeout,       ///< the device did not answer in time
  kDisconnected,  ///< the port/connection vanished (EOF, EIO, unplugged, connection reset)
  kProtocol,      ///< the device answered with something we cannot use (or an error reply)
  kIo,            ///< an operating-system or library I/O error
  kNotFound,      ///< no such port / device / USB identity
};

std::string_view to_string(DeviceErrorKind kind);

/// Thrown for setup errors and by blocking transport calls. The message always reads
/// "<device>: <operation>: <detail>", detail being the library's own text where there is one.
class DeviceError : public Error {
 public:
  DeviceError(DeviceErrorKind kind, std::string device, std::string operation, std::string detail);

  DeviceErrorKind kind() const { return kind_; }
  const std::string& device() const { return device_; }
  const std::string& operation() const { return operation_; }
  const std::string& detail() const { return detail_; }

 private:
  DeviceErrorKind kind_;
  std::string device_;
  std::string operation_;
  std::string detail_;
};

}  // namespace scanmesh::drivers
