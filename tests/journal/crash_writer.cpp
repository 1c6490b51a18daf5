// Test helper: writes the journal tests' scenario into a journal until killed (or for --ms
// milliseconds of sample time), printing "open" once the file exists and "acked N" on stdout
// each time the acknowledged sample count grows, so a test can kill it at any moment and know
// what had been acknowledged. On a write error it prints the last count, the error on stderr,
// and exits 3.
// Usage: journal_crash_writer FILE [--ms N] [--quiet]
// SPDX-License-Identifier: MIT
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <string>

#include "journal/scenario.hpp"
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
  for (int i = 2; i < argc; ++i) {
    if (std::strcmp(argv[i], "--ms") == 0 && i + 1 < argc) {
      max_ms = std::atoll(argv[++i]);
    } else if (std::strcmp(argv[i], "--quiet") == 0) {
      quiet = true;
    }
  }
  std::uint64_t said = 0;
  std::unique_ptr<acq::JournalWriter> w;
  try {
    w = std::make_unique<acq::JournalWriter>(file);
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
    say("acked " + std::to_string(w ? w->acknowledged_samples() : 0));
    std::fprintf(stderr, "%s\n", e.what());
    return 3;
  }
  return 0;
}
