// ByteStream over a Boost.Asio TCP socket with per-call timeouts (see tcp_stream.hpp). Like the
// serial stream, each stream owns a private io_context run only by its device's worker thread.
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/transports/tcp_stream.hpp"

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/write.hpp>

#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers {

namespace asio = boost::asio;
using asio::ip::tcp;

namespace {

/// The one place Boost/OS error codes of TCP streams become DeviceError (STYLE §4).
DeviceError to_device_error(const std::string& name, const std::string& op,
                            const boost::system::error_code& ec) {
  DeviceErrorKind kind = DeviceErrorKind::kIo;
  if (ec == asio::error::eof || ec == asio::error::connection_reset ||
      ec == asio::error::connection_refused || ec == asio::error::broken_pipe ||
      ec == asio::error::connection_aborted || ec == asio::error::not_connected ||
      ec == asio::error::host_unreachable || ec == asio::error::network_unreachable) {
    kind = DeviceErrorKind::kDisconnected;
  } else if (ec == asio::error::host_not_found || ec == asio::error::host_not_found_try_again) {
    kind = DeviceErrorKind::kNotFound;
  } else if (ec == asio::error::timed_out) {
    kind = DeviceErrorKind::kTimeout;
  }
  const std::string detail =
      ec == asio::error::eof ? std::string("end of file (the peer closed the connection)")
                             : ec.message();
  return DeviceError(kind, name, op, detail);
}

class TcpStream final : public ByteStream {
 public:
  TcpStream(const std::string& device, const std::string& host, int port,
            std::chrono::milliseconds timeout)
      : name_(device + " (" + host + ":" + std::to_string(port) + ")"), socket_(io_) {
    boost::system::error_code ec;
    tcp::resolver resolver(io_);
    const auto endpoints = resolver.resolve(host, std::to_string(port), ec);
    if (ec) throw to_device_error(name_, "resolve", ec);
    boost::system::error_code result = asio::error::would_block;
    bool done = false;
    asio::async_connect(socket_, endpoints,
                        [&](const boost::system::error_code& e, const tcp::endpoint&) {
                          result = e;
                          done = true;
                        });
    run(done, timeout);
    if (!done || result == asio::error::operation_aborted)
      throw DeviceError(DeviceErrorKind::kTimeout, name_, "connect",
                        "no connection within " + std::to_string(timeout.count()) + " ms");
    if (result) throw to_device_error(name_, "connect", result);
    socket_.set_option(tcp::no_delay(true), ec);
  }

  void write_all(std::span<const std::uint8_t> bytes, std::chrono::milliseconds timeout) override {
    boost::system::error_code result;
    bool done = false;
    asio::async_write(socket_, asio::buffer(bytes.data(), bytes.size()),
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
    socket_.async_read_some(asio::buffer(buffer.data(), buffer.size()),
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

  void discard_input() override {
    // Whatever is already buffered is stale (a late reply after a timeout).
    std::uint8_t sink[512];
    boost::system::error_code ec;
    while (socket_.available(ec) > 0 && !ec) socket_.read_some(asio::buffer(sink), ec);
  }

  const std::string& name() const override { return name_; }

 private:
  /// Runs the private io_context until the operation finished or the timeout passed; then
  /// cancels it and runs the (aborted) handler, so no handler outlives the call.
  void run(bool& done, std::chrono::milliseconds timeout) {
    io_.restart();
    io_.run_for(timeout);
    if (!done) {
      boost::system::error_code ignored;
      socket_.cancel(ignored);
      io_.restart();
      io_.run();
    }
  }

  std::string name_;
  asio::io_context io_{1};
  tcp::socket socket_;
};

}  // namespace

std::unique_ptr<ByteStream> open_tcp_stream(const std::string& device, const std::string& host,
                                             int port, std::chrono::milliseconds timeout) {
  return std::make_unique<TcpStream>(device, host, port, timeout);
}

}  // namespace scanmesh::drivers
