// Serial port enumeration with libserialport and usb: identity resolution (discovery.hpp).
// libserialport is used only for what it is best at (listing ports with their USB identity);
// the byte stream itself is Boost.Asio (serial_stream.cpp), which also works on ptys.
// SPDX-License-Identifier: MIT
#include <libserialport.h>

#include <charconv>
#include <memory>

#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/transports/discovery.hpp"

namespace scanmesh::drivers {

namespace {

/// The one place libserialport return codes become DeviceError.
void check(sp_return r, const char* operation) {
  if (r >= 0) return;
  std::string detail;
  if (r == SP_ERR_FAIL) {
    char* msg = sp_last_error_message();
    detail = msg ? msg : "failure";
    sp_free_error_message(msg);
  } else if (r == SP_ERR_MEM) {
    detail = "out of memory";
  } else if (r == SP_ERR_SUPP) {
    detail = "not supported on this system";
  } else {
    detail = "invalid argument";
  }
  throw DeviceError(DeviceErrorKind::kIo, "serial ports", operation, detail);
}

struct PortListDeleter {
  void operator()(sp_port** list) const { sp_free_port_list(list); }
};

std::string str(const char* s) { return s ? std::string(s) : std::string(); }

std::optional<std::uint16_t> parse_hex16(std::string_view s) {
  if (s.empty() || s.size() > 4) return std::nullopt;
  std::uint16_t v = 0;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v, 16);
  if (ec != std::errc() || p != s.data() + s.size()) return std::nullopt;
  return v;
}

std::string hex4(std::uint16_t v) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%04x", v);
  return buf;
}

}  // namespace

std::vector<SerialPortInfo> list_serial_ports() {
  sp_port** raw = nullptr;
  check(sp_list_ports(&raw), "list");
  std::unique_ptr<sp_port*, PortListDeleter> list(raw);
  std::vector<SerialPortInfo> out;
  for (sp_port** p = list.get(); p && *p; ++p) {
    SerialPortInfo info;
    info.path = str(sp_get_port_name(*p));
    info.description = str(sp_get_port_description(*p));
    switch (sp_get_port_transport(*p)) {
      case SP_TRANSPORT_USB: {
        info.transport = "usb";
        int vid = 0, pid = 0;
        if (sp_get_port_usb_vid_pid(*p, &vid, &pid) == SP_OK) {
          info.usb_vid = static_cast<std::uint16_t>(vid);
          info.usb_pid = static_cast<std::uint16_t>(pid);
        }
        info.usb_serial = str(sp_get_port_usb_serial(*p));
        info.usb_manufacturer = str(sp_get_port_usb_manufacturer(*p));
        info.usb_product = str(sp_get_port_usb_product(*p));
        break;
      }
      case SP_TRANSPORT_NATIVE:
        info.transport = "native";
        break;
      case SP_TRANSPORT_BLUETOOTH:
        info.transport = "bluetooth";
        break;
      default:
        info.transport = "unknown";
    }
    out.push_back(std::move(info));
  }
  return out;
}

std::optional<UsbIdentity> parse_usb_identity(std::string_view spec) {
  if (spec.substr(0, 4) != "usb:") return std::nullopt;
  std::string_view rest = spec.substr(4);
  const auto c1 = rest.find(':');
  if (c1 == std::string_view::npos)
    throw ConfigError("port '" + std::string(spec) + "': expected usb:VID:PID[:SERIAL] (hex)");
  const std::string_view vid_s = rest.substr(0, c1);
  rest = rest.substr(c1 + 1);
  const auto c2 = rest.find(':');
  const std::string_view pid_s = rest.substr(0, c2);
  UsbIdentity id;
  const auto vid = parse_hex16(vid_s);
  const auto pid = parse_hex16(pid_s);
  if (!vid || !pid)
    throw ConfigError("port '" + std::string(spec) +
                      "': VID and PID must be 1-4 hex digits (usb:VID:PID[:SERIAL])");
  id.vid = *vid;
  id.pid = *pid;
  if (c2 != std::string_view::npos) {
    const std::string_view serial = rest.substr(c2 + 1);
    if (serial.empty())
      throw ConfigError("port '" + std::string(spec) + "': empty serial number after the PID");
    id.serial = std::string(serial);
  }
  return id;
}

std::string resolve_serial_port(std::string_view spec, const std::vector<SerialPortInfo>& ports) {
  const auto id = parse_usb_identity(spec);
  if (!id) return std::string(spec);
  std::vector<const SerialPortInfo*> hits;
  for (const SerialPortInfo& p : ports) {
    if (p.usb_vid == id->vid && p.usb_pid == id->pid && (!id->serial || p.usb_serial == *id->serial))
      hits.push_back(&p);
  }
  if (hits.size() == 1) return hits.front()->path;
  std::string seen;
  for (const SerialPortInfo& p : ports) {
    if (!p.usb_vid) continue;
    seen += (seen.empty() ? "" : ", ") + p.path + " = usb:" + hex4(*p.usb_vid) + ":" +
            hex4(*p.usb_pid) + (p.usb_serial.empty() ? "" : ":" + p.usb_serial);
  }
  if (hits.empty())
    throw DeviceError(DeviceErrorKind::kNotFound, std::string(spec), "resolve port",
                      "no serial port has this USB identity (USB serial ports present: " +
                          (seen.empty() ? std::string("none") : seen) + ")");
  throw DeviceError(DeviceErrorKind::kNotFound, std::string(spec), "resolve port",
                    std::to_string(hits.size()) +
                        " ports match; add the serial number (usb:VID:PID:SERIAL): " + seen);
}

}  // namespace scanmesh::drivers
