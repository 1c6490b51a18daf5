// ByteStream over boost::asio::serial_port with per-call timeouts (see serial_stream.hpp).
// Each stream owns a private io_context that only its device worker thread runs, so a blocking
// call is "start async op, run the context for at most the timeout, cancel if unfinished".
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/transports/serial_stream.hpp"

#include <sys/ioctl.h>
#include <termios.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/serial_port.hpp>
#include <boost/asio/write.hpp>
#include <cerrno>

#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers {

namespace asio = boost::asio;

namespace {

/// The one place Boost/OS error codes become DeviceError (STYLE §4).
DeviceError to_device_error(const std::string& name, const std::string& op,
                            const boost::system::error_code& ec) {
  DeviceErrorKind kind = DeviceErrorKind::kIo;
  if (ec == asio::error::eof || ec == asio::error::connection_reset ||
      ec == asio::error::broken_pipe || ec == asio::error::bad_descriptor ||
      ec.value() == EIO || ec.value() == ENXIO || ec.value() == ENODEV) {
    kind = DeviceErrorKind::kDisconnected;
  } else if (ec == boost::system::errc::no_such_file_or_directory) {
    kind = DeviceErrorKind::kNotFound;
  }
  const std::string detail =
      ec == asio::error::eof ? std::string("end of file (the port was closed or unplugged)")
                             : ec.message();
  return DeviceError(kind, name, op, detail);
}

class SerialStream final : public ByteStream {
 public:
  SerialStream(const std::string& device, const SerialSettings& s)
      : name_(device + " (" + s.path + ")"), port_(io_) {
    boost::system::error_code ec;
    port_.open(s.path, ec);
    if (ec) throw to_device_error(name_, "open", ec);
    // Exclusive use: a second process opening the port gets EBUSY instead of stealing bytes.
    ::ioctl(port_.native_handle(), TIOCEXCL);
    using sp = asio::serial_port_base;
    const sp::parity::type parity = s.parity == 'E'   ? sp::parity::even
                                    : s.parity == 'O' ? sp::parity::odd
                                                      : sp::parity::none;
    port_.set_option(sp::baud_rate(s.baud), ec);
    if (!ec) port_.set_option(sp::character_size(s.data_bits), ec);
    if (!ec) port_.set_option(sp::parity(parity), ec);
    if (!ec)
      port_.set_option(sp::stop_bits(s.stop_bits == 2 ? sp::stop_bits::two : sp::stop_bits::one),
                       ec);
    if (!ec) port_.set_option(sp::flow_control(sp::flow_control::none), ec);
    if (ec) throw to_device_error(name_, "configure " + std::to_string(s.baud) + " baud", ec);
  }

  void write_all(std::span<const std::uint8_t> bytes, std::chrono::milliseconds timeout) override {
    boost::system::error_code result;
    bool done = false;
    asio::async_write(port_, asio::buffer(bytes.data(), bytes.size()),
                      [&](const boost::system::error_code& ec, std::size_t) {
                        result = ec;
                        done = true;
                      });
    run(done, timeout);
    if (result == asio::error::operation_aborted)
      throw DeviceError(DeviceErrorKind::kTimeout, name_, "write",
                        "not accepted within " + std::to_string(timeout.count()) + " ms");
    if (result) throw to_device_error(name_, "write", result);
  }

  std::size_t read_some(std::span<std::uint8_t> buffer,
                        std::chrono::milliseconds timeout) override {
    boost::system::error_code result;
    std::size_t n = 0;
    bool done = false;
    port_.async_read_some(asio::buffer(buffer.data(), buffer.size()),
                          [&](const boost::system::error_code& ec, std::size_t got) {
                            result = ec;
                            n = got;
                            done = true;
                          });
    run(done, timeout);
    if (result == asio::error::operation_aborted) return n;  // timeout
    if (result) throw to_device_error(name_, "read", result);
    return n;
  }

  void discard_input() override { ::tcflush(port_.native_handle(), TCIFLUSH); }

  const std::string& name() const override { return name_; }

 private:
  /// Runs the private io_context until the operation finished or the timeout passed; then
  /// cancels it and runs the (aborted) handler, so no handler outlives the call.
  void run(bool& done, std::chrono::milliseconds timeout) {
    io_.restart();
    io_.run_for(timeout);
    if (!done) {
      boost::system::error_code ignored;
      port_.cancel(ignored);
      io_.restart();
      io_.run();
    }
  }

  std::string name_;
  asio::io_context io_{1};
  asio::serial_port port_;
};

}  // namespace

std::unique_ptr<ByteStream> open_serial_stream(const std::string& device,
                                               const SerialSettings& settings) {
  return std::make_unique<SerialStream>(device, settings);
}

}  // namespace scanmesh::drivers
