// Touch-trigger probing on top of any MotionStage: move to the approach point, run one probing
// move, and turn the latch into a surface point with the probe tip radius compensated along the
// approach direction, or a clear "no contact" / "triggered before the approach" result.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <string>
#include <string_view>

#include "scanmesh/drivers/motion_stage.hpp"

namespace scanmesh::drivers {

struct ProbeRequest {
  double x_mm = 0, y_mm = 0, z_mm = 0;  ///< approach point: the tip centre before probing
  double i = 0, j = 0, k = -1;          ///< approach direction (normalised here)
  double travel_mm = 10;                ///< longest probing travel, > 0
  /// Tip radius, >= 0. Used when the controller does not compensate itself (capabilities().
  /// compensates_probe: a CMM compensates with its own qualified tip).
  double tip_radius_mm = 0;
  double feed_mm_min = 300;             ///< probing feed, > 0
  double approach_feed_mm_min = 3000;   ///< feed of the move to the approach point, > 0
  std::chrono::milliseconds move_timeout{60000};  ///< longest move to the approach point
};

struct ProbePoint {
  enum class Outcome {
    kPoint,                    ///< a measured point
    kNoContact,                ///< nothing within the travel
    kTriggeredBeforeApproach,  ///< the probe was deflected before the probing move
  };
  Outcome outcome = Outcome::kNoContact;
  double x_mm = 0, y_mm = 0, z_mm = 0;  ///< kPoint: the compensated surface point
  double i = 0, j = 0, k = 0;           ///< kPoint: unit surface normal estimate (towards the probe)
  double travel_mm = 0;                 ///< kPoint: probing travel until the trigger
  ProbeTrigger trigger;                 ///< kPoint: the latch it came from
  int device_code = 0;                  ///< the controller's code for the other outcomes
  std::string detail;                   ///< the controller's words for them
};

/// "point", "no_contact", "triggered_before_approach" (the `scanmesh stage probe --json` words).
std::string_view to_string(ProbePoint::Outcome outcome);

/// Moves to the approach point (the table stays), waits until the stage stands there, probes.
/// Throws ConfigError for a bad request, DeviceError when the stage does not get to the
/// approach point (alarm, timeout, lost) or reports a latch outside the travel: never a
/// made-up point.
ProbePoint probe_point(MotionStage& stage, const ProbeRequest& request);

}  // namespace scanmesh::drivers
