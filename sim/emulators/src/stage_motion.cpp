// The stage emulators' motion model: planner queue, homing, hold, probe contact on the reference
// mesh, external trajectories (see stage_motion.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/stage_motion.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "scanmesh/common/error.hpp"

namespace scanmesh::sim {

namespace {

/// The probe tip centre in the part frame at a stage pose.
Vec3 tip_in_part(const Calibration& c, const StagePose& p) {
  return part_from_sensor(c, p) * Vec3(0, 0, 0);
}

}  // namespace

StageMotion::StageMotion(StageMotionOptions options)
    : options_(std::move(options)), rest_(options_.start), rng_(options_.probe.seed) {
  std::vector<std::string> problems = options_.limits.problems();
  if (!(options_.homing_speed_mm_s > 0)) problems.push_back("homing speed must be > 0");
  if (!(options_.probe.tip_radius_mm > 0)) problems.push_back("probe tip radius must be > 0");
  if (!(options_.probe.noise_mm >= 0)) problems.push_back("probe noise must be >= 0");
  if (!problems.empty()) {
    std::string msg = "stage motion:";
    for (const auto& p : problems) msg += " " + p + ";";
    throw ConfigError(msg);
  }
}

bool StageMotion::touching(const StagePose& p) const {
  const auto& probe = options_.probe;
  if (!probe.scene || probe.scene->bvh().triangle_count() == 0) return false;
  const auto closest = probe.scene->bvh().closest_point(tip_in_part(probe.calibration, p));
  return closest.distance <= probe.tip_radius_mm + 1e-9;
}

void StageMotion::begin(const Segment& s, Timestamp start) {
  Trajectory t(start, rest_);
  const bool probing = s.probe_id != 0;
  StageLimits limits = options_.limits;
  if (s.linear_accel_mm_s2 > 0)
    limits.linear_accel_mm_s2 = std::min(limits.linear_accel_mm_s2, s.linear_accel_mm_s2);
  t.move_to(s.to, false, limits, s.linear_mm_s, s.angular_rad_s);
  if (probing) {
    ProbeOutcome& out = probes_[s.probe_id];
    const auto& probe = options_.probe;
    if (touching(rest_)) {
      // Deflected before the move: the controller refuses to start it.
      out.kind = ProbeOutcome::Kind::kTriggeredAtStart;
      out.latched = rest_;
      out.t = start;
      free_at_ = start;
      return;
    }
    if (t.moves().empty()) {  // zero travel: nothing to probe
      out.kind = ProbeOutcome::Kind::kNoContact;
      out.latched = rest_;
      out.t = start;
      free_at_ = start;
      return;
    }
    Move m = t.moves().front();
    out.kind = ProbeOutcome::Kind::kNoContact;
    out.latched = m.to;
    out.t = m.end;
    if (!never_triggers_ && probe.scene) {
      // The table stands during a probing move, so the tip's path in the part frame is straight.
      const Vec3 a = tip_in_part(probe.calibration, m.from);
      const Vec3 b = tip_in_part(probe.calibration, m.to);
      const double length = (b - a).norm();
      Bvh::SphereHit hit;
      if (length > 0 &&
          probe.scene->bvh().sphere_cast(a, (b - a) / length, probe.tip_radius_mm, length, hit)) {
        const double t_s = m.profile.time_at(hit.t / length);
        const Timestamp t_hit = m.start + std::chrono::nanoseconds(std::llround(t_s * 1e9));
        const StagePose at = m.at(t_hit);
        m.end = t_hit;
        m.end_pose = at;
        out.kind = ProbeOutcome::Kind::kContact;
        out.t = t_hit;
        out.latched = at;
        if (probe.noise_mm > 0) {
          std::normal_distribution<double> n(0.0, probe.noise_mm);
          out.latched.x_mm += n(rng_);
          out.latched.y_mm += n(rng_);
          out.latched.z_mm += n(rng_);
        }
      }
    }
    active_ = Active{m, s};
    return;
  }
  if (t.moves().empty()) {
    free_at_ = start;
    if (s.homing) homing_ = false;
    return;
  }
  active_ = Active{t.moves().front(), s};
}

void StageMotion::advance(Timestamp now) {
  if (follow_) {
    if (now < follow_until_) return;
    rest_ = follow_(follow_until_);
    free_at_ = follow_until_;
    follow_ = nullptr;
  }
  for (;;) {
    if (held_) return;
    if (active_) {
      if (now < active_->move.end) return;
      rest_ = active_->move.end_pose;
      free_at_ = active_->move.end;
      if (active_->segment.homing) homing_ = false;
      active_.reset();
    }
    if (queue_.empty()) return;
    const Segment s = queue_.front();
    const Timestamp start = std::max(free_at_, s.queued);
    if (start > now) return;
    queue_.pop_front();
    begin(s, start);
  }
}

StagePose StageMotion::pose_locked(Timestamp now) {
  advance(now);
  if (follow_) return follow_(now);
  if (active_ && !held_) return active_->move.at(now);
  return rest_;
}

void StageMotion::queue_move(const StagePose& to, double linear_speed_mm_s,
                             double angular_speed_rad_s, Timestamp now, double linear_accel_mm_s2) {
  std::lock_guard lock(mutex_);
  advance(now);
  queue_.push_back({to, linear_speed_mm_s, angular_speed_rad_s, now, 0, false, linear_accel_mm_s2});
  advance(now);
}

std::uint64_t StageMotion::queue_probe(const StagePose& to, double speed_mm_s, Timestamp now) {
  std::lock_guard lock(mutex_);
  advance(now);
  const std::uint64_t id = next_probe_id_++;
  probes_[id] = ProbeOutcome{};
  queue_.push_back({to, speed_mm_s, Trajectory::kNoCap, now, id, false, 0});
  advance(now);
  return id;
}

ProbeOutcome StageMotion::probe_outcome(std::uint64_t id, Timestamp now) {
  std::lock_guard lock(mutex_);
  advance(now);
  const auto it = probes_.find(id);
  if (it == probes_.end()) return {ProbeOutcome::Kind::kAborted, rest_, now};
  ProbeOutcome out = it->second;
  // Known as soon as the move was planned; reported once the axes got there.
  const bool running = active_ && active_->segment.probe_id == id;
  bool queued = false;
  for (const auto& s : queue_) queued = queued || s.probe_id == id;
  if (running || queued || out.t > now) out.kind = ProbeOutcome::Kind::kPending;
  return out;
}

void StageMotion::start_homing(Timestamp now) {
  std::lock_guard lock(mutex_);
  advance(now);
  if (active_) rest_ = active_->move.at(now);
  active_.reset();
  queue_.clear();
  held_ = false;
  follow_ = nullptr;
  free_at_ = now;
  homing_ = true;
  queue_.push_back({options_.home, options_.homing_speed_mm_s, Trajectory::kNoCap, now, 0, true, 0});
  advance(now);
}

bool StageMotion::homing(Timestamp now) {
  std::lock_guard lock(mutex_);
  advance(now);
  return homing_;
}

void StageMotion::hold(Timestamp now) {
  std::lock_guard lock(mutex_);
  advance(now);
  if (held_) return;
  if (active_) {
    rest_ = active_->move.at(now);
    Segment rest = active_->segment;
    if (rest.probe_id != 0) {
      // A held probing move is re-planned from the hold point on resume.
      probes_[rest.probe_id] = ProbeOutcome{};
    }
    queue_.push_front(rest);
    active_.reset();
  }
  held_ = true;
}

void StageMotion::resume(Timestamp now) {
  std::lock_guard lock(mutex_);
  if (!held_) return;
  held_ = false;
  free_at_ = now;
  for (auto& s : queue_) s.queued = now;
  advance(now);
}

bool StageMotion::held() const {
  std::lock_guard lock(mutex_);
  return held_;
}

void StageMotion::abort(Timestamp now) {
  std::lock_guard lock(mutex_);
  advance(now);
  if (active_) rest_ = active_->move.at(now);
  if (active_ && active_->segment.probe_id != 0)
    probes_[active_->segment.probe_id] = {ProbeOutcome::Kind::kAborted, rest_, now};
  for (const auto& s : queue_)
    if (s.probe_id != 0) probes_[s.probe_id] = {ProbeOutcome::Kind::kAborted, rest_, now};
  active_.reset();
  queue_.clear();
  held_ = false;
  homing_ = false;
  if (follow_) {
    rest_ = follow_(now);
    follow_ = nullptr;
  }
  free_at_ = now;
}

StagePose StageMotion::pose(Timestamp now) {
  std::lock_guard lock(mutex_);
  return pose_locked(now);
}

std::size_t StageMotion::planned(Timestamp now) {
  std::lock_guard lock(mutex_);
  advance(now);
  return queue_.size() + (active_ ? 1 : 0);
}

bool StageMotion::moving(Timestamp now) {
  std::lock_guard lock(mutex_);
  advance(now);
  if (follow_) return true;
  if (held_) return false;
  return active_.has_value() || !queue_.empty();
}

double StageMotion::speed_mm_s(Timestamp now) {
  std::lock_guard lock(mutex_);
  advance(now);
  if (!active_ || held_) return 0;
  const Move& m = active_->move;
  const double dx = m.to.x_mm - m.from.x_mm, dy = m.to.y_mm - m.from.y_mm,
               dz = m.to.z_mm - m.from.z_mm;
  const double length = std::sqrt(dx * dx + dy * dy + dz * dz);
  return length * m.profile.velocity(static_cast<double>((now - m.start).count()) * 1e-9);
}

bool StageMotion::probe_touching(Timestamp now) {
  std::lock_guard lock(mutex_);
  return touching(pose_locked(now));
}

void StageMotion::follow(std::function<StagePose(Timestamp)> path, Timestamp until) {
  std::lock_guard lock(mutex_);
  active_.reset();
  queue_.clear();
  held_ = false;
  homing_ = false;
  follow_ = std::move(path);
  follow_until_ = until;
}

void StageMotion::set_probe_never_triggers(bool on) {
  std::lock_guard lock(mutex_);
  never_triggers_ = on;
}

}  // namespace scanmesh::sim
