// StageBase: what every MotionStage driver shares on top of the device lifecycle
// (common/device_lifecycle.hpp): the latest status and position, numbered position reports and
// probe triggers to the callbacks, wait_idle(), and the command queue that runs callers'
// commands on the worker thread, which alone owns the transport.
// SPDX-License-Identifier: MIT
//
// A driver implements the lifecycle hooks (open_device, reconnect_once, acquire, ...) and the
// commands through call(): the caller's thread posts a job and waits (with a timeout) for the
// promise the job, or a later reply on the worker, fulfils. Jobs run at the start of the
// driver's acquire() (run_jobs()); a driver that sleeps between steps wakes for them
// (Worker::sleep_until_notified). A job dropped unrun (the device was lost) makes the caller's
// call throw DeviceError kDisconnected with the loss reason.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "scanmesh/drivers/common/device_lifecycle.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/motion_stage.hpp"

namespace scanmesh::drivers {

class StageBase : public DeviceLifecycle<MotionStage, StageCallbacks, StageOptions> {
 public:
  StageStatusReport status() const override;
  StageStatusReport wait_idle(std::chrono::milliseconds timeout) override;

 protected:
  explicit StageBase(StageOptions options);

  /// Validates the common options (throws ConfigError naming the device).
  void check_stage_options() const;

  // ---- worker side ----
  /// One position report: numbered, counted, delivered to on_sample; the status becomes
  /// `status` (an alarm keeps its code and text until set_alarm/clear_alarm_state).
  void publish(const StagePose& pose, StageStatus status, Timestamp t_host,
               std::optional<Timestamp> t_device = std::nullopt);
  /// Changes the status without a position (a command was acknowledged, homing began ...).
  void set_status(StageStatus status);
  /// A probe trigger: numbered and delivered to on_probe (trigger.seq is assigned).
  void publish_probe(ProbeTrigger& trigger);
  /// The controller's alarm (code and meaning); status kAlarm.
  void set_alarm(int code, std::string text);
  /// Forgets the alarm (after the controller cleared it).
  void clear_alarm_state();
  /// Forgets position and status (after a reconnect the stage may have moved or restarted).
  void forget_reports();

  // ---- command queue ----
  /// Posts `job` (run on the worker with a fresh promise) and waits up to `timeout` for its
  /// result. Throws DeviceError: kProtocol "start() first" when not running, kDisconnected when
  /// lost (before or while waiting), kTimeout when the promise is not fulfilled in time, or
  /// whatever the job put into the promise.
  template <class T>
  T call(const std::string& operation, std::chrono::milliseconds timeout,
         std::function<void(std::shared_ptr<std::promise<T>>)> job) {
    auto promise = std::make_shared<std::promise<T>>();
    std::future<T> future = promise->get_future();
    post(operation, [job = std::move(job), promise] { job(promise); });
    if (future.wait_for(timeout) != std::future_status::ready)
      throw DeviceError(DeviceErrorKind::kTimeout, name(), operation,
                        "no answer within " + std::to_string(timeout.count()) + " ms");
    try {
      return future.get();
    } catch (const std::future_error&) {
      throw DeviceError(DeviceErrorKind::kDisconnected, name(), operation, loss_text());
    }
  }
  /// Worker: runs the queued jobs in order.
  void run_jobs();
  /// Whether jobs are waiting (worker).
  bool has_jobs() const;
  /// Drops the queued jobs (their callers see the loss).
  void drop_jobs() noexcept;

  // ---- lifecycle hooks StageBase implements ----
  void on_lost(const std::string& reason) override;
  void on_stopped() noexcept override;

 private:
  void post(const std::string& operation, std::function<void()> job);
  std::string loss_text() const;

  mutable std::mutex mutex_;  // guards everything below
  std::condition_variable changed_;
  StageStatusReport report_;
  std::string loss_;
  std::uint64_t probe_seq_ = 0;
  std::deque<std::function<void()>> jobs_;
};

}  // namespace scanmesh::drivers
