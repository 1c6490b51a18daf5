// SensorLifecycle: the transport-independent device lifecycle of every DisplacementSensor driver:
// state, statistics, callbacks, the worker thread, lost / reconnect with bounded backoff through
// the driver's transport factory, and the counting of timeouts in a row.
// SPDX-License-Identifier: MIT
//
// A driver owns its transport (ByteStream, RegisterBus) and adds it through hooks: open the
// device (open_device), make a fresh transport answer again (reconnect_once), acquire once on
// the worker (acquire), drop the transport (drop_transport).
//
// Worker loop (drivers/README.md "How a device behaves"): acquire() until stop; a timeout is
// counted (stats().timeouts) and after options().timeouts_until_lost of them in a row, or when
// the transport throws, the device is lost: the transport is dropped, the state becomes kLost
// with the reason, and the worker calls reconnect_once() after each backoff delay
// (backoff_initial, doubled up to backoff_max) until the device answers again.
// Threading: open/close/start/stop from the owner's thread; the hooks run on that thread during
// open()/start() and on the worker thread while running, never concurrently.
#pragma once

#include <mutex>
#include <string>

#include "scanmesh/drivers/device_support.hpp"
#include "scanmesh/drivers/displacement_sensor.hpp"

namespace scanmesh::drivers {

/// One behaviour for every driver on this base:
/// - open() while acquiring does nothing; start() before open() throws DeviceError kProtocol
///   "open() first"; start() after a loss (no transport) begins by reconnecting (state kLost);
///   stop() leaves kOpen with a transport, kLost without one;
/// - any exception from the hooks during acquisition is a loss "<name>: lost: <reason>", and a
///   failed reconnect attempt is retried after the backoff: nothing but stop() ends the worker;
/// - the device's own sample counter is forgotten after a reconnect (SequenceTracker::resync()).
class SensorLifecycle : public DisplacementSensor {
 public:
  /// A subclass must call close() in its own destructor: the worker calls its hooks, which must
  /// not outlive the subclass's members.
  ~SensorLifecycle() override = default;

  const std::string& name() const override { return options_.name; }
  /// Opens the device through open_device(); state kOpen.
  void open() override;
  void close() noexcept override;
  void start(SensorCallbacks callbacks) override;
  void stop() noexcept override;

  DeviceIdentity identify() const override;
  DeviceState state() const override { return state_.get(); }
  DeviceStats stats() const override { return stats_.snapshot(); }

 protected:
  /// What one acquire() brought.
  enum class Step {
    kAnswered,  ///< the device answered (a sample, an error reply ...): timeouts in a row end
    kTimeout,   ///< nothing within the timeout: counted
  };

  /// counter_bits: width of the device's sample counter (SequenceTracker), 0 = none.
  SensorLifecycle(SensorOptions options, int counter_bits = 0);

  const SensorOptions& options() const { return options_; }
  AtomicStats& counters() { return stats_; }
  SequenceTracker& sequence() { return seq_; }
  /// Stores what the device says it is (identify() may be called from any thread).
  void set_identity(DeviceIdentity identity);
  /// Counts the sample and hands it to the callback (seq already assigned by the driver).
  void deliver(const SensorSample& sample);

  // ---- transport hooks ----
  /// Creates the transport through the factory and makes the device answer once; throws
  /// DeviceError naming the device, the port, the operation and the device's own words. The
  /// transport is dropped when it throws.
  virtual void open_device() = 0;
  /// Worker, after a loss: creates the transport again and makes the device answer; false (or a
  /// throw) when it does not answer yet (the transport is then dropped).
  virtual bool reconnect_once() = 0;
  /// Worker: one acquisition step (a poll, or one read of a stream). A throw is a loss.
  /// timeout_detail: what timed out, handed to lost_after_timeouts().
  virtual Step acquire(std::string& timeout_detail) = 0;
  /// Releases the transport (also from the destructor: must not call other hooks).
  virtual void drop_transport() noexcept = 0;
  virtual bool has_transport() const = 0;
  /// Loss reason after `count` timeouts in a row (detail: the last acquire()'s).
  virtual std::string lost_after_timeouts(int count, const std::string& detail) const = 0;
  /// In start(), before the worker runs.
  virtual void on_start() {}
  /// Worker, right after a timeout was counted.
  virtual void on_timeout() {}
  /// Worker, after a reconnect was reported.
  virtual void on_reconnected() {}
  /// Worker, between two acquisition steps that did not lose the device; false when stop was
  /// requested meanwhile.
  virtual bool pause(Worker&) { return true; }

 private:
  void run(Worker& worker);
  void lose(const std::string& reason);
  bool reconnect();
  /// Rethrows what the rules do not treat as a loss.

  SensorOptions options_;
  mutable std::mutex identity_mutex_;
  DeviceIdentity identity_;
  SensorCallbacks callbacks_;
  SequenceTracker seq_;
  AtomicStats stats_;
  StateCell state_;
  Worker worker_;
  bool running_ = false;
};

}  // namespace scanmesh::drivers
