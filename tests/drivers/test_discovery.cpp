// Device discovery: usb: identity specs, resolving them against a port list, and the real
// libserialport / libusb enumerations (whatever this machine has: no hardware is required).
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <string>

#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/transports/discovery.hpp"
#include "scanmesh/drivers/transports/usb.hpp"

using namespace scanmesh::drivers;

TEST_CASE("usb: identities parse; malformed ones are config errors", "[drivers][discovery]") {
  CHECK_FALSE(parse_usb_identity("/dev/ttyUSB0"));
  const auto a = parse_usb_identity("usb:0403:6001");
  REQUIRE(a);
  CHECK(a->vid == 0x0403);
  CHECK(a->pid == 0x6001);
  CHECK_FALSE(a->serial);
  const auto b = parse_usb_identity("usb:10C4:EA60:A12345");
  REQUIRE(b);
  CHECK(b->vid == 0x10c4);
  CHECK(b->pid == 0xea60);
  CHECK(b->serial == "A12345");
  for (const char* bad : {"usb:", "usb:0403", "usb:0403:", "usb:xyz:6001", "usb:12345:1",
                          "usb:0403:6001:"}) {
    INFO(bad);
    CHECK_THROWS_AS(parse_usb_identity(bad), scanmesh::ConfigError);
  }
}

TEST_CASE("usb: identities resolve to exactly one port", "[drivers][discovery]") {
  std::vector<SerialPortInfo> ports(3);
  ports[0].path = "/dev/ttyUSB0";
  ports[0].usb_vid = 0x0403;
  ports[0].usb_pid = 0x6001;
  ports[0].usb_serial = "AAA";
  ports[1].path = "/dev/ttyUSB1";
  ports[1].usb_vid = 0x0403;
  ports[1].usb_pid = 0x6001;
  ports[1].usb_serial = "BBB";
  ports[2].path = "/dev/ttyS0";

  CHECK(resolve_serial_port("/dev/ttyS0", ports) == "/dev/ttyS0");
  CHECK(resolve_serial_port("usb:0403:6001:BBB", ports) == "/dev/ttyUSB1");
  try {
    resolve_serial_port("usb:0403:6001", ports);
    FAIL("ambiguous identity resolved");
  } catch (const DeviceError& e) {
    CHECK(e.kind() == DeviceErrorKind::kNotFound);
    CHECK(std::string(e.what()).find("2 ports match") != std::string::npos);
  }
  try {
    resolve_serial_port("usb:1a86:7523", ports);
    FAIL("absent identity resolved");
  } catch (const DeviceError& e) {
    const std::string msg = e.what();
    CHECK(msg.find("usb:1a86:7523") != std::string::npos);
    CHECK(msg.find("/dev/ttyUSB0 = usb:0403:6001:AAA") != std::string::npos);
  }
}

TEST_CASE("libserialport and libusb enumerate without error", "[drivers][discovery]") {
  const auto ports = list_serial_ports();
  for (const auto& p : ports) {
    CHECK_FALSE(p.path.empty());
    CHECK((p.transport == "usb" || p.transport == "native" || p.transport == "bluetooth" ||
           p.transport == "unknown"));
    if (p.transport != "usb") CHECK_FALSE(p.usb_vid);
  }
  const auto usb = list_usb_devices();
  for (const auto& d : usb) CHECK(d.bus > 0);
}

TEST_CASE("libusb context: hotplug watch and a missing device", "[drivers][usb]") {
  UsbContext first;
  UsbContext ctx(std::move(first));  // move-only owner: the event thread follows the context
  CHECK(first.get() == nullptr);
  REQUIRE(ctx.get() != nullptr);
  if (ctx.has_hotplug()) {
    const int id = ctx.watch(0x1234, 0x5678, [](UsbEvent, const UsbDeviceInfo&) {});
    CHECK(id > 0);
    ctx.unwatch(id);
  }
  UsbBulkSettings s;
  s.identity = {0x1234, 0x5678, std::string("NOPE")};
  try {
    open_usb_bulk_stream("ild0", ctx, s);
    FAIL("opened an absent USB device");
  } catch (const DeviceError& e) {
    CHECK(e.kind() == DeviceErrorKind::kNotFound);
    CHECK(std::string(e.what()).find("ild0 (usb:1234:5678:NOPE)") != std::string::npos);
  }
}
