// The daemon process (daemon.hpp): one io thread, signals, systemd notifications, watchdog.
// SPDX-License-Identifier: MIT
#include "scanmesh/daemon/daemon.hpp"

#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <csignal>
#include <filesystem>
#include <optional>
#include <thread>

#include "scanmesh/daemon/server.hpp"
#include "scanmesh/daemon/systemd.hpp"

namespace scanmesh::daemon {

namespace asio = boost::asio;
using Clock = std::chrono::steady_clock;

namespace {

/// Engine callbacks arrive on engine threads; they are posted to the io thread (STYLE §5.3).
class PostingListener final : public EngineListener {
 public:
  PostingListener(asio::io_context& io, Server& server) : io_(io), server_(server) {}
  void on_scan(const ScanStatus& s) override {
    asio::post(io_, [this, s] { server_.on_scan(s); });
  }
  void on_device(const DeviceInfo& d) override {
    asio::post(io_, [this, d] { server_.on_device(d); });
  }
  void on_mesh(const MeshCounts& m) override {
    asio::post(io_, [this, m] { server_.on_mesh(m); });
  }

 private:
  asio::io_context& io_;
  Server& server_;
};

std::string status_text(const ScanStatus& s, const std::vector<DeviceInfo>& devices) {
  std::size_t ok = 0;
  for (const auto& d : devices) ok += d.state == DeviceState::kOk ? 1 : 0;
  const std::string dev = std::to_string(ok) + "/" + std::to_string(devices.size()) + " devices ok";
  switch (s.state) {
    case ScanState::kIdle:
      return "idle, " + dev;
    case ScanState::kRunning:
      return "scanning '" + s.name + "' (scan " + std::to_string(s.id) + "), " + dev;
    case ScanState::kPaused:
      return "paused '" + s.name + "' (scan " + std::to_string(s.id) + "): " + s.reason + ", " +
             dev;
    case ScanState::kStopping:
      return "stopping scan " + std::to_string(s.id) + ", " + dev;
  }
  return dev;
}

}  // namespace

struct Daemon::Impl {
  DaemonConfig config;
  ScanEngine& engine;
  Log& log;
  std::string version;
  std::function<DaemonConfig()> reload_fn;

  asio::io_context io{1};
  Server server{io, config, engine, log, version};
  PostingListener listener{io, server};
  asio::signal_set signals{io};
  asio::steady_timer watchdog_timer{io};
  asio::steady_timer drain_timer{io};
  Notifier notifier;
  std::optional<std::chrono::microseconds> watchdog;
  std::atomic<bool> stopping{false};
  std::thread shutdown_thread;

  Impl(DaemonConfig c, ScanEngine& e, Log& l, std::string v, std::function<DaemonConfig()> r)
      : config(std::move(c)), engine(e), log(l), version(std::move(v)), reload_fn(std::move(r)) {}

  void wait_signal() {
    signals.async_wait([this](const boost::system::error_code& ec, int sig) {
      if (ec) return;
      if (sig == SIGHUP) {
        reload();
        wait_signal();
      } else {
        log.notice(std::string("received ") + (sig == SIGTERM ? "SIGTERM" : "SIGINT") +
                   ": shutting down");
        shutdown();
      }
    });
  }

  void ping_watchdog() {
    // Pinged from the io loop itself: a stalled loop stops pinging and systemd notices.
    notifier.watchdog();
    watchdog_timer.expires_after(*watchdog / 2);
    watchdog_timer.async_wait([this](const boost::system::error_code& ec) {
      if (!ec) ping_watchdog();
    });
  }

  void reload() {
    notifier.reloading();
    server.set_daemon_state("reloading");
    try {
      DaemonConfig next = reload_fn();
      const auto restart = restart_needed(server.config(), next);
      server.apply(next);
      log.set_level(next.log_level);
      std::string msg = "configuration reloaded from " + next.source.string();
      if (!restart.empty()) {
        msg += "; these changes need a restart to take effect:";
        for (const auto& k : restart) msg += " " + k;
      }
      log.notice(msg);
    } catch (const std::exception& e) {
      log.error(std::string("reload refused, the running configuration stays:\n") + e.what());
    }
    server.set_daemon_state("ready");
    notifier.ready(status_text(engine.status(), engine.devices()));
  }

  void shutdown() {
    if (stopping.exchange(true)) return;
    server.set_daemon_state("stopping");
    notifier.stopping("stopping");
    server.stop_accepting();
    // The engine stops its scan and flushes the journal off the io thread, so clients still see
    // the scan's last events while it does.
    shutdown_thread = std::thread([this] {
      engine.shutdown();
      asio::post(io, [this] {
        server.close_clients();
        watchdog_timer.cancel();
        boost::system::error_code ec;
        signals.cancel(ec);
        drain(Clock::now() + std::chrono::seconds(3));
      });
    });
  }

  /// Ends the loop once every client has read its last lines (or at the deadline).
  void drain(Clock::time_point deadline) {
    if (server.clients() == 0 || Clock::now() >= deadline) {
      io.stop();
      return;
    }
    drain_timer.expires_after(std::chrono::milliseconds(5));
    drain_timer.async_wait([this, deadline](const boost::system::error_code& e) {
      if (!e) drain(deadline);
    });
  }

  int run() {
    try {
      std::error_code ec;
      std::filesystem::create_directories(config.state_dir, ec);
      if (ec)
        throw ConfigError(config.state_dir.string() +
                          ": cannot create the state folder: " + ec.message());
      for (const auto& d : config.export_dirs) {
        std::filesystem::create_directories(d, ec);
        if (ec) log.warning(d.string() + ": cannot create the export folder: " + ec.message());
      }
      engine.open(listener);
      const auto activated = take_activated_socket(config.socket_path, log);
      server.listen(activated);
    } catch (const std::exception& e) {
      log.error(std::string("startup failed: ") + e.what());
      engine.shutdown();
      return 1;
    }
    server.on_state_change = [this](const ScanStatus& s) {
      notifier.status(status_text(s, engine.devices()));
    };
    signals.add(SIGTERM);
    signals.add(SIGINT);
    signals.add(SIGHUP);
    wait_signal();
    watchdog = watchdog_interval();
    if (watchdog) {
      log.info("watchdog: pinging every " + std::to_string(watchdog->count() / 2000) + " ms");
      ping_watchdog();
    }
    const std::string status = status_text(engine.status(), engine.devices());
    notifier.ready(status);
    log.notice("scanmeshd " + version + " ready (" + std::string(engine.backend()) +
               " backend): " + status);
    for (;;) {
      try {
        io.run();
        break;
      } catch (const std::exception& e) {
        // A handler threw: log it and keep serving (STYLE §4: nothing escapes silently).
        log.error(std::string("internal error in the io loop: ") + e.what());
      }
    }
    if (shutdown_thread.joinable()) shutdown_thread.join();
    log.notice("stopped");
    return 0;
  }
};

Daemon::Daemon(DaemonConfig config, ScanEngine& engine, Log& log, std::string version,
               std::function<DaemonConfig()> reload)
    : impl_(std::make_unique<Impl>(std::move(config), engine, log, std::move(version),
                                   std::move(reload))) {}
Daemon::~Daemon() {
  if (impl_->shutdown_thread.joinable()) impl_->shutdown_thread.join();
}

int Daemon::run() { return impl_->run(); }

void Daemon::request_stop() {
  asio::post(impl_->io, [this] { impl_->shutdown(); });
}

}  // namespace scanmesh::daemon
