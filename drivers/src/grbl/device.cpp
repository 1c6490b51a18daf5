// Device class of GRBL controllers: flow control, status polling, commands and probing on the
// worker thread (see grbl/device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/grbl/device.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::grbl {

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kDegPerRad = 180.0 / std::numbers::pi;
/// Longest a read slice of the worker blocks: bounds how late a posted command is sent.
constexpr auto kReadSlice = std::chrono::milliseconds(10);

std::string ms_text(std::chrono::milliseconds d) { return std::to_string(d.count()) + " ms"; }

StageStatus stage_status(MachineState s) {
  switch (s) {
    case MachineState::kIdle:
    case MachineState::kCheck:
    case MachineState::kSleep:
      return StageStatus::kIdle;
    case MachineState::kRun:
    case MachineState::kJog:
    case MachineState::kHold:
    case MachineState::kDoor:
      return StageStatus::kMoving;  // a held move is still a move: it resumes with `~`
    case MachineState::kHome:
      return StageStatus::kHoming;
    case MachineState::kAlarm:
      return StageStatus::kAlarm;
  }
  return StageStatus::kIdle;
}

}  // namespace

Device::Device(StageOptions options, ByteStreamFactory transport, Options grbl)
    : StageBase(std::move(options)),
      factory_(std::move(transport)),
      grbl_(grbl),
      rx_budget_(grbl.rx_buffer_bytes - 1) {
  check_stage_options();
  if (!factory_) throw ConfigError(name() + ": no transport factory");
  if (grbl_.rx_buffer_bytes < 16 || grbl_.rx_buffer_bytes > 65536)
    throw ConfigError(name() + ": rx_buffer_bytes must be 16 .. 65536");
  if (!(grbl_.max_feed_mm_min >= 0)) throw ConfigError(name() + ": max feed must be >= 0");
}

Device::~Device() { close(); }

std::string Device::where() const { return transport_ ? transport_->name() : name(); }

StageCapabilities Device::capabilities() const {
  StageCapabilities c;
  for (StageAxis a : {StageAxis::kX, StageAxis::kY, StageAxis::kZ})
    c.axes.push_back({a, "mm", 0, 0});
  if (grbl_.rotary_a) c.axes.push_back({StageAxis::kA, "deg", 0, 0});
  c.max_feed_mm_min = grbl_.max_feed_mm_min;
  c.report_rate_hz = 1e6 / static_cast<double>(options().poll_interval.count());
  c.homing = c.probing = c.jog = true;
  return c;
}

StagePose Device::to_pose(const AxisValues& m) const {
  StagePose p;
  if (m.count > 0) p.x_mm = m.v[0];
  if (m.count > 1) p.y_mm = m.v[1];
  if (m.count > 2) p.z_mm = m.v[2];
  if (grbl_.rotary_a && m.count > 3) p.a_rad = m.v[3] / kDegPerRad;
  return p;
}

AxisWords Device::to_words(const StageTarget& t) const {
  AxisWords w;
  w.x = t.x_mm;
  w.y = t.y_mm;
  w.z = t.z_mm;
  if (t.a_rad) {
    if (!grbl_.rotary_a) throw ConfigError(name() + ": this controller has no A axis");
    w.a = *t.a_rad * kDegPerRad;
  }
  return w;
}

double Device::checked_feed(double feed, const std::string& operation) const {
  if (!(feed > 0) || !std::isfinite(feed))
    throw ConfigError(name() + ": " + operation + ": the feed must be > 0 mm/min");
  return grbl_.max_feed_mm_min > 0 ? std::min(feed, grbl_.max_feed_mm_min) : feed;
}

// ---- commands (caller threads) ----

void Device::send_and_wait(const std::string& operation, std::string bytes, LineKind kind,
                           std::chrono::milliseconds timeout) {
  call<void>(operation, timeout, [this, bytes = std::move(bytes), kind](auto done) mutable {
    Line line;
    line.bytes = std::move(bytes);
    line.kind = kind;
    line.done = std::move(done);
    to_send_.push_back(std::move(line));
  });
}

void Device::move_to(const StageTarget& target, double feed_mm_min) {
  const std::string line = move_line(true, to_words(target), checked_feed(feed_mm_min, "move"));
  // A line waits for its `ok` while the planner is full: bounded by the homing timeout, the
  // device's liveness by the status polls.
  send_and_wait(line.substr(0, line.size() - 1), line, LineKind::kPlain, options().homing_timeout);
}

void Device::move_by(const StageTarget& delta, double feed_mm_min) {
  const std::string line = move_line(false, to_words(delta), checked_feed(feed_mm_min, "move"));
  send_and_wait(line.substr(0, line.size() - 1), line, LineKind::kPlain, options().homing_timeout);
}

void Device::jog(const StageTarget& delta, double feed_mm_min) {
  const std::string line = jog_line(to_words(delta), checked_feed(feed_mm_min, "jog"));
  send_and_wait(line.substr(0, line.size() - 1), line, LineKind::kPlain, options().homing_timeout);
}

void Device::send_line(const std::string& text) {
  if (text.size() + 1 > kMaxLineLength || text.find_first_of("\r\n") != std::string::npos)
    throw ConfigError(name() + ": a G-code line is one line of at most 79 characters");
  send_and_wait(text, text + "\n", LineKind::kPlain, options().homing_timeout);
}

void Device::home() {
  // Returns once $H is written; the status is kHoming until its `ok` (wait_idle()).
  call<void>("$H", options().timeout, [this](auto done) {
    Line line;
    line.bytes = "$H\n";
    line.kind = LineKind::kHome;
    to_send_.push_back(std::move(line));
    set_status(StageStatus::kHoming);
    done->set_value();
  });
}

void Device::clear_alarm() {
  send_and_wait("$X", "$X\n", LineKind::kPlain, options().timeout * 4);
  clear_alarm_state();
}

void Device::write_realtime(char byte) {
  transport_->write_all(std::span(reinterpret_cast<const std::uint8_t*>(&byte), 1),
                        options().timeout);
}

void Device::feed_hold() {
  call<void>("feed hold", options().timeout, [this](auto done) {
    write_realtime(kFeedHold);
    done->set_value();
  });
}

void Device::cycle_start() {
  call<void>("cycle start", options().timeout, [this](auto done) {
    write_realtime(kCycleStart);
    done->set_value();
  });
}

void Device::halt() {
  // Quirk: feed hold first, reset only once the axes stand, so the position is kept.
  call<void>("halt", options().timeout * 8 + std::chrono::milliseconds(2000), [this](auto done) {
    write_realtime(kFeedHold);
    write_realtime(kStatusQuery);  // learn at once whether the hold completed
    status_outstanding_ = true;
    status_sent_ = Clock::now();
    hold_requested_ = true;
    halting_ = std::move(done);
  });
}

ProbeMoveResult Device::probe_move(const ProbeMove& move) {
  const double norm = std::sqrt(move.i * move.i + move.j * move.j + move.k * move.k);
  if (!(norm > 1e-9) || !std::isfinite(norm))
    throw ConfigError(name() + ": probe: the direction must be a non-zero vector");
  if (!(move.travel_mm > 0) || !std::isfinite(move.travel_mm))
    throw ConfigError(name() + ": probe: the travel must be > 0 mm");
  AxisWords w;
  const double s = move.travel_mm / norm;
  // Only the axes that move are written (a zero word would still be legal G-code).
  if (move.i != 0) w.x = move.i * s;
  if (move.j != 0) w.y = move.j * s;
  if (move.k != 0) w.z = move.k * s;
  const std::string line = probe_line(w, checked_feed(move.feed_mm_min, "probe"));
  // The `ok` of G38.2 comes when the probing move has ended.
  const auto travel_time = std::chrono::milliseconds(
      static_cast<std::int64_t>(move.travel_mm / move.feed_mm_min * 60000.0 * 2));
  ProbeMoveResult r = call<ProbeMoveResult>(
      "G38.2", options().homing_timeout + travel_time, [this, line](auto promise) {
        last_probe_.reset();
        last_alarm_ = 0;
        Line l;
        l.bytes = line;
        l.kind = LineKind::kProbe;
        l.probe = std::move(promise);
        to_send_.push_back(std::move(l));
      });
  if (r.outcome != ProbeMoveResult::Outcome::kContact) {
    // Quirk: ALARM:4/5 lock the controller; probing without contact is an expected outcome.
    if (status().status == StageStatus::kAlarm || r.device_code == 4 || r.device_code == 5)
      clear_alarm();
  }
  return r;
}

// ---- worker ----

void Device::flush_lines() {
  // After a soft reset Grbl drops what it receives until it has restarted (its banner).
  if (awaiting_banner_) return;
  const int budget = rx_budget_.load();
  while (!to_send_.empty()) {
    Line& next = to_send_.front();
    const int size = static_cast<int>(next.bytes.size());
    // Character counting: the unacknowledged bytes must fit in the receive buffer.
    if (in_flight_bytes_ + size > budget && !in_flight_.empty()) return;
    transport_->write_all(next.bytes, options().timeout);
    in_flight_bytes_ += size;
    if (next.kind == LineKind::kHome) {
      homing_ = true;
      homing_since_ = Clock::now();
      status_outstanding_ = false;  // Grbl sends no report while homing
    }
    in_flight_.push_back(std::move(next));
    to_send_.pop_front();
  }
}

void Device::complete_line(const Reply& r) {
  if (in_flight_.empty()) {
    // An `ok` nobody waits for (e.g. a line acknowledged after a reset): counted, not trusted.
    counters().malformed.fetch_add(1);
    return;
  }
  Line line = std::move(in_flight_.front());
  in_flight_.pop_front();
  in_flight_bytes_ = std::max(0, in_flight_bytes_ - static_cast<int>(line.bytes.size()));
  const std::string text = line.bytes.substr(0, line.bytes.size() - 1);
  if (r.kind == ReplyKind::kError) counters().error_replies.fetch_add(1);
  auto error = [&] {
    return std::make_exception_ptr(DeviceError(
        DeviceErrorKind::kProtocol, where(), text,
        "error:" + std::to_string(r.code) + ": " + std::string(error_text(r.code))));
  };
  switch (line.kind) {
    case LineKind::kHome:
      homing_ = false;
      if (r.kind == ReplyKind::kError) {
        set_alarm(r.code, "$H: error:" + std::to_string(r.code) + ": " +
                              std::string(error_text(r.code)));
      } else if (last_alarm_ == 0) {
        set_status(StageStatus::kIdle);
      }
      next_poll_ = Clock::now();  // report the home position at once
      break;
    case LineKind::kProbe: {
      if (r.kind == ReplyKind::kError) {
        line.probe->set_exception(error());
        break;
      }
      ProbeMoveResult result;
      if (last_alarm_ == 4) {
        result.outcome = ProbeMoveResult::Outcome::kTriggeredAtStart;
        result.device_code = 4;
        result.detail = "ALARM:4: " + std::string(alarm_text(4));
      } else if (last_probe_ && last_probe_->success) {
        result.outcome = ProbeMoveResult::Outcome::kContact;
        result.trigger.pose = to_pose(last_probe_->pos);
        result.trigger.t = monotonic_now();
      } else {
        result.outcome = ProbeMoveResult::Outcome::kNoContact;
        result.device_code = last_alarm_;
        result.detail = last_alarm_ ? "ALARM:" + std::to_string(last_alarm_) + ": " +
                                          std::string(alarm_text(last_alarm_))
                                    : "[PRB:...:0]: no contact within the travel";
      }
      line.probe->set_value(result);
      next_poll_ = Clock::now();
      break;
    }
    case LineKind::kPlain:
      if (line.done) {
        if (r.kind == ReplyKind::kError)
          line.done->set_exception(error());
        else
          line.done->set_value();
      }
      break;
  }
}

void Device::fail_lines(const std::string& reason) {
  auto fail = [&](Line& l) {
    const auto e = std::make_exception_ptr(
        DeviceError(DeviceErrorKind::kDisconnected, where(),
                    l.bytes.substr(0, l.bytes.size() - 1), reason));
    if (l.done) l.done->set_exception(e);
    if (l.probe) l.probe->set_exception(e);
  };
  for (Line& l : in_flight_) fail(l);
  for (Line& l : to_send_) fail(l);
  in_flight_.clear();
  to_send_.clear();
  in_flight_bytes_ = 0;
  homing_ = false;
}

void Device::on_status(const StatusReport& s, Timestamp t_host) {
  if (s.has_wco) wco_ = s.wco;
  AxisValues machine = s.pos;
  if (!s.machine_pos) {
    // Quirk: WPos reports ($10) are work coordinates: MPos = WPos + WCO.
    for (int k = 0; k < machine.count && k < wco_.count; ++k) machine.v[k] += wco_.v[k];
  }
  StageStatus st = stage_status(s.state);
  if (st == StageStatus::kAlarm) {
    // The status report has no code: keep the one of the last ALARM:N (0 for the start-up lock).
    StageStatusReport now = status();
    if (now.alarm_code == 0 && now.alarm_text.empty())
      set_alarm(0, "alarm state: unlock with $X or home with $H");
  } else if (last_alarm_ != 0) {
    last_alarm_ = 0;  // the controller left the alarm
  }
  publish(to_pose(machine), st, t_host);
  if (hold_requested_ && halting_) {
    // The hold completed (Hold:0), a jog was cancelled (Idle), or an alarm stopped everything.
    const bool stood = (s.state == MachineState::kHold && s.substate == 0) ||
                       s.state == MachineState::kIdle || s.state == MachineState::kAlarm;
    if (stood) {
      write_realtime(kSoftReset);
      fail_lines("halted");
      hold_requested_ = false;
      awaiting_banner_ = true;
      reset_sent_ = Clock::now();
    }
  }
}

void Device::on_reply(const Reply& r, Timestamp t_host, bool& got_status) {
  switch (r.kind) {
    case ReplyKind::kOk:
    case ReplyKind::kError:
      got_ok_ = true;
      complete_line(r);
      break;
    case ReplyKind::kStatus:
      status_outstanding_ = false;
      got_status = true;
      on_status(r.status, t_host);
      break;
    case ReplyKind::kAlarm:
      last_alarm_ = r.code;
      set_alarm(r.code, "ALARM:" + std::to_string(r.code) + ": " + std::string(alarm_text(r.code)));
      break;
    case ReplyKind::kProbe:
      last_probe_ = r.probe;
      if (r.probe.success) {
        ProbeTrigger g;
        g.t = t_host;
        g.pose = to_pose(r.probe.pos);
        publish_probe(g);
      }
      break;
    case ReplyKind::kMessage:
      if (r.tag == "VER") {
        firmware_ = std::string(r.text);
      } else if (r.tag == "OPT") {
        options_text_ = std::string(r.text);
        // [OPT:<codes>,<planner blocks>,<rx buffer bytes>]: count against the real buffer.
        const std::size_t comma = r.text.rfind(',');
        if (comma != std::string_view::npos) {
          int bytes = 0;
          for (char c : r.text.substr(comma + 1)) {
            if (c < '0' || c > '9' || bytes > 1000000) {
              bytes = 0;
              break;
            }
            bytes = bytes * 10 + (c - '0');
          }
          if (bytes >= 16 && bytes - 1 < rx_budget_.load()) rx_budget_.store(bytes - 1);
        }
      }
      break;
    case ReplyKind::kWelcome:
      // Grbl (re)started: whatever was in its buffers is gone.
      if (awaiting_banner_) {
        awaiting_banner_ = false;
        if (halting_) {
          halting_->set_value();
          halting_.reset();
        }
      } else {
        fail_lines("the controller restarted");
      }
      break;
    case ReplyKind::kSetting:
    case ReplyKind::kStartup:
      break;
  }
}

bool Device::handle_input(std::span<const std::uint8_t> bytes, Timestamp t_host) {
  bool got_status = false;
  decoder_.feed(
      bytes, [&](const Reply& r) { on_reply(r, t_host, got_status); },
      [&](const char*) { counters().malformed.fetch_add(1); });
  return got_status;
}

void Device::handshake() {
  transport_->discard_input();
  decoder_.reset();
  in_flight_.clear();
  to_send_.clear();
  in_flight_bytes_ = 0;
  awaiting_banner_ = false;
  got_ok_ = false;
  const std::chrono::milliseconds timeout = options().timeout;
  std::uint8_t buf[256];
  auto exchange = [&](std::string_view request, const std::string& op, auto done) {
    transport_->write_all(request, timeout);
    const auto deadline = Clock::now() + timeout;
    bool got_status = false;
    while (!done(got_status)) {
      const auto now = Clock::now();
      if (now >= deadline)
        throw DeviceError(DeviceErrorKind::kTimeout, where(), op, "no reply within " +
                                                                    ms_text(timeout));
      const std::size_t n = transport_->read_some(
          buf, std::chrono::ceil<std::chrono::milliseconds>(deadline - now));
      if (n > 0) got_status = handle_input(std::span(buf, n), monotonic_now()) || got_status;
    }
  };
  // $I answers ok (or error:8 while running): either way a Grbl answered. [VER:] [OPT:] come
  // before the ok.
  Line info;
  info.bytes = "$I\n";
  in_flight_.push_back(std::move(info));
  in_flight_bytes_ = 3;
  exchange("$I\n", "$I", [&](bool) { return got_ok_; });
  exchange(std::string_view("?", 1), "?", [&](bool got_status) { return got_status; });
  DeviceIdentity id;
  id.vendor = "Grbl";
  id.model = options_text_.empty() ? "Grbl" : "Grbl [OPT:" + options_text_ + "]";
  id.firmware = firmware_;
  set_identity(std::move(id));
}

void Device::open_device() {
  transport_ = factory_();  // throws DeviceError naming the device and the port
  handshake();
}

bool Device::reconnect_once() {
  transport_ = factory_();
  handshake();
  return true;
}

void Device::on_start() {
  next_poll_ = Clock::now();
  status_outstanding_ = false;
}

void Device::on_reconnected() {
  next_poll_ = Clock::now();
  status_outstanding_ = false;
  clear_alarm_state();
}

Device::Step Device::acquire(std::string& timeout_detail) {
  run_jobs();
  flush_lines();
  auto now = Clock::now();
  const auto timeout = options().timeout;
  if (awaiting_banner_ && now - reset_sent_ > timeout * 4) {
    // No banner after a soft reset: carry on (an older firmware may not send one).
    awaiting_banner_ = false;
    if (halting_) {
      halting_->set_value();
      halting_.reset();
    }
  }
  if (homing_) {
    if (now - homing_since_ > options().homing_timeout)
      throw DeviceError(DeviceErrorKind::kTimeout, where(), "$H",
                        "homing not finished within " + ms_text(options().homing_timeout));
  } else if (!status_outstanding_ && now >= next_poll_) {
    write_realtime(kStatusQuery);  // real-time: not counted against the receive buffer
    status_outstanding_ = true;
    status_sent_ = now;
    next_poll_ += std::chrono::duration_cast<Clock::duration>(options().poll_interval);
    if (next_poll_ < now) next_poll_ = now + options().poll_interval;
  }
  auto until = now + kReadSlice;
  if (!status_outstanding_ && !homing_) until = std::min(until, next_poll_);
  if (status_outstanding_) until = std::min(until, status_sent_ + timeout);
  const auto wait = std::max(std::chrono::milliseconds(1),
                             std::chrono::ceil<std::chrono::milliseconds>(until - now));
  std::uint8_t buf[512];
  const std::size_t n = transport_->read_some(buf, wait);
  bool got_status = false;
  if (n > 0) got_status = handle_input(std::span(buf, n), monotonic_now());
  if (got_status) return Step::kAnswered;
  now = Clock::now();
  if (status_outstanding_ && now >= status_sent_ + timeout) {
    status_outstanding_ = false;
    timeout_detail = "?: no status report within " + ms_text(timeout);
    return Step::kTimeout;
  }
  return Step::kPending;
}

void Device::drop_transport() noexcept {
  fail_lines("the connection was dropped");
  if (halting_) {
    halting_->set_exception(std::make_exception_ptr(
        DeviceError(DeviceErrorKind::kDisconnected, name(), "halt", "the connection was dropped")));
    halting_.reset();
  }
  hold_requested_ = false;
  awaiting_banner_ = false;
  transport_.reset();
}

std::string Device::lost_after_timeouts(int count, const std::string& detail) const {
  return where() + ": " + detail + ", " + std::to_string(count) + " times in a row";
}

}  // namespace scanmesh::drivers::grbl
