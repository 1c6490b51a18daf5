// The control socket server: accepts clients on a Unix stream socket, reads JSON-lines requests,
// answers them from the engine, and sends events to watching clients. Everything here runs on
// the one io thread; slow work (catalog, exports, previews) runs on a job thread and its reply
// is posted back.
// SPDX-License-Identifier: MIT
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/local/stream_protocol.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/thread_pool.hpp>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "scanmesh/daemon/config.hpp"
#include "scanmesh/daemon/engine.hpp"
#include "scanmesh/daemon/log.hpp"
#include "scanmesh/daemon/protocol.hpp"
#include "scanmesh/daemon/security.hpp"

namespace scanmesh::daemon {

class Session;

/// Figures the server keeps (status, tests, bench).
struct ServerStats {
  std::uint64_t accepted = 0, refused = 0;  ///< connections; refused: over max_clients
  std::uint64_t requests = 0, protocol_errors = 0;
  std::uint64_t dropped_slow = 0;  ///< clients disconnected for not reading
  std::uint64_t events = 0;        ///< event lines queued to clients
};

class Server {
 public:
  /// `engine` and `log` outlive the server. The daemon's version string goes into HELLO.
  Server(boost::asio::io_context& io, DaemonConfig config, ScanEngine& engine, const Log& log,
         std::string version);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// Adopts a socket from socket activation (fd), or binds `config.socket_path` itself (a stale
  /// socket file is removed; mode 0660; group config.socket_group when set). Starts accepting.
  void listen(std::optional<int> activated_fd);
  /// Stops accepting and removes the socket file when the server bound it.
  void stop_accepting();
  /// Closes every client (after its queued output, bounded by a short grace).
  void close_clients();
  /// Applies a reloaded configuration (the parts that do not need a restart).
  void apply(const DaemonConfig& config);
  const DaemonConfig& config() const { return config_; }

  /// Engine events, on the io thread.
  void on_scan(const ScanStatus& status);
  void on_device(const DeviceInfo& device);
  void on_mesh(const MeshCounts& counts);

  /// Called with every scan state change (the daemon turns it into STATUS=).
  std::function<void(const ScanStatus&)> on_state_change;
  /// "ready", "reloading", "stopping": reported in status.
  void set_daemon_state(std::string state) { daemon_state_ = std::move(state); }

  std::size_t clients() const { return sessions_.size(); }
  const ServerStats& stats() const { return stats_; }

 private:
  friend class Session;
  struct Command;
  void accept();
  void handle_line(const std::shared_ptr<Session>& session, std::string_view line);
  void run_command(const std::shared_ptr<Session>& session, const proto::Request& request);
  void remove(Session* session);
  void broadcast(const std::string& line, bool progress);
  void progress_tick();
  StatusInfo status_info() const;
  proto::Object config_object() const;

  // Commands: each returns the reply body or throws ProtocolError / EngineError.
  proto::Object cmd_scan_start(const proto::Request& r);
  proto::Object cmd_mesh_export(const proto::Request& r);
  proto::Object cmd_mesh_preview(const proto::Request& r);

  boost::asio::io_context& io_;
  DaemonConfig config_;
  ScanEngine& engine_;
  const Log& log_;
  std::string version_;
  std::string daemon_state_ = "ready";
  std::chrono::steady_clock::time_point started_;
  boost::asio::local::stream_protocol::acceptor acceptor_;
  bool bound_here_ = false;
  bool accepting_ = false;
  boost::asio::steady_timer accept_retry_;
  boost::asio::steady_timer progress_timer_;
  std::map<std::uint64_t, std::shared_ptr<Session>> sessions_;
  std::uint64_t next_session_ = 1;
  std::map<std::string, Command, std::less<>> commands_;
  ServerStats stats_;
  std::string last_progress_;
  ScanState last_state_ = ScanState::kIdle;
  /// Scan paused by the daemon because a device was lost: resumed when every device is back.
  bool paused_for_device_ = false;
  boost::asio::thread_pool jobs_{1};
};

}  // namespace scanmesh::daemon
