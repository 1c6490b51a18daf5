// libusb owners (STYLE §5.3): the context with its event thread and hotplug notifications, and
// a bulk-endpoint ByteStream for sensors with a native USB interface. Move-only RAII; errors
// are DeviceError with libusb_error_name().
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "scanmesh/drivers/byte_stream.hpp"
#include "scanmesh/drivers/transports/discovery.hpp"

struct libusb_context;

namespace scanmesh::drivers {

enum class UsbEvent { kArrived, kLeft };

/// One libusb context and the thread that runs its events (hotplug callbacks run there:
/// they must be quick and must not call back into libusb synchronously).
class UsbContext {
 public:
  UsbContext();  ///< throws DeviceError
  ~UsbContext();
  UsbContext(UsbContext&&) noexcept;
  UsbContext& operator=(UsbContext&&) noexcept;
  UsbContext(const UsbContext&) = delete;
  UsbContext& operator=(const UsbContext&) = delete;

  libusb_context* get() const;

  /// Whether this libusb build can deliver hotplug events (Linux: yes, via udev/netlink).
  bool has_hotplug() const;
  /// Calls `on_event` when a device with this VID/PID (0 = any) arrives or leaves, and once
  /// for each matching device present now (kArrived). Returns a handle id for unwatch().
  int watch(std::uint16_t vid, std::uint16_t pid,
            std::function<void(UsbEvent, const UsbDeviceInfo&)> on_event);
  void unwatch(int handle);

 private:
  struct Impl;  // the context, its event thread and the hotplug registrations (stable address)
  std::unique_ptr<Impl> impl_;
};

/// Settings of a USB bulk byte stream.
struct UsbBulkSettings {
  UsbIdentity identity;          ///< which device (serial optional when only one matches)
  int interface_number = 0;      ///< interface to claim (the kernel driver is auto-detached)
  std::uint8_t endpoint_in = 0x81;   ///< bulk IN endpoint address
  std::uint8_t endpoint_out = 0x01;  ///< bulk OUT endpoint address
};

/// Opens the device by identity, claims the interface and returns a ByteStream over the bulk
/// endpoints. Throws DeviceError kNotFound (naming the identity) when no device matches.
std::unique_ptr<ByteStream> open_usb_bulk_stream(const std::string& device, UsbContext& context,
                                                 const UsbBulkSettings& settings);

}  // namespace scanmesh::drivers
