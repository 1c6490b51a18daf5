// Scan journal benchmark: samples per second and MB/s of journal writing with the default fsync
// policy on this machine's disk (targets: 10 million samples/s, 200 MB/s), bytes per sample,
// reading speed, and the recovery time of a 1 GB journal with a torn tail (cold and warm page
// cache). Files go to the directory given (default: the current one) and are deleted after.
// Usage: bench_journal [DIR] [--gigabytes G]
// SPDX-License-Identifier: MIT
#include <fcntl.h>
#include <time.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "scanmesh/acquisition/journal.hpp"

#ifndef SCANMESH_BENCH_BUILD_TYPE
#define SCANMESH_BENCH_BUILD_TYPE "unknown"
#endif

namespace {

using namespace scanmesh;
namespace drv = scanmesh::drivers;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

/// Batches of a sensor stream: `batch` samples at `rate_hz` (host times), a line profile of
/// `points` points per seq with a device clock when points > 1.
struct Stream {
  std::uint32_t points = 1;
  double rate_hz = 10e6;
  std::size_t batch = 1000;
};

void fill(std::vector<drv::SensorSample>& b, const Stream& s, std::uint64_t first) {
  b.resize(s.batch);
  const double period_ns = 1e9 / s.rate_hz;
  for (std::size_t k = 0; k < s.batch; ++k) {
    const std::uint64_t i = first + k;
    drv::SensorSample& x = b[k];
    x.seq = i / s.points;
    x.index = static_cast<std::uint32_t>(i % s.points);
    x.t_host.ns = 1'000'000'000 + static_cast<std::int64_t>(i) * std::llround(period_ns);
    if (s.points > 1) x.t_device = drv::Timestamp{static_cast<std::int64_t>(x.seq) * 1000};
    x.status = i % 50 == 49 ? drv::SensorStatus::kNoTarget : drv::SensorStatus::kOk;
    x.value_mm = x.status == drv::SensorStatus::kOk ? 10.0 + 1e-6 * static_cast<double>(i % 100000)
                                                    : std::nan("");
  }
}

struct WriteFigures {
  std::uint64_t samples = 0;
  std::uint64_t bytes = 0;
  std::uint64_t fsyncs = 0;
  double seconds = 0;
  double cpu = 0;
};

/// Writes `total` samples of stream s plus a 1 kHz stage (by sample time) into `file`.
WriteFigures write_journal(const std::filesystem::path& file, const Stream& s, std::uint64_t total,
                           const acq::JournalOptions& options) {
  std::filesystem::remove(file);
  std::vector<drv::SensorSample> batch;
  // Fill the batches before the clock starts: the figure is the journal's, not the generator's.
  const std::size_t distinct = 256;
  std::vector<std::vector<drv::SensorSample>> batches(distinct);
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = cpu_seconds();
  acq::JournalWriter w(file, options);
  const auto sensor = w.add_sensor("bench0");
  const auto stage = w.add_stage("xyz");
  std::int64_t next_stage_ns = 1'000'000'000;
  std::uint64_t stage_seq = 0;
  for (std::uint64_t first = 0; first < total; first += s.batch) {
    // Regenerating every batch would cost more than journaling it; times must still advance,
    // so only seq and the host times are rewritten in a reused batch (about 1 ns a sample; a
    // batch holds whole profiles).
    auto& b = batches[(first / s.batch) % distinct];
    if (b.empty()) {
      fill(b, s, first);
    } else {
      const auto period_ns = static_cast<std::int64_t>(std::llround(1e9 / s.rate_hz));
      const std::uint64_t seq0 = first / s.points;
      const std::int64_t t0 = 1'000'000'000 + static_cast<std::int64_t>(first) * period_ns;
      for (std::size_t k = 0; k < b.size(); ++k) {
        b[k].t_host.ns = t0 + static_cast<std::int64_t>(k) * period_ns;
        b[k].seq = seq0 + (s.points == 1 ? k : 0);
      }
    }
    w.write_sensor(sensor, b);
    while (next_stage_ns <= b.back().t_host.ns) {
      drv::StageSample st;
      st.seq = stage_seq++;
      st.t.ns = next_stage_ns;
      st.pose = {1, 2, 3, 0.5};
      w.write_stage(stage, st);
      next_stage_ns += 1'000'000;
    }
  }
  w.close();
  WriteFigures f;
  f.seconds = seconds_since(t0);
  f.cpu = cpu_seconds() - c0;
  f.samples = w.acknowledged_samples();
  f.bytes = w.stats().bytes;
  f.fsyncs = w.stats().fsyncs;
  return f;
}

void print_write(const char* what, const WriteFigures& f) {
  std::printf(
      "%-44s %12.2f M samples/s %9.1f MB/s %7.2f bytes/sample %5llu fsyncs  (%.2f s; cpu "
      "%.1f ns/sample)\n",
      what, static_cast<double>(f.samples) / f.seconds * 1e-6,
      static_cast<double>(f.bytes) / f.seconds * 1e-6,
      static_cast<double>(f.bytes) / static_cast<double>(f.samples),
      static_cast<unsigned long long>(f.fsyncs), f.seconds,
      f.cpu / static_cast<double>(f.samples) * 1e9);
}

class Counter final : public acq::JournalVisitor {
 public:
  std::uint64_t samples = 0;
  void on_sensor(const acq::ChannelInfo&, std::span<const drv::SensorSample> s) override {
    samples += s.size();
  }
  void on_stage(const acq::ChannelInfo&, const drv::StageSample&) override { ++samples; }
};

/// Drops the file's pages from the page cache (the next read comes from the disk).
void evict(const std::filesystem::path& file) {
  const int fd = ::open(file.c_str(), O_RDONLY);
  if (fd < 0) return;
  ::fdatasync(fd);
  ::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
  ::close(fd);
}

/// The disk itself: `bytes` in 64 KiB write() calls with an fdatasync every `sync_every` bytes
/// (0: only at the end), as dd would; MB/s.
double raw_disk(const std::filesystem::path& file, std::uint64_t bytes, std::uint64_t sync_every) {
  std::filesystem::remove(file);
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
  if (fd < 0) return 0;
  std::vector<char> block(64 * 1024, 'x');
  const auto t0 = std::chrono::steady_clock::now();
  std::uint64_t since = 0;
  for (std::uint64_t done = 0; done < bytes; done += block.size()) {
    if (::write(fd, block.data(), block.size()) != static_cast<ssize_t>(block.size())) break;
    since += block.size();
    if (sync_every > 0 && since >= sync_every) {
      ::fdatasync(fd);
      since = 0;
    }
  }
  ::fdatasync(fd);
  ::close(fd);
  const double s = seconds_since(t0);
  std::filesystem::remove(file);
  return static_cast<double>(bytes) / s * 1e-6;
}

}  // namespace

int main(int argc, char** argv) {
  std::filesystem::path dir = ".";
  double gigabytes = 1.0;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--gigabytes") == 0 && i + 1 < argc) {
      gigabytes = std::atof(argv[++i]);
    } else {
      dir = argv[i];
    }
  }
  std::printf("bench_journal (%s build), files in %s\n", SCANMESH_BENCH_BUILD_TYPE,
              std::filesystem::absolute(dir).c_str());
  const auto file = dir / "bench_journal.mcap";
  const acq::JournalOptions defaults;
  std::printf(
      "default policy: chunks of %zu KiB or %lld ms, fdatasync every %lld ms of sample "
      "time or %llu MiB\n\n",
      defaults.chunk_bytes / 1024,
      static_cast<long long>(defaults.chunk_duration.count() / 1'000'000),
      static_cast<long long>(defaults.fsync_interval.count() / 1'000'000),
      static_cast<unsigned long long>(defaults.fsync_bytes >> 20));

  const auto gb = static_cast<std::uint64_t>(gigabytes * 1e9);
  std::printf("%-44s %9.1f MB/s (fdatasync at the end) %9.1f MB/s (every 64 MiB)\n",
              "the disk itself: 64 KiB write() calls", raw_disk(dir / "bench_raw", gb, 0),
              raw_disk(dir / "bench_raw", gb, std::uint64_t{64} << 20));

  // Writing: a point sensor (no device clock: 25 bytes a sample) at 10 MHz in batches of 1000,
  // then a line profiler (800 points, device clock) at 10 kHz profiles, then the point sensor
  // with fsync off (page cache only) for comparison.
  const auto total = static_cast<std::uint64_t>(gigabytes * 1e9 / 25.5);
  const Stream point{1, 10e6, 1000};
  const WriteFigures wp = write_journal(file, point, total, defaults);
  print_write("write, point sensor, default fsync policy", wp);
  const Stream line{800, 8e6, 800};
  const WriteFigures wl = write_journal(dir / "bench_journal_line.mcap", line, total / 2, defaults);
  print_write("write, line profiler, default fsync policy", wl);
  std::filesystem::remove(dir / "bench_journal_line.mcap");
  acq::JournalOptions no_writeback = defaults;
  no_writeback.writeback_bytes = 0;
  const WriteFigures wk =
      write_journal(dir / "bench_journal_nowb.mcap", point, total, no_writeback);
  print_write("write, point sensor, no early writeback", wk);
  std::filesystem::remove(dir / "bench_journal_nowb.mcap");
  acq::JournalOptions no_sync = defaults;
  no_sync.fsync_bytes = 0;
  no_sync.fsync_interval = std::chrono::nanoseconds(0);
  const WriteFigures wn =
      write_journal(dir / "bench_journal_nosync.mcap", point, total / 4, no_sync);
  print_write("write, point sensor, fsync only at close", wn);
  std::filesystem::remove(dir / "bench_journal_nosync.mcap");

  // The journal's own ceiling: the same stream into a memory file system (no disk).
  if (std::filesystem::is_directory("/dev/shm") &&
      std::filesystem::absolute(dir) != std::filesystem::path("/dev/shm")) {
    const auto shm = std::filesystem::path("/dev/shm") / "bench_journal.mcap";
    const WriteFigures wm = write_journal(shm, point, total / 4, defaults);
    print_write("write, point sensor, into tmpfs (no disk)", wm);
    std::filesystem::remove(shm);
  }

  // Reading and checking the point-sensor journal (warm page cache).
  {
    Counter c;
    const auto t0 = std::chrono::steady_clock::now();
    (void)acq::read_journal(file, c);
    const double s = seconds_since(t0);
    std::printf("%-44s %12.2f M samples/s %9.1f MB/s\n", "read (decode every sample), warm",
                static_cast<double>(c.samples) / s * 1e-6,
                static_cast<double>(std::filesystem::file_size(file)) / s * 1e-6);
  }

  // Recovery of the journal with a torn tail: cut in the middle of its last chunk.
  const auto report = acq::check_journal(file);
  const auto& last = report.scan.chunks.back();
  std::filesystem::resize_file(file, last.offset + last.length / 2);
  const auto bytes = std::filesystem::file_size(file);
  for (const bool cold : {true, false}) {
    if (cold) evict(file);
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = acq::recover_journal(file);
    const double s = seconds_since(t0);
    std::printf(
        "recover %.2f GB with a torn tail (%s cache): %.2f s (%.0f MB/s), kept %llu chunks, "
        "%llu samples, cut %llu bytes\n",
        static_cast<double>(bytes) * 1e-9, cold ? "cold" : "warm", s,
        static_cast<double>(bytes) / s * 1e-6, static_cast<unsigned long long>(r.mcap.kept_chunks),
        static_cast<unsigned long long>(r.kept.samples),
        static_cast<unsigned long long>(r.mcap.cut_bytes));
    if (!cold) break;
    std::filesystem::resize_file(file, last.offset + last.length / 2);  // torn again
  }
  std::filesystem::remove(file);
  std::printf(
      "\ntargets: >= 10 M samples/s and >= 200 MB/s of journal writing: point sensor %s, "
      "%s\n",
      static_cast<double>(wp.samples) / wp.seconds >= 10e6 ? "met" : "NOT met",
      static_cast<double>(wp.bytes) / wp.seconds >= 200e6 ? "met" : "NOT met");
  return 0;
}
