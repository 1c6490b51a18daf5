// The daemon under load (issue 55's speed targets): a simulated scan ingesting at least 400k
// samples per second through the real Daemon and pipeline engine, 50 clients connected and
// watching, each asking `status` every 20 ms. Prints the ingest rate, the status round-trip
// percentiles, and the CPU the daemon's own threads (io, pipeline: the simulated scanner's
// delivery, journal, mapping; jobs) use, meshing excluded (the batch mesher meshes at the end).
// SPDX-License-Identifier: MIT
#include <pthread.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "scanmesh/daemon/client.hpp"
#include "scanmesh/daemon/daemon.hpp"
#include "scanmesh/daemon/engine_factory.hpp"

using namespace scanmesh::daemon;
using Clock = std::chrono::steady_clock;

namespace {

/// CPU seconds (user + system) of each thread of this process, by thread id, with its name.
/// (By id, not summed by name: threads that end between two snapshots, such as the simulated
/// scanner's ray casting, would make a name's sum go down.)
using ThreadCpu = std::map<std::string, std::pair<std::string, double>>;
ThreadCpu thread_cpu() {
  ThreadCpu out;
  const double tick = static_cast<double>(::sysconf(_SC_CLK_TCK));
  for (const auto& e : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream comm(e.path() / "comm"), stat(e.path() / "stat");
    std::string name, line;
    std::getline(comm, name);
    std::getline(stat, line);
    const auto close = line.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream rest(line.substr(close + 2));
    std::string field;
    unsigned long long utime = 0, stime = 0;
    for (int i = 3; i <= 15 && rest >> field; ++i) {
      if (i == 14) utime = std::stoull(field);
      if (i == 15) stime = std::stoull(field);
    }
    out[e.path().filename().string()] = {name, static_cast<double>(utime + stime) / tick};
  }
  return out;
}

/// CPU seconds the threads named `name` used between two snapshots.
double used_between(const ThreadCpu& before, const ThreadCpu& after, const std::string& name) {
  double used = 0;
  for (const auto& [tid, t] : after) {
    if (t.first != name) continue;
    const auto it = before.find(tid);
    used += t.second - (it == before.end() ? 0.0 : it->second.second);
  }
  return used;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

}  // namespace

int main(int argc, char** argv) {
  const int clients = argc > 1 ? std::atoi(argv[1]) : 50;
  const double playback = argc > 2 ? std::atof(argv[2]) : 40;
  const int pollers = argc > 3 ? std::atoi(argv[3]) : clients;
  std::printf(
      "bench_daemon (%s build): %d clients watching, %d of them asking status every 20 ms\n",
      SCANMESH_BENCH_BUILD_TYPE, clients, pollers);
  const auto dir =
      std::filesystem::temp_directory_path() / ("bench_daemon." + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  DaemonConfig config;
  config.socket_path = dir / "control.sock";
  config.state_dir = dir / "state";
  config.export_dirs = {dir / "exports"};
  config.max_clients = static_cast<std::size_t>(clients + 8);
  config.log_level = LogLevel::kWarning;
  // A line profiler over the container from four sides: 667,400 samples in 55.8 s of scanning.
  config.sim.sensor = "line";
  config.sim.path = "views";
  config.sim.spacing_mm = 0.3;
  config.sim.playback = playback;
  config.scan_defaults["mesher"] = std::string("batch");  // mesh once, at the end
  Log log(config.log_level);
  auto engine = make_engine(config, log);
  Daemon daemon(config, *engine, log, "bench", [&] { return config; });
  std::thread io([&] {
    ::pthread_setname_np(::pthread_self(), "daemon-io");
    daemon.run();
  });
  while (!std::filesystem::exists(config.socket_path))
    std::this_thread::sleep_for(std::chrono::milliseconds(5));

  std::atomic<bool> measuring{false}, done{false};
  std::mutex m;
  std::vector<double> rtt_ms;
  std::vector<std::thread> threads;
  std::atomic<int> ready{0};
  for (int i = 0; i < clients; ++i) {
    threads.emplace_back([&, i] {
      ::pthread_setname_np(::pthread_self(), "bench-client");
      Client c(config.socket_path, std::chrono::seconds(30));
      c.request("watch");
      ++ready;
      if (i >= pollers) {  // watching only: drain events until the daemon closes
        while (c.read()) {
        }
        return;
      }
      std::vector<double> mine;
      while (!done) {
        const auto t0 = Clock::now();
        const std::int64_t id = c.send("status");
        for (;;) {
          auto msg = c.read();
          if (!msg) return;
          if (msg->cls == scanmesh::daemon::proto::MessageClass::kReply && msg->id == id) break;
        }
        if (measuring)
          mine.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
        std::this_thread::sleep_until(t0 + std::chrono::milliseconds(20) +
                                      std::chrono::microseconds(37 * i % 1000));
      }
      std::lock_guard lock(m);
      rtt_ms.insert(rtt_ms.end(), mine.begin(), mine.end());
    });
  }
  while (ready < clients) std::this_thread::sleep_for(std::chrono::milliseconds(5));

  Client ctl(config.socket_path);
  ctl.request("scan.start", scanmesh::daemon::proto::Object().set("name", "bench"));
  // Measure while samples flow (after the simulation's ray casting, which is the scanner's work).
  auto status = [&] {
    return scanmesh::daemon::proto::status_info_from(ctl.request("status").body).scan;
  };
  while (status().counters.samples == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  const auto cpu0 = thread_cpu();
  const auto s0 = status();
  const auto t0 = Clock::now();
  measuring = true;
  ScanStatus s1 = s0;
  while (s1.progress < 0.95 && s1.state != ScanState::kIdle) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    s1 = status();
  }
  measuring = false;
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  const auto cpu1 = thread_cpu();
  done = true;
  for (int i = 0; i < pollers && i < clients; ++i) threads[static_cast<std::size_t>(i)].join();
  ctl.request("scan.stop");

  const double samples = static_cast<double>(s1.counters.samples - s0.counters.samples);
  std::printf("ingest          %.0f samples/s over %.2f s (%.0f samples; target >= 400000)\n",
              samples / wall, wall, samples);
  std::printf(
      "status RTT      p50 %.3f ms, p99 %.3f ms, max %.3f ms over %zu round trips (target p99 < 5 "
      "ms)\n",
      percentile(rtt_ms, 0.5), percentile(rtt_ms, 0.99), percentile(rtt_ms, 1.0), rtt_ms.size());
  double daemon_cpu = 0;
  for (const char* name : {"daemon-io", "scan-pipeline", "daemon-jobs"}) {
    const double used = used_between(cpu0, cpu1, name);
    std::printf("cpu %-14s %5.1f %% of one core\n", name, 100 * used / wall);
    daemon_cpu += used;
  }
  std::printf("daemon overhead %5.1f %% of one core (io + pipeline + jobs; target < 10 %%)\n",
              100 * daemon_cpu / wall);
  daemon.request_stop();
  io.join();
  for (auto& t : threads)
    if (t.joinable()) t.join();
  std::filesystem::remove_all(dir);
  return 0;
}
