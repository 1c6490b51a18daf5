// Device class of GRBL G-code controllers: a MotionStage over a serial ByteStream, with
// character-counting flow control, `?` status polling, jog, homing, feed hold / cycle start /
// soft reset, alarms, and G38.2 probing (see grbl/codec.hpp for the protocol).
// SPDX-License-Identifier: MIT
//
// Models: Grbl 1.1 and derivatives (grblHAL; GRBL-based turntable boards with an A axis).
// Documents: gnea/grbl doc/markdown/interface.md, commands.md; grbl/probe.c (PROTOCOLS.md §3.2).
// Transport: ByteStream from a ByteStreamFactory (serial 115200 8N1; the emulator's pty).
// Behaviour and quirks (each also commented where handled):
//   - Flow control by character counting: the bytes of lines sent but not yet acknowledged
//     (ok / error:N, one per line, in order) never exceed the receive buffer minus one (Grbl's
//     ring buffer holds size-1 bytes); the buffer size is Options::rx_buffer_bytes, lowered to
//     the one the controller reports in [OPT:...,<blocks>,<bytes>].
//   - `?`, `!`, `~` and 0x18 are real-time bytes: not counted, never queued.
//   - Grbl acknowledges a motion line when it is planned, not when it ends; a line waits in the
//     receive buffer while the planner is full, so its `ok` may come late: liveness is judged by
//     the status reports alone.
//   - No status report is sent during homing ($H acknowledges at its end): status timeouts are
//     not counted while homing; homing longer than StageOptions::homing_timeout is a loss.
//   - [PRB:...] positions are machine coordinates; WPos reports are turned into MPos with the
//     last WCO (WPos = MPos - WCO).
//   - G38.2 without contact raises ALARM:5 (and a probe already deflected ALARM:4); probe_move
//     reports these as kNoContact / kTriggeredAtStart and unlocks the controller ($X), since
//     they are expected outcomes of probing, not machine faults.
//   - halt(): feed hold `!`, wait until the hold completes (Hold:0, or Idle after a jog), then
//     soft reset 0x18, which flushes the buffers and keeps the position (no ALARM:3 when the
//     axes stand); the lines still queued fail with "halted".
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "scanmesh/drivers/byte_stream.hpp"
#include "scanmesh/drivers/common/stage_base.hpp"
#include "scanmesh/drivers/grbl/codec.hpp"

namespace scanmesh::drivers::grbl {

inline constexpr unsigned kDefaultBaud = 115200;

struct Options {
  /// Receive buffer the character counting fills (bytes); the controller's [OPT:] value wins
  /// when smaller. Default 128 (stock Grbl); valid 16 .. 65536.
  int rx_buffer_bytes = kDefaultRxBufferBytes;
  /// The controller drives a rotary A axis (degrees on the wire). Default false (X, Y, Z).
  bool rotary_a = false;
  /// Largest feed the driver sends, mm/min (0: no limit). Default 0.
  double max_feed_mm_min = 0;
};

class Device final : public StageBase {
 public:
  /// Validates the options (throws ConfigError). `transport` opens the serial port (and reopens
  /// it after a loss).
  Device(StageOptions options, ByteStreamFactory transport, Options grbl = {});
  ~Device() override;

  StageCapabilities capabilities() const override;

  void move_to(const StageTarget& target, double feed_mm_min) override;
  void move_by(const StageTarget& delta, double feed_mm_min) override;
  void jog(const StageTarget& delta, double feed_mm_min) override;
  void home() override;
  void halt() override;
  void clear_alarm() override;
  ProbeMoveResult probe_move(const ProbeMove& move) override;

  /// Feed hold `!` and cycle start `~` (resume), as the real-time bytes.
  void feed_hold();
  void cycle_start();
  /// Sends a raw G-code line (without newline) and waits for its `ok`; throws on error:N.
  void send_line(const std::string& line);
  /// The receive-buffer budget in use (after [OPT:]).
  int rx_buffer_bytes() const { return rx_budget_.load() + 1; }

 private:
  enum class LineKind { kPlain, kHome, kProbe };
  struct Line {
    std::string bytes;  // with its '\n'
    LineKind kind = LineKind::kPlain;
    std::shared_ptr<std::promise<void>> done;              // kPlain / kHome
    std::shared_ptr<std::promise<ProbeMoveResult>> probe;  // kProbe
  };

  void send_and_wait(const std::string& operation, std::string bytes, LineKind kind,
                     std::chrono::milliseconds timeout);
  void write_realtime(char byte);
  /// Writes queued lines while they fit in the receive buffer (worker).
  void flush_lines();
  /// Feeds received bytes to the decoder and acts on every reply (worker). Returns whether a
  /// status report arrived.
  bool handle_input(std::span<const std::uint8_t> bytes, Timestamp t_host);
  void on_reply(const Reply& r, Timestamp t_host, bool& got_status);
  void on_status(const StatusReport& s, Timestamp t_host);
  void complete_line(const Reply& r);
  void fail_lines(const std::string& reason);
  /// open()/reconnect: $I and one status report, synchronously. Throws DeviceError.
  void handshake();
  std::string where() const;
  StagePose to_pose(const AxisValues& machine) const;
  AxisWords to_words(const StageTarget& target) const;
  double checked_feed(double feed_mm_min, const std::string& operation) const;

  // ---- StageBase / lifecycle hooks ----
  void open_device() override;
  bool reconnect_once() override;
  Step acquire(std::string& timeout_detail) override;
  void drop_transport() noexcept override;
  bool has_transport() const override { return transport_ != nullptr; }
  std::string lost_after_timeouts(int count, const std::string& detail) const override;
  void on_start() override;
  void on_reconnected() override;

  ByteStreamFactory factory_;
  Options grbl_;
  std::unique_ptr<ByteStream> transport_;
  Decoder decoder_;
  std::atomic<int> rx_budget_;

  // Worker state (open()/reconnect, then only the worker).
  std::deque<Line> to_send_;
  std::deque<Line> in_flight_;
  int in_flight_bytes_ = 0;
  AxisValues wco_{};
  bool status_outstanding_ = false;
  std::chrono::steady_clock::time_point status_sent_{};
  std::chrono::steady_clock::time_point next_poll_{};
  bool homing_ = false;
  std::chrono::steady_clock::time_point homing_since_{};
  bool awaiting_banner_ = false;
  std::chrono::steady_clock::time_point reset_sent_{};
  std::shared_ptr<std::promise<void>> halting_;  // a halt waiting for the hold to complete
  bool hold_requested_ = false;
  std::optional<ProbeReport> last_probe_;
  int last_alarm_ = 0;
  std::string firmware_;
  std::string options_text_;
  bool got_ok_ = false;  // handshake
};

}  // namespace scanmesh::drivers::grbl
