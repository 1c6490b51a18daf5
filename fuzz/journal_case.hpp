// One journal-reader case made from bytes, shared by the fuzz target (fuzz_journal.cpp) and the
// test that replays its seeds (tests/journal/test_fuzz_seeds.cpp). A journal is outside input
// after a crash: the bytes are written to an in-memory file (memfd) and go through check,
// strict and tolerant reading and recovery. An even first byte puts the MCAP magic in front of
// the rest, so most inputs get past it.
//
// Expected outcomes: InputError (not MCAP, damage in a strict read, a damaged header recovery
// cannot repair in place). Otherwise the promises must hold, or the case traps: a tolerant read
// delivers what check counts; after recover the file is complete with the samples recovery
// reports kept, and a second recover changes nothing.
// SPDX-License-Identifier: MIT
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include "scanmesh/acquisition/journal.hpp"

namespace scanmesh::fuzz {

class CountingVisitor final : public acq::JournalVisitor {
 public:
  std::uint64_t samples = 0;
  void on_sensor(const acq::ChannelInfo&, std::span<const drivers::SensorSample> s) override {
    samples += s.size();
  }
  void on_stage(const acq::ChannelInfo&, const drivers::StageSample&) override { ++samples; }
  void on_probe(const acq::ChannelInfo&, const drivers::ProbeTrigger&) override { ++samples; }
};

/// Returns false when the bytes are not an MCAP file at all.
inline bool run_journal_case(const std::uint8_t* data, std::size_t size) {
  const int fd = ::memfd_create("fuzz_journal", MFD_CLOEXEC);
  if (fd < 0) __builtin_trap();
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  auto put = [&](const void* p, std::size_t n) {
    if (n > 0 && ::write(fd, p, n) != static_cast<ssize_t>(n)) __builtin_trap();
  };
  if (size > 0 && data[0] % 2 == 0) {
    put(acq::mcap::kMagic.data(), acq::mcap::kMagic.size());
    put(data + 1, size - 1);
  } else {
    put(data, size);
  }
  const std::string path = "/proc/self/fd/" + std::to_string(fd);
  acq::JournalReport checked;
  try {
    checked = acq::check_journal(path);
  } catch (const InputError&) {
    return false;  // not an MCAP file
  }
  CountingVisitor tolerant;
  acq::ReadOptions lenient;
  lenient.tolerate_damage = true;
  const auto read = acq::read_journal(path, tolerant, lenient);
  if (tolerant.samples != checked.samples || read.samples != checked.samples) __builtin_trap();
  try {
    CountingVisitor strict;
    (void)acq::read_journal(path, strict);
    if (strict.samples != checked.samples) __builtin_trap();
  } catch (const InputError&) {
  }
  acq::JournalRecovery rec;
  try {
    rec = acq::recover_journal(path);
  } catch (const InputError&) {
    return true;  // a damaged header with data after it: refused, nothing changed
  }
  const auto after = acq::check_journal(path);
  if (!after.scan.complete() || after.samples != rec.kept.samples) __builtin_trap();
  if (!acq::recover_journal(path).mcap.already_complete) __builtin_trap();
  return true;
}

}  // namespace scanmesh::fuzz
