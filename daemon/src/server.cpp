// The control socket server (server.hpp): sessions, request dispatch, events.
// SPDX-License-Identifier: MIT
#include "scanmesh/daemon/server.hpp"

#include <grp.h>
#include <pthread.h>
#include <sys/stat.h>
#include <unistd.h>

#include <boost/asio/post.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/write.hpp>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <vector>

#include "scanmesh/meshio/meshio.hpp"
#include "scanmesh/preview/render.hpp"

namespace scanmesh::daemon {

namespace asio = boost::asio;
using local = asio::local::stream_protocol;

namespace {
/// Requests of one client that may wait on the job thread at once; more get ERROR busy.
constexpr std::size_t kMaxJobsPerClient = 4;
/// How long a closing client may take to read its last lines before it is cut off.
constexpr std::chrono::seconds kCloseGrace{2};

std::string lower_extension(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e.empty() ? e : e.substr(1);
}

std::string thousands(std::uint64_t v) {
  // Built forwards (GCC 12 warns falsely about std::string::insert here at -O3).
  const std::string digits = std::to_string(v);
  std::string s;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) s += ',';
    s += digits[i];
  }
  return s;
}
}  // namespace

/// One connected client.
class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(Server& server, std::uint64_t number, local::socket socket, PeerCredentials peer)
      : server_(server),
        number_(number),
        socket_(std::move(socket)),
        peer_(peer),
        close_timer_(socket_.get_executor()) {}

  std::uint64_t number() const { return number_; }
  const PeerCredentials& peer() const { return peer_; }
  bool watching = false;
  std::size_t jobs = 0;

  void start() {
    send(proto::hello_line(server_.version_));
    read();
  }

  std::string describe() const {
    return "client " + std::to_string(number_) + " (pid " + std::to_string(peer_.pid) + ", uid " +
           std::to_string(peer_.uid) + ")";
  }

  /// Queues a line; a client holding more unsent output than the limit is disconnected.
  void send(std::string line) {
    if (closed_) return;
    queued_bytes_ += line.size();
    if (queued_bytes_ > server_.config_.client_output_limit_bytes) {
      ++server_.stats_.dropped_slow;
      server_.log_.warning(
          describe() + " is not reading: " + std::to_string(queued_bytes_ + inflight_bytes_) +
          " bytes unsent (limit " + std::to_string(server_.config_.client_output_limit_bytes) +
          "), disconnected");
      close();
      return;
    }
    queue_.push_back(std::move(line));
    write();
  }

  /// Progress events are coalesced: while output is pending, a newer one replaces the older.
  void send_progress(const std::string& line) {
    if (closed_) return;
    if (writing_ || !queue_.empty()) {
      pending_progress_ = line;
      return;
    }
    send(line);
  }

  /// Stops reading, sends what is queued, then closes.
  void close_after_flush() {
    if (closed_) return;
    closing_ = true;
    boost::system::error_code ec;
    socket_.shutdown(local::socket::shutdown_receive, ec);
    if (!writing_ && queue_.empty()) return close();
    close_timer_.expires_after(kCloseGrace);
    close_timer_.async_wait([self = shared_from_this()](const boost::system::error_code& ec) {
      if (!ec) self->close();
    });
  }

  void close() {
    if (closed_) return;
    closed_ = true;
    boost::system::error_code ec;
    socket_.shutdown(local::socket::shutdown_both, ec);
    socket_.close(ec);
    close_timer_.cancel();
    server_.remove(this);
  }

 private:
  void read() {
    asio::async_read_until(socket_, asio::dynamic_buffer(in_, proto::kMaxLineBytes + 1), '\n',
                           [self = shared_from_this()](const boost::system::error_code& ec,
                                                       std::size_t n) { self->on_read(ec, n); });
  }

  void on_read(const boost::system::error_code& ec, std::size_t n) {
    if (closed_ || closing_) return;
    if (ec == asio::error::not_found) {  // the buffer is full and holds no newline
      ++server_.stats_.protocol_errors;
      server_.log_.notice(describe() + " sent a line longer than " +
                          std::to_string(proto::kMaxLineBytes) + " bytes: disconnected");
      send(proto::error_line(std::nullopt, proto::errc::kLineTooLong,
                             "a request line may be at most " +
                                 std::to_string(proto::kMaxLineBytes) +
                                 " bytes; closing the connection"));
      close_after_flush();
      return;
    }
    if (ec) {
      close();
      return;
    }
    std::string_view line(in_.data(), n - 1);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (!line.empty()) server_.handle_line(shared_from_this(), line);
    in_.erase(0, n);
    if (!closed_ && !closing_) read();
  }

  void write() {
    if (writing_ || closed_) return;
    if (queue_.empty()) {
      if (pending_progress_.empty()) {
        if (closing_) close();
        return;
      }
      queue_.push_back(std::move(pending_progress_));
      queued_bytes_ += queue_.back().size();
      pending_progress_.clear();
    }
    writing_ = true;
    inflight_.clear();
    buffers_.clear();
    while (!queue_.empty()) {
      inflight_.push_back(std::move(queue_.front()));
      queue_.pop_front();
    }
    for (const auto& s : inflight_) buffers_.emplace_back(s.data(), s.size());
    // The limit bounds what waits in the queue; what is being written was counted there before.
    inflight_bytes_ = queued_bytes_;
    queued_bytes_ = 0;
    asio::async_write(
        socket_, buffers_,
        [self = shared_from_this()](const boost::system::error_code& ec, std::size_t) {
          self->writing_ = false;
          self->inflight_bytes_ = 0;
          if (ec) {
            self->close();
            return;
          }
          self->write();
        });
  }

  Server& server_;
  std::uint64_t number_;
  local::socket socket_;
  PeerCredentials peer_;
  asio::steady_timer close_timer_;
  std::string in_;
  std::deque<std::string> queue_;
  std::vector<std::string> inflight_;
  std::vector<asio::const_buffer> buffers_;
  std::string pending_progress_;
  std::size_t queued_bytes_ = 0;    ///< in queue_, not yet handed to a write
  std::size_t inflight_bytes_ = 0;  ///< in the write under way
  bool writing_ = false;
  bool closing_ = false;
  bool closed_ = false;
};

struct Server::Command {
  bool privileged = false;  ///< changes state or writes files: control users only
  /// Immediate commands answer on the io thread. Job commands check their arguments on the io
  /// thread and return the work to run on the job thread.
  std::function<proto::Object(const proto::Request&)> now;
  std::function<std::function<proto::Object()>(const proto::Request&)> job;
};

Server::Server(asio::io_context& io, DaemonConfig config, ScanEngine& engine, const Log& log,
               std::string version)
    : io_(io),
      config_(std::move(config)),
      engine_(engine),
      log_(log),
      version_(std::move(version)),
      started_(std::chrono::steady_clock::now()),
      acceptor_(io),
      accept_retry_(io),
      progress_timer_(io) {
  auto now = [this](std::string name, bool privileged, auto fn) {
    Command c;
    c.privileged = privileged;
    c.now = std::move(fn);
    commands_.emplace(std::move(name), std::move(c));
  };
  auto job = [this](std::string name, bool privileged, auto fn) {
    Command c;
    c.privileged = privileged;
    c.job = std::move(fn);
    commands_.emplace(std::move(name), std::move(c));
  };
  now("version", false, [this](const proto::Request&) {
    return proto::to_object(
        VersionInfo{version_, proto::kMajor, proto::kMinor, std::string(engine_.backend())});
  });
  now("status", false, [this](const proto::Request&) { return proto::to_object(status_info()); });
  now("devices", false, [this](const proto::Request&) {
    std::vector<proto::Object> list;
    for (const auto& d : engine_.devices()) list.push_back(proto::to_object(d));
    proto::Object o;
    o.set("devices", list);
    return o;
  });
  now("config.get", false, [this](const proto::Request&) {
    proto::Object o;
    o.set("config", config_object());
    return o;
  });
  now("scan.start", true, [this](const proto::Request& r) { return cmd_scan_start(r); });
  now("scan.pause", true, [this](const proto::Request&) {
    engine_.pause("operator");
    paused_for_device_ = false;
    proto::Object o;
    o.set("scan", proto::to_object(engine_.status()));
    return o;
  });
  now("scan.resume", true, [this](const proto::Request&) {
    engine_.resume();
    paused_for_device_ = false;
    proto::Object o;
    o.set("scan", proto::to_object(engine_.status()));
    return o;
  });
  now("scan.stop", true, [this](const proto::Request&) {
    engine_.stop("operator");
    paused_for_device_ = false;
    proto::Object o;
    o.set("scan", proto::to_object(engine_.status()));
    return o;
  });
  job("scan.list", false, [this](const proto::Request&) {
    return std::function<proto::Object()>([this] {
      std::vector<proto::Object> list;
      for (const auto& s : engine_.list_scans()) list.push_back(proto::to_object(s));
      proto::Object o;
      o.set("scans", list);
      return o;
    });
  });
  auto scan_id = [](const proto::Request& r) {
    const auto id = r.args.get_int("scan");
    if (!id)
      throw proto::ProtocolError(proto::errc::kBadArgument, "'scan' (a scan id) is required");
    return *id;
  };
  job("scan.info", false, [this, scan_id](const proto::Request& r) {
    const std::int64_t id = scan_id(r);
    return std::function<proto::Object()>([this, id] {
      const auto rec = engine_.scan_info(id);
      if (!rec)
        throw EngineError(proto::errc::kNotFound,
                          "no scan " + std::to_string(id) + " in the catalog");
      proto::Object o;
      o.set("scan", proto::to_object(*rec));
      return o;
    });
  });
  job("scan.resume_interrupted", true, [this, scan_id](const proto::Request& r) {
    const std::int64_t id = scan_id(r);
    return std::function<proto::Object()>([this, id] {
      proto::Object o;
      o.set("scan", proto::to_object(engine_.resume_interrupted(id)));
      return o;
    });
  });
  job("scan.close_interrupted", true, [this, scan_id](const proto::Request& r) {
    const std::int64_t id = scan_id(r);
    return std::function<proto::Object()>([this, id] {
      proto::Object o;
      o.set("scan", proto::to_object(engine_.close_interrupted(id)));
      return o;
    });
  });
  job("mesh.export", true, [this](const proto::Request& r) {
    const auto path = r.args.get_string("path");
    if (!path)
      throw proto::ProtocolError(proto::errc::kBadArgument,
                                 "'path' (the file to write) is required");
    if (!meshio::writes_mesh_extension(*path))
      throw proto::ProtocolError(proto::errc::kBadArgument,
                                 "'path' must end in .stl, .ply or .obj, got '" + *path + "'");
    const std::optional<std::int64_t> scan = r.args.get_int("scan");
    const bool ascii = r.args.get_bool("ascii").value_or(false);
    const std::int64_t current = engine_.status().id;
    return std::function<proto::Object()>(
        [this, p = *path, scan, ascii, current, dirs = config_.export_dirs] {
          const ConfinedPath out = confine_output(p, dirs);
          const auto mesh = engine_.mesh(scan);
          if (!mesh || mesh->triangles.empty())
            throw EngineError(proto::errc::kNoMesh,
                              "no mesh yet for " + (scan ? "scan " + std::to_string(*scan)
                                                         : std::string("the current scan")));
          try {
            meshio::write_mesh(*mesh, out.path(), meshio::WriteOptions{ascii});
          } catch (const OutputError& e) {
            throw EngineError(proto::errc::kIoError, e.what());
          }
          ExportInfo info;
          info.scan = scan.value_or(current);
          info.path = out.shown().string();
          info.format = lower_extension(p);
          info.vertices = mesh->vertices.size();
          info.triangles = mesh->triangles.size();
          std::error_code ec;
          info.bytes = std::filesystem::file_size(out.path(), ec);
          return proto::to_object(info);
        });
  });
  job("mesh.preview", true, [this](const proto::Request& r) {
    const auto path = r.args.get_string("path");
    if (!path)
      throw proto::ProtocolError(proto::errc::kBadArgument,
                                 "'path' (the .png to write) is required");
    if (lower_extension(*path) != "png")
      throw proto::ProtocolError(proto::errc::kBadArgument,
                                 "'path' must end in .png, got '" + *path + "'");
    const std::optional<std::int64_t> scan = r.args.get_int("scan");
    preview::RenderOptions options;
    const std::int64_t w = r.args.get_int("width_px").value_or(options.width_px);
    const std::int64_t h = r.args.get_int("height_px").value_or(options.height_px);
    if (w < 64 || w > 8192 || h < 64 || h > 8192)
      throw proto::ProtocolError(proto::errc::kBadArgument,
                                 "'width_px' and 'height_px' must be in [64, 8192]");
    options.width_px = static_cast<int>(w);
    options.height_px = static_cast<int>(h);
    const ScanStatus st = engine_.status();
    return std::function<proto::Object()>([this, p = *path, scan, options, st,
                                           dirs = config_.export_dirs]() mutable {
      const ConfinedPath out = confine_output(p, dirs);
      const auto mesh = engine_.mesh(scan);
      if (!mesh || mesh->triangles.empty())
        throw EngineError(proto::errc::kNoMesh,
                          "no mesh yet for " + (scan ? "scan " + std::to_string(*scan)
                                                     : std::string("the current scan")));
      std::string title;
      if (!scan || *scan == st.id) {
        title = st.name + " (scan " + std::to_string(st.id) + "): ";
        if (st.state == ScanState::kIdle)
          title += "done";
        else if (st.progress >= 0)
          title += std::to_string(static_cast<int>(std::lround(st.progress * 100))) + " % scanned";
        else
          title += std::string(to_string(st.state));
        title += ", " + thousands(st.counters.points) + " points, ";
      } else {
        title = "scan " + std::to_string(*scan) + ": ";
      }
      title += thousands(mesh->triangles.size()) + " triangles";
      options.title = title;
      try {
        preview::render_mesh_png(*mesh, out.path(), options);
      } catch (const OutputError& e) {
        throw EngineError(proto::errc::kIoError, e.what());
      }
      PreviewInfo info;
      info.scan = scan.value_or(st.id);
      info.path = out.shown().string();
      info.width_px = options.width_px;
      info.height_px = options.height_px;
      std::error_code ec;
      info.bytes = std::filesystem::file_size(out.path(), ec);
      return proto::to_object(info);
    });
  });
  now("watch", false, [](const proto::Request&) { return proto::Object(); });  // see run_command
  asio::post(jobs_, [] { ::pthread_setname_np(::pthread_self(), "daemon-jobs"); });
}

Server::~Server() {
  jobs_.join();
  for (auto& [n, s] : std::map(sessions_)) s->close();
}

void Server::listen(std::optional<int> activated_fd) {
  boost::system::error_code ec;
  if (activated_fd) {
    acceptor_.assign(local(), *activated_fd, ec);
    if (ec) throw Error("cannot adopt the activated socket: " + ec.message());
    log_.info("listening on " + config_.socket_path.string() + " (socket activation)");
  } else {
    const auto& path = config_.socket_path;
    std::error_code fs_ec;
    std::filesystem::create_directories(path.parent_path(), fs_ec);
    // A socket file left by a previous run (crash, SIGKILL) would make bind fail: remove it,
    // but never anything that is not a socket.
    struct stat st {};
    if (::lstat(path.c_str(), &st) == 0) {
      if (!S_ISSOCK(st.st_mode))
        throw ConfigError(path.string() + ": exists and is not a socket; not replacing it");
      ::unlink(path.c_str());
    }
    acceptor_.open(local(), ec);
    if (!ec) acceptor_.bind(local::endpoint(path.string()), ec);
    if (ec) throw ConfigError(path.string() + ": cannot bind the control socket: " + ec.message());
    bound_here_ = true;
    if (::chmod(path.c_str(), 0660) != 0)
      throw ConfigError(path.string() + ": chmod 0660 failed: " + std::strerror(errno));
    if (!config_.socket_group.empty()) {
      const group* g = ::getgrnam(config_.socket_group.c_str());
      if (g == nullptr || ::chown(path.c_str(), static_cast<uid_t>(-1), g->gr_gid) != 0)
        throw ConfigError(path.string() + ": cannot give the socket to group '" +
                          config_.socket_group + "': " + std::strerror(errno));
    }
    acceptor_.listen(asio::socket_base::max_listen_connections, ec);
    if (ec) throw ConfigError(path.string() + ": listen failed: " + ec.message());
    log_.info("listening on " + path.string());
  }
  accepting_ = true;
  accept();
  progress_tick();
}

void Server::stop_accepting() {
  accepting_ = false;
  boost::system::error_code ec;
  acceptor_.close(ec);
  accept_retry_.cancel();
  progress_timer_.cancel();
  if (bound_here_) {
    ::unlink(config_.socket_path.c_str());
    bound_here_ = false;
  }
}

void Server::close_clients() {
  std::vector<std::shared_ptr<Session>> all;
  for (auto& [n, s] : sessions_) all.push_back(s);
  for (auto& s : all) s->close_after_flush();
}

void Server::apply(const DaemonConfig& config) {
  // Only what may change without a restart (config.hpp marks the rest).
  config_.max_clients = config.max_clients;
  config_.client_output_limit_bytes = config.client_output_limit_bytes;
  config_.progress_interval = config.progress_interval;
  config_.control_users = config.control_users;
  config_.control_uids = config.control_uids;
  config_.export_dirs = config.export_dirs;
  config_.log_level = config.log_level;
  config_.scan_defaults = config.scan_defaults;
}

void Server::accept() {
  if (!accepting_) return;
  acceptor_.async_accept([this](const boost::system::error_code& ec, local::socket socket) {
    if (ec == asio::error::operation_aborted || !accepting_) return;
    if (ec) {
      // Out of descriptors or memory: retry later instead of spinning.
      log_.warning("accept on the control socket failed: " + ec.message());
      accept_retry_.expires_after(std::chrono::milliseconds(200));
      accept_retry_.async_wait([this](const boost::system::error_code& e) {
        if (!e) accept();
      });
      return;
    }
    PeerCredentials peer;
    try {
      peer = peer_credentials(socket.native_handle());
    } catch (const Error& e) {
      log_.warning(std::string("refusing a client: ") + e.what());
      accept();
      return;
    }
    if (sessions_.size() >= config_.max_clients) {
      ++stats_.refused;
      log_.notice("refusing client pid " + std::to_string(peer.pid) + ": " +
                  std::to_string(sessions_.size()) + " clients connected (daemon.max_clients)");
      auto s = std::make_shared<local::socket>(std::move(socket));
      auto line = std::make_shared<std::string>(proto::error_line(
          std::nullopt, proto::errc::kTooManyClients,
          "the daemon serves at most " + std::to_string(config_.max_clients) + " clients at once"));
      asio::async_write(*s, asio::buffer(*line),
                        [s, line](const boost::system::error_code&, std::size_t) {
                          boost::system::error_code e;
                          s->close(e);
                        });
      accept();
      return;
    }
    ++stats_.accepted;
    const std::uint64_t n = next_session_++;
    auto session = std::make_shared<Session>(*this, n, std::move(socket), peer);
    sessions_.emplace(n, session);
    log_.debug(session->describe() + " connected");
    session->start();
    accept();
  });
}

void Server::remove(Session* session) {
  log_.debug(session->describe() + " disconnected");
  sessions_.erase(session->number());
}

void Server::handle_line(const std::shared_ptr<Session>& session, std::string_view line) {
  ++stats_.requests;
  try {
    const proto::Request request = proto::decode_request(line);
    run_command(session, request);
  } catch (const proto::ProtocolError& e) {
    ++stats_.protocol_errors;
    session->send(proto::error_line(e.id(), e.code(), e.what()));
  }
}

void Server::run_command(const std::shared_ptr<Session>& session, const proto::Request& request) {
  const auto it = commands_.find(request.cmd);
  if (it == commands_.end()) {
    std::string list;
    for (const auto& [name, c] : commands_) list += (list.empty() ? "" : ", ") + name;
    throw proto::ProtocolError(proto::errc::kUnknownCommand,
                               "unknown command '" + request.cmd + "' (commands: " + list + ")",
                               request.id);
  }
  const Command& command = it->second;
  if (command.privileged && !may_control(session->peer(), config_.control_uids)) {
    log_.notice(session->describe() + " refused " + request.cmd + ": not a control user");
    throw proto::ProtocolError(proto::errc::kPermissionDenied,
                               request.cmd + " changes state or writes files: uid " +
                                   std::to_string(session->peer().uid) +
                                   " is not root, the daemon's user or in daemon.control_users",
                               request.id);
  }
  try {
    if (command.now) {
      proto::Object body = command.now(request);
      if (request.cmd == "watch") {
        session->watching = request.args.get_bool("enable").value_or(true);
        body.set("watching", session->watching);
        session->send(proto::reply_line(request.id, request.cmd, body));
        // A baseline to apply later events to.
        if (session->watching)
          session->send(proto::event_line("state", proto::to_object(engine_.status())));
        return;
      }
      session->send(proto::reply_line(request.id, request.cmd, body));
      return;
    }
    if (session->jobs >= kMaxJobsPerClient)
      throw EngineError(proto::errc::kBusy, std::to_string(kMaxJobsPerClient) +
                                                " requests of this client are still running");
    std::function<proto::Object()> work = command.job(request);
    ++session->jobs;
    std::weak_ptr<Session> weak = session;
    asio::post(jobs_, [this, weak, work = std::move(work), id = request.id, cmd = request.cmd] {
      std::string line;
      try {
        line = proto::reply_line(id, cmd, work());
      } catch (const proto::ProtocolError& e) {
        line = proto::error_line(id, e.code(), e.what());
      } catch (const EngineError& e) {
        line = proto::error_line(id, e.code(), e.what());
      } catch (const std::exception& e) {
        line = proto::error_line(id, proto::errc::kInternal, e.what());
      }
      const bool failed = line.rfind("{\"class\":\"ERROR\"", 0) == 0;
      asio::post(io_, [this, weak, failed, line = std::move(line)]() mutable {
        if (failed) ++stats_.protocol_errors;
        if (auto s = weak.lock()) {
          --s->jobs;
          s->send(std::move(line));
        }
      });
    });
  } catch (const proto::ProtocolError& e) {
    throw proto::ProtocolError(e.code(), e.what(), request.id);
  } catch (const EngineError& e) {
    throw proto::ProtocolError(e.code(), e.what(), request.id);
  } catch (const std::exception& e) {
    log_.error(request.cmd + " failed: " + e.what());
    throw proto::ProtocolError(proto::errc::kInternal, e.what(), request.id);
  }
}

proto::Object Server::cmd_scan_start(const proto::Request& r) {
  const auto name = r.args.get_string("name");
  if (!name || name->empty() || name->size() > 200)
    throw proto::ProtocolError(proto::errc::kBadArgument,
                               "'name' (1 to 200 characters) is required");
  for (unsigned char c : *name)
    if (c < 0x20 || c == 0x7f)
      throw proto::ProtocolError(proto::errc::kBadArgument,
                                 "'name' must not contain control characters");
  Parameters merged = config_.scan_defaults;
  if (const auto p = r.args.get_parameters("parameters"))
    for (const auto& [k, v] : *p) merged[k] = v;
  const ScanRecord rec = engine_.start(*name, merged);
  paused_for_device_ = false;
  log_.notice("scan " + std::to_string(rec.id) + " '" + rec.name + "' started");
  proto::Object o;
  o.set("scan", proto::to_object(rec));
  return o;
}

void Server::broadcast(const std::string& line, bool progress) {
  std::vector<std::shared_ptr<Session>> watchers;
  for (auto& [n, s] : sessions_)
    if (s->watching) watchers.push_back(s);
  for (auto& s : watchers) {
    ++stats_.events;
    if (progress)
      s->send_progress(line);
    else
      s->send(line);
  }
}

void Server::progress_tick() {
  progress_timer_.expires_after(config_.progress_interval);
  progress_timer_.async_wait([this](const boost::system::error_code& ec) {
    if (ec) return;
    bool any = false;
    for (auto& [n, s] : sessions_) any = any || s->watching;
    if (any) {
      std::string line = proto::event_line("progress", proto::to_object(engine_.status()));
      if (line != last_progress_) {
        broadcast(line, true);
        last_progress_ = std::move(line);
      }
    }
    progress_tick();
  });
}

void Server::on_scan(const ScanStatus& status) {
  if (status.state == ScanState::kIdle) paused_for_device_ = false;
  if (status.state != last_state_)
    log_.info("scan " + std::to_string(status.id) + " '" + status.name +
              "': " + std::string(to_string(status.state)) +
              (status.reason.empty() ? std::string() : " (" + status.reason + ")"));
  last_state_ = status.state;
  broadcast(proto::event_line("state", proto::to_object(status)), false);
  if (on_state_change) on_state_change(status);
}

void Server::on_device(const DeviceInfo& device) {
  const bool bad = device.state == DeviceState::kLost || device.state == DeviceState::kFailed;
  log_.device(bad ? LogLevel::kWarning : LogLevel::kInfo, device.name,
              std::string(to_string(device.state)) +
                  (device.detail.empty() ? std::string() : ": " + device.detail));
  broadcast(proto::event_line("device", proto::to_object(device)), false);
  // Device loss pauses a running scan (nothing is recorded without every device); when every
  // device is back, the scan the daemon paused resumes.
  try {
    const ScanStatus st = engine_.status();
    if (bad && st.state == ScanState::kRunning) {
      engine_.pause("device_lost: " + device.name);
      paused_for_device_ = true;
    } else if (!bad && paused_for_device_ && st.state == ScanState::kPaused) {
      bool all_ok = true;
      for (const auto& d : engine_.devices()) all_ok = all_ok && d.state == DeviceState::kOk;
      if (all_ok) {
        paused_for_device_ = false;
        engine_.resume();
      }
    }
  } catch (const EngineError& e) {
    log_.warning(std::string("device policy: ") + e.what());
  }
}

void Server::on_mesh(const MeshCounts& counts) {
  broadcast(proto::event_line("mesh", proto::to_object(counts)), false);
}

StatusInfo Server::status_info() const {
  StatusInfo s;
  s.daemon_state = daemon_state_;
  s.backend = std::string(engine_.backend());
  s.uptime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  s.clients = sessions_.size();
  s.protocol_errors = stats_.protocol_errors;
  s.devices = engine_.devices();
  s.scan = engine_.status();
  return s;
}

proto::Object Server::config_object() const {
  const DaemonConfig& c = config_;
  std::vector<std::string> dirs;
  for (const auto& d : c.export_dirs) dirs.push_back(d.string());
  proto::Object daemon;
  daemon.set("socket", c.socket_path.string()).set("socket_group", c.socket_group);
  daemon.set("state_dir", c.state_dir.string()).set("max_clients", c.max_clients);
  daemon.set("client_output_limit_bytes", c.client_output_limit_bytes);
  daemon.set("progress_interval_ms", static_cast<std::int64_t>(c.progress_interval.count()));
  daemon.set("control_users", c.control_users).set("export_dirs", dirs);
  daemon.set("log_level", to_string(c.log_level));
  proto::Object backend;
  backend.set("kind", c.backend);
  proto::Object sim;
  sim.set("part", c.sim.part).set("mesh", c.sim.mesh.string()).set("sensor", c.sim.sensor);
  sim.set("path", c.sim.path).set("spacing_mm", c.sim.spacing_mm);
  sim.set("line_spacing_mm", c.sim.line_spacing_mm).set("speed_mm_s", c.sim.speed_mm_s);
  sim.set("noise_mm", c.sim.noise_mm).set("seed", c.sim.seed).set("views", c.sim.views);
  sim.set("profile_points", c.sim.profile_points).set("playback", c.sim.playback);
  sim.set("sensor_loss_at_s", c.sim.sensor_loss_at_s).set("sensor_loss_s", c.sim.sensor_loss_s);
  sim.set("transport", c.sim.transport);
  proto::Object replay;
  replay.set("journal", c.replay.journal.string()).set("playback", c.replay.playback);
  std::vector<proto::Object> devices;
  for (const auto& d : c.devices) {
    proto::Object o;
    o.set("role", d.role).set("config", d.config.string());
    devices.push_back(o);
  }
  proto::Object o;
  o.set("source", c.source.string()).set("daemon", daemon).set("backend", backend);
  o.set("sim", sim).set("replay", replay).set("devices", devices).set("scan", c.scan_defaults);
  return o;
}

}  // namespace scanmesh::daemon
