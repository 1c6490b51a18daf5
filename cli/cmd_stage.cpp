// `scanmesh stage status|move|home|jog|probe`: talk to one motion stage (GRBL controller, Modbus
// drives, I++ DME CMM) through its driver and print where it stands, in the stage's own units.
// SPDX-License-Identifier: MIT
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "scanmesh/drivers/error.hpp"
#include "scanmesh/drivers/factory.hpp"
#include "scanmesh/drivers/probing.hpp"

namespace scanmesh::cli {

namespace {

using nlohmann::json;
namespace drv = scanmesh::drivers;
constexpr double kDegPerRad = 180.0 / std::numbers::pi;

struct StageArgs {
  std::string action;
  drv::StageConfig config;
  int timeout_ms = 500;
  double interval_ms = 50;
  double wait_s = 120;
  bool json = false;
  // move / jog
  std::optional<double> x, y, z, a;
  double feed = 1000;
  bool relative = false;
  // probe
  std::string from, dir;
  double travel = 10;
  double tip_radius = 0;
};

/// "1,2,3" -> three finite numbers (ConfigError naming the flag otherwise).
std::array<double, 3> triple(const std::string& text, const std::string& flag) {
  std::array<double, 3> v{};
  std::istringstream in(text);
  std::string part;
  int n = 0;
  while (std::getline(in, part, ',')) {
    char* end = nullptr;
    const double d = std::strtod(part.c_str(), &end);
    if (n >= 3 || part.empty() || end != part.c_str() + part.size() || !std::isfinite(d))
      throw ConfigError("stage probe: " + flag + " must be three numbers X,Y,Z, got '" + text + "'");
    v[n++] = d;
  }
  if (n != 3)
    throw ConfigError("stage probe: " + flag + " must be three numbers X,Y,Z, got '" + text + "'");
  return v;
}

double axis_value(const drv::StagePose& p, drv::StageAxis axis) {
  switch (axis) {
    case drv::StageAxis::kX: return p.x_mm;
    case drv::StageAxis::kY: return p.y_mm;
    case drv::StageAxis::kZ: return p.z_mm;
    case drv::StageAxis::kA: return p.a_rad * kDegPerRad;
  }
  return 0;
}

/// The status in the stage's units: {"status", "position": {"x": mm, "a": deg}, "units", ...}.
json status_json(const drv::MotionStage& stage, const drv::StageStatusReport& r) {
  json pos = json::object(), units = json::object();
  for (const auto& a : stage.capabilities().axes) {
    const std::string name(drv::to_string(a.axis));
    pos[name] = axis_value(r.pose, a.axis);
    units[name] = a.unit;
  }
  json j = {{"device", stage.name()},
            {"status", std::string(drv::to_string(r.status))},
            {"position", pos},
            {"units", units},
            {"t_host_ns", r.t.ns}};
  if (r.alarm_code != 0 || !r.alarm_text.empty()) {
    j["alarm_code"] = r.alarm_code;
    j["alarm_text"] = r.alarm_text;
  }
  return j;
}

void print_status(const drv::MotionStage& stage, const drv::StageStatusReport& r, bool as_json) {
  if (as_json) {
    std::cout << status_json(stage, r).dump() << "\n";
    return;
  }
  std::cout << "status  " << drv::to_string(r.status) << "\n";
  for (const auto& a : stage.capabilities().axes)
    std::cout << drv::to_string(a.axis) << "       " << axis_value(r.pose, a.axis) << " " << a.unit
              << "\n";
  if (r.alarm_code != 0 || !r.alarm_text.empty())
    std::cout << "alarm   " << r.alarm_code << " " << r.alarm_text << "\n";
}

/// Waits until the stage stands; a stage still moving after the wait, or lost, is exit 5.
drv::StageStatusReport wait_standing(drv::MotionStage& stage, double wait_s) {
  const auto r = stage.wait_idle(std::chrono::milliseconds(static_cast<std::int64_t>(wait_s * 1000)));
  if (r.status == drv::StageStatus::kLost)
    throw drv::DeviceError(drv::DeviceErrorKind::kDisconnected, stage.name(), "wait", "lost");
  if (r.status == drv::StageStatus::kMoving || r.status == drv::StageStatus::kHoming)
    throw drv::DeviceError(drv::DeviceErrorKind::kTimeout, stage.name(), "wait",
                           "still " + std::string(drv::to_string(r.status)) + " after " +
                               std::to_string(wait_s) + " s");
  return r;
}

int run_stage(StageArgs args) {
  auto& cfg = args.config;
  if (cfg.port.empty() == cfg.tcp.empty())
    throw ConfigError("stage: give exactly one of --port PATH and --tcp HOST:PORT");
  if (args.timeout_ms < 1 || args.timeout_ms > 60000)
    throw ConfigError("stage: --timeout must be 1..60000 ms");
  if (!(args.interval_ms >= 1 && args.interval_ms <= 10000))
    throw ConfigError("stage: --interval must be 1..10000 ms");
  if (cfg.options.name == "stage") cfg.options.name = cfg.driver;
  cfg.options.timeout = std::chrono::milliseconds(args.timeout_ms);
  cfg.options.poll_interval =
      std::chrono::microseconds(static_cast<std::int64_t>(args.interval_ms * 1000));
  cfg.options.homing_timeout =
      std::chrono::milliseconds(static_cast<std::int64_t>(std::max(1.0, args.wait_s) * 1000));
  const bool motion = args.action == "move" || args.action == "jog";
  drv::StageTarget target;
  if (motion) {
    target.x_mm = args.x;
    target.y_mm = args.y;
    target.z_mm = args.z;
    if (args.a) target.a_rad = *args.a / kDegPerRad;
    if (target.empty()) throw ConfigError("stage " + args.action + ": give at least one of --x --y --z --a");
  }
  std::array<double, 3> from{}, dir{};
  if (args.action == "probe") {
    if (args.from.empty() || args.dir.empty())
      throw ConfigError("stage probe: --from X,Y,Z and --dir I,J,K are required");
    from = triple(args.from, "--from");
    dir = triple(args.dir, "--dir");
  }
  auto stage = drv::make_motion_stage(cfg);
  stage->open();  // throws DeviceError (exit 5) when the controller does not answer
  stage->start({});
  int status = kExitOk;
  if (args.action == "status") {
    // A fresh report, taken after the worker started.
    const auto first = stage->status();
    auto r = stage->wait_idle(std::chrono::milliseconds(args.timeout_ms * 4));
    if (!r.has_report) r = first;
    print_status(*stage, r, args.json);
  } else if (args.action == "home") {
    stage->home();
    print_status(*stage, wait_standing(*stage, args.wait_s), args.json);
  } else if (motion) {
    if (args.action == "jog")
      stage->jog(target, args.feed);
    else if (args.relative)
      stage->move_by(target, args.feed);
    else
      stage->move_to(target, args.feed);
    const auto r = wait_standing(*stage, args.wait_s);
    print_status(*stage, r, args.json);
    if (r.status == drv::StageStatus::kAlarm) status = kExitDevice;
  } else {
    drv::ProbeRequest q;
    q.x_mm = from[0];
    q.y_mm = from[1];
    q.z_mm = from[2];
    q.i = dir[0];
    q.j = dir[1];
    q.k = dir[2];
    q.travel_mm = args.travel;
    q.tip_radius_mm = args.tip_radius;
    q.feed_mm_min = args.feed;
    q.move_timeout = std::chrono::milliseconds(static_cast<std::int64_t>(args.wait_s * 1000));
    const drv::ProbePoint p = drv::probe_point(*stage, q);
    json j = {{"device", stage->name()}, {"outcome", std::string(drv::to_string(p.outcome))}};
    if (p.outcome == drv::ProbePoint::Outcome::kPoint) {
      j["x_mm"] = p.x_mm;
      j["y_mm"] = p.y_mm;
      j["z_mm"] = p.z_mm;
      j["normal"] = {p.i, p.j, p.k};
      j["travel_mm"] = p.travel_mm;
      j["latched"] = {{"x_mm", p.trigger.pose.x_mm},
                      {"y_mm", p.trigger.pose.y_mm},
                      {"z_mm", p.trigger.pose.z_mm}};
      j["compensated_by"] = p.trigger.surface ? "controller" : "tip_radius";
    } else {
      if (p.device_code != 0) j["device_code"] = p.device_code;
      j["detail"] = p.detail;
    }
    if (args.json) {
      std::cout << j.dump() << "\n";
    } else if (p.outcome == drv::ProbePoint::Outcome::kPoint) {
      std::cout << "point   " << p.x_mm << " " << p.y_mm << " " << p.z_mm << " mm\n"
                << "normal  " << p.i << " " << p.j << " " << p.k << "\n"
                << "travel  " << p.travel_mm << " mm\n";
    } else {
      std::cout << drv::to_string(p.outcome) << (p.detail.empty() ? "" : ": " + p.detail) << "\n";
    }
  }
  stage->stop();
  const drv::DeviceStats st = stage->stats();
  stage->close();
  std::cout.flush();
  std::cerr << "scanmesh: " << cfg.options.name << ": " << st.samples << " reports, "
            << st.malformed << " malformed, " << st.error_replies << " error replies, "
            << st.timeouts << " timeouts, " << st.reconnects << " reconnects\n";
  return status;
}

}  // namespace

void add_stage_command(CLI::App& app, Runner& run) {
  auto* stage = app.add_subcommand("stage", "Talk to one motion stage (GRBL, Modbus drives, I++ DME)");
  stage->require_subcommand(1);
  std::string drivers_list;
  for (const auto& d : drv::stage_drivers()) drivers_list += (drivers_list.empty() ? "" : ", ") + d.name;
  for (const char* action : {"status", "move", "home", "jog", "probe"}) {
    auto args = std::make_shared<StageArgs>();
    args->action = action;
    const std::string what = std::string(action) == "status" ? "Print where the stage stands"
                             : std::string(action) == "move" ? "Move to a position and wait"
                             : std::string(action) == "home" ? "Run the homing cycle and wait"
                             : std::string(action) == "jog"  ? "Jog by a distance and wait"
                                                             : "Probe one point";
    auto* cmd = stage->add_subcommand(action, what);
    cmd->add_option("--driver", args->config.driver, "Driver: " + drivers_list)->required();
    cmd->add_option("--port", args->config.port, "Serial port path or usb:VID:PID[:SERIAL]");
    cmd->add_option("--tcp", args->config.tcp, "HOST:PORT (Modbus TCP, I++ DME)");
    cmd->add_option("--baud", args->config.baud, "Baud rate (default: the driver's)");
    cmd->add_option("--parity", args->config.parity, "Serial parity N, E or O (default N)")
        ->check(CLI::IsMember({'N', 'E', 'O'}));
    cmd->add_option("--unit", args->config.unit, "Modbus unit of a single-axis profile");
    cmd->add_option("--profile", args->config.profile,
                    "Drive register-map profile (TOML, config/devices/) for modbus-stage")
        ->check(CLI::ExistingFile);
    cmd->add_flag("--a-axis", args->config.rotary_a, "grbl: the controller has a rotary A axis");
    cmd->add_option("--name", args->config.options.name, "Device name used in messages");
    cmd->add_option("--timeout", args->timeout_ms, "Reply timeout in ms (default 500)");
    cmd->add_option("--interval", args->interval_ms, "Position report period in ms (default 50)");
    cmd->add_option("--wait", args->wait_s, "Longest wait for a motion to end, s (default 120)")
        ->check(kPositive);
    cmd->add_flag("--json", args->json, "One JSON object on stdout");
    if (args->action == "move" || args->action == "jog") {
      cmd->add_option("--x", args->x, "X target / distance, mm");
      cmd->add_option("--y", args->y, "Y target / distance, mm");
      cmd->add_option("--z", args->z, "Z target / distance, mm");
      cmd->add_option("--a", args->a, "A (rotary table) target / distance, degrees");
      cmd->add_option("--feed", args->feed, "Feed, mm/min (deg/min for A alone; default 1000)")
          ->check(kPositive);
      if (args->action == "move") cmd->add_flag("--relative", args->relative, "Distances, not targets");
    }
    if (args->action == "probe") {
      cmd->add_option("--from", args->from, "Approach point X,Y,Z (mm): the tip centre")->required();
      cmd->add_option("--dir", args->dir, "Approach direction I,J,K")->required();
      cmd->add_option("--travel", args->travel, "Longest probing travel, mm (default 10)")
          ->check(kPositive);
      cmd->add_option("--tip-radius", args->tip_radius,
                      "Probe tip radius, mm (default 0; a CMM compensates with its own)")
          ->check(kNonNegative);
      cmd->add_option("--feed", args->feed, "Probing feed, mm/min (default 1000)")->check(kPositive);
    }
    cmd->callback([&run, args] { run = [args] { return run_stage(*args); }; });
  }
}

}  // namespace scanmesh::cli
