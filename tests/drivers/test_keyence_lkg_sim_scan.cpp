// The virtual scanner feeding a protocol emulator: a simulated raster scan of a sphere is served
// by the KEYENCE LK-G emulator over a pty, read back by the real driver on the real transport,
// and must come out as the simulator produced it (to the protocol's resolution).
// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <vector>

#include "scanmesh/drivers/keyence_lkg/device.hpp"
#include "scanmesh/drivers/transports/serial_stream.hpp"
#include "scanmesh/sim/emulators/keyence_lkg.hpp"
#include "scanmesh/sim/parts.hpp"
#include "scanmesh/sim/simulator.hpp"
#include "support/temp_dir.hpp"

using namespace std::chrono_literals;
namespace drv = scanmesh::drivers;
namespace sim = scanmesh::sim;

TEST_CASE("A simulated scan served by the LK-G emulator reaches the driver unchanged",
          "[drivers][sim]") {
  const sim::Scene scene(sim::make_part("sphere"));
  sim::SimConfig cfg;
  cfg.sensor = sim::default_sensor(sim::SensorKind::kPoint);
  cfg.path.kind = sim::PathKind::kRaster;
  cfg.path.spacing_mm = 0.5;
  cfg.sensor.rate_hz = 200;
  cfg.path.line_spacing_mm = 4;
  cfg.imperfections.range_noise_mm = 0.002;
  cfg.imperfections.dropout_probability = 0.05;
  cfg.imperfections.seed = 11;
  const sim::Simulator simulator(scene, cfg);
  std::vector<drv::SensorSample> source = sim::simulate(simulator).sensor;
  REQUIRE(source.size() > 400);
  source.resize(400);
  std::size_t source_ok = 0;
  for (const auto& s : source) source_ok += s.status == drv::SensorStatus::kOk;
  REQUIRE(source_ok > 100);            // the sphere is really seen ...
  REQUIRE(source_ok < source.size());  // ... and so are misses (edges, dropouts)

  scanmesh::test::TempDir dir;
  sim::KeyenceLkgEmulator emu((dir / "lkg").string(), sim::sample_values(source));
  emu.start();
  drv::SensorOptions options;
  options.name = "lkg-sim";
  options.timeout = 300ms;
  const std::string port = emu.port();
  drv::keyence_lkg::Device device(options, [&] {
    return drv::open_serial_stream("lkg-sim", {port, drv::keyence_lkg::kDefaultBaud});
  });
  device.open();
  const std::uint64_t first = emu.measurements();  // open() identified with one M0

  std::mutex m;
  std::condition_variable cv;
  std::vector<drv::SensorSample> got;
  const std::size_t want = source.size() - first;
  device.start({.on_sample = [&](const drv::SensorSample& s) {
                  std::lock_guard lock(m);
                  got.push_back(s);
                  cv.notify_one();
                },
                .on_state = {}});
  {
    std::unique_lock lock(m);
    cv.wait_for(lock, 20s, [&] { return got.size() >= want; });
  }
  device.stop();
  REQUIRE(got.size() >= want);
  CHECK(device.stats().malformed == 0);
  CHECK(device.stats().timeouts == 0);
  for (std::size_t k = 0; k < want; ++k) {
    const drv::SensorSample& in = source[first + k];
    const drv::SensorSample& out = got[k];
    INFO("sample " << k << ": simulated " << in.value_mm << " " << drv::to_string(in.status)
                   << ", driver " << out.value_mm << " " << drv::to_string(out.status));
    CHECK(out.seq == k);
    if (in.status == drv::SensorStatus::kOk) {
      REQUIRE(out.status == drv::SensorStatus::kOk);
      CHECK(std::abs(out.value_mm - in.value_mm) <= 0.5e-4 + 1e-12);  // 4 decimals on the wire
    } else {
      CHECK(out.status != drv::SensorStatus::kOk);
      CHECK(std::isnan(out.value_mm));
    }
  }
}
