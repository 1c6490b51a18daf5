// Device class of I++ DME CMM controllers (see ippdme/device.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/ippdme/device.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/error.hpp"

namespace scanmesh::drivers::ippdme {

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kDegPerRad = 180.0 / std::numbers::pi;
constexpr auto kReadSlice = std::chrono::milliseconds(10);
constexpr Tag kReportTag{true, 1};

std::string ms_text(std::chrono::milliseconds d) { return std::to_string(d.count()) + " ms"; }

std::string error_words(const Reply& r) {
  return "Error(" + std::to_string(r.severity) + ", " + std::to_string(r.code) + ", \"" +
         std::string(r.cause) + "\", \"" + std::string(r.text) + "\")";
}

}  // namespace

Device::Device(StageOptions options, ByteStreamFactory transport, Options ipp)
    : StageBase(std::move(options)), factory_(std::move(transport)), ipp_(ipp) {
  check_stage_options();
  if (!factory_) throw ConfigError(name() + ": no transport factory");
  if (ipp_.max_in_flight < 1 || ipp_.max_in_flight > 64)
    throw ConfigError(name() + ": max_in_flight must be 1..64");
}

Device::~Device() { close(); }

std::string Device::where() const { return transport_ ? transport_->name() : name(); }

StageCapabilities Device::capabilities() const {
  StageCapabilities c;
  for (StageAxis a : {StageAxis::kX, StageAxis::kY, StageAxis::kZ})
    c.axes.push_back({a, "mm", 0, 0});
  if (ipp_.rotary_table) c.axes.push_back({StageAxis::kA, "deg", 0, 0});
  c.report_rate_hz = 1e6 / static_cast<double>(options().poll_interval.count());
  c.homing = c.probing = true;
  c.compensates_probe = true;
  return c;
}

std::string Device::position_items() const {
  return ipp_.rotary_table ? "X(), Y(), Z(), R()" : "X(), Y(), Z()";
}

StagePose Device::pose_from(const Reply& r, StagePose base) const {
  auto value = [&](std::string_view name, double& out, double factor) {
    if (const Item* it = r.find(name); it && it->count >= 1) out = it->v[0] * factor;
  };
  value("X", base.x_mm, 1);
  value("Y", base.y_mm, 1);
  value("Z", base.z_mm, 1);
  if (ipp_.rotary_table) value("R", base.a_rad, 1 / kDegPerRad);
  return base;
}

StageStatus Device::motion_status() const {
  if (homes_open_ > 0) return StageStatus::kHoming;
  if (motions_open_ > 0) return StageStatus::kMoving;
  const StageStatusReport now = status();
  if (now.alarm_code != 0 || now.status == StageStatus::kAlarm) return StageStatus::kAlarm;
  return StageStatus::kIdle;
}

// ---- transactions (worker) ----

void Device::submit(Transaction t) {
  if (t.tag.event) {
    send(std::move(t));
    return;
  }
  waiting_.push_back(std::move(t));
  flush();
}

void Device::flush() {
  // Bounded: the server's queue is not ours to flood.
  while (!waiting_.empty() && static_cast<int>(open_.size()) < ipp_.max_in_flight) {
    Transaction t = std::move(waiting_.front());
    waiting_.pop_front();
    send(std::move(t));
  }
}

void Device::send(Transaction t) {
  if (!t.tag.event) {
    // Tags cycle through 00001..99999, skipping any still in flight.
    do {
      t.tag = {false, next_tag_};
      next_tag_ = next_tag_ % 99999 + 1;
    } while (open_.count(t.tag.number));
  }
  transport_->write_all(command_line(t.tag, t.method), options().timeout);
  if (t.kind == Kind::kMotion) ++motions_open_;
  if (t.kind == Kind::kHome) ++homes_open_;
  if (t.kind == Kind::kMotion || t.kind == Kind::kHome) last_report_ = Clock::now();
  if (t.tag.event) {
    events_[t.tag.number] = std::move(t);
  } else {
    open_[t.tag.number] = std::move(t);
    max_seen_.store(std::max(max_seen_.load(), static_cast<int>(open_.size())));
  }
}

void Device::dispatch(const Reply& r, Timestamp t_host, bool& answered) {
  if (r.tag == kReportTag && r.marker == Marker::kData) {
    // The move-report daemon: the position while the normal queue is busy moving.
    answered = true;
    last_report_ = Clock::now();
    publish(pose_from(r, status().pose), motion_status(), t_host);
    return;
  }
  if (r.tag.event && r.tag.number == 0) {
    // Unsolicited event: an error raised by the machine (emergency stop, collision ...).
    answered = true;
    if (r.marker == Marker::kError) {
      counters().error_replies.fetch_add(1);
      set_alarm(r.code, std::to_string(r.code) + " " + std::string(r.text));
    }
    return;
  }
  auto& table = r.tag.event ? events_ : open_;
  const auto it = table.find(r.tag.number);
  if (it == table.end()) {
    if (r.tag == kReportTag) return;  // the daemon's own & and %
    // A reply for a tag not in flight: counted, never trusted.
    unknown_tags_.fetch_add(1);
    counters().malformed.fetch_add(1);
    return;
  }
  answered = true;
  Transaction& t = it->second;
  switch (r.marker) {
    case Marker::kAck:
      if (t.on_ack) t.on_ack();
      return;
    case Marker::kData:
      if (t.on_data) t.on_data(r);
      return;
    case Marker::kComplete:
    case Marker::kError: {
      Transaction done = std::move(t);
      table.erase(it);
      if (done.kind == Kind::kMotion) --motions_open_;
      if (done.kind == Kind::kHome) --homes_open_;
      if (r.marker == Marker::kError) {
        counters().error_replies.fetch_add(1);
        // Severity >= 2: the server waits for ClearAllErrors().
        if (r.severity >= 2 && done.kind != Kind::kGet)
          set_alarm(r.code, std::to_string(r.code) + " " + std::string(r.text) + " (" +
                                std::string(r.cause) + ")");
        if (done.on_error) done.on_error(r);
      } else if (done.on_done) {
        done.on_done();
      }
      if (done.kind == Kind::kMotion || done.kind == Kind::kHome) next_poll_ = Clock::now();
      flush();
      return;
    }
  }
}

void Device::fail_all(const std::string& reason) {
  Reply r;
  r.marker = Marker::kError;
  r.severity = 9;
  r.code = 503;
  r.cause = "connection";
  r.text = reason;
  auto fail = [&](Transaction& t) {
    if (t.on_error) t.on_error(r);
  };
  for (auto& [tag, t] : open_) fail(t);
  for (auto& [tag, t] : events_) fail(t);
  for (auto& t : waiting_) fail(t);
  open_.clear();
  events_.clear();
  waiting_.clear();
  motions_open_ = homes_open_ = 0;
  get_outstanding_ = false;
}

void Device::read_once(std::chrono::milliseconds wait, bool& answered) {
  std::uint8_t buf[1024];
  const std::size_t n = transport_->read_some(buf, wait);
  if (n == 0) return;
  const Timestamp t = monotonic_now();
  decoder_.feed(
      std::span<const std::uint8_t>(buf, n), [&](const Reply& r) { dispatch(r, t, answered); },
      [&](const char*) { counters().malformed.fetch_add(1); });
}

void Device::transact_sync(const std::string& method, std::function<void(const Reply&)> on_data) {
  bool finished = false;
  std::string error;
  Transaction t;
  t.method = method;
  t.on_data = std::move(on_data);
  t.on_done = [&] { finished = true; };
  t.on_error = [&](const Reply& r) {
    finished = true;
    error = error_words(r);
  };
  submit(std::move(t));
  const auto timeout = options().timeout;
  const auto deadline = Clock::now() + timeout;
  while (!finished) {
    const auto now = Clock::now();
    if (now >= deadline)
      throw DeviceError(DeviceErrorKind::kTimeout, where(), method,
                        "no reply within " + ms_text(timeout));
    bool answered = false;
    read_once(std::chrono::ceil<std::chrono::milliseconds>(deadline - now), answered);
  }
  if (!error.empty()) throw DeviceError(DeviceErrorKind::kProtocol, where(), method, error);
}

void Device::handshake() {
  transport_->discard_input();
  decoder_.reset();
  open_.clear();
  events_.clear();
  waiting_.clear();
  motions_open_ = homes_open_ = 0;
  get_outstanding_ = false;
  transact_sync("StartSession()");
  transact_sync("OnPtMeasReport(X(), Y(), Z(), IJK())");
  // The move-report daemon: positions every poll interval while the normal queue moves.
  const double period_s = static_cast<double>(options().poll_interval.count()) * 1e-6;
  transport_->write_all(command_line(kReportTag, "OnMoveReportE(Time(" + format_number(period_s) +
                                                     "), Dis(0), " + position_items() + ")"),
                        options().timeout);
  version_.clear();
  transact_sync("GetDMEVersion()", [&](const Reply& r) {
    const Item* v = r.find("DMEVersion");
    version_ = v ? std::string(v->text) : std::string(r.data);
  });
  // [unverified] the tool radius property; a server without it leaves the radius unknown.
  try {
    transact_sync("GetProp(Tool.A.Radius())", [&](const Reply& r) {
      if (const Item* it = r.find("Tool.A.Radius"); it && it->count == 1)
        tip_radius_mm_.store(it->v[0]);
    });
  } catch (const DeviceError& e) {
    if (e.kind() != DeviceErrorKind::kProtocol) throw;
    transact_sync("ClearAllErrors()");
  }
  StagePose pose;
  transact_sync("Get(" + position_items() + ")", [&](const Reply& r) { pose = pose_from(r, pose); });
  publish(pose, motion_status(), monotonic_now());
  DeviceIdentity id;
  id.vendor = "I++ DME server";
  id.model = "CMM";
  id.firmware = version_;
  set_identity(std::move(id));
}

void Device::open_device() {
  transport_ = factory_();
  handshake();
}

bool Device::reconnect_once() {
  transport_ = factory_();
  handshake();
  return true;
}

void Device::on_start() { next_poll_ = Clock::now(); }

void Device::on_reconnected() {
  next_poll_ = Clock::now();
  clear_alarm_state();
}

Device::Step Device::acquire(std::string& timeout_detail) {
  run_jobs();
  flush();
  auto now = Clock::now();
  const auto timeout = options().timeout;
  const bool moving = motions_open_ > 0 || homes_open_ > 0;
  if (!moving && !get_outstanding_ && now >= next_poll_) {
    Transaction t;
    t.method = "Get(" + position_items() + ")";
    t.kind = Kind::kGet;
    t.on_data = [this](const Reply& r) {
      publish(pose_from(r, status().pose), motion_status(), monotonic_now());
    };
    t.on_done = [this] { get_outstanding_ = false; };
    t.on_error = [this](const Reply&) { get_outstanding_ = false; };
    get_outstanding_ = true;
    get_sent_ = now;
    submit(std::move(t));
    next_poll_ += std::chrono::duration_cast<Clock::duration>(options().poll_interval);
    if (next_poll_ < now) next_poll_ = now + options().poll_interval;
  }
  auto until = now + kReadSlice;
  if (!moving && !get_outstanding_) until = std::min(until, next_poll_);
  const auto wait = std::max(std::chrono::milliseconds(1),
                             std::chrono::ceil<std::chrono::milliseconds>(until - now));
  bool answered = false;
  read_once(wait, answered);
  if (answered) return Step::kAnswered;
  now = Clock::now();
  if (get_outstanding_ && now >= get_sent_ + timeout) {
    // The Get stays in flight (a late reply is still matched by its tag).
    get_sent_ = now;
    timeout_detail = "Get: no reply within " + ms_text(timeout);
    return Step::kTimeout;
  }
  if ((motions_open_ > 0 || homes_open_ > 0) && now >= last_report_ + timeout) {
    last_report_ = now;
    timeout_detail = "OnMoveReportE: no position report within " + ms_text(timeout);
    return Step::kTimeout;
  }
  return Step::kPending;
}

void Device::drop_transport() noexcept {
  fail_all("the connection was dropped");
  if (transport_) {
    try {
      // A polite end of the session; a gone server cannot hear it anyway.
      transport_->write_all(command_line({false, 99999}, "EndSession()"),
                            std::chrono::milliseconds(50));
    } catch (...) {
    }
  }
  transport_.reset();
}

std::string Device::lost_after_timeouts(int count, const std::string& detail) const {
  return where() + ": " + detail + ", " + std::to_string(count) + " times in a row";
}

// ---- commands (caller threads) ----

void Device::call_transaction(const std::string& op, const std::string& method, Kind kind,
                              bool wait_done, std::chrono::milliseconds timeout) {
  call<void>(op, timeout, [this, method, kind, wait_done](auto promise) {
    Transaction t;
    t.method = method;
    t.kind = kind;
    auto settled = std::make_shared<bool>(false);
    auto succeed = [promise, settled] {
      if (!*settled) promise->set_value();
      *settled = true;
    };
    if (wait_done)
      t.on_done = succeed;
    else
      t.on_ack = succeed;
    t.on_error = [this, promise, settled, method](const Reply& r) {
      if (*settled) return;
      *settled = true;
      promise->set_exception(std::make_exception_ptr(
          DeviceError(r.code == 503 && r.severity == 9 ? DeviceErrorKind::kDisconnected
                                                       : DeviceErrorKind::kProtocol,
                      where(), method, error_words(r) + ": " + std::string(error_text(r.code)))));
    };
    if (kind == Kind::kMotion) set_status(StageStatus::kMoving);
    if (kind == Kind::kHome) set_status(StageStatus::kHoming);
    submit(std::move(t));
  });
}

std::string Device::goto_method(const StageTarget& t, const StagePose& from) const {
  std::string m = "GoTo(";
  bool first = true;
  auto add = [&](const char* axis, const std::optional<double>& v, double factor) {
    if (!v) return;
    if (!std::isfinite(*v)) throw ConfigError(name() + ": target is not finite");
    m += (first ? "" : ", ") + std::string(axis) + "(" + format_number(*v * factor) + ")";
    first = false;
  };
  (void)from;
  add("X", t.x_mm, 1);
  add("Y", t.y_mm, 1);
  add("Z", t.z_mm, 1);
  if (t.a_rad) {
    if (!ipp_.rotary_table) throw ConfigError(name() + ": this CMM has no rotary table");
    add("R", t.a_rad, kDegPerRad);
  }
  return m + ")";
}

void Device::move_to(const StageTarget& target, double feed_mm_min) {
  if (!(feed_mm_min > 0) || !std::isfinite(feed_mm_min))
    throw ConfigError(name() + ": move: the feed must be > 0");
  if (target.empty()) throw ConfigError(name() + ": move: no axis given");
  const std::string go = goto_method(target, {});
  call_transaction("SetProp", "SetProp(Tool.GoToPar.Speed(" + format_number(feed_mm_min / 60) + "))",
                   Kind::kPlain, false, options().timeout * 4);
  call_transaction(go, go, Kind::kMotion, false, options().timeout * 4);
}

void Device::move_by(const StageTarget& delta, double feed_mm_min) {
  const StagePose p = status().pose;
  StageTarget t;
  if (delta.x_mm) t.x_mm = p.x_mm + *delta.x_mm;
  if (delta.y_mm) t.y_mm = p.y_mm + *delta.y_mm;
  if (delta.z_mm) t.z_mm = p.z_mm + *delta.z_mm;
  if (delta.a_rad) t.a_rad = p.a_rad + *delta.a_rad;
  move_to(t, feed_mm_min);
}

void Device::jog(const StageTarget& delta, double feed_mm_min) { move_by(delta, feed_mm_min); }

void Device::home() {
  call_transaction("Home()", "Home()", Kind::kHome, false, options().timeout * 4);
}

void Device::clear_alarm() {
  call_transaction("ClearAllErrors()", "ClearAllErrors()", Kind::kPlain, true,
                   options().timeout * 4);
  clear_alarm_state();
}

void Device::halt() {
  // AbortE overtakes the normal queue (fast queue, E-tag); the aborted transactions fail.
  call<void>("AbortE()", options().timeout * 4, [this](auto promise) {
    Transaction t;
    t.tag = {true, next_event_};
    next_event_ = next_event_ % 9999 + 1;
    if (next_event_ == 1) next_event_ = 2;
    t.method = "AbortE()";
    t.on_done = [promise] { promise->set_value(); };
    t.on_error = [this, promise](const Reply& r) {
      promise->set_exception(std::make_exception_ptr(
          DeviceError(DeviceErrorKind::kProtocol, where(), "AbortE()", error_words(r))));
    };
    submit(std::move(t));
  });
  clear_alarm();
}

ProbeMoveResult Device::probe_move(const ProbeMove& m) {
  const double norm = std::sqrt(m.i * m.i + m.j * m.j + m.k * m.k);
  if (!(norm > 1e-9) || !std::isfinite(norm))
    throw ConfigError(name() + ": probe: the direction must be a non-zero vector");
  if (!(m.travel_mm > 0) || !std::isfinite(m.travel_mm) || !(m.feed_mm_min > 0))
    throw ConfigError(name() + ": probe: travel and feed must be > 0");
  const double d[3] = {m.i / norm, m.j / norm, m.k / norm};
  const double half = m.travel_mm / 2;
  call_transaction("SetProp",
                   "SetProp(Tool.PtMeasPar.Approach(" + format_number(half) +
                       "), Tool.PtMeasPar.Search(" + format_number(half) +
                       "), Tool.PtMeasPar.Retract(-1), Tool.PtMeasPar.Speed(" +
                       format_number(m.feed_mm_min / 60) + "))",
                   Kind::kPlain, true, options().timeout * 4);
  const auto limit = options().timeout * 8 +
                     std::chrono::milliseconds(static_cast<std::int64_t>(
                         m.travel_mm / m.feed_mm_min * 60000.0 * 4)) +
                     std::chrono::seconds(2);
  ProbeMoveResult result = call<ProbeMoveResult>("PtMeas", limit, [this, d, half](auto promise) {
    // The nominal point lies half the travel ahead; IJK points from the surface to the probe.
    const StagePose from = status().pose;
    const double nominal[3] = {from.x_mm + d[0] * half, from.y_mm + d[1] * half,
                               from.z_mm + d[2] * half};
    Transaction t;
    t.kind = Kind::kMotion;
    t.method = "PtMeas(X(" + format_number(nominal[0]) + "), Y(" + format_number(nominal[1]) +
               "), Z(" + format_number(nominal[2]) + "), IJK(" + format_number(-d[0]) + ", " +
               format_number(-d[1]) + ", " + format_number(-d[2]) + "))";
    auto result = std::make_shared<ProbeMoveResult>();
    t.on_data = [this, result](const Reply& r) {
      SurfacePoint s;
      const StagePose p = pose_from(r, {});
      s.x_mm = p.x_mm;
      s.y_mm = p.y_mm;
      s.z_mm = p.z_mm;
      if (const Item* n = r.find("IJK"); n && n->count == 3) {
        s.i = n->v[0];
        s.j = n->v[1];
        s.k = n->v[2];
      }
      const double radius = tip_radius_mm_.load();
      result->outcome = ProbeMoveResult::Outcome::kContact;
      result->trigger.t = monotonic_now();
      result->trigger.pose = status().pose;
      result->trigger.pose.x_mm = s.x_mm + radius * s.i;
      result->trigger.pose.y_mm = s.y_mm + radius * s.j;
      result->trigger.pose.z_mm = s.z_mm + radius * s.k;
      result->trigger.surface = s;
    };
    t.on_done = [this, promise, result] {
      if (result->outcome == ProbeMoveResult::Outcome::kContact) publish_probe(result->trigger);
      promise->set_value(*result);
    };
    t.on_error = [this, promise, method = t.method](const Reply& r) {
      ProbeMoveResult out;
      out.device_code = r.code;
      out.detail = error_words(r);
      if (r.code == 1006 || r.code == 1003) {
        out.outcome = ProbeMoveResult::Outcome::kNoContact;
      } else if (r.code == 1001) {
        out.outcome = ProbeMoveResult::Outcome::kTriggeredAtStart;
      } else {
        promise->set_exception(std::make_exception_ptr(
            DeviceError(r.code == 503 && r.severity == 9 ? DeviceErrorKind::kDisconnected
                                                         : DeviceErrorKind::kProtocol,
                        where(), method, error_words(r) + ": " + std::string(error_text(r.code)))));
        return;
      }
      promise->set_value(out);
    };
    set_status(StageStatus::kMoving);
    submit(std::move(t));
  });
  if (result.outcome != ProbeMoveResult::Outcome::kContact) clear_alarm();
  return result;
}

}  // namespace scanmesh::drivers::ippdme
