// I++ DME server emulator on 127.0.0.1: a CMM controller speaking the I++ DME line protocol
// (session, tagged normal queue executed in order, fast E-queue, OnMoveReportE daemon, GoTo,
// Home, PtMeas with approach/search/retract, AbortE, ClearAllErrors, errors by severity) over the
// shared StageMotion model, with the touch probe on the reference mesh (PROTOCOLS.md §3.4).
// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "scanmesh/sim/emulators/stage_motion.hpp"

namespace scanmesh::sim {

struct IppDmeEmulatorOptions {
  StageMotionOptions motion;  ///< limits, start/home, probe (its tip radius is the tool's)
  bool rotary_table = false;  ///< R() in degrees
  std::string version = "1.4.3";
  int port = 0;  ///< 0: an ephemeral port (port() tells which; kept across vanish/reappear)
};

struct IppDmeFaults {
  bool silent = false;                ///< read commands, answer nothing
  bool garbage_before_reply = false;  ///< line noise before every line sent
  std::chrono::milliseconds reply_delay{0};
};

/// Emulated I++ DME server. Behaviour (written apart from the driver's codec on purpose):
/// - every command line is answered `tag &` on receipt; normal-queue commands then run one
///   after the other (`tag # ...` data, `tag %`); E-commands run at once;
/// - GoTo / Home / PtMeas take the motion model's time; OnMoveReportE(Time(t), ...) sends
///   `E0001 # X(), Y(), Z()` every t seconds while the axes move;
/// - PtMeas(X, Y, Z, IJK): from nominal + IJK * approach, searches along -IJK for approach +
///   search; contact: `# X(), Y(), Z(), IJK()` = tip centre - IJK * radius (compensated along
///   the nominal vector); none: Error(2, 1006, "PtMeas", "Surface not found"); probe deflected
///   at the start: Error(2, 1001, "PtMeas", "Illegal touch"); retract < 0 returns to the start;
/// - after an error of severity >= 2 only ClearAllErrors(), E-commands and EndSession() are
///   executed, the rest get Error(2, 0514, ...);
/// - unknown methods: Error(3, 0501, "<method>", "Unsupported command").
class IppDmeEmulator {
 public:
  explicit IppDmeEmulator(IppDmeEmulatorOptions options);
  ~IppDmeEmulator();
  IppDmeEmulator(const IppDmeEmulator&) = delete;
  IppDmeEmulator& operator=(const IppDmeEmulator&) = delete;

  void start();  ///< throws scanmesh::Error when it cannot listen
  void stop() noexcept;
  void vanish();    ///< closes the listener and the client: the driver sees the server gone
  void reappear();  ///< listens again on the same port
  /// Closes the client's connection (the listener stays).
  void drop_client();
  int port() const { return port_; }

  void set_faults(const IppDmeFaults& faults);
  /// Fault: the machine raises an error (e.g. 500 emergency stop) as an unsolicited E0000 event;
  /// motion stops and the error state holds until ClearAllErrors().
  void raise_error(int code, int severity = 3);
  /// Fault: a reply with a tag nobody sent.
  void send_unknown_tag();
  void set_probe_never_triggers(bool on) { motion_->set_probe_never_triggers(on); }
  StageMotion& motion() { return *motion_; }
  /// Command lines received (without CR LF), in order.
  std::vector<std::string> lines() const;
  /// Most normal-queue commands waiting or running at once.
  int max_queued() const { return max_queued_.load(); }

 private:
  struct Command {
    std::string tag;
    std::string method;  ///< name
    std::string args;    ///< inside the outer parentheses
    std::string line;
  };
  void run(std::stop_token stop);
  void serve_client(int fd, std::stop_token& stop);
  void on_line(const std::string& line, drivers::Timestamp now);
  void execute_fast(const Command& c, drivers::Timestamp now);
  /// Runs or continues the head of the normal queue; true when it finished.
  bool step_queue(drivers::Timestamp now);
  void send(const std::string& line);
  void error_reply(const std::string& tag, int severity, int code, const std::string& cause,
                   const std::string& text);
  std::string position_data(drivers::Timestamp now) const;
  void close_client() noexcept;

  IppDmeEmulatorOptions options_;
  std::unique_ptr<StageMotion> motion_;
  int port_ = 0;
  int listen_fd_ = -1;
  std::jthread thread_;
  mutable std::mutex mutex_;  // faults_, lines_, pending fault requests
  IppDmeFaults faults_;
  std::vector<std::string> lines_;
  int pending_error_ = 0;
  int pending_severity_ = 0;
  bool pending_unknown_ = false;
  bool pending_drop_ = false;
  std::atomic<int> max_queued_{0};

  // Emulator thread only.
  int client_fd_ = -1;
  std::string pending_in_;
  std::deque<Command> queue_;
  bool running_head_ = false;  ///< the head of the queue started (a motion under way)
  int phase_ = 0;              ///< PtMeas: 0 approach, 1 search, 2 retract
  std::uint64_t probe_id_ = 0;
  bool error_state_ = false;
  double approach_ = 2, search_ = 2, retract_ = -1, probe_speed_ = 10, goto_speed_ = 100;
  double report_period_s_ = 0;  ///< 0: no move-report daemon
  drivers::Timestamp next_report_{};
  drivers::StagePose probe_start_{};
  std::string probe_reply_;
};

}  // namespace scanmesh::sim
