// Acquisition throughput on one core: the accumulator (pose interpolation, calibration), the
// journal writing, and both as the pipeline's ingest thread runs them, for a point sensor and a
// line profiler. Prints samples per second, ns per sample, journal MB/s and bytes per sample.
// Targets (issue 54): >= 10 M samples/s through alignment and journal writing; journal >= 200
// MB/s on this machine's disk with the default fsync policy.
// SPDX-License-Identifier: MIT
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "scanmesh/acquisition/accumulator.hpp"
#include "scanmesh/acquisition/journal_backend.hpp"

using namespace scanmesh;
using Clock = std::chrono::steady_clock;
using drivers::SensorSample;
using drivers::SensorStatus;
using drivers::StageSample;

namespace {

struct Workload {
  std::string name;
  acq::SensorConfig sensor;
  std::vector<StageSample> stage;
  std::vector<SensorSample> samples;  // time order
  std::size_t batch = 0;              // samples per delivery (a profile, or a block of points)
};

/// A serpentine over 100 x 100 mm at 50 mm/s; the stage reports at 1 kHz.
StageSample stage_at(std::uint64_t k) {
  const double t = static_cast<double>(k) * 1e-3;
  const double x = std::fmod(t * 50.0, 200.0);
  return StageSample{k, {static_cast<std::int64_t>(k) * 1'000'000},
                     {x < 100 ? x : 200 - x, std::floor(t * 50.0 / 100.0) * 0.5, 100, 0}};
}

Workload point_sensor(std::size_t n) {
  Workload w;
  w.name = "point sensor 400 kHz";
  w.sensor = acq::default_sensor(acq::SensorKind::kPoint);
  w.batch = 400;  // one millisecond of samples per delivery
  const std::int64_t period = 2500;  // ns
  w.samples.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    SensorSample& s = w.samples[i];
    s.seq = i;
    s.t_host = {static_cast<std::int64_t>(i) * period + 1'000'000};
    s.value_mm = 10 + 0.001 * static_cast<double>(i % 1000);
    s.status = i % 50 == 0 ? SensorStatus::kNoTarget : SensorStatus::kOk;
    if (s.status != SensorStatus::kOk) s.value_mm = NAN;
  }
  const std::uint64_t stages = static_cast<std::uint64_t>(n) * period / 1'000'000 + 3;
  for (std::uint64_t k = 0; k < stages; ++k) w.stage.push_back(stage_at(k));
  return w;
}

Workload profiler(std::size_t n) {
  Workload w;
  w.name = "line profiler 10 kHz x 1000";
  w.sensor = acq::default_sensor(acq::SensorKind::kLine);
  w.sensor.profile_points = 1000;
  w.batch = 1000;
  const std::int64_t period = 100'000;  // 10 kHz profiles
  w.samples.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    SensorSample& s = w.samples[i];
    s.seq = i / 1000;
    s.index = static_cast<std::uint32_t>(i % 1000);
    s.t_host = {static_cast<std::int64_t>(i / 1000) * period + 1'000'000};
    s.value_mm = 10 + 0.001 * static_cast<double>(i % 997);
    s.status = SensorStatus::kOk;
  }
  const std::uint64_t stages = static_cast<std::uint64_t>(n / 1000) * period / 1'000'000 + 3;
  for (std::uint64_t k = 0; k < stages; ++k) w.stage.push_back(stage_at(k));
  return w;
}

/// Feeds the workload as live: stage reports as their time comes, samples in batches.
template <class OnStage, class OnSensor>
void feed(const Workload& w, OnStage&& on_stage, OnSensor&& on_sensor) {
  std::size_t k = 0;
  for (std::size_t i = 0; i < w.samples.size(); i += w.batch) {
    const std::size_t n = std::min(w.batch, w.samples.size() - i);
    const auto last_t = w.samples[i + n - 1].t_host;
    while (k < w.stage.size() && w.stage[k].t <= last_t) on_stage(w.stage[k++]);
    on_sensor(std::span(w.samples).subspan(i, n));
  }
  while (k < w.stage.size()) on_stage(w.stage[k++]);
}

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

void run(const Workload& w, const std::filesystem::path& dir) {
  const double n = static_cast<double>(w.samples.size());
  std::printf("\n%s: %.0f samples, %zu stage reports\n", w.name.c_str(), n, w.stage.size());
  std::printf("  %-34s %14s %10s %10s %12s\n", "stage", "samples/s", "ns/sample", "MB/s",
              "bytes/sample");
  // Accumulator alone.
  {
    acq::Accumulator acc;
    const auto dev = acc.add_sensor(w.sensor, {});
    std::vector<acq::MeasuredPoint> out;
    out.reserve(w.batch * 2);
    std::uint64_t points = 0;
    const auto t0 = Clock::now();
    feed(
        w,
        [&](const StageSample& s) {
          acc.add_stage(s, out);
          points += out.size();
          out.clear();
        },
        [&](std::span<const SensorSample> s) {
          acc.add_sensor_samples(dev, s, out);
          points += out.size();
          out.clear();
        });
    acc.finish(out);
    const double t = seconds_since(t0);
    std::printf("  %-34s %14.3e %10.1f %10s %12s   (%llu points)\n", "accumulator", n / t,
                t / n * 1e9, "-", "-", static_cast<unsigned long long>(points + out.size()));
  }
  // Journal alone, then both, each into a new file with the default durability policy.
  for (const bool with_accumulator : {false, true}) {
    const auto file = dir / (std::string("bench_") + (with_accumulator ? "both" : "journal") + ".mcap");
    std::filesystem::remove(file);
    acq::ScannerModel model;
    model.sensors.push_back({"sensor", w.sensor, {}});
    model.stage = "stage";
    acq::Accumulator acc;
    const auto dev = acc.add_sensor(w.sensor, {});
    std::vector<acq::MeasuredPoint> out;
    const auto t0 = Clock::now();
    std::uint64_t bytes = 0;
    {
      acq::JournalRecorder rec(file, model);
      std::size_t batches = 0;
      feed(
          w,
          [&](const StageSample& s) {
            rec.write_stage(s);
            if (with_accumulator) {
              acc.add_stage(s, out);
              out.clear();
            }
          },
          [&](std::span<const SensorSample> s) {
            rec.write_sensor(0, s);
            if (with_accumulator) {
              acc.add_sensor_samples(dev, s, out);
              out.clear();
            }
            if (++batches % 10 == 0) rec.flush();  // the ingest thread's cycle
          });
      rec.close();
      bytes = rec.bytes();
    }
    const double t = seconds_since(t0);
    std::printf("  %-34s %14.3e %10.1f %10.1f %12.1f\n",
                with_accumulator ? "journal + accumulator (ingest)" : "journal (default fsync)",
                n / t, t / n * 1e9, static_cast<double>(bytes) / t / 1e6,
                static_cast<double>(bytes) / n);
    std::filesystem::remove(file);
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::printf("bench_acquisition (%s build)\n", SCANMESH_BENCH_BUILD_TYPE);
  const std::filesystem::path dir = argc > 1 ? argv[1] : std::filesystem::current_path();
  std::printf("journal files in %s\n", dir.c_str());
  run(point_sensor(20'000'000), dir);
  run(profiler(20'000'000), dir);
  return 0;
}
