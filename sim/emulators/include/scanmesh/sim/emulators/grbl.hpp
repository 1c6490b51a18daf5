// GRBL controller emulator on a pty: a Grbl 1.1 line protocol front end (128-byte receive
// buffer, 15-block planner, ok / error:N, real-time bytes, status reports, $H, $J=, $X, G38.2
// probing with [PRB:...]) over the shared StageMotion model (PROTOCOLS.md §3.2).
// SPDX-License-Identifier: MIT
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/sim/emulators/serial_emulator.hpp"
#include "scanmesh/sim/emulators/stage_motion.hpp"

namespace scanmesh::sim {

struct GrblEmulatorOptions {
  StageMotionOptions motion;
  bool rotary_a = false;       ///< a fourth axis A (degrees) in reports and G-code
  bool homing_enabled = true;  ///< $22: $H allowed (else error:5)
  bool homing_lock = false;    ///< starts in Alarm until $H or $X (Grbl with $22=1)
  int rx_buffer_bytes = 128;   ///< serial receive buffer (holds one byte less)
  int planner_blocks = 15;     ///< motion lines planned ahead
  bool report_wpos = false;    ///< $10: WPos instead of MPos in status reports
  std::array<double, 4> work_offset{};  ///< WCO (mm; A in degrees)
  int wco_every = 10;          ///< the WCO field in every Nth report (and the first)
  std::string version = "1.1h.20190825";
};

/// Emulated Grbl. Behaviour (written apart from the driver's codec on purpose):
/// - bytes other than the real-time ones go to the receive buffer; bytes beyond its capacity are
///   dropped and counted (rx_overflows()): a host that counts characters never overflows it;
/// - a line is taken from the buffer when complete, motion lines only while the planner has
///   room, then answered `ok` or `error:N`; $H answers at the end of homing, G38.2 at the end of
///   the probing move (after ALARM:5 / ALARM:4 and [PRB:...:0|1]);
/// - `?` answers `<State|MPos:...|FS:...[|Pn:P][|WCO:...]>` at once, except while homing;
///   `!` holds, `~` resumes, 0x85 cancels a jog, 0x18 resets (ALARM:3 when moving) and prints
///   the banner;
/// - in Alarm state G-code is refused with error:9 until $X or $H.
class GrblEmulator final : public SerialEmulator {
 public:
  GrblEmulator(std::string link_path, GrblEmulatorOptions options);
  ~GrblEmulator() override;

  StageMotion& motion() { return *motion_; }
  /// Fault: ALARM:N now (motion stops, state Alarm).
  void raise_alarm(int code) { pending_alarm_.store(code); }
  /// Fault: probing moves never touch anything.
  void set_probe_never_triggers(bool on) { motion_->set_probe_never_triggers(on); }

  int rx_overflows() const { return overflows_.load(); }
  /// Largest receive-buffer fill seen, bytes.
  int max_rx_fill() const { return max_fill_.load(); }
  /// G-code lines taken from the receive buffer, in order (for wire-level assertions).
  std::vector<std::string> lines() const;
  bool alarm() const { return alarm_.load(); }

 protected:
  std::string on_input(std::string_view bytes) override;
  std::string on_tick() override;
  std::chrono::microseconds tick_interval() const override { return std::chrono::microseconds(2000); }

 private:
  enum class Wait { kNone, kHoming, kProbe, kSync };
  std::string process_lines(drivers::Timestamp now);
  std::string execute(const std::string& line, drivers::Timestamp now);
  std::string execute_gcode(const std::string& line, bool jog, drivers::Timestamp now);
  std::string status_report(drivers::Timestamp now);
  std::string reset(drivers::Timestamp now);
  std::string raise(int code, drivers::Timestamp now);
  std::string finish_wait(drivers::Timestamp now);

  GrblEmulatorOptions options_;
  std::unique_ptr<StageMotion> motion_;
  std::atomic<int> pending_alarm_{0};
  std::atomic<int> overflows_{0};
  std::atomic<int> max_fill_{0};
  std::atomic<bool> alarm_{false};
  mutable std::mutex lines_mutex_;
  std::vector<std::string> lines_;

  // Emulator thread only.
  std::string rx_;
  Wait wait_ = Wait::kNone;
  std::uint64_t probe_id_ = 0;
  bool jogging_ = false;
  bool absolute_ = true;
  double feed_mm_min_ = 0;
  int reports_ = 0;
  StagePose planned_end_{};  // where the last planned move ends
};

}  // namespace scanmesh::sim
