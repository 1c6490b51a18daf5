// bench_stage_polling: position polling of the Modbus drive-stage emulator over Modbus TCP on
// 127.0.0.1 by the real driver at a configured rate (default 200 Hz, three axes = nine register
// reads per poll), printing the achieved rate and the jitter of the report times. Target (issue
// 53): the configured rate, at least 200 Hz.
// Usage: bench_stage_polling [RATE_HZ] [SECONDS]
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <thread>
#include <vector>

#include "scanmesh/drivers/modbus_stage/device.hpp"
#include "scanmesh/drivers/transports/modbus_bus.hpp"
#include "scanmesh/sim/emulators/modbus_stage.hpp"

int main(int argc, char** argv) {
  namespace drv = scanmesh::drivers;
  const double rate_hz = argc > 1 ? std::atof(argv[1]) : 200.0;
  const double seconds = argc > 2 ? std::atof(argv[2]) : 5.0;
  if (!(rate_hz > 0) || !(seconds > 0)) {
    std::fprintf(stderr, "usage: bench_stage_polling [RATE_HZ] [SECONDS]\n");
    return 2;
  }
  auto model = std::make_shared<scanmesh::sim::ModbusStageModel>(scanmesh::sim::ModbusStageOptions{
      drv::modbus_stage::leadshine_pr_map(), scanmesh::sim::StageMotionOptions{}});
  scanmesh::sim::ModbusTcpEmulator emulator(nullptr, {}, 1, 0);
  emulator.set_handler(model);
  emulator.start();
  drv::StageOptions o;
  o.name = "bench";
  o.poll_interval = std::chrono::microseconds(static_cast<std::int64_t>(1e6 / rate_hz));
  o.timeout = std::chrono::milliseconds(200);
  const int port = emulator.port();
  drv::modbus_stage::Device stage(
      o, [port] { return drv::open_modbus_tcp("bench", "127.0.0.1", port, 1, std::chrono::milliseconds(200)); },
      drv::modbus_stage::leadshine_pr_map());
  std::mutex mutex;
  std::vector<std::int64_t> t_ns;
  t_ns.reserve(static_cast<std::size_t>(rate_hz * seconds * 2) + 16);
  drv::StageCallbacks cb;
  cb.on_sample = [&](const drv::StageSample& s) {
    std::lock_guard lock(mutex);
    t_ns.push_back(s.t.ns);
  };
  stage.open();
  stage.start(cb);
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  stage.stop();
  const drv::DeviceStats st = stage.stats();
  stage.close();
  if (t_ns.size() < 3) {
    std::printf("too few reports (%zu)\n", t_ns.size());
    return 1;
  }
  std::vector<double> dt;
  for (std::size_t i = 1; i < t_ns.size(); ++i) dt.push_back((t_ns[i] - t_ns[i - 1]) * 1e-6);
  const double span = (t_ns.back() - t_ns.front()) * 1e-9;
  const double achieved = static_cast<double>(t_ns.size() - 1) / span;
  double mean = 0;
  for (double d : dt) mean += d;
  mean /= static_cast<double>(dt.size());
  double var = 0;
  for (double d : dt) var += (d - mean) * (d - mean);
  const double sd = std::sqrt(var / static_cast<double>(dt.size()));
  std::vector<double> sorted = dt;
  std::sort(sorted.begin(), sorted.end());
  auto pct = [&](double p) { return sorted[static_cast<std::size_t>(p * (sorted.size() - 1))]; };
  // Schedule error: each report against the ideal fixed-rate grid started at the first one.
  const double period_ms = 1e3 / rate_hz;
  double worst_lag = 0;
  for (std::size_t i = 0; i < t_ns.size(); ++i) {
    const double ideal = static_cast<double>(i) * period_ms;
    const double lag = (t_ns[i] - t_ns.front()) * 1e-6 - ideal;
    worst_lag = std::max(worst_lag, std::abs(lag));
  }
  std::printf("bench_stage_polling (%s build): Modbus TCP, 3 axes (9 reads per poll), %.0f Hz for %.1f s\n",
              SCANMESH_BENCH_BUILD_TYPE, rate_hz, seconds);
  std::printf("reports %zu  achieved %.1f Hz  timeouts %llu  error replies %llu\n", t_ns.size(),
              achieved, static_cast<unsigned long long>(st.timeouts),
              static_cast<unsigned long long>(st.error_replies));
  std::printf("interval ms: mean %.3f  sd %.3f  p1 %.3f  p50 %.3f  p99 %.3f  max %.3f\n", mean, sd,
              pct(0.01), pct(0.5), pct(0.99), sorted.back());
  std::printf("largest deviation from the fixed-rate grid: %.3f ms\n", worst_lag);
  const bool pass = achieved >= 0.99 * rate_hz && rate_hz >= 200;
  std::printf("target: >= 200 Hz at the configured rate: %s\n", pass ? "PASS" : "MISS");
  return 0;
}
