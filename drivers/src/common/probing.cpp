// Touch-trigger probing on any MotionStage (see probing.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/probing.hpp"

#include <cmath>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers {

std::string_view to_string(ProbePoint::Outcome outcome) {
  switch (outcome) {
    case ProbePoint::Outcome::kPoint:
      return "point";
    case ProbePoint::Outcome::kNoContact:
      return "no_contact";
    case ProbePoint::Outcome::kTriggeredBeforeApproach:
      return "triggered_before_approach";
  }
  return "?";
}

ProbePoint probe_point(MotionStage& stage, const ProbeRequest& q) {
  const double norm = std::sqrt(q.i * q.i + q.j * q.j + q.k * q.k);
  if (!(norm > 1e-9) || !std::isfinite(norm))
    throw ConfigError(stage.name() + ": probe: the direction must be a non-zero vector");
  if (!(q.travel_mm > 0) || !std::isfinite(q.travel_mm))
    throw ConfigError(stage.name() + ": probe: the travel must be > 0 mm");
  if (!(q.tip_radius_mm >= 0) || !std::isfinite(q.tip_radius_mm))
    throw ConfigError(stage.name() + ": probe: the tip radius must be >= 0 mm");
  if (!(q.feed_mm_min > 0) || !(q.approach_feed_mm_min > 0))
    throw ConfigError(stage.name() + ": probe: the feeds must be > 0");
  if (!std::isfinite(q.x_mm) || !std::isfinite(q.y_mm) || !std::isfinite(q.z_mm))
    throw ConfigError(stage.name() + ": probe: the approach point must be finite");
  const double d[3] = {q.i / norm, q.j / norm, q.k / norm};

  stage.move_to({q.x_mm, q.y_mm, q.z_mm, std::nullopt}, q.approach_feed_mm_min);
  const StageStatusReport at = stage.wait_idle(q.move_timeout);
  if (at.status != StageStatus::kIdle)
    throw DeviceError(DeviceErrorKind::kProtocol, stage.name(), "probe: approach",
                      "the stage is " + std::string(to_string(at.status)) +
                          (at.alarm_text.empty() ? "" : " (" + at.alarm_text + ")") +
                          " instead of standing at the approach point");
  const double off = std::sqrt((at.pose.x_mm - q.x_mm) * (at.pose.x_mm - q.x_mm) +
                               (at.pose.y_mm - q.y_mm) * (at.pose.y_mm - q.y_mm) +
                               (at.pose.z_mm - q.z_mm) * (at.pose.z_mm - q.z_mm));
  if (off > 0.01)
    throw DeviceError(DeviceErrorKind::kProtocol, stage.name(), "probe: approach",
                      "the stage stopped " + std::to_string(off) + " mm from the approach point");

  const ProbeMoveResult r = stage.probe_move({d[0], d[1], d[2], q.travel_mm, q.feed_mm_min});
  ProbePoint p;
  p.device_code = r.device_code;
  p.detail = r.detail;
  switch (r.outcome) {
    case ProbeMoveResult::Outcome::kNoContact:
      p.outcome = ProbePoint::Outcome::kNoContact;
      return p;
    case ProbeMoveResult::Outcome::kTriggeredAtStart:
      p.outcome = ProbePoint::Outcome::kTriggeredBeforeApproach;
      return p;
    case ProbeMoveResult::Outcome::kContact:
      break;
  }
  const StagePose& c = r.trigger.pose;
  const double travel =
      (c.x_mm - at.pose.x_mm) * d[0] + (c.y_mm - at.pose.y_mm) * d[1] + (c.z_mm - at.pose.z_mm) * d[2];
  // A latch behind the start or beyond the travel cannot be a point of this approach.
  if (travel < -0.01 || travel > q.travel_mm + 0.01)
    throw DeviceError(DeviceErrorKind::kProtocol, stage.name(), "probe",
                      "latched " + std::to_string(travel) + " mm along the approach, outside 0 .. " +
                          std::to_string(q.travel_mm) + " mm");
  p.outcome = ProbePoint::Outcome::kPoint;
  p.trigger = r.trigger;
  p.travel_mm = travel;
  if (r.trigger.surface) {
    // The controller compensated with its own tip.
    const SurfacePoint& s = *r.trigger.surface;
    p.x_mm = s.x_mm;
    p.y_mm = s.y_mm;
    p.z_mm = s.z_mm;
    p.i = s.i;
    p.j = s.j;
    p.k = s.k;
    return p;
  }
  // Tip centre at the latch, moved by the radius along the approach: exact where the surface
  // faces the approach.
  p.x_mm = c.x_mm + d[0] * q.tip_radius_mm;
  p.y_mm = c.y_mm + d[1] * q.tip_radius_mm;
  p.z_mm = c.z_mm + d[2] * q.tip_radius_mm;
  p.i = -d[0];
  p.j = -d[1];
  p.k = -d[2];
  return p;
}

}  // namespace scanmesh::drivers
