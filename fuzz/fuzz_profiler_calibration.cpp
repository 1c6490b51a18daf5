// libFuzzer target for the line profiler's calibration files (OpenCV YAML from a user): any
// bytes give a calibration that passes its own checks, or an InputError; never a crash, a hang
// or another exception.
// SPDX-License-Identifier: MIT
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/profiler/calibration.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace prof = scanmesh::drivers::profiler;
  try {
    const prof::ProfilerCalibration c =
        prof::parse_calibration(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.yml");
    // What was accepted is usable.
    if (!prof::camera_problems(c.camera).empty() || !prof::plane_problems(c.plane).empty())
      std::abort();
  } catch (const scanmesh::InputError&) {
  }
  return 0;
}
