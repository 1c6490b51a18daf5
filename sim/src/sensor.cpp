// The simulation's ground-truth causes.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/samples.hpp"

namespace scanmesh::sim {

std::string_view to_string(SampleCause cause) {
  switch (cause) {
    case SampleCause::kOk:
      return "ok";
    case SampleCause::kNoHit:
      return "no_hit";
    case SampleCause::kOutOfRange:
      return "out_of_range";
    case SampleCause::kGrazing:
      return "grazing";
    case SampleCause::kShadowed:
      return "shadowed";
    case SampleCause::kDropout:
      return "dropout";
    case SampleCause::kSpike:
      return "spike";
  }
  return "?";
}

}  // namespace scanmesh::sim
