// Test helper: writes the journal tests' scenario into a journal until killed (or for --ms
// milliseconds of sample time), printing "open" once the file exists and "acked N" on stdout
// each time the acknowledged sample count grows, so a test can kill it at any moment and know
// what had been acknowledged. On a write error it prints the last count, the error on stderr,
// and exits 3; with --catalog it records the scan there and, on the error, marks it failed with
// the error as the reason.
// Usage: journal_crash_writer FILE [--ms N] [--quiet] [--catalog DB] [--chunk-bytes N]
// SPDX-License-Identifier: MIT
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <string>

#include "journal/scenario.hpp"
#include "scanmesh/acquisition/catalog.hpp"
#include "scanmesh/acquisition/journal.hpp"

namespace {

void say(const std::string& line) {
  const std::string s = line + "\n";
  std::size_t done = 0;
  while (done < s.size()) {
    const ssize_t w = ::write(1, s.data() + done, s.size() - done);
    if (w <= 0) std::_Exit(4);
    done += static_cast<std::size_t>(w);
  }
}

}  // namespace

int main(int argc, char** argv) {
  using namespace scanmesh;
  if (argc < 2) {
    std::fputs("usage: journal_crash_writer FILE [--ms N] [--quiet]\n", stderr);
    return 2;
  }
  const std::string file = argv[1];
  long long max_ms = -1;
  bool quiet = false;
  std::string catalog_file;
  acq::JournalOptions options;
  for (int i = 2; i < argc; ++i) {
    if (std::strcmp(argv[i], "--ms") == 0 && i + 1 < argc) {
      max_ms = std::atoll(argv[++i]);
    } else if (std::strcmp(argv[i], "--quiet") == 0) {
      quiet = true;
    } else if (std::strcmp(argv[i], "--chunk-bytes") == 0 && i + 1 < argc) {
      options.chunk_bytes = static_cast<std::size_t>(std::atoll(argv[++i]));
    } else if (std::strcmp(argv[i], "--catalog") == 0 && i + 1 < argc) {
      catalog_file = argv[++i];
    }
  }
  std::uint64_t said = 0;
  std::unique_ptr<acq::JournalWriter> w;
  std::optional<acq::Catalog> catalog;
  std::int64_t scan_id = 0;
  try {
    if (!catalog_file.empty()) {
      const auto now = std::chrono::system_clock::now();
      catalog.emplace(acq::Catalog::open(catalog_file, now));
      scan_id = catalog->create_scan({"crash writer", file, {}, {}, {}, {}}, now);
    }
    w = std::make_unique<acq::JournalWriter>(file, options);
    say("open");
    const test::Scenario sc;
    const auto channels = test::begin_scenario(*w);
    for (long long ms = 0; max_ms < 0 || ms < max_ms; ++ms) {
      test::write_step(*w, channels, test::scenario_step(sc, static_cast<int>(ms)));
      const std::uint64_t acked = w->acknowledged_samples();
      if (!quiet && acked != said) {
        say("acked " + std::to_string(acked));
        said = acked;
      }
    }
    w->close();
    say("closed acked " + std::to_string(w->acknowledged_samples()));
  } catch (const acq::JournalWriteError& e) {
    const std::uint64_t acked = w ? w->acknowledged_samples() : 0;
    say("acked " + std::to_string(acked));
    std::fprintf(stderr, "%s\n", e.what());
    if (catalog)
      catalog->finish(scan_id, acq::ScanState::kFailed, e.what(), acked, 0,
                      std::chrono::system_clock::now());
    return 3;
  }
  return 0;
}
