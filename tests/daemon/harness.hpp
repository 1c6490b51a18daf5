// An in-process scanmeshd for tests: the real Daemon (server, sessions, signals off the test's
// path) on its own thread over a ScriptedEngine, listening on a socket in a temporary folder.
// SPDX-License-Identifier: MIT
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <functional>
#include <thread>

#include "daemon/eventually.hpp"
#include "daemon/scripted_engine.hpp"
#include "scanmesh/daemon/client.hpp"
#include "scanmesh/daemon/daemon.hpp"
#include "support/process.hpp"
#include "support/temp_dir.hpp"

namespace scanmesh::test {

inline daemon::DaemonConfig harness_config(const TempDir& dir) {
  daemon::DaemonConfig c;
  c.socket_path = dir / "control.sock";
  c.state_dir = dir / "state";
  c.export_dirs = {dir / "exports"};
  c.log_level = daemon::LogLevel::kDebug;
  c.progress_interval = std::chrono::milliseconds(20);
  return c;
}

class DaemonHarness {
 public:
  explicit DaemonHarness(std::function<void(daemon::DaemonConfig&)> adjust = {})
      : config_(harness_config(dir_)) {
    if (adjust) adjust(config_);
    log_fd_ =
        ::open((dir_ / "daemon.log").c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    log_ = std::make_unique<daemon::Log>(config_.log_level, log_fd_);
    daemon_ = std::make_unique<daemon::Daemon>(config_, engine_, *log_, "test",
                                               [this] { return config_; });
    thread_ = std::thread([this] { status_ = daemon_->run(); });
    if (!eventually([this] { return std::filesystem::exists(config_.socket_path); }))
      throw std::runtime_error("the daemon did not start: " + log());
  }
  ~DaemonHarness() {
    stop();
    ::close(log_fd_);
  }

  int stop() {
    if (thread_.joinable()) {
      daemon_->request_stop();
      thread_.join();
    }
    return status_;
  }
  ScriptedEngine& engine() { return engine_; }
  const daemon::DaemonConfig& config() const { return config_; }
  const TempDir& dir() const { return dir_; }
  std::filesystem::path socket() const { return config_.socket_path; }
  std::string log() const { return slurp(dir_ / "daemon.log"); }
  std::unique_ptr<daemon::Client> client() {
    return std::make_unique<daemon::Client>(socket(), std::chrono::seconds(10));
  }

 private:
  TempDir dir_;
  daemon::DaemonConfig config_;
  ScriptedEngine engine_;
  int log_fd_ = -1;
  std::unique_ptr<daemon::Log> log_;
  std::unique_ptr<daemon::Daemon> daemon_;
  std::thread thread_;
  int status_ = -1;
};

}  // namespace scanmesh::test
