// The simulation loop: stage and sensor clocks ticking over a planned trajectory, ray casting
// with triangulation shadowing, seeded imperfections, and the touch probe's sphere casts.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/simulator.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <functional>
#include <limits>
#include <mutex>
#include <numbers>
#include <string>
#include <thread>

#include "scanmesh/common/error.hpp"
#include "scanmesh/sim/rng.hpp"

namespace scanmesh::sim {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::int64_t kNever = std::numeric_limits<std::int64_t>::max();

// One random stream per imperfection (substream ids are part of the determinism contract:
// changing them changes every simulated scan).
enum Stream : std::uint64_t {
  kRangeNoise = 1,
  kDropout = 2,
  kSpike = 3,
  kMissing = 4,
  kStageNoiseLinear = 5,
  kStageNoiseAngle = 6,
  kProbeNoise = 7,
};

bool probability(double p) { return p >= 0 && p <= 1; }

/// Standard normals from one Rng, both Box-Muller branches (cosine first, then sine), so one
/// log and two uniforms serve two samples.
class GaussianStream {
 public:
  explicit GaussianStream(std::uint64_t seed) : rng_(seed) {}
  double next() {
    if (have_) {
      have_ = false;
      return spare_;
    }
    const double r = std::sqrt(-2.0 * std::log(rng_.uniform_open_low()));
    const double a = 2.0 * std::numbers::pi * rng_.uniform();
    spare_ = r * std::sin(a);
    have_ = true;
    return r * std::cos(a);
  }

 private:
  Rng rng_;
  double spare_ = 0;
  bool have_ = false;
};

}  // namespace

std::vector<std::string> ImperfectionConfig::problems() const {
  std::vector<std::string> out;
  auto nonneg = [&](double v, const char* name) {
    if (!(std::isfinite(v) && v >= 0))
      out.push_back(std::string("imperfection ") + name + " must be >= 0, got " +
                    std::to_string(v));
  };
  nonneg(range_noise_mm, "range_noise_mm");
  nonneg(stage_noise_mm, "stage_noise_mm");
  nonneg(stage_noise_rad, "stage_noise_rad");
  if (!probability(dropout_probability))
    out.push_back("imperfection dropout_probability must be in [0, 1], got " +
                  std::to_string(dropout_probability));
  if (!probability(spike_probability))
    out.push_back("imperfection spike_probability must be in [0, 1], got " +
                  std::to_string(spike_probability));
  if (!(missing_probability >= 0 && missing_probability < 1))
    out.push_back("imperfection missing_probability must be in [0, 1), got " +
                  std::to_string(missing_probability));
  const std::chrono::nanoseconds max_latency = std::chrono::seconds(1);
  if (sensor_latency.count() < 0 || sensor_latency > max_latency)
    out.push_back("imperfection sensor_latency must be in [0, 1 s]");
  if (stage_latency.count() < 0 || stage_latency > max_latency)
    out.push_back("imperfection stage_latency must be in [0, 1 s]");
  return out;
}

void SimConfig::validate() const {
  std::vector<std::string> p = sensor.problems();
  for (auto& s : path.problems()) p.push_back(std::move(s));
  for (auto& s : imperfections.problems()) p.push_back(std::move(s));
  if (!(std::isfinite(stage_rate_hz) && stage_rate_hz >= 0 && stage_rate_hz <= 1e8))
    p.push_back("stage_rate_hz must be in [0, 1e8] (0: the sensor rate), got " +
                std::to_string(stage_rate_hz));
  if (p.empty()) return;
  std::string msg = "invalid simulation configuration:";
  for (const auto& s : p) msg += "\n  " + s;
  throw ConfigError(msg);
}

Scene::Scene(recon::Mesh mesh) : mesh_(std::move(mesh)), bvh_(mesh_) {
  if (bvh_.triangle_count() == 0)
    throw ConfigError("the scene mesh has no (non-degenerate) triangles");
}

namespace {

std::int64_t period_ns(double rate_hz) {
  return std::max<std::int64_t>(1, std::llround(1e9 / rate_hz));
}

}  // namespace

RayTracer::RayTracer(const Scene& scene, const SensorConfig& sensor)
    : scene_(&scene), standoff_mm_(sensor.standoff_mm), range_mm_(sensor.range_mm) {
  // Shadow rays start this far off the lit surface (far above rounding, far below any feature).
  const Vec3 lo = scene.lo(), hi = scene.hi();
  shadow_offset_mm_ =
      1e-9 * ((hi - lo).norm() + std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff()));
  cos_max_incidence_ = std::cos(sensor.max_incidence_rad);
}

RayHit RayTracer::trace_at(const SensorOptics& optics, const Calibration& calibration,
                           const StagePose& pose, std::uint32_t index) const {
  const Eigen::Isometry3d x = part_from_sensor(calibration, pose);
  const Vec3 emitter = x.translation();
  RayHit hit;
  trace(emitter, x * optics.receiver(), x.linear() * optics.ray_dir(index), hit);
  return hit;
}

void RayTracer::trace(const Vec3& emitter, const Vec3& receiver, const Vec3& dir,
                      RayHit& out) const {
  const Bvh& bvh = scene_->bvh();
  out.shadow_ray = false;
  Bvh::Hit hit;
  // Beyond a full range past the far end nothing returns at all.
  if (!bvh.intersect(emitter, dir, 0.0, standoff_mm_ + 2 * range_mm_, hit)) {
    out.cause = SampleCause::kNoHit;
    return;
  }
  out.t = hit.t;
  out.point = emitter + dir * hit.t;
  const Vec3& n = bvh.normal(hit.triangle);
  const double cos_in = n.dot(dir);
  if (std::abs(cos_in) < cos_max_incidence_) {
    out.cause = SampleCause::kGrazing;
    return;
  }
  if (hit.t < standoff_mm_ || hit.t > standoff_mm_ + range_mm_) {
    out.cause = SampleCause::kOutOfRange;
    return;
  }
  // Triangulation: the receiver must see the lit spot, from the lit side of the surface.
  const Vec3 facing = cos_in < 0 ? n : Vec3(-n);
  const Vec3 to_r = receiver - out.point;
  const double dist = to_r.norm();
  out.shadow_ray = facing.dot(to_r) > 0;
  if (!out.shadow_ray ||
      bvh.occluded(out.point + facing * shadow_offset_mm_, to_r / dist, 0.0, dist)) {
    out.cause = SampleCause::kShadowed;
    return;
  }
  out.cause = SampleCause::kOk;
}

Simulator::Simulator(const Scene& scene, SimConfig config)
    : scene_(&scene),
      config_((config.validate(), std::move(config))),
      optics_(config_.sensor),
      plan_(plan_scan(config_.path, config_.sensor, scene.lo(), scene.hi())),
      tracer_(scene, optics_.config()) {
  if (config_.sensor.kind != SensorKind::kProbe) return;
  // Touch probe: approach each point until contact, latch, back off, go to the next.
  const Bvh& bvh = scene_->bvh();
  const StageLimits& lim = config_.path.limits;
  Trajectory& traj = plan_.trajectory;
  const double r = config_.sensor.tip_radius_mm;
  bool first = true;
  for (const ProbeApproach& ap : plan_.approaches) {
    if (!first) traj.move_to(ap.start, false, lim);
    first = false;
    const Vec3 d = ap.direction;
    const StagePose end{ap.start.x_mm + d.x() * ap.travel_mm, ap.start.y_mm + d.y() * ap.travel_mm,
                        ap.start.z_mm + d.z() * ap.travel_mm, ap.start.a_rad};
    traj.move_to(end, true, lim, config_.sensor.probe_speed_mm_s);
    // Tip centre in the part frame at the approach start.
    const Eigen::Isometry3d x = part_from_sensor(plan_.calibration, ap.start);
    const Vec3 c = x.translation();
    const Vec3 dir_p = x.linear() * optics_.ray_dir(0);
    Bvh::SphereHit hit;
    if (bvh.sphere_cast(c, dir_p, r, ap.travel_mm, hit)) {
      const Move& m = traj.moves().back();
      const double tau = m.profile.time_at(hit.t / ap.travel_mm);
      const Timestamp t = m.start + std::chrono::nanoseconds(std::llround(tau * 1e9));
      traj.cut_last(t);
      probe_triggers_.push_back({t, hit.contact});
    }
    traj.move_to(ap.start, false, lim);
  }
}

double Simulator::stage_rate_hz() const {
  return config_.stage_rate_hz > 0 ? config_.stage_rate_hz : config_.sensor.rate_hz;
}

/// One sensor measurement's geometry: when, where the stage was, and the emitter and receiver
/// in the part frame.
struct Simulator::Tick {
  Timestamp t;
  StagePose pose;                                     ///< true stage pose at t
  Eigen::Matrix3d rot = Eigen::Matrix3d::Identity();  ///< sensor -> part rotation
  Vec3 emitter = Vec3::Zero();
  Vec3 receiver = Vec3::Zero();
};



namespace {

/// Background workers that each run the current job once per start(); wait() blocks until all
/// of them have returned from it. The caller usually runs the same job meanwhile (the jobs share
/// their work through an atomic counter), so one thread means no workers at all.
class WorkerPool {
 public:
  explicit WorkerPool(unsigned threads) {
    for (unsigned w = 1; w < threads; ++w) workers_.emplace_back([this] { loop(); });
  }
  ~WorkerPool() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    start_.notify_all();
    for (auto& t : workers_) t.join();
  }
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  void start(std::function<void()> job) {
    if (workers_.empty()) return;
    {
      std::lock_guard lock(mutex_);
      job_ = std::move(job);
      pending_ = static_cast<unsigned>(workers_.size());
      ++generation_;
    }
    start_.notify_all();
  }
  void wait() {
    std::unique_lock lock(mutex_);
    done_.wait(lock, [this] { return pending_ == 0; });
  }

 private:
  void loop() {
    std::uint64_t seen = 0;
    for (;;) {
      std::function<void()> job;
      {
        std::unique_lock lock(mutex_);
        start_.wait(lock, [&] { return stop_ || generation_ != seen; });
        if (stop_) return;
        seen = generation_;
        job = job_;
      }
      job();  // geometry only: no allocation, no I/O, nothing that throws
      {
        std::lock_guard lock(mutex_);
        if (--pending_ == 0) done_.notify_all();
      }
    }
  }

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable start_;
  std::condition_variable done_;
  std::function<void()> job_;
  unsigned pending_ = 0;
  std::uint64_t generation_ = 0;
  bool stop_ = false;
};

/// Rays per geometry batch, and per chunk of work handed to one thread at a time.
constexpr std::size_t kBatchRays = 16384;
constexpr std::size_t kChunkRays = 512;

}  // namespace

/// A batch of sensor ticks and their ray results. Filled with tick times by the emitting thread,
/// then traced (poses, transforms, rays) in chunks by every thread.
struct Simulator::Batch {
  std::vector<Tick> ticks;
  std::vector<RayHit> results;
  std::size_t chunk_ticks = 1;
  std::atomic<std::size_t> next_chunk{0};

  std::size_t chunks() const { return (ticks.size() + chunk_ticks - 1) / chunk_ticks; }
};

void Simulator::trace_chunks(Batch& batch) const {
  const Trajectory& traj = plan_.trajectory;
  const Calibration& cal = plan_.calibration;
  const std::uint32_t rays = optics_.ray_count();
  const std::size_t n = batch.chunks();
  double cached_a = std::numeric_limits<double>::quiet_NaN();
  Eigen::Matrix3d table_r = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d rot = Eigen::Matrix3d::Identity();
  for (;;) {
    const std::size_t c = batch.next_chunk.fetch_add(1, std::memory_order_relaxed);
    if (c >= n) return;
    const std::size_t first = c * batch.chunk_ticks;
    const std::size_t last = std::min(batch.ticks.size(), first + batch.chunk_ticks);
    // The move of the chunk's first tick by binary search, then a cursor (times grow).
    const auto& moves = traj.moves();
    std::size_t m = static_cast<std::size_t>(
        std::upper_bound(moves.begin(), moves.end(), batch.ticks[first].t,
                         [](Timestamp t, const Move& mv) { return t < mv.start; }) -
        moves.begin());
    m = m > 0 ? m - 1 : 0;
    for (std::size_t k = first; k < last; ++k) {
      Tick& tk = batch.ticks[k];
      while (m + 1 < moves.size() && moves[m + 1].start <= tk.t) ++m;
      tk.pose = moves[m].at(tk.t);  // sensor ticks lie inside sensing moves
      // The table angle changes rarely (raster: never): keep its rotation.
      if (tk.pose.a_rad != cached_a) {
        cached_a = tk.pose.a_rad;
        table_r = Eigen::AngleAxisd(-tk.pose.a_rad, Vec3::UnitZ()).toRotationMatrix();
        rot = table_r * cal.mount.linear();
      }
      tk.rot = rot;
      tk.emitter = table_r * (Vec3(tk.pose.x_mm, tk.pose.y_mm, tk.pose.z_mm) +
                              cal.mount.translation() - cal.table_center_mm) +
                   cal.table_center_mm;
      tk.receiver = tk.emitter + rot * optics_.receiver();
      for (std::uint32_t i = 0; i < rays; ++i)
        tracer_.trace(tk.emitter, tk.receiver, tk.rot * optics_.ray_dir(i), batch.results[k * rays + i]);
    }
  }
}

SimStats Simulator::run(SampleSink& out, TruthSink* truth_sink) const {
  const ImperfectionConfig& imp = config_.imperfections;
  const Trajectory& traj = plan_.trajectory;
  const auto& moves = traj.moves();
  const SensorConfig& sc = optics_.config();

  GaussianStream noise_rng(substream_seed(imp.seed, kRangeNoise));
  Rng dropout_rng(substream_seed(imp.seed, kDropout));
  Rng spike_rng(substream_seed(imp.seed, kSpike));
  Rng missing_rng(substream_seed(imp.seed, kMissing));
  Rng stage_lin_rng(substream_seed(imp.seed, kStageNoiseLinear));
  Rng stage_ang_rng(substream_seed(imp.seed, kStageNoiseAngle));
  Rng probe_rng(substream_seed(imp.seed, kProbeNoise));

  SimStats stats;
  stats.start = traj.start();
  stats.end = traj.end();

  const std::int64_t sensor_period = period_ns(sc.rate_hz);
  const std::int64_t stage_period = period_ns(stage_rate_hz());
  const Timestamp t0 = traj.start();
  const Timestamp t_end = traj.end();
  const bool probe = sc.kind == SensorKind::kProbe;
  const std::uint32_t rays = optics_.ray_count();

  unsigned threads = config_.threads > 0 ? config_.threads : std::thread::hardware_concurrency();
  threads = std::clamp(threads, 1u, 64u);
  if (probe) threads = 1;
  WorkerPool pool(threads);

  // Pose lookup with a cursor for the stage clock (its times only grow).
  std::size_t cursor = 0;
  auto move_at = [&](std::size_t& c, Timestamp t) {
    while (c + 1 < moves.size() && moves[c + 1].start <= t) ++c;
    return c;
  };
  auto pose_at = [&](Timestamp t) {
    if (moves.empty() || t < t0) return traj.pose_at(t);
    return moves[move_at(cursor, t)].at(t);
  };
  // Sensor ticks k at t0 + k * period, skipping those outside sensing moves.
  std::size_t tick_cursor = 0;
  auto next_sensing_tick = [&](std::int64_t k) -> std::int64_t {
    for (;;) {
      const Timestamp ts{t0.ns + k * sensor_period};
      if (moves.empty() || ts > t_end) return -1;
      std::size_t i = move_at(tick_cursor, ts);
      if (moves[i].sensing && ts < moves[i].end) return k;
      while (i < moves.size() && !(moves[i].sensing && moves[i].end > ts)) ++i;
      if (i == moves.size()) return -1;
      const std::int64_t from = std::max(moves[i].start.ns, ts.ns + 1) - t0.ns;
      k = (from + sensor_period - 1) / sensor_period;
    }
  };

  // Two batches: the one being emitted and the next one being traced meanwhile.
  const std::size_t batch_ticks = std::max<std::size_t>(1, kBatchRays / rays);
  Batch batches[2];
  for (Batch& b : batches) {
    b.ticks.reserve(batch_ticks);
    b.results.resize(batch_ticks * rays);
    b.chunk_ticks = std::max<std::size_t>(1, kChunkRays / rays);
  }
  std::int64_t next_k = probe ? -1 : next_sensing_tick(0);
  auto fill_times = [&](Batch& b) {
    b.ticks.clear();
    b.next_chunk.store(0, std::memory_order_relaxed);
    while (b.ticks.size() < batch_ticks && next_k >= 0) {
      Tick tk;
      tk.t = Timestamp{t0.ns + next_k * sensor_period};
      b.ticks.push_back(tk);
      next_k = next_sensing_tick(next_k + 1);
    }
    stats.rays += b.ticks.size() * rays;
  };
  auto launch = [&](Batch& b) { pool.start([this, &b] { trace_chunks(b); }); };
  auto finish = [&](Batch& b) {
    trace_chunks(b);  // help, then wait for the workers' last chunks
    pool.wait();
  };
  Batch* cur = &batches[0];
  Batch* nxt = &batches[1];
  fill_times(*cur);
  launch(*cur);
  finish(*cur);
  fill_times(*nxt);
  if (!nxt->ticks.empty()) launch(*nxt);
  std::size_t tick_pos = 0;

  std::vector<SensorSample> samples(rays);
  std::vector<SampleTruth> truths(rays);
  std::uint64_t sensor_seq = 0, stage_seq = 0, probe_seq = 0;
  std::size_t next_trigger = 0;
  std::int64_t kp = 0;
  for (;;) {
    if (tick_pos == cur->ticks.size() && !nxt->ticks.empty()) {
      finish(*nxt);
      std::swap(cur, nxt);
      tick_pos = 0;
      fill_times(*nxt);
      if (!nxt->ticks.empty()) launch(*nxt);
    }
    const bool sensor_due = tick_pos < cur->ticks.size();
    const Timestamp ts = sensor_due ? cur->ticks[tick_pos].t : Timestamp{kNever};
    const Timestamp tp{t0.ns + kp * stage_period};
    const bool stage_due = tp <= t_end;
    const bool trigger_due = next_trigger < probe_triggers_.size();
    if (!sensor_due && !stage_due && !trigger_due) break;
    // Order: stage, then probe trigger, then sensor at equal times.
    const Timestamp tt = trigger_due ? probe_triggers_[next_trigger].t : Timestamp{kNever};
    if (stage_due && tp <= tt && tp <= ts) {
      // On a synchronous clock the pose was computed with the sensor tick.
      const StagePose p = tp == ts ? cur->ticks[tick_pos].pose : pose_at(tp);
      StageSample s;
      s.seq = stage_seq++;
      s.t = tp + imp.stage_latency;
      s.pose = p;
      if (imp.stage_noise_mm > 0) {
        s.pose.x_mm += imp.stage_noise_mm * stage_lin_rng.gaussian();
        s.pose.y_mm += imp.stage_noise_mm * stage_lin_rng.gaussian();
        s.pose.z_mm += imp.stage_noise_mm * stage_lin_rng.gaussian();
      }
      if (imp.stage_noise_rad > 0) s.pose.a_rad += imp.stage_noise_rad * stage_ang_rng.gaussian();
      out.on_stage(s);
      ++stats.stage_samples;
      ++kp;
      continue;
    }
    if (trigger_due && tt <= ts) {
      const Contact& tr = probe_triggers_[next_trigger++];
      const StagePose p = pose_at(tr.t);
      ProbeTrigger g;
      g.seq = probe_seq++;
      g.t = tr.t + imp.stage_latency;
      g.pose = p;
      if (imp.stage_noise_mm > 0) {
        g.pose.x_mm += imp.stage_noise_mm * probe_rng.gaussian();
        g.pose.y_mm += imp.stage_noise_mm * probe_rng.gaussian();
        g.pose.z_mm += imp.stage_noise_mm * probe_rng.gaussian();
      }
      out.on_probe(g);
      ++stats.measurements;
      ++stats.samples;
      ++stats.causes[static_cast<std::size_t>(SampleCause::kOk)];
      if (truth_sink) {
        const SampleTruth t{tr.t, SampleCause::kOk, tr.contact, 0.0};
        truth_sink->on_truth(std::span<const SampleTruth>(&t, 1));
      }
      continue;
    }
    // Sensor measurement.
    const Tick& tick = cur->ticks[tick_pos];
    const RayHit* res = cur->results.data() + tick_pos * rays;
    ++tick_pos;
    const std::uint64_t seq = sensor_seq++;
    // Every stream draws for every measurement, lost or not, so the streams stay aligned.
    const bool lost =
        imp.missing_probability > 0 && missing_rng.uniform() < imp.missing_probability;
    const Timestamp t_host = tick.t + imp.sensor_latency;
    std::optional<Timestamp> t_dev;
    if (imp.device_clock_offset) t_dev = tick.t + *imp.device_clock_offset;
    for (std::uint32_t i = 0; i < rays; ++i) {
      const double g = imp.range_noise_mm > 0 ? noise_rng.next() : 0.0;
      const double u_drop = imp.dropout_probability > 0 ? dropout_rng.uniform() : 1.0;
      const double u_spike = imp.spike_probability > 0 ? spike_rng.uniform() : 1.0;
      if (lost) continue;
      const RayHit& r = res[i];
      stats.rays += r.shadow_ray ? 1 : 0;
      SensorSample& s = samples[i];
      SampleTruth& tr = truths[i];
      s.seq = seq;
      s.t_device = t_dev;
      s.t_host = t_host;
      s.index = i;
      s.value_mm = kNaN;
      s.status = SensorStatus::kNoTarget;
      tr.t_true = tick.t;
      tr.cause = r.cause;
      const bool hit = r.cause != SampleCause::kNoHit;
      tr.surface_point_mm = hit ? r.point : Vec3::Constant(kNaN);
      tr.true_value_mm = hit ? r.t - sc.standoff_mm : kNaN;
      if (r.cause == SampleCause::kOutOfRange) s.status = SensorStatus::kOverRange;
      if (r.cause != SampleCause::kOk) continue;
      if (u_drop < imp.dropout_probability) {
        tr.cause = SampleCause::kDropout;
        continue;
      }
      s.status = SensorStatus::kOk;
      if (u_spike < imp.spike_probability) {
        // u_spike / p is uniform on [0, 1) given u_spike < p: the spike's value.
        tr.cause = SampleCause::kSpike;
        s.value_mm = u_spike / imp.spike_probability * sc.range_mm;
      } else {
        s.value_mm = tr.true_value_mm + imp.range_noise_mm * g;
      }
    }
    if (lost) {
      ++stats.missing;
      continue;
    }
    for (std::uint32_t i = 0; i < rays; ++i)
      ++stats.causes[static_cast<std::size_t>(truths[i].cause)];
    ++stats.measurements;
    stats.samples += rays;
    out.on_sensor(std::span<const SensorSample>(samples.data(), rays));
    if (truth_sink) truth_sink->on_truth(std::span<const SampleTruth>(truths.data(), rays));
  }
  return stats;
}

void ScanRecorder::on_sensor(std::span<const SensorSample> samples) {
  scan_.sensor.insert(scan_.sensor.end(), samples.begin(), samples.end());
  last_was_probe_ = false;
}
void ScanRecorder::on_stage(const StageSample& sample) { scan_.stage.push_back(sample); }
void ScanRecorder::on_probe(const ProbeTrigger& trigger) {
  scan_.probe.push_back(trigger);
  last_was_probe_ = true;
}
void ScanRecorder::on_truth(std::span<const SampleTruth> truth) {
  auto& dst = last_was_probe_ ? scan_.probe_truth : scan_.truth;
  dst.insert(dst.end(), truth.begin(), truth.end());
}

SimulatedScan simulate(const Simulator& simulator) {
  ScanRecorder rec;
  const SimStats stats = simulator.run(rec, &rec);
  SimulatedScan out = std::move(rec.scan());
  out.stats = stats;
  return out;
}

}  // namespace scanmesh::sim
