// Device emulators on pseudo-terminals: the emulator holds the master side of a pty pair and
// publishes the slave under a fixed link path, which the real driver opens with its real serial
// transport. Subclasses speak one vendor protocol; this base does the pty, the thread, the value
// source and the protocol-independent faults (garbage, byte-split writes, late or missing
// replies, the port vanishing and coming back).
// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::sim {

/// A raw (cfmakeraw) pseudo-terminal pair. The slave is published as a symlink at link_path so
/// a driver can reopen "the same port" after the pair was recreated. Move-only.
class PtyPair {
 public:
  /// Opens the pair and creates the link (replacing a stale one). Throws scanmesh::Error.
  explicit PtyPair(std::string link_path);
  PtyPair(PtyPair&& other) noexcept;
  PtyPair& operator=(PtyPair&& other) noexcept;
  PtyPair(const PtyPair&) = delete;
  PtyPair& operator=(const PtyPair&) = delete;
  ~PtyPair();

  int master_fd() const { return master_; }
  const std::string& slave_path() const { return slave_path_; }  ///< /dev/pts/N
  const std::string& link_path() const { return link_path_; }

 private:
  void reset() noexcept;
  int master_ = -1;
  int slave_keepalive_ = -1;  // keeps the master from seeing HUP while no driver has it open
  std::string slave_path_;
  std::string link_path_;
};

/// Faults any serial emulator can inject. Protocol-specific ones (bad checksum, error reply)
/// are applied by the subclass that knows the framing.
struct SerialFaults {
  bool garbage_before_reply = false;  ///< prepend a few bytes of line noise to every reply
  bool split_every_byte = false;      ///< write replies one byte per write()
  bool bad_checksum = false;          ///< protocol-specific: corrupt the checksum / marker bits
  bool error_reply = false;           ///< protocol-specific: answer with the protocol's error
  bool silent = false;                ///< read requests, answer nothing
  std::chrono::milliseconds reply_delay{0};  ///< answer this late
};

/// Where emulated measurements come from: called once per measurement the device makes.
using ValueSource = std::function<drivers::SensorSample()>;

/// A value source that is told the instant (host monotonic clock) the measurement is taken at: a
/// simulated sensor looking at a moving stage measures where the stage is at that instant.
using TimedValueSource = std::function<drivers::SensorSample(drivers::Timestamp measured)>;

/// Cycles through a scripted list of distances in mm: NaN means no target, +/-inf over range.
ValueSource scripted_values(std::vector<double> values_mm);
/// Plays back samples (e.g. from sim::Simulator), then repeats the last one.
ValueSource sample_values(std::vector<drivers::SensorSample> samples);

class SerialEmulator {
 public:
  explicit SerialEmulator(std::string link_path, ValueSource values);
  virtual ~SerialEmulator();
  SerialEmulator(const SerialEmulator&) = delete;
  SerialEmulator& operator=(const SerialEmulator&) = delete;

  /// Path the driver opens (a symlink to the current /dev/pts/N).
  const std::string& port() const { return link_path_; }

  void start();
  void stop() noexcept;
  /// Closes the pty: the driver's reads fail as on an unplugged USB adapter. The link is removed.
  void vanish();
  /// A new pty appears under the same link path (the adapter was plugged back).
  void reappear();

  void set_faults(const SerialFaults& faults);
  SerialFaults faults() const;
  /// Bytes received from the driver so far (for wire-level assertions).
  std::string received() const;
  /// Number of measurements taken from the value source.
  std::uint64_t measurements() const { return measurements_.load(); }

 protected:
  /// Called on the emulator thread with every chunk read from the pty. Returns the reply bytes
  /// (possibly empty). Subclasses buffer partial requests themselves.
  virtual std::string on_input(std::string_view bytes) = 0;
  /// Called every tick_interval() while running, for devices that stream on their own.
  virtual std::string on_tick() { return {}; }
  /// 0 = no ticks.
  virtual std::chrono::microseconds tick_interval() const { return std::chrono::microseconds(0); }
  /// Next measurement from the value source (counts measurements()).
  drivers::SensorSample next_value();
  /// Next measurement from `timed` at `measured` (counts measurements()).
  drivers::SensorSample next_value_at(const TimedValueSource& timed, drivers::Timestamp measured);
  /// For CR-terminated ASCII request protocols, from on_input(): appends bytes to `pending` (the
  /// subclass's partial request, emulator thread only) and calls answer(request) for every
  /// complete non-empty request, without its CR; LF is dropped and a request is cut at max_line
  /// bytes. Returns the answers concatenated.
  static std::string answer_lines(std::string_view bytes, std::string& pending,
                                  const std::function<std::string(std::string_view)>& answer,
                                  std::size_t max_line = 64);

 private:
  void run(std::stop_token stop);
  void send(int fd, const std::string& bytes, const SerialFaults& faults, std::stop_token& stop);

  std::string link_path_;
  ValueSource values_;
  mutable std::mutex mutex_;  // guards pty_, faults_, received_
  std::vector<PtyPair> pty_;  // zero or one
  SerialFaults faults_;
  std::string received_;
  std::atomic<std::uint64_t> measurements_{0};
  std::atomic<int> generation_{0};
  std::jthread thread_;
};

}  // namespace scanmesh::sim
