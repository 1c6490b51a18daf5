// Small building blocks every device class uses: bounded reconnect backoff, sequence/gap
// accounting, thread-safe counters and state, and the worker thread that runs a device loop.
// SPDX-License-Identifier: MIT
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <stop_token>
#include <string>
#include <thread>

#include "scanmesh/drivers/displacement_sensor.hpp"

namespace scanmesh::drivers {

/// Bounded exponential backoff: initial, 2x, 4x ... capped at max; reset() after a success.
class Backoff {
 public:
  Backoff(std::chrono::milliseconds initial, std::chrono::milliseconds max)
      : initial_(initial), max_(max), next_(initial) {}
  std::chrono::milliseconds next() {
    const auto d = next_;
    next_ = std::min(max_, next_ * 2);
    return d;
  }
  void reset() { next_ = initial_; }

 private:
  std::chrono::milliseconds initial_, max_, next_;
};

/// Assigns host sequence numbers and counts gaps from a device counter that wraps at
/// 2^counter_bits (e.g. the ILD1420's 18-bit measurement counter). Without a device counter
/// call next() only.
class SequenceTracker {
 public:
  explicit SequenceTracker(int counter_bits = 0) : bits_(counter_bits) {}
  /// Next host sequence number for a sample without a device counter.
  std::uint64_t next() { return seq_++; }
  /// Next host sequence number for a sample carrying device counter `counter`; a jump of k
  /// adds k-1 gaps and advances seq by k so that seq differences still measure lost samples.
  std::uint64_t next(std::uint64_t counter) {
    if (have_last_ && bits_ > 0) {
      const std::uint64_t mask = bits_ >= 64 ? ~0ULL : ((1ULL << bits_) - 1);
      const std::uint64_t step = (counter - last_) & mask;
      if (step > 1) {
        gaps_ += step - 1;
        seq_ += step - 1;
      }
    }
    last_ = counter;
    have_last_ = true;
    return seq_++;
  }
  /// Forget the device counter (after a reconnect the device may have restarted it).
  void resync() { have_last_ = false; }
  std::uint64_t gaps() const { return gaps_; }

 private:
  int bits_;
  std::uint64_t seq_ = 0;
  std::uint64_t last_ = 0;
  bool have_last_ = false;
  std::uint64_t gaps_ = 0;
};

/// DeviceStats with atomic fields, written by the worker and snapshotted by anyone.
struct AtomicStats {
  std::atomic<std::uint64_t> samples{0}, gaps{0}, malformed{0}, error_replies{0}, timeouts{0},
      reconnects{0};
  DeviceStats snapshot() const {
    return {samples.load(), gaps.load(), malformed.load(), error_replies.load(), timeouts.load(),
            reconnects.load()};
  }
};

/// Holds the device state and reports changes through the callbacks (at most once per change).
class StateCell {
 public:
  DeviceState get() const { return state_.load(); }
  /// Sets the state; calls on_state when it changed. Callbacks: any family's callback set with an
  /// on_state member (SensorCallbacks, StageCallbacks).
  template <class Callbacks>
  void set(DeviceState s, const std::string& reason, const Callbacks* callbacks) {
    const DeviceState old = state_.exchange(s);
    if (callbacks && callbacks->on_state && (old != s)) callbacks->on_state(s, reason);
  }
  /// Sets the state without reporting it.
  void set(DeviceState s, const std::string&, std::nullptr_t) { state_.store(s); }

 private:
  std::atomic<DeviceState> state_{DeviceState::kClosed};
};

/// A std::jthread whose body receives a stop_token and never lets an exception escape (it is
/// handed to on_exception instead). sleep_for() wakes up early when stop is requested.
class Worker {
 public:
  Worker() = default;
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;
  ~Worker() { stop(); }

  void start(std::function<void(Worker&)> body,
             std::function<void(const std::exception&)> on_exception) {
    stop();
    {
      std::lock_guard lock(mutex_);
      stopping_ = false;
    }
    thread_ = std::jthread([this, body = std::move(body),
                            on_exception = std::move(on_exception)](std::stop_token) {
      try {
        body(*this);
      } catch (const std::exception& e) {
        if (on_exception) on_exception(e);
      } catch (...) {
        if (on_exception) on_exception(std::runtime_error("unknown exception"));
      }
    });
  }
  /// Requests stop and joins. Safe to call twice, and from no other thread than the owner's.
  void stop() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }
  bool stop_requested() const {
    std::lock_guard lock(mutex_);
    return stopping_;
  }
  /// Sleeps up to d; returns false when stop was requested (then return from the body).
  bool sleep_for(std::chrono::nanoseconds d) {
    std::unique_lock lock(mutex_);
    return !cv_.wait_for(lock, d, [this] { return stopping_; });
  }
  /// Sleeps until `until`, stop, or notify() from another thread (work for the worker); returns
  /// false when stop was requested.
  bool sleep_until_notified(std::chrono::steady_clock::time_point until) {
    std::unique_lock lock(mutex_);
    cv_.wait_until(lock, until, [this] { return stopping_ || notified_; });
    notified_ = false;
    return !stopping_;
  }
  /// Wakes sleep_until_notified() (any thread).
  void notify() {
    {
      std::lock_guard lock(mutex_);
      notified_ = true;
    }
    cv_.notify_all();
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  bool stopping_ = false;
  bool notified_ = false;
  std::jthread thread_;
};

}  // namespace scanmesh::drivers
