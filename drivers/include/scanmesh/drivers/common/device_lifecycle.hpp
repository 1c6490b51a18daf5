// DeviceLifecycle: the transport-independent lifecycle every device family shares (sensors,
// stages): state, statistics, identity, callbacks, the worker thread, timeouts in a row -> lost,
// and reconnecting with bounded backoff through the driver's transport hooks.
// SPDX-License-Identifier: MIT
//
// A family base instantiates it with its interface, its callback set and its options:
//   SensorLifecycle = DeviceLifecycle<DisplacementSensor, SensorCallbacks, SensorOptions>,
//   StageBase       = DeviceLifecycle<MotionStage, StageCallbacks, StageOptions>.
// Family must declare name/open/close/start(Callbacks)/stop/identify/state/stats as virtuals;
// Callbacks must have an `on_state(DeviceState, const std::string&)` member; Options must have
// name, timeouts_until_lost, backoff_initial and backoff_max.
//
// Worker loop: acquire() until stop. A kTimeout step is counted (stats().timeouts) and after
// options().timeouts_until_lost of them in a row, or when a hook throws, the device is lost: the
// transport is dropped, the state becomes kLost with the reason naming the device, and the
// worker calls reconnect_once() after each backoff delay (backoff_initial, doubled up to
// backoff_max) until the device answers again. kAnswered ends a run of timeouts; kPending (a
// step that neither got nor missed an answer, e.g. a read slice of a streaming protocol) leaves
// it as it is.
// Threading: open/close/start/stop from the owner's thread; the hooks run on that thread during
// open()/start() and on the worker thread while running, never concurrently. No callback runs
// after stop() returned.
#pragma once

#include <exception>
#include <mutex>
#include <string>
#include <utility>

#include "scanmesh/drivers/device_support.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers {

template <class Family, class Callbacks, class Options>
class DeviceLifecycle : public Family {
 public:
  /// A subclass must call close() in its own destructor: the worker calls its hooks, which must
  /// not outlive the subclass's members.
  ~DeviceLifecycle() override = default;

  const std::string& name() const override { return options_.name; }

  /// Opens the device through open_device(); state kOpen. Does nothing while running.
  void open() override {
    if (running_) return;
    drop_transport();
    try {
      open_device();
    } catch (...) {
      drop_transport();
      throw;
    }
    state_.set(DeviceState::kOpen, "", nullptr);
  }

  void close() noexcept override {
    stop();
    drop_transport();
    state_.set(DeviceState::kClosed, "", nullptr);
  }

  /// Starts the worker. Throws DeviceError kProtocol "open() first" when closed. Started after a
  /// loss (no transport), the worker begins by reconnecting (state kLost).
  void start(Callbacks callbacks) override {
    if (running_) return;
    if (state_.get() == DeviceState::kClosed)
      throw DeviceError(DeviceErrorKind::kProtocol, options_.name, "start", "open() first");
    callbacks_ = std::move(callbacks);
    running_ = true;
    on_start();
    state_.set(has_transport() ? DeviceState::kAcquiring : DeviceState::kLost,
               options_.name + (has_transport() ? ": acquiring" : ": lost: reconnecting"),
               &callbacks_);
    worker_.start([this](Worker& w) { run(w); },
                  [this](const std::exception& e) {
                    // Nothing escapes the worker: an unexpected error ends it as a state.
                    const std::string reason = options_.name + ": worker stopped: " + e.what();
                    drop_transport();
                    state_.set(DeviceState::kLost, reason, &callbacks_);
                  });
  }

  /// Stops the worker and joins it; leaves kOpen with a transport, kLost without one.
  void stop() noexcept override {
    if (!running_) return;
    worker_.stop();
    running_ = false;
    on_stopped();
    state_.set(has_transport() ? DeviceState::kOpen : DeviceState::kLost, "", nullptr);
  }

  DeviceIdentity identify() const override {
    std::lock_guard lock(identity_mutex_);
    return identity_;
  }
  DeviceState state() const override { return state_.get(); }
  DeviceStats stats() const override { return stats_.snapshot(); }

 protected:
  /// What one acquire() brought.
  enum class Step {
    kAnswered,  ///< the device answered (a sample, an error reply ...): timeouts in a row end
    kTimeout,   ///< a request got nothing within its timeout: counted
    kPending,   ///< neither yet (a read slice while a request is still in time)
  };

  /// counter_bits: width of the device's sample counter (SequenceTracker), 0 = none.
  explicit DeviceLifecycle(Options options, int counter_bits = 0)
      : options_(std::move(options)), seq_(counter_bits) {}

  const Options& options() const { return options_; }
  AtomicStats& counters() { return stats_; }
  SequenceTracker& sequence() { return seq_; }
  const Callbacks& callbacks() const { return callbacks_; }
  /// Whether the worker runs (between start() and stop()).
  bool running() const { return running_; }
  /// Wakes the worker from Worker::sleep_until_notified() (work arrived from another thread).
  void wake_worker() { worker_.notify(); }
  /// Stores what the device says it is (identify() may be called from any thread).
  void set_identity(DeviceIdentity identity) {
    std::lock_guard lock(identity_mutex_);
    identity_ = std::move(identity);
  }

  // ---- transport hooks ----
  /// Creates the transport through the factory and makes the device answer once; throws
  /// DeviceError naming the device, the port, the operation and the device's own words.
  virtual void open_device() = 0;
  /// Worker, after a loss: creates the transport again and makes the device answer; false (or a
  /// throw) when it does not answer yet (the transport is then dropped).
  virtual bool reconnect_once() = 0;
  /// Worker: one acquisition step. A throw is a loss. timeout_detail: what timed out.
  virtual Step acquire(std::string& timeout_detail) = 0;
  /// Releases the transport (also from the destructor: must not call other hooks).
  virtual void drop_transport() noexcept = 0;
  virtual bool has_transport() const = 0;
  /// Loss reason after `count` timeouts in a row (detail: the last acquire()'s).
  virtual std::string lost_after_timeouts(int count, const std::string& detail) const = 0;
  /// In start(), before the worker runs.
  virtual void on_start() {}
  /// In stop(), after the worker was joined.
  virtual void on_stopped() noexcept {}
  /// Worker, right after a timeout was counted.
  virtual void on_timeout() {}
  /// Worker, after a reconnect was reported.
  virtual void on_reconnected() {}
  /// Worker, after the device was declared lost (the transport is already dropped).
  virtual void on_lost(const std::string& reason) { (void)reason; }
  /// Worker, between two acquisition steps that did not lose the device; false when stop was
  /// requested meanwhile.
  virtual bool pause(Worker&) { return true; }

 private:
  void lose(const std::string& reason) {
    drop_transport();
    const std::string text = options_.name + ": lost: " + reason;
    on_lost(text);
    state_.set(DeviceState::kLost, text, &callbacks_);
  }

  bool reconnect() {
    try {
      // The transport opening is not enough (a silent device keeps its port): it must answer.
      if (!reconnect_once()) {
        drop_transport();
        return false;
      }
    } catch (const std::exception&) {  // any failure is one failed attempt: try again later
      drop_transport();
      return false;
    }
    stats_.reconnects.fetch_add(1);
    seq_.resync();  // the device may have restarted its own sample counter
    state_.set(DeviceState::kAcquiring, options_.name + ": reconnected", &callbacks_);
    on_reconnected();
    return true;
  }

  void run(Worker& worker) {
    Backoff backoff(options_.backoff_initial, options_.backoff_max);
    int consecutive_timeouts = 0;
    while (!worker.stop_requested()) {
      if (!has_transport()) {
        if (!worker.sleep_for(backoff.next())) return;
        if (reconnect()) backoff.reset();
        consecutive_timeouts = 0;
        continue;
      }
      try {
        std::string detail;
        const Step step = acquire(detail);
        if (step == Step::kTimeout) {
          stats_.timeouts.fetch_add(1);
          on_timeout();
          if (++consecutive_timeouts >= options_.timeouts_until_lost) {
            lose(lost_after_timeouts(consecutive_timeouts, detail));
            consecutive_timeouts = 0;
            continue;
          }
        } else if (step == Step::kAnswered) {
          consecutive_timeouts = 0;
        }
      } catch (const std::exception& e) {
        // A DeviceError (port gone, write timeout ...) or anything unexpected: the device is
        // lost and the worker reconnects; nothing ends acquisition but stop().
        lose(e.what());
        consecutive_timeouts = 0;
        continue;
      }
      if (!pause(worker)) return;
    }
  }

  Options options_;
  mutable std::mutex identity_mutex_;
  DeviceIdentity identity_;
  Callbacks callbacks_;
  SequenceTracker seq_;
  AtomicStats stats_;
  StateCell state_;
  Worker worker_;
  bool running_ = false;
};

}  // namespace scanmesh::drivers
