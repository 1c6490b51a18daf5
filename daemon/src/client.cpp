// The blocking control-protocol client (client.hpp) over a Boost.Asio Unix stream socket.
// SPDX-License-Identifier: MIT
#include "scanmesh/daemon/client.hpp"

#include <sys/socket.h>
#include <sys/time.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/local/stream_protocol.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/write.hpp>

namespace scanmesh::daemon {

namespace asio = boost::asio;

struct Client::Impl {
  asio::io_context io;
  asio::local::stream_protocol::socket socket{io};
  std::string buffer;
  std::filesystem::path path;
};

Client::Client(const std::filesystem::path& socket, std::chrono::milliseconds timeout)
    : impl_(std::make_unique<Impl>()) {
  impl_->path = socket;
  boost::system::error_code ec;
  impl_->socket.connect(asio::local::stream_protocol::endpoint(socket.string()), ec);
  if (ec) throw Error(socket.string() + ": cannot connect to scanmeshd: " + ec.message());
  set_timeout(timeout);
  auto line = read_line();
  if (!line) throw Error(socket.string() + ": the daemon closed the connection before its HELLO");
  hello_line_ = *line;
  hello_ = proto::decode_message(*line);
  if (hello_.cls == proto::MessageClass::kError)
    throw Error(socket.string() + ": refused: " + hello_.error_code + ": " + hello_.error_message);
  if (hello_.cls != proto::MessageClass::kHello)
    throw Error(socket.string() + ": expected a HELLO, got " + *line);
  const auto major = hello_.body.get_int("proto_major").value_or(0);
  if (major != proto::kMajor)
    throw Error(socket.string() + ": the daemon speaks protocol " + std::to_string(major) +
                ".x, this client " + std::to_string(proto::kMajor) + ".x");
}

Client::~Client() = default;

void Client::set_timeout(std::chrono::milliseconds timeout) {
  timeval tv{};
  tv.tv_sec = static_cast<time_t>(timeout.count() / 1000);
  tv.tv_usec = static_cast<suseconds_t>((timeout.count() % 1000) * 1000);
  ::setsockopt(impl_->socket.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
}

int Client::native_handle() const { return impl_->socket.native_handle(); }

std::int64_t Client::send(std::string_view cmd, const proto::Object& args) {
  const std::int64_t id = next_id_++;
  send_raw(proto::request_line(cmd, id, args));
  return id;
}

void Client::send_raw(std::string_view bytes) {
  boost::system::error_code ec;
  asio::write(impl_->socket, asio::buffer(bytes.data(), bytes.size()), ec);
  if (ec) throw Error(impl_->path.string() + ": write failed: " + ec.message());
}

std::optional<std::string> Client::read_line() {
  boost::system::error_code ec;
  const std::size_t n =
      asio::read_until(impl_->socket, asio::dynamic_buffer(impl_->buffer), '\n', ec);
  if (ec == asio::error::eof || ec == asio::error::connection_reset) return std::nullopt;
  if (ec == asio::error::would_block || ec == asio::error::try_again ||
      ec == asio::error::timed_out)
    throw Error(impl_->path.string() + ": no answer from the daemon in time");
  if (ec) throw Error(impl_->path.string() + ": read failed: " + ec.message());
  std::string line = impl_->buffer.substr(0, n - 1);
  impl_->buffer.erase(0, n);
  return line;
}

std::optional<proto::Message> Client::read(std::string* raw) {
  if (!pending_.empty()) {
    auto [m, line] = std::move(pending_.front());
    pending_.pop_front();
    if (raw) *raw = std::move(line);
    return m;
  }
  auto line = read_line();
  if (!line) return std::nullopt;
  proto::Message m = proto::decode_message(*line);
  if (raw) *raw = std::move(*line);
  return m;
}

proto::Message Client::request(std::string_view cmd, const proto::Object& args, std::string* raw) {
  const std::int64_t id = send(cmd, args);
  for (;;) {
    auto line = read_line();
    if (!line) throw Error(impl_->path.string() + ": the daemon closed the connection");
    proto::Message m = proto::decode_message(*line);
    // An ERROR without an id (a line the daemon could not read) answers this request too.
    if ((m.cls == proto::MessageClass::kReply && m.id == id) ||
        (m.cls == proto::MessageClass::kError && (!m.id || m.id == id))) {
      if (raw) *raw = std::move(*line);
      return m;
    }
    pending_.emplace_back(std::move(m), std::move(*line));
  }
}

}  // namespace scanmesh::daemon
