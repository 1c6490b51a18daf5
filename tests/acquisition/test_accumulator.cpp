// The point accumulator and the clock mapper against the simulated scanner's ground truth:
// time alignment, interleaving independence, counting by cause, pose gaps and holds, drift.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdint>
#include <map>
#include <vector>

#include "scanmesh/acquisition/accumulator.hpp"
#include "scanmesh/acquisition/clock_mapper.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/rng.hpp"
#include "scanmesh/sim/simulator.hpp"

using namespace scanmesh;
using acq::MeasuredPoint;
using drivers::SensorSample;
using drivers::SensorStatus;
using drivers::StageSample;
using drivers::Timestamp;
using recon::Vec3;
using namespace std::chrono_literals;

namespace {

sim::SimConfig point_scan(std::chrono::nanoseconds sensor_latency, double noise_mm) {
  sim::SimConfig c;
  c.sensor = sim::default_sensor(sim::SensorKind::kPoint);
  c.sensor.rate_hz = 1000;
  c.path.kind = sim::PathKind::kSerpentine;
  c.path.spacing_mm = 0.1;  // 100 mm/s along the lines
  c.path.line_spacing_mm = 4;
  c.imperfections.range_noise_mm = noise_mm;
  c.imperfections.sensor_latency = sensor_latency;
  c.imperfections.seed = 11;
  c.stage_rate_hz = 250;  // the stage reports on its own, slower clock
  return c;
}

/// Distances of each point to the true lit surface point of its sample.
std::vector<double> truth_errors(const sim::SimulatedScan& scan,
                                 const std::vector<MeasuredPoint>& points) {
  std::map<std::pair<std::uint64_t, std::uint32_t>, std::size_t> index;
  for (std::size_t i = 0; i < scan.sensor.size(); ++i)
    index[{scan.sensor[i].seq, scan.sensor[i].index}] = i;
  std::vector<double> err;
  for (const auto& p : points) {
    const auto& t = scan.truth[index.at({p.seq, p.index})];
    if (t.cause != sim::SampleCause::kOk) continue;
    err.push_back((p.point_mm - t.surface_point_mm).norm());
  }
  return err;
}

double percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

/// Feeds a recorded scan as the devices would deliver it live: every record when its host time
/// comes, the stage's reports `stage_delay` late (polling), the sensor in chunks of `chunk`.
std::vector<MeasuredPoint> feed_live(acq::Accumulator& acc, std::uint16_t dev,
                                     const sim::SimulatedScan& scan,
                                     std::chrono::nanoseconds stage_delay, std::size_t chunk) {
  std::vector<MeasuredPoint> out;
  std::size_t si = 0, ki = 0;
  while (si < scan.sensor.size() || ki < scan.stage.size()) {
    const bool stage_next =
        ki < scan.stage.size() &&
        (si >= scan.sensor.size() || scan.stage[ki].t + stage_delay <= scan.sensor[si].t_host);
    if (stage_next) {
      acc.add_stage(scan.stage[ki++], out);
    } else {
      const std::size_t n = std::min(chunk, scan.sensor.size() - si);
      acc.add_sensor_samples(dev, std::span(scan.sensor).subspan(si, n), out);
      si += n;
    }
  }
  acc.finish(out);
  return out;
}

bool same_points(const std::vector<MeasuredPoint>& a, const std::vector<MeasuredPoint>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].seq != b[i].seq || a[i].index != b[i].index || a[i].point_mm != b[i].point_mm ||
        a[i].sensor_mm != b[i].sensor_mm || a[i].t != b[i].t)
      return false;
  }
  return true;
}

}  // namespace

TEST_CASE("Accumulator: the true latency puts points on the surface, a wrong one does not",
          "[acq]") {
  const sim::Scene scene(sim::make_part("steps"));
  const auto latency = 3ms;
  const double noise = 0.005;
  const sim::Simulator simulator(scene, point_scan(latency, noise));
  const sim::SimulatedScan scan = sim::simulate(simulator);
  REQUIRE(scan.sensor.size() > 5000);

  acq::AccumulatorConfig right;
  right.sensor_latency = latency;
  acq::AccumulatorStats st;
  const auto good = acq::points_from_samples(simulator.optics(), simulator.calibration(),
                                             scan.stage, scan.sensor, {}, &st, right);
  acq::AccumulatorConfig wrong;  // latency ignored: each sample takes the pose 3 ms too late
  const auto bad = acq::points_from_samples(simulator.optics(), simulator.calibration(),
                                            scan.stage, scan.sensor, {}, nullptr, wrong);
  const auto e_good = truth_errors(scan, good);
  const auto e_bad = truth_errors(scan, bad);
  REQUIRE(e_good.size() > 3000);
  // Right latency: the error is the range noise (sigma 5 um): 99 % within 4 sigma. The 250 Hz
  // stage is interpolated linearly, exact on straight lines at constant speed; the ramps at the
  // line ends add a little.
  const double p99_good = percentile(e_good, 0.99);
  const double p50_bad = percentile(e_bad, 0.5);
  INFO("p99 error with the true 3 ms latency: " << p99_good << " mm; median with 0 ms: "
                                                << p50_bad << " mm");
  CHECK(p99_good < 4 * noise);
  // Wrong latency: 3 ms at 100 mm/s moves points 0.3 mm along the lines.
  CHECK(p50_bad > 0.25);
  CHECK(p50_bad < 0.35);
  CHECK(st.no_pose() == 0);
}

TEST_CASE("Accumulator: live interleaving and batch cuts give the batch's points exactly", "[acq]") {
  const sim::Scene scene(sim::make_part("container"));
  auto cfg = point_scan(2ms, 0.01);
  cfg.imperfections.dropout_probability = 0.05;
  cfg.imperfections.missing_probability = 0.01;
  const sim::Simulator simulator(scene, cfg);
  const sim::SimulatedScan scan = sim::simulate(simulator);
  acq::AccumulatorConfig ac;
  ac.sensor_latency = 2ms;
  const auto batch = acq::points_from_samples(simulator.optics(), simulator.calibration(),
                                              scan.stage, scan.sensor, {}, nullptr, ac);
  for (const auto delay : {0ms, 7ms, 40ms}) {
    for (const std::size_t chunk : {std::size_t{1}, std::size_t{37}, std::size_t{5000}}) {
      acq::Accumulator acc(ac);
      const auto dev = acc.add_sensor(simulator.optics().config(), simulator.calibration());
      const auto live = feed_live(acc, dev, scan, delay, chunk);
      INFO("stage delay " << delay.count() << " ms, chunk " << chunk);
      CHECK(same_points(live, batch));
      CHECK(acc.stats().pending == 0);
      CHECK(acc.stats().lost == scan.stats.missing);
    }
  }
}

TEST_CASE("Accumulator: invalid values counted by cause, sequence gaps as lost", "[acq]") {
  acq::Accumulator acc;
  const auto dev = acc.add_sensor(sim::default_sensor(sim::SensorKind::kPoint), {});
  std::vector<MeasuredPoint> out;
  acc.add_stage({0, {0}, {0, 0, 100, 0}}, out);
  acc.add_stage({1, {1000}, {10, 0, 100, 0}}, out);
  auto sample = [](std::uint64_t seq, std::int64_t t, double v, SensorStatus st) {
    SensorSample s;
    s.seq = seq;
    s.t_host = {t};
    s.value_mm = v;
    s.status = st;
    return s;
  };
  const std::vector<SensorSample> samples{
      sample(0, 0, 10, SensorStatus::kOk),
      sample(1, 100, NAN, SensorStatus::kNoTarget),
      sample(2, 200, NAN, SensorStatus::kOverRange),
      sample(5, 500, NAN, SensorStatus::kAlarm),          // 3, 4 lost
      sample(6, 600, NAN, SensorStatus::kDeviceError),
      sample(7, 700, INFINITY, SensorStatus::kOk),        // not a value
      sample(8, 500, 20, SensorStatus::kOk),
      sample(20, 1000, 30, SensorStatus::kOk),            // 9 .. 19 lost
  };
  acc.add_sensor_samples(dev, samples, out);
  acc.finish(out);
  const auto& st = acc.stats();
  CHECK(st.samples == 8);
  CHECK(st.points == 3);
  CHECK(out.size() == 3);
  CHECK(st.invalid[static_cast<int>(SensorStatus::kNoTarget)] == 1);
  CHECK(st.invalid[static_cast<int>(SensorStatus::kOverRange)] == 1);
  CHECK(st.invalid[static_cast<int>(SensorStatus::kAlarm)] == 1);
  CHECK(st.invalid[static_cast<int>(SensorStatus::kDeviceError)] == 1);
  CHECK(st.invalid[static_cast<int>(SensorStatus::kOk)] == 1);
  CHECK(st.lost == 2 + 11);
  // The default sensor looks down (-z) with a standoff of 80: a value v lies at z = 100-80-v;
  // the pose at t = 500 is halfway, x = 5.
  REQUIRE(out[1].seq == 8);
  CHECK(out[1].point_mm.x() == Approx(5));
  CHECK(out[1].point_mm.z() == Approx(0));
  CHECK(out[1].sensor_mm.z() == Approx(100));
  CHECK(out[2].point_mm.x() == Approx(10));
}

TEST_CASE("Accumulator: pose gaps, holds and the ends of the history", "[acq]") {
  acq::AccumulatorConfig c;
  c.max_pose_gap = 100ms;
  c.max_hold = 5ms;
  acq::Accumulator acc(c);
  const auto dev = acc.add_sensor(sim::default_sensor(sim::SensorKind::kPoint), {});
  std::vector<MeasuredPoint> out;
  auto at = [](std::uint64_t seq, std::chrono::nanoseconds t) {
    SensorSample s;
    s.seq = seq;
    s.t_host = Timestamp{} + t;
    s.value_mm = 1;
    s.status = SensorStatus::kOk;
    return s;
  };
  const std::int64_t ms = 1'000'000;
  // Before the first report: held within 5 ms, else no pose.
  acc.add_sensor_samples(dev, std::vector{at(0, 990ms), at(1, 997ms)}, out);
  CHECK(out.empty());  // waits for the stage
  acc.add_stage({0, {1000 * ms}, {0, 0, 0, 0}}, out);
  CHECK(out.size() == 1);
  CHECK(acc.stats().no_pose_before == 1);
  acc.add_stage({1, {1050 * ms}, {5, 0, 0, 0}}, out);
  acc.add_stage({2, {1300 * ms}, {30, 0, 0, 0}}, out);  // 250 ms without a report
  acc.add_sensor_samples(dev, std::vector{at(2, 1025ms), at(3, 1100ms), at(4, 1302ms),
                                          at(5, 1310ms)},
                         out);
  CHECK(out.size() == 2);  // 1025 ms interpolated; 1100 ms falls in the gap; the rest wait
  CHECK(out[1].point_mm.x() == Approx(2.5));
  CHECK(acc.stats().no_pose_gap == 1);
  CHECK(acc.stats().pending == 2);
  acc.finish(out);
  CHECK(out.size() == 3);  // 1302 ms held at the last pose; 1310 ms too far
  CHECK(out[2].point_mm.x() == Approx(30));
  CHECK(acc.stats().no_pose_after == 1);
  CHECK(acc.stats().pending == 0);
}

TEST_CASE("Accumulator: a profile shares one pose; long scans keep a bounded history", "[acq]") {
  acq::Accumulator acc;
  auto line = sim::default_sensor(sim::SensorKind::kLine);
  line.profile_points = 50;
  const auto dev = acc.add_sensor(line, {});
  std::vector<MeasuredPoint> out;
  const std::int64_t ms = 1'000'000;
  std::uint64_t seq = 0;
  for (std::int64_t k = 0; k < 200000; ++k) {  // 200 s of stage reports at 1 kHz
    acc.add_stage({static_cast<std::uint64_t>(k), {k * ms}, {static_cast<double>(k) * 0.01, 0, 100, 0}},
                  out);
    if (k % 100 == 50) {
      std::vector<SensorSample> profile(50);
      for (std::uint32_t i = 0; i < 50; ++i) {
        profile[i].seq = seq;
        profile[i].index = i;
        profile[i].t_host = {k * ms - ms / 2};
        profile[i].value_mm = 5;
        profile[i].status = SensorStatus::kOk;
      }
      ++seq;
      out.clear();
      acc.add_sensor_samples(dev, profile, out);
      REQUIRE(out.size() == 50);
      for (const auto& p : out) CHECK(p.sensor_mm == out.front().sensor_mm);
      CHECK(out.front().sensor_mm.x() == Approx(static_cast<double>(k) * 0.01 - 0.005));
    }
  }
  CHECK(acc.stats().lost == 0);
  CHECK(acc.stats().points == 50 * seq);
  CHECK(acc.history_size() < 20000);  // of 200,000 reports
}

TEST_CASE("Clock mapper: offset and drift of a device clock recovered from jittered arrivals",
          "[acq]") {
  acq::ClockMapper mapper;
  sim::Rng rng(3);
  const double drift = 80e-6;          // the device clock runs 80 ppm slow
  const std::int64_t offset = 5'000'000'000;  // and started 5 s "later"
  double worst = 0;
  for (std::int64_t k = 0; k < 200000; ++k) {
    const std::int64_t t_true = 1'000'000'000 + k * 100'000;  // 10 kHz for 20 s
    const auto device = Timestamp{static_cast<std::int64_t>(t_true * (1 - drift)) + offset};
    // Transit: 200 us plus an exponential tail (mean 300 us).
    const double jitter = -300e3 * std::log(1 - rng.uniform());
    const Timestamp host{t_true + 200'000 + static_cast<std::int64_t>(jitter)};
    mapper.observe(device, host);
    if (k > 20000) {
      const double err = static_cast<double>(mapper.to_host(device).ns - (t_true + 200'000));
      worst = std::max(worst, std::abs(err));
    }
  }
  INFO("worst mapping error after 2 s: " << worst / 1e3 << " us; drift " << mapper.drift_ppm()
                                         << " ppm");
  CHECK(worst < 50e3);  // 50 us, against a 300 us mean transit jitter
  CHECK(mapper.drift_ppm() == Approx(drift * 1e6 / (1 - drift)).margin(5));
}
