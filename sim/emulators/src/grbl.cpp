// GRBL controller emulator (see grbl.hpp). Written apart from the driver's codec on purpose, so
// the tests check two independent readings of the protocol against each other.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/grbl.hpp"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <optional>

#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::sim {

namespace {

using drivers::Timestamp;
constexpr double kRadPerDeg = std::numbers::pi / 180.0;

std::string fmt3(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", std::abs(v) < 0.0005 ? 0.0 : v);
  return buf;
}

/// Appends "v0,v1,..." with 3 decimals.
void append_axes(std::string& out, const double* v, int n) {
  for (int k = 0; k < n; ++k) {
    if (k) out += ',';
    out += fmt3(v[k]);
  }
}

/// One G-code word: a letter and its number.
struct Word {
  char letter;
  double value;
};

/// Splits "G91G1X10.5 F300" into words; false on a letter without a number.
bool words_of(std::string_view line, std::vector<Word>& out) {
  std::size_t i = 0;
  while (i < line.size()) {
    const char c = static_cast<char>(std::toupper(static_cast<unsigned char>(line[i])));
    if (c == ' ') {
      ++i;
      continue;
    }
    if (c < 'A' || c > 'Z') return false;
    ++i;
    const std::size_t start = i;
    while (i < line.size() && (std::isdigit(static_cast<unsigned char>(line[i])) ||
                               line[i] == '.' || line[i] == '-' || line[i] == '+'))
      ++i;
    if (i == start) return false;
    const std::string number(line.substr(start, i - start));
    char* end = nullptr;
    const double v = std::strtod(number.c_str(), &end);
    if (end != number.c_str() + number.size()) return false;
    out.push_back({c, v});
  }
  return true;
}

}  // namespace

GrblEmulator::GrblEmulator(std::string link_path, GrblEmulatorOptions options)
    : SerialEmulator(std::move(link_path), scripted_values({0.0})),
      options_(std::move(options)),
      motion_(std::make_unique<StageMotion>(options_.motion)),
      alarm_(options_.homing_lock),
      planned_end_(options_.motion.start) {}

GrblEmulator::~GrblEmulator() { stop(); }

std::vector<std::string> GrblEmulator::lines() const {
  std::lock_guard lock(lines_mutex_);
  return lines_;
}

std::string GrblEmulator::status_report(Timestamp now) {
  const StagePose p = motion_->pose(now);
  std::string state;
  if (alarm_.load()) {
    state = "Alarm";
  } else if (motion_->held()) {
    state = "Hold:0";
  } else if (motion_->moving(now)) {
    state = jogging_ ? "Jog" : "Run";
  } else {
    jogging_ = false;
    state = "Idle";
  }
  double axes[4] = {p.x_mm, p.y_mm, p.z_mm, p.a_rad / kRadPerDeg};
  const int n = options_.rotary_a ? 4 : 3;
  if (options_.report_wpos)
    for (int k = 0; k < n; ++k) axes[k] -= options_.work_offset[k];
  std::string out = "<" + state + (options_.report_wpos ? "|WPos:" : "|MPos:");
  append_axes(out, axes, n);
  const double feed = motion_->moving(now) ? feed_mm_min_ : 0.0;
  out += "|FS:";
  out += std::to_string(std::lround(feed));
  out += ",0";
  if (motion_->probe_touching(now)) out += "|Pn:P";
  if (options_.wco_every > 0 && reports_ % options_.wco_every == 0) {
    out += "|WCO:";
    append_axes(out, options_.work_offset.data(), n);
  }
  ++reports_;
  return out + ">\r\n";
}

std::string GrblEmulator::reset(Timestamp now) {
  const bool was_moving = motion_->moving(now) || wait_ == Wait::kHoming;
  motion_->abort(now);
  rx_.clear();
  wait_ = Wait::kNone;
  jogging_ = false;
  std::string out;
  if (was_moving) {
    alarm_.store(true);  // position not guaranteed after a reset in motion
    out += "ALARM:3\r\n";
  }
  out += "\r\nGrbl " + options_.version.substr(0, options_.version.find('.', 2)) +
         " ['$' for help]\r\n";
  if (alarm_.load()) out += "[MSG:'$H'|'$X' to unlock]\r\n";
  return out;
}

std::string GrblEmulator::raise(int code, Timestamp now) {
  motion_->abort(now);
  jogging_ = false;
  alarm_.store(true);
  std::string out = "ALARM:" + std::to_string(code) + "\r\n";
  if (wait_ != Wait::kNone) {
    wait_ = Wait::kNone;
    out += "ok\r\n";  // the homing / probing line ends with the alarm
  }
  return out;
}

std::string GrblEmulator::on_input(std::string_view bytes) {
  const Timestamp now = drivers::monotonic_now();
  std::string out;
  for (const char c : bytes) {
    switch (static_cast<unsigned char>(c)) {
      case '?':
        if (wait_ != Wait::kHoming) out += status_report(now);  // no report while homing
        continue;
      case '!':
        if (jogging_) {
          motion_->abort(now);  // a hold during a jog cancels the jog
          jogging_ = false;
        } else {
          motion_->hold(now);
        }
        continue;
      case '~':
        motion_->resume(now);
        continue;
      case 0x18:
        out += reset(now);
        continue;
      case 0x85:
        if (jogging_) {
          motion_->abort(now);
          jogging_ = false;
        }
        continue;
      default:
        break;
    }
    // The ring buffer holds one byte less than its size; what does not fit is lost.
    if (static_cast<int>(rx_.size()) >= options_.rx_buffer_bytes - 1) {
      overflows_.fetch_add(1);
      continue;
    }
    rx_.push_back(c);
    if (static_cast<int>(rx_.size()) > max_fill_.load()) max_fill_.store(static_cast<int>(rx_.size()));
  }
  return out + process_lines(now);
}

std::string GrblEmulator::on_tick() {
  const Timestamp now = drivers::monotonic_now();
  std::string out;
  if (const int code = pending_alarm_.exchange(0); code != 0) out += raise(code, now);
  out += finish_wait(now);
  return out + process_lines(now);
}

std::string GrblEmulator::finish_wait(Timestamp now) {
  switch (wait_) {
    case Wait::kNone:
      return {};
    case Wait::kHoming:
      if (motion_->homing(now)) return {};
      wait_ = Wait::kNone;
      alarm_.store(false);
      return "ok\r\n";
    case Wait::kSync:
      if (motion_->planned(now) > 0) return {};
      wait_ = Wait::kNone;
      return "ok\r\n";
    case Wait::kProbe: {
      const ProbeOutcome o = motion_->probe_outcome(probe_id_, now);
      if (o.kind == ProbeOutcome::Kind::kPending) return {};
      wait_ = Wait::kNone;
      const int n = options_.rotary_a ? 4 : 3;
      const double axes[4] = {o.latched.x_mm, o.latched.y_mm, o.latched.z_mm,
                              o.latched.a_rad / kRadPerDeg};
      std::string prb = "[PRB:";
      append_axes(prb, axes, n);
      switch (o.kind) {
        case ProbeOutcome::Kind::kTriggeredAtStart:
          alarm_.store(true);
          return "ALARM:4\r\nok\r\n";
        case ProbeOutcome::Kind::kContact:
          return prb + ":1]\r\nok\r\n";
        case ProbeOutcome::Kind::kNoContact:
          alarm_.store(true);
          return "ALARM:5\r\n" + prb + ":0]\r\nok\r\n";
        default:
          return {};
      }
    }
  }
  return {};
}

std::string GrblEmulator::process_lines(Timestamp now) {
  std::string out;
  while (wait_ == Wait::kNone) {
    const std::size_t nl = rx_.find('\n');
    if (nl == std::string::npos) break;
    std::string line = rx_.substr(0, nl);
    while (!line.empty() && line.back() == '\r') line.pop_back();
    // Motion lines wait in the receive buffer while the planner is full.
    const bool motion = !line.empty() && (line.rfind("$J=", 0) == 0 ||
                                          (line[0] != '$' && line.find_first_of("XYZAxyza") !=
                                                                 std::string::npos));
    if (motion && static_cast<int>(motion_->planned(now)) >= options_.planner_blocks) break;
    rx_.erase(0, nl + 1);
    {
      std::lock_guard lock(lines_mutex_);
      lines_.push_back(line);
    }
    out += execute(line, now);
  }
  return out;
}

std::string GrblEmulator::execute(const std::string& line, Timestamp now) {
  if (line.empty()) return "ok\r\n";
  if (line.size() > 80) return "error:11\r\n";
  if (line[0] != '$') return execute_gcode(line, false, now);
  if (line == "$I") {
    return "[VER:" + options_.version + ":]\r\n[OPT:V," + std::to_string(options_.planner_blocks) +
           "," + std::to_string(options_.rx_buffer_bytes) + "]\r\nok\r\n";
  }
  if (line == "$X") {
    if (!alarm_.load()) return "ok\r\n";
    alarm_.store(false);
    return "[MSG:Caution: Unlocked]\r\nok\r\n";
  }
  if (line == "$H") {
    if (!options_.homing_enabled) return "error:5\r\n";
    motion_->start_homing(now);
    jogging_ = false;
    wait_ = Wait::kHoming;
    return {};
  }
  if (line == "$$") {
    return std::string("$10=") + (options_.report_wpos ? "0" : "1") + "\r\n$22=" +
           (options_.homing_enabled ? "1" : "0") + "\r\nok\r\n";
  }
  if (line.rfind("$J=", 0) == 0) return execute_gcode(line.substr(3), true, now);
  return "error:3\r\n";
}

std::string GrblEmulator::execute_gcode(const std::string& line, bool jog, Timestamp now) {
  if (alarm_.load()) return "error:9\r\n";  // G-code locked out during alarm
  std::vector<Word> words;
  if (!words_of(line, words)) return "error:1\r\n";
  bool absolute = absolute_;
  int motion_mode = jog ? 1 : -1;  // 0 G0, 1 G1, 382 G38.2, 383 G38.3, 4 G4
  std::optional<double> axis[4];
  std::optional<double> feed;
  for (const Word& w : words) {
    switch (w.letter) {
      case 'G': {
        const int g = static_cast<int>(std::lround(w.value * 10));
        if (g == 900) absolute = true;
        else if (g == 910) absolute = false;
        else if (g == 0 || g == 10) motion_mode = g / 10;
        else if (g == 382 || g == 383) motion_mode = g;
        else if (g == 40) motion_mode = 4;
        else if (g == 210 || g == 170 || g == 940 || g == 540) {
          // mm, XY plane, units/min feed, G54: the emulator's only modes
        } else {
          return "error:20\r\n";
        }
        break;
      }
      case 'X': axis[0] = w.value; break;
      case 'Y': axis[1] = w.value; break;
      case 'Z': axis[2] = w.value; break;
      case 'A':
        if (!options_.rotary_a) return "error:20\r\n";
        axis[3] = w.value;
        break;
      case 'F':
        if (w.value <= 0) return "error:4\r\n";
        feed = w.value;
        break;
      case 'P':
      case 'N':
      case 'M':
        break;
      default:
        return "error:20\r\n";
    }
  }
  if (!jog) absolute_ = absolute;  // a jog line's G90/G91 does not change the modal state
  if (jog && !feed) return "error:22\r\n";
  if (feed) feed_mm_min_ = *feed;
  if (motion_mode == 4) {
    wait_ = Wait::kSync;
    return finish_wait(now);
  }
  const bool any_axis = axis[0] || axis[1] || axis[2] || axis[3];
  if (motion_mode < 0 && any_axis) motion_mode = 1;  // the modal motion of Grbl's start-up
  if (!any_axis) return "ok\r\n";
  // Targets are relative to where the last planned move ends.
  StagePose from = motion_->pose(now);
  if (motion_->planned(now) > 0) from = planned_end_;
  StagePose to = from;
  double* cur[4] = {&to.x_mm, &to.y_mm, &to.z_mm, &to.a_rad};
  for (int k = 0; k < 4; ++k) {
    if (!axis[k]) continue;
    const double v = k == 3 ? *axis[k] * kRadPerDeg : *axis[k];
    *cur[k] = absolute ? v : *cur[k] + v;
  }
  if (motion_mode == 382 || motion_mode == 383) {
    if (!feed_mm_min_) return "error:22\r\n";
    if (to == from) return "error:33\r\n";
    probe_id_ = motion_->queue_probe(to, feed_mm_min_ / 60.0, now);
    wait_ = Wait::kProbe;
    planned_end_ = to;
    return finish_wait(now);
  }
  if (motion_mode == 1 && feed_mm_min_ <= 0) return "error:22\r\n";
  const double linear = motion_mode == 0 ? Trajectory::kNoCap : feed_mm_min_ / 60.0;
  const double angular = motion_mode == 0 ? Trajectory::kNoCap : feed_mm_min_ / 60.0 * kRadPerDeg;
  motion_->queue_move(to, linear, angular, now);
  planned_end_ = to;
  if (jog) jogging_ = true;
  return "ok\r\n";
}

}  // namespace scanmesh::sim
