// libFuzzer entry point for the scan journal's reader, check and recovery (journal_case.hpp):
// a journal is outside input after a crash. Seeds: fuzz/seeds/journal/ (small journals, whole,
// torn and damaged).
// SPDX-License-Identifier: MIT
#include <cstddef>
#include <cstdint>

#include "journal_case.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)scanmesh::fuzz::run_journal_case(data, size);
  return 0;
}
