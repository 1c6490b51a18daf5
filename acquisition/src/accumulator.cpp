// The point accumulator: pose interpolation, clock mapping, calibration, counting.
// SPDX-License-Identifier: MIT
#include "scanmesh/acquisition/accumulator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "scanmesh/common/error.hpp"

namespace scanmesh::acq {

namespace {

using std::chrono::nanoseconds;

constexpr nanoseconds kSecond = std::chrono::seconds(1);

std::string ms(nanoseconds d) { return std::to_string(static_cast<double>(d.count()) / 1e6) + " ms"; }

}  // namespace

std::vector<std::string> AccumulatorConfig::problems() const {
  std::vector<std::string> p;
  auto latency = [&](const char* name, nanoseconds v) {
    if (v < nanoseconds(0) || v > kSecond)
      p.push_back(std::string(name) + " must be in 0 .. 1000 ms (got " + ms(v) + ")");
  };
  latency("sensor_latency", sensor_latency);
  latency("stage_latency", stage_latency);
  if (max_pose_gap <= nanoseconds(0))
    p.push_back("max_pose_gap must be > 0 (got " + ms(max_pose_gap) + ")");
  if (history_horizon < nanoseconds(0))
    p.push_back("history_horizon must be >= 0 (got " + ms(history_horizon) + ")");
  if (max_hold < nanoseconds(0) || max_hold > kSecond)
    p.push_back("max_hold must be in 0 .. 1000 ms (got " + ms(max_hold) + ")");
  for (auto& s : clock.problems()) p.push_back(std::move(s));
  return p;
}

void AccumulatorConfig::validate() const {
  const auto p = problems();
  if (p.empty()) return;
  std::string msg = "invalid accumulator configuration:";
  for (const auto& s : p) msg += "\n  " + s;
  throw ConfigError(msg);
}

std::uint64_t AccumulatorStats::invalid_total() const {
  std::uint64_t n = 0;
  for (const auto v : invalid) n += v;
  return n;
}

StagePose interpolate(const StageSample& a, const StageSample& b, Timestamp t) {
  if (b.t <= a.t || t <= a.t) return a.pose;
  if (t >= b.t) return b.pose;
  const double f = static_cast<double>(t.ns - a.t.ns) / static_cast<double>(b.t.ns - a.t.ns);
  const StagePose& p = a.pose;
  const StagePose& q = b.pose;
  return StagePose{p.x_mm + (q.x_mm - p.x_mm) * f, p.y_mm + (q.y_mm - p.y_mm) * f,
                   p.z_mm + (q.z_mm - p.z_mm) * f, p.a_rad + (q.a_rad - p.a_rad) * f};
}

Accumulator::Accumulator(AccumulatorConfig config) : config_(config) { config_.validate(); }

std::uint16_t Accumulator::add_sensor(const SensorConfig& sensor, const Calibration& calibration) {
  if (sensors_.size() >= std::numeric_limits<std::uint16_t>::max())
    throw ConfigError("too many sensors in one accumulator");
  Sensor s{SensorOptics(sensor), calibration, ClockMapper(config_.clock), {}, {}, {}, 0, false};
  const Eigen::Matrix3d m = calibration.mount.linear();
  for (std::uint32_t i = 0; i < s.optics.ray_count(); ++i) s.mounted_dirs.push_back(m * s.optics.ray_dir(i));
  s.mount_origin = calibration.mount.translation();
  sensors_.push_back(std::move(s));
  return static_cast<std::uint16_t>(sensors_.size() - 1);
}

const SensorOptics& Accumulator::optics(std::uint16_t device) const {
  return sensors_.at(device).optics;
}
const Calibration& Accumulator::calibration(std::uint16_t device) const {
  return sensors_.at(device).calibration;
}

void Accumulator::add_stage(const StageSample& sample, std::vector<MeasuredPoint>& out) {
  ++stats_.stage_samples;
  if (!history_.empty() && sample.t < history_.back().t) {
    ++stats_.stage_out_of_order;
    return;
  }
  history_.push_back(sample);
  drain(out, false);
  prune_history();
}

void Accumulator::add_sensor_samples(std::uint16_t device, std::span<const SensorSample> samples,
                                     std::vector<MeasuredPoint>& out) {
  Sensor& sensor = sensors_.at(device);
  const std::uint32_t rays = sensor.optics.ray_count();
  for (const SensorSample& s : samples) {
    ++stats_.samples;
    if (sensor.last_seq && s.seq > *sensor.last_seq + 1) stats_.lost += s.seq - *sensor.last_seq - 1;
    sensor.last_seq = s.seq;
    Timestamp t = s.t_host;
    if (config_.use_device_clock && s.t_device) {
      sensor.clock.observe(*s.t_device, s.t_host);
      t = sensor.clock.to_host(*s.t_device);
    }
    if (s.status != SensorStatus::kOk) {
      ++stats_.invalid[static_cast<std::size_t>(s.status)];
      continue;
    }
    if (!std::isfinite(s.value_mm) || s.index >= rays) {
      ++stats_.invalid[static_cast<std::size_t>(SensorStatus::kOk)];
      continue;
    }
    const Timestamp query = t - config_.sensor_latency + config_.stage_latency;
    // Fast path: nothing waiting and the history already covers the instant.
    if (pending_begin_ == pending_.size() && !history_.empty() && query <= history_.back().t) {
      resolve(s, t, query, device, out);
    } else {
      pending_.push_back(Pending{s, t, query, device});
      ++stats_.pending;
    }
  }
  drain(out, false);
}

void Accumulator::add_probe(std::uint16_t device, const ProbeTrigger& trigger,
                            std::vector<MeasuredPoint>& out) {
  const Sensor& sensor = sensors_.at(device);
  const Eigen::Isometry3d x = part_from_sensor(sensor.calibration, trigger.pose);
  const Vec3 tip = x * Vec3::Zero();
  out.push_back({trigger.seq, 0, trigger.t, measured_probe_point(sensor.optics, sensor.calibration,
                                                                   trigger.pose),
                 true, device, tip});
  ++stats_.points;
  ++stats_.probe_points;
}

void Accumulator::finish(std::vector<MeasuredPoint>& out) { drain(out, true); }

void Accumulator::drain(std::vector<MeasuredPoint>& out, bool final) {
  while (pending_begin_ < pending_.size()) {
    const Pending& p = pending_[pending_begin_];
    if (!final && (history_.empty() || p.query > history_.back().t)) break;
    resolve(p.sample, p.t, p.query, p.device, out);
    ++pending_begin_;
    --stats_.pending;
  }
  if (pending_begin_ == pending_.size()) {
    pending_.clear();
    pending_begin_ = 0;
  } else if (pending_begin_ > 4096 && pending_begin_ * 2 > pending_.size()) {
    pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(pending_begin_));
    pending_begin_ = 0;
  }
}

void Accumulator::resolve(const SensorSample& s, Timestamp t, Timestamp query,
                          std::uint16_t device, std::vector<MeasuredPoint>& out) {
  if (history_.empty()) {
    ++stats_.no_pose_before;
    return;
  }
  const StageSample& first = history_.front();
  const StageSample& last = history_.back();
  if (query > last.t) {  // only when final
    if (query - last.t <= config_.max_hold) {
      emit(s, t, query, device, last.pose, out);
    } else {
      ++stats_.no_pose_after;
    }
    return;
  }
  if (query < first.t) {
    if (first.t - query <= config_.max_hold) {
      emit(s, t, query, device, first.pose, out);
    } else {
      ++stats_.no_pose_before;
    }
    return;
  }
  // Bracket: the report at or before the query, by the device's moving cursor.
  Sensor& sensor = sensors_[device];
  std::size_t c =
      sensor.cursor > history_base_ ? static_cast<std::size_t>(sensor.cursor - history_base_) : 0;
  if (c >= history_.size()) c = history_.size() - 1;
  if (history_[c].t > query) {
    const auto it = std::upper_bound(
        history_.begin(), history_.begin() + static_cast<std::ptrdiff_t>(c), query,
        [](Timestamp v, const StageSample& x) { return v < x.t; });
    c = static_cast<std::size_t>(it - history_.begin()) - 1;
  }
  while (c + 1 < history_.size() && history_[c + 1].t <= query) ++c;
  sensor.cursor = history_base_ + c;
  sensor.active = true;
  const StageSample& a = history_[c];
  if (a.t == query) {
    emit(s, t, query, device, a.pose, out);
    return;
  }
  const StageSample& b = history_[c + 1];  // exists: a.t < query <= last.t
  if (b.t - a.t > config_.max_pose_gap) {
    ++stats_.no_pose_gap;
    return;
  }
  emit(s, t, query, device, interpolate(a, b, query), out);
}

void Accumulator::emit(const SensorSample& s, Timestamp t, Timestamp query, std::uint16_t device,
                       const StagePose& pose, std::vector<MeasuredPoint>& out) {
  // part_from_sensor, unrolled: p = Rz(-a) (stage + mount * (dir * r) - c) + c.
  const Sensor& sensor = sensors_[device];
  const Vec3& c = sensor.calibration.table_center_mm;
  if (!cached_query_ || *cached_query_ != query || cached_device_ != device) {
    cached_query_ = query;
    cached_device_ = device;
    cached_base_ = Vec3(pose.x_mm, pose.y_mm, pose.z_mm) + sensor.mount_origin - c;
    if (pose.a_rad != cached_a_) {
      cached_a_ = pose.a_rad;
      cos_a_ = std::cos(pose.a_rad);
      sin_a_ = std::sin(pose.a_rad);
    }
  }
  const double r = sensor.optics.config().standoff_mm + s.value_mm;
  const Vec3 q = cached_base_ + sensor.mounted_dirs[s.index] * r;
  const Vec3 p(cos_a_ * q.x() + sin_a_ * q.y() + c.x(), -sin_a_ * q.x() + cos_a_ * q.y() + c.y(),
               q.z() + c.z());
  const Vec3& o = cached_base_;
  const Vec3 origin(cos_a_ * o.x() + sin_a_ * o.y() + c.x(), -sin_a_ * o.x() + cos_a_ * o.y() + c.y(),
                    o.z() + c.z());
  out.push_back({s.seq, s.index, t, p, false, device, origin});
  ++stats_.points;
}

void Accumulator::prune_history() {
  if (history_.size() < 8192 || config_.history_horizon == nanoseconds(0)) return;
  // Keep what an active sensor's cursor still points at, and the recent horizon for sensors
  // that have not delivered yet.
  const Timestamp horizon = history_.back().t - config_.history_horizon;
  std::size_t keep = static_cast<std::size_t>(
      std::lower_bound(history_.begin(), history_.end(), horizon,
                       [](const StageSample& s, Timestamp v) { return s.t < v; }) -
      history_.begin());
  for (const Sensor& s : sensors_) {
    if (!s.active) continue;
    const std::size_t c = s.cursor > history_base_ ? static_cast<std::size_t>(s.cursor - history_base_) : 0;
    keep = std::min(keep, c);
  }
  if (keep > 0) keep -= 1;  // one report before, for safety at exact boundaries
  if (keep * 2 < history_.size()) return;
  history_.erase(history_.begin(), history_.begin() + static_cast<std::ptrdiff_t>(keep));
  history_base_ += keep;
}

std::vector<MeasuredPoint> points_from_samples(const SensorOptics& optics,
                                               const Calibration& calibration,
                                               std::span<const StageSample> stage,
                                               std::span<const SensorSample> sensor,
                                               std::span<const ProbeTrigger> probe,
                                               AccumulatorStats* stats,
                                               const AccumulatorConfig& config) {
  AccumulatorConfig batch = config;
  batch.history_horizon = nanoseconds(0);  // the whole history is the input
  Accumulator acc(batch);
  const std::uint16_t dev = acc.add_sensor(optics.config(), calibration);
  std::vector<MeasuredPoint> out;
  out.reserve(sensor.size() + probe.size());
  for (const StageSample& s : stage) acc.add_stage(s, out);
  acc.add_sensor_samples(dev, sensor, out);
  acc.finish(out);
  for (const ProbeTrigger& g : probe) acc.add_probe(dev, g, out);
  if (stats) *stats = acc.stats();
  return out;
}

}  // namespace scanmesh::acq
