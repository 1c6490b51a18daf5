// The scan pipeline end to end over the simulated scanner: a complete scan meshed, pause and
// resume, a device lost and back, stop, a failing journal, snapshots while scanning.
// SPDX-License-Identifier: MIT
#include <atomic>
#include <catch2/catch.hpp>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "scanmesh/acquisition/meshers.hpp"
#include "scanmesh/acquisition/pipeline.hpp"
#include "scanmesh/recon/analysis.hpp"
#include "scanmesh/recon/deviation.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/scanner_backend.hpp"
#include "pipeline_events.hpp"

using namespace scanmesh;
using namespace std::chrono_literals;

namespace {

sim::SimulatedScannerOptions at_speed(double speed) {
  sim::SimulatedScannerOptions o;
  o.speed = speed;
  return o;
}

sim::SimConfig container_scan() {
  sim::SimConfig c;
  c.sensor = sim::default_sensor(sim::SensorKind::kLine);
  c.sensor.profile_points = 120;
  c.sensor.rate_hz = 200;
  c.path.kind = sim::PathKind::kSerpentine;
  c.path.spacing_mm = 0.4;
  c.imperfections.range_noise_mm = 0.01;
  c.imperfections.seed = 5;
  return c;
}

/// Records what a Recorder is asked to write; fails after `fail_after` sample writes.
class MemoryRecorder final : public acq::Recorder {
 public:
  explicit MemoryRecorder(std::uint64_t fail_after = UINT64_MAX) : fail_after_(fail_after) {}
  void write_parameters(std::string_view json) override { parameters = json; }
  void write_sensor(std::uint16_t, std::span<const drivers::SensorSample> s) override {
    if (written_ + s.size() > fail_after_)
      throw std::runtime_error("/tmp/scan.mcap: No space left on device");
    written_ += s.size();
  }
  void write_stage(const drivers::StageSample&) override { ++stage; }
  void write_probe(std::uint16_t, const drivers::ProbeTrigger&) override {}
  void write_event(std::string_view json) override { events.emplace_back(json); }
  void flush() override { acked_ = written_; }
  void close() override {
    acked_ = written_;
    closed = true;
  }
  std::uint64_t acknowledged_samples() const override { return acked_; }
  std::uint64_t bytes() const override { return written_ * 24; }
  std::uint64_t written() const { return written_; }

  std::string parameters;
  std::vector<std::string> events;
  std::uint64_t stage = 0;
  bool closed = false;

 private:
  std::uint64_t fail_after_;
  std::uint64_t written_ = 0;
  std::atomic<std::uint64_t> acked_{0};
};

using Events = test::PipelineEvents;

std::uint64_t total_sensor_samples(const sim::SimulatedScanner& backend) {
  sim::ScanRecorder r;
  backend.simulator().run(r);
  return r.scan().sensor.size();
}

}  // namespace

TEST_CASE("Pipeline: a simulated scan of the container is recorded and meshed", "[acq]") {
  const bool incremental = GENERATE(false, true);
  INFO((incremental ? "incremental" : "batch") << " mesher");
  const recon::Mesh part = sim::make_part("container");
  sim::SimulatedScanner backend(part, container_scan(), at_speed(0));
  const std::uint64_t total = total_sensor_samples(backend);
  auto recorder = std::make_unique<MemoryRecorder>();
  MemoryRecorder* rec = recorder.get();
  Events events;
  acq::PipelineConfig pc;
  pc.parameters_json = R"({"scan":"container"})";
  std::unique_ptr<acq::Mesher> mesher;
  if (incremental) {
    mesher = std::make_unique<acq::IncrementalMesher>();
  } else {
    mesher = std::make_unique<acq::BatchMesher>();
  }
  acq::Pipeline pipeline(backend, std::move(recorder), std::move(mesher), pc, events.callback());
  pipeline.start();
  REQUIRE(pipeline.wait() == acq::PipelineState::kCompleted);
  const auto st = pipeline.stats();
  CHECK(st.samples_received == total);
  CHECK(st.samples_recorded == total);  // every sample acknowledged by the journal
  CHECK(rec->closed);
  CHECK(rec->parameters == pc.parameters_json);
  CHECK(st.points > 15000);
  CHECK(st.points + st.invalid + st.no_pose == st.samples_received);
  CHECK(st.no_pose == 0);
  CHECK(st.mesh.points_in == st.points);
  CHECK(st.meshing_lag == 0);
  CHECK(events.saw_state(acq::PipelineState::kRunning));
  CHECK(events.saw_state(acq::PipelineState::kCompleted));

  const recon::Mesh& mesh = pipeline.result();
  const auto report = recon::analyze(mesh);
  CHECK(report.triangles > 5000);
  CHECK(report.non_manifold_edges == 0);
  CHECK(report.non_manifold_vertices == 0);
  CHECK(report.orientation_consistent);
  // One view from above: the top faces and what the line profiler sees of the walls, on the part.
  const recon::SurfaceDistance to_part(part);
  double worst = 0;
  for (const auto& v : mesh.vertices) worst = std::max(worst, to_part.distance(v));
  CHECK(worst < 0.1);
}

TEST_CASE("Pipeline: pause, resume, snapshots while scanning, a device lost and back", "[acq]") {
  const recon::Mesh part = sim::make_part("container");
  sim::SimulatedScannerOptions opt;
  opt.speed = 8;  // a few seconds of scanning
  opt.sensor_loss_at = 2s;  // scan time
  sim::SimulatedScanner backend(part, container_scan(), opt);
  const std::uint64_t total = total_sensor_samples(backend);
  Events events;
  acq::Pipeline pipeline(backend, std::make_unique<MemoryRecorder>(),
                         std::make_unique<acq::IncrementalMesher>(), {}, events.callback());
  pipeline.start();
  // Pause early in the scan (by points received: on a loaded machine the mesher may lag the
  // scan, so waiting for triangles first could see the scan end).
  while (pipeline.stats().points < 5000) REQUIRE_FALSE(pipeline.wait_for(2ms));
  pipeline.pause();
  CHECK(pipeline.stats().state == acq::PipelineState::kPaused);
  const auto before = pipeline.stats().samples_received;
  REQUIRE_FALSE(pipeline.wait_for(150ms));
  // Held: at most what was in flight when the pause came.
  CHECK(pipeline.stats().samples_received - before < 2000);
  pipeline.resume();
  // A snapshot as soon as the first regions are meshed (mid-scan unless the machine is so
  // loaded that the mesher only catches up at the end) is a valid partial mesh.
  while (pipeline.stats().mesh.triangles == 0 && !pipeline.wait_for(2ms)) {
  }
  const recon::Mesh partial = pipeline.snapshot();
  const auto pr = recon::analyze(partial);
  CHECK(pr.triangles > 0);
  CHECK(pr.non_manifold_edges == 0);
  REQUIRE(pipeline.wait() == acq::PipelineState::kCompleted);
  CHECK(events.saw_state(acq::PipelineState::kPaused, "paused by request"));
  CHECK(events.saw_state(acq::PipelineState::kPaused, "device lost: sim-sensor"));
  {
    std::lock_guard lock(events.mutex);
    bool lost = false, back = false;
    for (const auto& e : events.list) {
      if (e.kind == "device" && e.device == "sim-sensor" &&
          e.message.find("lost") != std::string::npos)
        lost = true;
      if (e.kind == "device" && e.device == "sim-sensor" &&
          e.message.find("back") != std::string::npos)
        back = true;
    }
    CHECK(lost);
    CHECK(back);
  }
  // Nothing lost while the sensor was away.
  CHECK(pipeline.stats().samples_received == total);
  CHECK(recon::analyze(pipeline.result()).non_manifold_edges == 0);
}

TEST_CASE("Pipeline: stop before the end keeps what was measured", "[acq]") {
  const recon::Mesh part = sim::make_part("container");
  sim::SimulatedScanner backend(part, container_scan(), at_speed(8));
  const std::uint64_t total = total_sensor_samples(backend);
  acq::Pipeline pipeline(backend, std::make_unique<MemoryRecorder>(),
                         std::make_unique<acq::BatchMesher>());
  pipeline.start();
  while (pipeline.stats().points < 20000) REQUIRE_FALSE(pipeline.wait_for(10ms));
  pipeline.stop();
  REQUIRE(pipeline.wait() == acq::PipelineState::kStopped);
  const auto st = pipeline.stats();
  CHECK(st.reason == "stopped by request");
  CHECK(st.samples_received < total);
  CHECK(st.samples_recorded == st.samples_received);
  CHECK(st.mesh.points_in == st.points);
  CHECK(recon::analyze(pipeline.result()).triangles > 1000);
}

TEST_CASE("Pipeline: a journal that fails stops the scan with its error, the mesh keeps what was "
          "recorded",
          "[acq]") {
  const recon::Mesh part = sim::make_part("container");
  sim::SimulatedScanner backend(part, container_scan(), at_speed(0));
  auto recorder = std::make_unique<MemoryRecorder>(30000);
  MemoryRecorder* rec = recorder.get();
  acq::Pipeline pipeline(backend, std::move(recorder), std::make_unique<acq::BatchMesher>());
  pipeline.start();
  REQUIRE(pipeline.wait() == acq::PipelineState::kFailed);
  const auto st = pipeline.stats();
  CHECK(st.reason == "journal: /tmp/scan.mcap: No space left on device");
  CHECK(rec->written() <= 30000);
  CHECK(rec->written() > 20000);
  CHECK(st.samples_recorded <= rec->written());
  CHECK_FALSE(rec->closed);  // a failed journal is not written to again
  // Only samples the journal took were meshed.
  CHECK(st.points <= rec->written());
  CHECK(recon::analyze(pipeline.result()).triangles > 0);
}

TEST_CASE("Pipeline: a backend that cannot start fails the scan with its error",
          "[acq]") {
  class Broken final : public acq::ScanBackend {
   public:
    std::string_view kind() const override { return "devices"; }
    acq::ScannerModel model() const override {
      acq::ScannerModel m;
      m.sensors.push_back({"lkg0", sim::default_sensor(sim::SensorKind::kPoint), {}});
      return m;
    }
    std::vector<acq::DeviceStatus> devices() const override { return {}; }
    void start(acq::SampleInput&) override {
      throw std::runtime_error("lkg0 (/dev/ttyUSB0): open: No such file or directory");
    }
    void pause() override {}
    void resume() override {}
    void stop() noexcept override {}
  } broken;
  acq::Pipeline pipeline(broken, nullptr, std::make_unique<acq::BatchMesher>());
  CHECK_THROWS_WITH(pipeline.start(), Catch::Contains("lkg0 (/dev/ttyUSB0)"));
  CHECK(pipeline.stats().state == acq::PipelineState::kFailed);
}
