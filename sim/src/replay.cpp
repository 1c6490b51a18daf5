// Replay of a recorded stream in time order, paced by an injected clock.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/replay.hpp"

#include <chrono>
#include <cmath>
#include <limits>

#include "scanmesh/common/error.hpp"

namespace scanmesh::sim {

namespace {
constexpr std::int64_t kNever = std::numeric_limits<std::int64_t>::max();
enum Kind : int { kNone = -1, kStage = 0, kProbe = 1, kSensor = 2 };
}  // namespace

Timestamp SteadyClock::now() const {
  return Timestamp{std::chrono::duration_cast<std::chrono::nanoseconds>(
                       std::chrono::steady_clock::now().time_since_epoch())
                       .count()};
}

Replayer::Replayer(const RecordedStream& stream, const Clock& clock, ReplayOptions options)
    : stream_(&stream), clock_(&clock), options_(options) {
  if (!(options_.speed > 0) || !std::isfinite(options_.speed))
    throw ConfigError("replay speed must be > 0, got " + std::to_string(options_.speed));
  std::int64_t first = kNever;
  if (!stream.sensor.empty()) first = std::min(first, stream.sensor.front().t_host.ns);
  if (!stream.stage.empty()) first = std::min(first, stream.stage.front().t.ns);
  if (!stream.probe.empty()) first = std::min(first, stream.probe.front().t.ns);
  stream_start_ = Timestamp{first == kNever ? 0 : first};
}

void Replayer::start() {
  started_ = true;
  clock_start_ = clock_->now();
}

Timestamp Replayer::record_time(std::size_t kind) const {
  switch (kind) {
    case kStage:
      return stream_->stage[stage_pos_].t;
    case kProbe:
      return stream_->probe[probe_pos_].t;
    default:
      return stream_->sensor[sensor_pos_].t_host;
  }
}

int Replayer::next_kind() const {
  int best = kNone;
  std::int64_t best_t = kNever;
  // Equal times: stage, then probe, then sensor (the simulator's order).
  if (stage_pos_ < stream_->stage.size() && stream_->stage[stage_pos_].t.ns < best_t) {
    best = kStage;
    best_t = stream_->stage[stage_pos_].t.ns;
  }
  if (probe_pos_ < stream_->probe.size() && stream_->probe[probe_pos_].t.ns < best_t) {
    best = kProbe;
    best_t = stream_->probe[probe_pos_].t.ns;
  }
  if (sensor_pos_ < stream_->sensor.size() && stream_->sensor[sensor_pos_].t_host.ns < best_t)
    best = kSensor;
  return best;
}

std::optional<Timestamp> Replayer::next_due() const {
  const int k = next_kind();
  if (k == kNone) return std::nullopt;
  const Timestamp start = started_ ? clock_start_ : clock_->now();
  const double offset_ns =
      static_cast<double>((record_time(static_cast<std::size_t>(k)) - stream_start_).count()) /
      options_.speed;
  return Timestamp{start.ns + static_cast<std::int64_t>(std::ceil(offset_ns))};
}

bool Replayer::done() const { return next_kind() == kNone; }

std::size_t Replayer::deliver_next(SampleSink& sink) {
  const int k = next_kind();
  if (k == kNone) return 0;
  // Rebased timestamps are the due times on the replay clock.
  auto rebase = [&](Timestamp t) {
    if (!options_.rebase_timestamps) return t;
    const double offset_ns = static_cast<double>((t - stream_start_).count()) / options_.speed;
    return Timestamp{clock_start_.ns + static_cast<std::int64_t>(std::ceil(offset_ns))};
  };
  if (k == kStage) {
    StageSample s = stream_->stage[stage_pos_++];
    s.t = rebase(s.t);
    sink.on_stage(s);
  } else if (k == kProbe) {
    ProbeTrigger g = stream_->probe[probe_pos_++];
    g.t = rebase(g.t);
    sink.on_probe(g);
  } else {
    const auto& s = stream_->sensor;
    std::size_t end = sensor_pos_ + 1;
    while (end < s.size() && s[end].seq == s[sensor_pos_].seq) ++end;
    buffer_.assign(s.begin() + static_cast<std::ptrdiff_t>(sensor_pos_),
                   s.begin() + static_cast<std::ptrdiff_t>(end));
    for (SensorSample& x : buffer_) x.t_host = rebase(x.t_host);
    sensor_pos_ = end;
    sink.on_sensor(buffer_);
  }
  return 1;
}

std::size_t Replayer::poll(SampleSink& sink) {
  if (!started_) start();
  const Timestamp now = clock_->now();
  std::size_t n = 0;
  for (;;) {
    const auto due = next_due();
    if (!due || *due > now) break;
    n += deliver_next(sink);
  }
  return n;
}

std::size_t Replayer::run_all(SampleSink& sink) {
  if (!started_) start();
  std::size_t n = 0;
  while (!done()) n += deliver_next(sink);
  return n;
}

}  // namespace scanmesh::sim
