// Finding devices by identity: serial ports with their USB identity (libserialport) and USB
// devices (libusb), so a configuration can say `usb:0403:6001:A12345` instead of a /dev/ttyUSBn
// that changes between boots.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace scanmesh::drivers {

/// One serial port as the OS lists it.
struct SerialPortInfo {
  std::string path;          ///< /dev/ttyUSB0, /dev/ttyS0, ...
  std::string transport;     ///< "usb", "native", "bluetooth" or "unknown"
  std::string description;   ///< libserialport's description
  std::optional<std::uint16_t> usb_vid;  ///< USB identity (usb transport only)
  std::optional<std::uint16_t> usb_pid;
  std::string usb_serial;
  std::string usb_manufacturer;
  std::string usb_product;
};

/// Lists the serial ports (libserialport). Throws DeviceError kIo with the library's message.
std::vector<SerialPortInfo> list_serial_ports();

/// A `usb:VID:PID[:SERIAL]` device spec (VID/PID in hex).
struct UsbIdentity {
  std::uint16_t vid = 0;
  std::uint16_t pid = 0;
  std::optional<std::string> serial;
};

/// Parses "usb:VID:PID[:SERIAL]" (hex VID/PID, 1-4 digits each). nullopt if `spec` does not
/// start with "usb:"; throws ConfigError for a malformed usb: spec.
std::optional<UsbIdentity> parse_usb_identity(std::string_view spec);

/// Resolves a configured port: a path is returned unchanged; a usb: identity is looked up in
/// `ports` and must match exactly one port (DeviceError kNotFound listing what was seen, or
/// naming the ambiguity so the user adds the serial number).
std::string resolve_serial_port(std::string_view spec, const std::vector<SerialPortInfo>& ports);

/// One USB device as libusb lists it.
struct UsbDeviceInfo {
  std::uint8_t bus = 0;
  std::uint8_t address = 0;
  std::uint16_t vid = 0;
  std::uint16_t pid = 0;
  std::string manufacturer;  ///< string descriptors: empty when the device cannot be opened
  std::string product;
  std::string serial;
};

/// Lists USB devices (libusb). Throws DeviceError kIo with libusb's error name.
std::vector<UsbDeviceInfo> list_usb_devices();

}  // namespace scanmesh::drivers
