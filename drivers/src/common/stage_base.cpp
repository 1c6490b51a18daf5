// StageBase: status, reports, wait_idle and the command queue shared by the stage drivers (see
// common/stage_base.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/common/stage_base.hpp"

#include <utility>

#include "scanmesh/common/error.hpp"

namespace scanmesh::drivers {

std::string_view to_string(StageAxis axis) {
  switch (axis) {
    case StageAxis::kX:
      return "x";
    case StageAxis::kY:
      return "y";
    case StageAxis::kZ:
      return "z";
    case StageAxis::kA:
      return "a";
  }
  return "?";
}

StageBase::StageBase(StageOptions options) : DeviceLifecycle(std::move(options)) {}

void StageBase::check_stage_options() const {
  const StageOptions& o = options();
  std::string problems;
  auto problem = [&](const std::string& p) { problems += (problems.empty() ? "" : "; ") + p; };
  if (o.timeout < std::chrono::milliseconds(1) || o.timeout > std::chrono::seconds(60))
    problem("timeout must be 1 ms .. 60 s");
  if (o.poll_interval < std::chrono::milliseconds(1) || o.poll_interval > std::chrono::seconds(10))
    problem("poll interval must be 1 ms .. 10 s");
  if (o.timeouts_until_lost < 1) problem("timeouts_until_lost must be >= 1");
  if (o.backoff_initial.count() < 1 || o.backoff_max < o.backoff_initial)
    problem("backoff must be >= 1 ms with maximum >= initial");
  if (o.homing_timeout < std::chrono::seconds(1)) problem("homing timeout must be >= 1 s");
  if (!problems.empty()) throw ConfigError(o.name + ": " + problems);
}

StageStatusReport StageBase::status() const {
  std::lock_guard lock(mutex_);
  StageStatusReport r = report_;
  if (state() == DeviceState::kLost || state() == DeviceState::kClosed)
    r.status = StageStatus::kLost;
  return r;
}

StageStatusReport StageBase::wait_idle(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  const std::uint64_t seq0 = report_.seq;
  changed_.wait_for(lock, timeout, [&] {
    if (state() == DeviceState::kLost || state() == DeviceState::kClosed) return true;
    return report_.seq > seq0 &&
           (report_.status == StageStatus::kIdle || report_.status == StageStatus::kAlarm);
  });
  lock.unlock();
  return status();
}

void StageBase::publish(const StagePose& pose, StageStatus status, Timestamp t_host,
                        std::optional<Timestamp> t_device) {
  StageSample s;
  s.pose = pose;
  s.t = t_host;
  s.t_device = t_device;
  s.status = status;
  {
    std::lock_guard lock(mutex_);
    s.seq = sequence().next();
    report_.pose = pose;
    report_.t = t_host;
    report_.seq = s.seq + 1;  // reports so far: 0 means none yet
    report_.has_report = true;
    report_.status = status;
    if (status != StageStatus::kAlarm) {
      report_.alarm_code = 0;
      report_.alarm_text.clear();
    }
  }
  changed_.notify_all();
  counters().samples.fetch_add(1);
  if (callbacks().on_sample) callbacks().on_sample(s);
}

void StageBase::set_status(StageStatus status) {
  {
    std::lock_guard lock(mutex_);
    report_.status = status;
  }
  changed_.notify_all();
}

void StageBase::publish_probe(ProbeTrigger& trigger) {
  {
    std::lock_guard lock(mutex_);
    trigger.seq = probe_seq_++;
  }
  if (callbacks().on_probe) callbacks().on_probe(trigger);
}

void StageBase::set_alarm(int code, std::string text) {
  {
    std::lock_guard lock(mutex_);
    report_.status = StageStatus::kAlarm;
    report_.alarm_code = code;
    report_.alarm_text = std::move(text);
  }
  changed_.notify_all();
}

void StageBase::clear_alarm_state() {
  {
    std::lock_guard lock(mutex_);
    report_.alarm_code = 0;
    report_.alarm_text.clear();
    if (report_.status == StageStatus::kAlarm) report_.status = StageStatus::kIdle;
  }
  changed_.notify_all();
}

void StageBase::forget_reports() {
  std::lock_guard lock(mutex_);
  report_.has_report = false;
  report_.status = StageStatus::kIdle;
  report_.alarm_code = 0;
  report_.alarm_text.clear();
}

void StageBase::post(const std::string& operation, std::function<void()> job) {
  if (!running())
    throw DeviceError(DeviceErrorKind::kProtocol, name(), operation, "start() first");
  {
    std::lock_guard lock(mutex_);
    if (state() == DeviceState::kLost)
      throw DeviceError(DeviceErrorKind::kDisconnected, name(), operation,
                        loss_.empty() ? "lost" : loss_);
    jobs_.push_back(std::move(job));
  }
  wake_worker();
}

void StageBase::run_jobs() {
  for (;;) {
    std::function<void()> job;
    {
      std::lock_guard lock(mutex_);
      if (jobs_.empty()) return;
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    job();
  }
}

bool StageBase::has_jobs() const {
  std::lock_guard lock(mutex_);
  return !jobs_.empty();
}

void StageBase::drop_jobs() noexcept {
  std::deque<std::function<void()>> dropped;
  {
    std::lock_guard lock(mutex_);
    dropped.swap(jobs_);
  }
  // Destroying the jobs destroys their promises: the waiting callers see broken promises.
}

void StageBase::on_lost(const std::string& reason) {
  {
    std::lock_guard lock(mutex_);
    loss_ = reason;
  }
  drop_jobs();
  changed_.notify_all();
}

void StageBase::on_stopped() noexcept {
  {
    std::lock_guard lock(mutex_);
    if (loss_.empty()) loss_ = name() + ": stopped";
  }
  drop_jobs();
  changed_.notify_all();
}

std::string StageBase::loss_text() const {
  std::lock_guard lock(mutex_);
  return loss_.empty() ? "lost" : loss_;
}

}  // namespace scanmesh::drivers
