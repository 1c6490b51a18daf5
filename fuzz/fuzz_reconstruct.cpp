// libFuzzer entry point for the whole reconstruction (scanmesh::recon::reconstruct) on point
// clouds made from the bytes (reconstruct_case.hpp), with the core's debug invariants on: the
// recon sources are compiled into this target without NDEBUG, so the front's invariant checks
// after every step, the turning points' shortcut checks and the insertion's checks assert.
// A broken promise of the output traps.
// SPDX-License-Identifier: MIT
#include <cstdio>

#include "reconstruct_case.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string broken = scanmesh::fuzz::run_reconstruct_case(data, size);
  if (!broken.empty()) {
    std::fprintf(stderr, "fuzz_reconstruct: %s\n", broken.c_str());
    __builtin_trap();
  }
  return 0;
}
