// libusb context, event thread, hotplug and bulk byte stream (usb.hpp). The one place libusb
// return codes become DeviceError is usb_error().
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/transports/usb.hpp"

#include <libusb.h>

#include <atomic>
#include <cstdio>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers {

namespace {

DeviceError usb_error(int code, const std::string& device, const std::string& operation) {
  DeviceErrorKind kind = DeviceErrorKind::kIo;
  switch (code) {
    case LIBUSB_ERROR_TIMEOUT:
      kind = DeviceErrorKind::kTimeout;
      break;
    case LIBUSB_ERROR_NO_DEVICE:
    case LIBUSB_ERROR_PIPE:
      kind = DeviceErrorKind::kDisconnected;
      break;
    case LIBUSB_ERROR_NOT_FOUND:
      kind = DeviceErrorKind::kNotFound;
      break;
    default:
      break;
  }
  return DeviceError(kind, device, operation, libusb_error_name(code));
}

std::string string_descriptor(libusb_device_handle* h, std::uint8_t index) {
  if (!h || index == 0) return {};
  unsigned char buf[256];
  const int n = libusb_get_string_descriptor_ascii(h, index, buf, sizeof buf);
  return n > 0 ? std::string(reinterpret_cast<char*>(buf), static_cast<std::size_t>(n))
               : std::string();
}

/// Fills an info record; string descriptors only when the device can be opened.
UsbDeviceInfo describe(libusb_device* dev, bool read_strings) {
  UsbDeviceInfo info;
  info.bus = libusb_get_bus_number(dev);
  info.address = libusb_get_device_address(dev);
  libusb_device_descriptor d{};
  if (libusb_get_device_descriptor(dev, &d) == 0) {
    info.vid = d.idVendor;
    info.pid = d.idProduct;
    libusb_device_handle* h = nullptr;
    if (read_strings && libusb_open(dev, &h) == 0) {
      info.manufacturer = string_descriptor(h, d.iManufacturer);
      info.product = string_descriptor(h, d.iProduct);
      info.serial = string_descriptor(h, d.iSerialNumber);
      libusb_close(h);
    }
  }
  return info;
}

struct DeviceListDeleter {
  void operator()(libusb_device** list) const { libusb_free_device_list(list, 1); }
};

std::string identity_text(const UsbIdentity& id) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "usb:%04x:%04x", id.vid, id.pid);
  return std::string(buf) + (id.serial ? ":" + *id.serial : "");
}

class UsbBulkStream final : public ByteStream {
 public:
  UsbBulkStream(std::string name, libusb_device_handle* handle, const UsbBulkSettings& s)
      : name_(std::move(name)), handle_(handle), settings_(s) {}
  ~UsbBulkStream() override {
    libusb_release_interface(handle_, settings_.interface_number);
    libusb_close(handle_);
  }

  void write_all(std::span<const std::uint8_t> bytes, std::chrono::milliseconds timeout) override {
    std::size_t done = 0;
    while (done < bytes.size()) {
      int sent = 0;
      const int r = libusb_bulk_transfer(handle_, settings_.endpoint_out,
                                         const_cast<unsigned char*>(bytes.data() + done),
                                         static_cast<int>(bytes.size() - done), &sent,
                                         static_cast<unsigned>(timeout.count()));
      done += static_cast<std::size_t>(sent);
      if (r != 0) throw usb_error(r, name_, "bulk write");
    }
  }

  std::size_t read_some(std::span<std::uint8_t> buffer,
                        std::chrono::milliseconds timeout) override {
    int got = 0;
    const int r =
        libusb_bulk_transfer(handle_, settings_.endpoint_in, buffer.data(),
                             static_cast<int>(buffer.size()), &got,
                             static_cast<unsigned>(std::max<std::int64_t>(1, timeout.count())));
    if (r == LIBUSB_ERROR_TIMEOUT) return static_cast<std::size_t>(got);
    if (r != 0) throw usb_error(r, name_, "bulk read");
    return static_cast<std::size_t>(got);
  }

  void discard_input() override {
    unsigned char buf[512];
    int got = 0;
    while (libusb_bulk_transfer(handle_, settings_.endpoint_in, buf, sizeof buf, &got, 1) == 0 &&
           got > 0) {
    }
  }

  const std::string& name() const override { return name_; }

 private:
  std::string name_;
  libusb_device_handle* handle_;
  UsbBulkSettings settings_;
};

}  // namespace

struct UsbContext::Impl {
  libusb_context* ctx = nullptr;
  std::atomic<bool> stop{false};
  std::thread events;
  std::mutex mutex;
  std::map<int, libusb_hotplug_callback_handle> handles;
  std::map<int, std::unique_ptr<std::function<void(UsbEvent, const UsbDeviceInfo&)>>> callbacks;
  int next_id = 1;
};

UsbContext::UsbContext() : impl_(std::make_unique<Impl>()) {
  const int r = libusb_init(&impl_->ctx);
  if (r != 0) throw usb_error(r, "usb", "init");
  impl_->events = std::thread([impl = impl_.get()] {
    while (!impl->stop.load()) {
      timeval tv{0, 100000};  // wake up at least every 100 ms to notice stop
      libusb_handle_events_timeout_completed(impl->ctx, &tv, nullptr);
    }
  });
}

UsbContext::UsbContext(UsbContext&&) noexcept = default;
UsbContext& UsbContext::operator=(UsbContext&& other) noexcept {
  if (this != &other) {
    UsbContext gone(std::move(*this));  // releases ours
    impl_ = std::move(other.impl_);
  }
  return *this;
}

libusb_context* UsbContext::get() const { return impl_ ? impl_->ctx : nullptr; }

UsbContext::~UsbContext() {
  if (!impl_) return;  // moved from
  libusb_context* ctx = impl_->ctx;
  {
    std::lock_guard lock(impl_->mutex);
    for (auto& [id, h] : impl_->handles) libusb_hotplug_deregister_callback(ctx, h);
    impl_->handles.clear();
  }
  impl_->stop.store(true);
  libusb_interrupt_event_handler(ctx);
  if (impl_->events.joinable()) impl_->events.join();
  libusb_exit(ctx);
}

bool UsbContext::has_hotplug() const {
  return libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG) != 0;
}

int UsbContext::watch(std::uint16_t vid, std::uint16_t pid,
                      std::function<void(UsbEvent, const UsbDeviceInfo&)> on_event) {
  if (!has_hotplug())
    throw DeviceError(DeviceErrorKind::kIo, "usb", "watch", "libusb has no hotplug support here");
  auto cb = std::make_unique<std::function<void(UsbEvent, const UsbDeviceInfo&)>>(
      std::move(on_event));
  auto trampoline = [](libusb_context*, libusb_device* dev, libusb_hotplug_event event,
                       void* user) -> int {
    auto& f = *static_cast<std::function<void(UsbEvent, const UsbDeviceInfo&)>*>(user);
    // No string descriptors here: opening a device inside a hotplug callback is not allowed.
    f(event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED ? UsbEvent::kArrived : UsbEvent::kLeft,
      describe(dev, false));
    return 0;
  };
  libusb_hotplug_callback_handle handle = 0;
  const int r = libusb_hotplug_register_callback(
      get(),
      static_cast<libusb_hotplug_event>(LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED |
                                        LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT),
      LIBUSB_HOTPLUG_ENUMERATE, vid ? vid : LIBUSB_HOTPLUG_MATCH_ANY,
      pid ? pid : LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY, trampoline, cb.get(),
      &handle);
  if (r != 0) throw usb_error(r, "usb", "register hotplug callback");
  std::lock_guard lock(impl_->mutex);
  const int id = impl_->next_id++;
  impl_->handles[id] = handle;
  impl_->callbacks[id] = std::move(cb);
  return id;
}

void UsbContext::unwatch(int id) {
  std::lock_guard lock(impl_->mutex);
  const auto it = impl_->handles.find(id);
  if (it == impl_->handles.end()) return;
  libusb_hotplug_deregister_callback(get(), it->second);
  impl_->handles.erase(it);
  // The callback object stays alive until the context dies: a callback already running on the
  // event thread may still use it.
}

std::vector<UsbDeviceInfo> list_usb_devices() {
  UsbContext ctx;
  libusb_device** raw = nullptr;
  const ssize_t n = libusb_get_device_list(ctx.get(), &raw);
  if (n < 0) throw usb_error(static_cast<int>(n), "usb", "list devices");
  std::unique_ptr<libusb_device*, DeviceListDeleter> list(raw);
  std::vector<UsbDeviceInfo> out;
  for (ssize_t i = 0; i < n; ++i) out.push_back(describe(raw[i], true));
  return out;
}

std::unique_ptr<ByteStream> open_usb_bulk_stream(const std::string& device, UsbContext& context,
                                                 const UsbBulkSettings& settings) {
  const std::string name = device + " (" + identity_text(settings.identity) + ")";
  libusb_device** raw = nullptr;
  const ssize_t n = libusb_get_device_list(context.get(), &raw);
  if (n < 0) throw usb_error(static_cast<int>(n), name, "list devices");
  std::unique_ptr<libusb_device*, DeviceListDeleter> list(raw);
  for (ssize_t i = 0; i < n; ++i) {
    libusb_device_descriptor d{};
    if (libusb_get_device_descriptor(raw[i], &d) != 0) continue;
    if (d.idVendor != settings.identity.vid || d.idProduct != settings.identity.pid) continue;
    libusb_device_handle* h = nullptr;
    int r = libusb_open(raw[i], &h);
    if (r != 0) throw usb_error(r, name, "open");
    if (settings.identity.serial && string_descriptor(h, d.iSerialNumber) != *settings.identity.serial) {
      libusb_close(h);
      continue;
    }
    libusb_set_auto_detach_kernel_driver(h, 1);
    r = libusb_claim_interface(h, settings.interface_number);
    if (r != 0) {
      libusb_close(h);
      throw usb_error(r, name, "claim interface " + std::to_string(settings.interface_number));
    }
    return std::make_unique<UsbBulkStream>(name, h, settings);
  }
  throw DeviceError(DeviceErrorKind::kNotFound, name, "open",
                    "no USB device with this identity is connected");
}

}  // namespace scanmesh::drivers
