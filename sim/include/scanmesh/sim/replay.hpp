// Replay of recorded sample streams at recorded speed on an injected clock (a virtual clock in
// tests, so nothing sleeps) or as fast as possible.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <optional>

#include "scanmesh/sim/samples.hpp"
#include "scanmesh/sim/simulator.hpp"
#include "scanmesh/sim/stream.hpp"

namespace scanmesh::sim {

/// Source of "now" for the replayer.
class Clock {
 public:
  virtual ~Clock() = default;
  virtual Timestamp now() const = 0;
};

/// A clock that moves only when told to (tests, simulations).
class VirtualClock : public Clock {
 public:
  explicit VirtualClock(Timestamp start = {}) : now_(start) {}
  Timestamp now() const override { return now_; }
  void advance(std::chrono::nanoseconds d) { now_ = now_ + d; }
  void set(Timestamp t) { now_ = t; }

 private:
  Timestamp now_;
};

/// std::chrono::steady_clock (manual --realtime runs only).
class SteadyClock : public Clock {
 public:
  Timestamp now() const override;
};

struct ReplayOptions {
  /// Playback speed relative to the recording, > 0 (2: twice as fast). Default 1.
  double speed = 1;
  /// Shift every delivered timestamp so the stream starts at the clock's start time (at speed
  /// 1 the samples then look live); otherwise the recorded timestamps are kept.
  bool rebase_timestamps = false;
};

/// Delivers a recorded stream's records in time order (sensor by host time; at equal times
/// stage first, then sensor, then probe), each when the clock reaches its due time. Keeps a
/// reference to the stream, which must outlive it.
class Replayer {
 public:
  Replayer(const RecordedStream& stream, const Clock& clock, ReplayOptions options = {});

  /// Anchors the first record to clock.now(). Called by the first poll() if not before.
  void start();
  /// Delivers every record due by clock.now(); returns how many measurements/stage samples.
  std::size_t poll(SampleSink& sink);
  /// Clock time at which the next record becomes due; nullopt when done.
  std::optional<Timestamp> next_due() const;
  bool done() const;
  /// Delivers everything now, ignoring the clock (as fast as possible).
  std::size_t run_all(SampleSink& sink);

 private:
  Timestamp record_time(std::size_t kind) const;
  std::size_t deliver_next(SampleSink& sink);
  int next_kind() const;

  const RecordedStream* stream_;
  const Clock* clock_;
  ReplayOptions options_;
  bool started_ = false;
  Timestamp clock_start_;
  Timestamp stream_start_;
  std::size_t sensor_pos_ = 0;
  std::size_t stage_pos_ = 0;
  std::size_t probe_pos_ = 0;
  std::vector<SensorSample> buffer_;
};

}  // namespace scanmesh::sim
