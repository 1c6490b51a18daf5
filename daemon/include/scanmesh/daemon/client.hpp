// A blocking control-protocol client (scanctl, the tests, the benchmark): connects, checks the
// HELLO, sends requests with increasing ids and reads lines back, keeping events that arrive
// while it waits for a reply.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <deque>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "scanmesh/daemon/protocol.hpp"

namespace scanmesh::daemon {

class Client {
 public:
  /// Connects and reads the HELLO. Throws Error naming the socket when it cannot connect, when
  /// the first line is not a HELLO (an ERROR such as too_many_clients is quoted), or when the
  /// daemon speaks another major protocol version. `timeout`: longest wait for one line
  /// (zero: no limit).
  explicit Client(const std::filesystem::path& socket,
                  std::chrono::milliseconds timeout = std::chrono::seconds(30));
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  const proto::Message& hello() const { return hello_; }
  const std::string& hello_line() const { return hello_line_; }

  /// Sends one request; returns its id.
  std::int64_t send(std::string_view cmd, const proto::Object& args = {});
  /// Sends raw bytes as they are (tests of malformed input).
  void send_raw(std::string_view bytes);
  /// The next line from the daemon (buffered events first); nullopt when the daemon closed the
  /// connection. Throws Error on a timeout. `raw` gets the line as received.
  std::optional<proto::Message> read(std::string* raw = nullptr);
  /// Sends a request and reads until its REPLY or ERROR (events that arrive meanwhile are kept
  /// for read()). Throws Error when the connection closes first.
  proto::Message request(std::string_view cmd, const proto::Object& args = {},
                         std::string* raw = nullptr);
  /// Changes the longest wait for one line.
  void set_timeout(std::chrono::milliseconds timeout);
  int native_handle() const;

 private:
  std::optional<std::string> read_line();
  struct Impl;
  std::unique_ptr<Impl> impl_;
  proto::Message hello_;
  std::string hello_line_;
  std::int64_t next_id_ = 1;
  std::deque<std::pair<proto::Message, std::string>> pending_;
};

}  // namespace scanmesh::daemon
