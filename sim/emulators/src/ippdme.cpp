// I++ DME server emulator (see ippdme.hpp). Written apart from the driver's codec on purpose.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/ippdme.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <numbers>
#include <utility>

#include "scanmesh/common/error.hpp"

namespace scanmesh::sim {

namespace {

using drivers::Timestamp;
constexpr double kRadPerDeg = std::numbers::pi / 180.0;

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.4f", std::abs(v) < 5e-5 ? 0.0 : v);
  return buf;
}

/// The numbers inside `name(...)` in `args` (a name at a token boundary); false if absent.
bool arg(const std::string& args, const std::string& name, std::vector<double>& out) {
  std::size_t at = 0;
  for (;;) {
    at = args.find(name + "(", at);
    if (at == std::string::npos) return false;
    if (at == 0 || args[at - 1] == ' ' || args[at - 1] == ',' || args[at - 1] == '(') break;
    ++at;
  }
  const std::size_t open = at + name.size() + 1;
  const std::size_t close = args.find(')', open);
  if (close == std::string::npos) return false;
  out.clear();
  std::string inner = args.substr(open, close - open);
  std::size_t i = 0;
  while (i < inner.size()) {
    while (i < inner.size() && (inner[i] == ' ' || inner[i] == ',')) ++i;
    if (i >= inner.size()) break;
    char* end = nullptr;
    const double v = std::strtod(inner.c_str() + i, &end);
    if (end == inner.c_str() + i) return false;
    out.push_back(v);
    i = static_cast<std::size_t>(end - inner.c_str());
  }
  return true;
}

}  // namespace

IppDmeEmulator::IppDmeEmulator(IppDmeEmulatorOptions options)
    : options_(std::move(options)),
      motion_(std::make_unique<StageMotion>(options_.motion)),
      port_(options_.port) {}

IppDmeEmulator::~IppDmeEmulator() { stop(); }

void IppDmeEmulator::start() {
  stop();
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw Error(std::string("ippdme emulator: socket: ") + std::strerror(errno));
  const int one = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = htons(static_cast<std::uint16_t>(port_));
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(fd, 4) != 0) {
    const std::string msg = std::strerror(errno);
    ::close(fd);
    throw Error("ippdme emulator: listen on 127.0.0.1:" + std::to_string(port_) + ": " + msg);
  }
  socklen_t len = sizeof addr;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  port_ = ntohs(addr.sin_port);
  listen_fd_ = fd;
  thread_ = std::jthread([this](std::stop_token st) { run(st); });
}

void IppDmeEmulator::stop() noexcept {
  if (thread_.joinable()) {
    thread_.request_stop();
    thread_.join();
  }
  close_client();
  if (listen_fd_ >= 0) ::close(listen_fd_);
  listen_fd_ = -1;
}

void IppDmeEmulator::vanish() { stop(); }
void IppDmeEmulator::reappear() { start(); }

void IppDmeEmulator::drop_client() {
  std::lock_guard lock(mutex_);
  pending_drop_ = true;
}

void IppDmeEmulator::set_faults(const IppDmeFaults& faults) {
  std::lock_guard lock(mutex_);
  faults_ = faults;
}

void IppDmeEmulator::raise_error(int code, int severity) {
  std::lock_guard lock(mutex_);
  pending_error_ = code;
  pending_severity_ = severity;
}

void IppDmeEmulator::send_unknown_tag() {
  std::lock_guard lock(mutex_);
  pending_unknown_ = true;
}

std::vector<std::string> IppDmeEmulator::lines() const {
  std::lock_guard lock(mutex_);
  return lines_;
}

void IppDmeEmulator::close_client() noexcept {
  if (client_fd_ >= 0) ::close(client_fd_);
  client_fd_ = -1;
  pending_in_.clear();
  queue_.clear();
  running_head_ = false;
  report_period_s_ = 0;
}

void IppDmeEmulator::send(const std::string& line) {
  if (client_fd_ < 0) return;
  IppDmeFaults f;
  {
    std::lock_guard lock(mutex_);
    f = faults_;
  }
  if (f.silent) return;
  if (f.reply_delay.count() > 0) std::this_thread::sleep_for(f.reply_delay);
  std::string out = f.garbage_before_reply ? std::string("\x13~#", 3) : std::string();
  out += line;
  out += "\r\n";
  std::size_t done = 0;
  while (done < out.size()) {
    const ssize_t n = ::send(client_fd_, out.data() + done, out.size() - done, MSG_NOSIGNAL);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
    } else if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
      pollfd p{client_fd_, POLLOUT, 0};
      ::poll(&p, 1, 10);
    } else {
      return;  // the client is gone
    }
  }
}

void IppDmeEmulator::error_reply(const std::string& tag, int severity, int code,
                                 const std::string& cause, const std::string& text) {
  char number[8];
  std::snprintf(number, sizeof number, "%04d", code);
  send(tag + " ! Error(" + std::to_string(severity) + ", " + number + ", \"" + cause + "\", \"" +
       text + "\")");
  if (severity >= 2) error_state_ = true;
}

std::string IppDmeEmulator::position_data(Timestamp now) const {
  const StagePose p = motion_->pose(now);
  std::string s = "X(" + num(p.x_mm) + "), Y(" + num(p.y_mm) + "), Z(" + num(p.z_mm) + ")";
  if (options_.rotary_table) s += ", R(" + num(p.a_rad / kRadPerDeg) + ")";
  return s;
}

void IppDmeEmulator::on_line(const std::string& line, Timestamp now) {
  {
    std::lock_guard lock(mutex_);
    lines_.push_back(line);
    if (faults_.silent) return;  // a dead controller: nothing is executed either
  }
  Command c;
  c.line = line;
  if (line.size() < 7 || line[5] != ' ') {
    error_reply(line.size() >= 5 ? line.substr(0, 5) : "E0000", 3, 2, "", "No space at pos. 6");
    return;
  }
  c.tag = line.substr(0, 5);
  const std::string rest = line.substr(6);
  const std::size_t open = rest.find('(');
  if (open == std::string::npos || rest.back() != ')') {
    error_reply(c.tag, 3, 8, "", "Protocol error");
    return;
  }
  c.method = rest.substr(0, open);
  c.args = rest.substr(open + 1, rest.size() - open - 2);
  send(c.tag + " &");
  if (c.tag[0] == 'E') {
    execute_fast(c, now);
    return;
  }
  queue_.push_back(c);
  max_queued_.store(std::max(max_queued_.load(), static_cast<int>(queue_.size())));
}

void IppDmeEmulator::execute_fast(const Command& c, Timestamp now) {
  if (c.method == "OnMoveReportE") {
    std::vector<double> t;
    report_period_s_ = arg(c.args, "Time", t) && !t.empty() ? std::max(0.005, t[0]) : 0.1;
    next_report_ = now;
    return;  // a daemon: no `%` while it runs
  }
  if (c.method == "AbortE") {
    motion_->abort(now);
    for (const Command& q : queue_)
      error_reply(q.tag, 2, 6, q.method, "Transaction aborted (Use ClearAllErrors To Continue)");
    queue_.clear();
    running_head_ = false;
    send(c.tag + " %");
    return;
  }
  if (c.method == "GetErrStatusE") {
    send(c.tag + " # ErrStatus(" + std::string(error_state_ ? "1" : "0") + ")");
    send(c.tag + " %");
    return;
  }
  if (c.method == "StopDaemon") {
    report_period_s_ = 0;
    send(c.tag + " %");
    return;
  }
  error_reply(c.tag, 3, 501, c.method, "Unsupported command");
}

bool IppDmeEmulator::step_queue(Timestamp now) {
  if (queue_.empty()) return false;
  const Command c = queue_.front();
  const std::string& m = c.method;
  auto finish = [&] {
    send(c.tag + " %");
    queue_.pop_front();
    running_head_ = false;
    return true;
  };
  auto fail = [&](int severity, int code, const std::string& text) {
    error_reply(c.tag, severity, code, m, text);
    queue_.pop_front();
    running_head_ = false;
    return true;
  };
  if (!running_head_) {
    if (error_state_ && m != "ClearAllErrors" && m != "EndSession" && m != "StartSession")
      return fail(2, 514, "Use ClearAllErrors to continue");
    std::vector<double> v;
    if (m == "StartSession" || m == "EndSession" || m == "OnPtMeasReport") return finish();
    if (m == "ClearAllErrors") {
      error_state_ = false;
      return finish();
    }
    if (m == "GetDMEVersion") {
      send(c.tag + " # DMEVersion(\"" + options_.version + "\")");
      return finish();
    }
    if (m == "IsHomed") {
      send(c.tag + " # IsHomed(1)");
      return finish();
    }
    if (m == "Get") {
      send(c.tag + " # " + position_data(now));
      return finish();
    }
    if (m == "GetProp") {
      if (c.args.find("Tool.A.Radius") == std::string::npos)
        return fail(2, 510, "Bad property");
      send(c.tag + " # Tool.A.Radius(" + num(options_.motion.probe.tip_radius_mm) + ")");
      return finish();
    }
    if (m == "SetProp") {
      if (arg(c.args, "Tool.PtMeasPar.Approach", v) && v.size() == 1) approach_ = v[0];
      if (arg(c.args, "Tool.PtMeasPar.Search", v) && v.size() == 1) search_ = v[0];
      if (arg(c.args, "Tool.PtMeasPar.Retract", v) && v.size() == 1) retract_ = v[0];
      if (arg(c.args, "Tool.PtMeasPar.Speed", v) && v.size() == 1 && v[0] > 0) probe_speed_ = v[0];
      if (arg(c.args, "Tool.GoToPar.Speed", v) && v.size() == 1 && v[0] > 0) goto_speed_ = v[0];
      return finish();
    }
    if (m == "Home") {
      motion_->start_homing(now);
      running_head_ = true;
      return false;
    }
    if (m == "GoTo") {
      StagePose to = motion_->pose(now);
      if (arg(c.args, "X", v) && v.size() == 1) to.x_mm = v[0];
      if (arg(c.args, "Y", v) && v.size() == 1) to.y_mm = v[0];
      if (arg(c.args, "Z", v) && v.size() == 1) to.z_mm = v[0];
      if (arg(c.args, "R", v) && v.size() == 1) {
        if (!options_.rotary_table) return fail(3, 1002, "Axis does not exist");
        to.a_rad = v[0] * kRadPerDeg;
      }
      motion_->queue_move(to, goto_speed_, goto_speed_ * kRadPerDeg, now);
      running_head_ = true;
      return false;
    }
    if (m == "PtMeas") {
      std::vector<double> x, y, z, n;
      if (!arg(c.args, "X", x) || !arg(c.args, "Y", y) || !arg(c.args, "Z", z) ||
          !arg(c.args, "IJK", n) || x.size() != 1 || y.size() != 1 || z.size() != 1 ||
          n.size() != 3)
        return fail(3, 502, "Incorrect arguments");
      const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      if (len < 1e-9) return fail(2, 1010, "Vector has no norm");
      StagePose approach = motion_->pose(now);
      approach.x_mm = x[0] + n[0] / len * approach_;
      approach.y_mm = y[0] + n[1] / len * approach_;
      approach.z_mm = z[0] + n[2] / len * approach_;
      probe_start_ = approach;
      motion_->queue_move(approach, goto_speed_, Trajectory::kNoCap, now);
      phase_ = 0;
      running_head_ = true;
      return false;
    }
    return fail(3, 501, "Unsupported command");
  }
  // The head is a motion under way.
  if (m == "Home") return motion_->homing(now) ? false : finish();
  if (m == "GoTo") return motion_->moving(now) ? false : finish();
  // PtMeas phases.
  std::vector<double> x, y, z, n;
  arg(c.args, "X", x);
  arg(c.args, "Y", y);
  arg(c.args, "Z", z);
  arg(c.args, "IJK", n);
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  const double u[3] = {n[0] / len, n[1] / len, n[2] / len};
  if (phase_ == 0) {
    if (motion_->moving(now)) return false;
    StagePose end = probe_start_;
    end.x_mm = x[0] - u[0] * search_;
    end.y_mm = y[0] - u[1] * search_;
    end.z_mm = z[0] - u[2] * search_;
    probe_id_ = motion_->queue_probe(end, probe_speed_, now);
    phase_ = 1;
    return false;
  }
  if (phase_ == 1) {
    const ProbeOutcome o = motion_->probe_outcome(probe_id_, now);
    switch (o.kind) {
      case ProbeOutcome::Kind::kPending:
        return false;
      case ProbeOutcome::Kind::kTriggeredAtStart:
        return fail(2, 1001, "Illegal touch");
      case ProbeOutcome::Kind::kNoContact:
      case ProbeOutcome::Kind::kAborted:
        return fail(2, 1006, "Surface not found");
      case ProbeOutcome::Kind::kContact: {
        // Compensated along the nominal vector: the CMM does not know the true surface normal.
        const double r = options_.motion.probe.tip_radius_mm;
        probe_reply_ = c.tag + " # X(" + num(o.latched.x_mm - u[0] * r) + "), Y(" +
                       num(o.latched.y_mm - u[1] * r) + "), Z(" + num(o.latched.z_mm - u[2] * r) +
                       "), IJK(" + num(u[0]) + ", " + num(u[1]) + ", " + num(u[2]) + ")";
        send(probe_reply_);
        if (retract_ < 0) {
          motion_->queue_move(probe_start_, goto_speed_, Trajectory::kNoCap, now);
        } else if (retract_ > 0) {
          StagePose back = motion_->pose(now);
          back.x_mm += u[0] * retract_;
          back.y_mm += u[1] * retract_;
          back.z_mm += u[2] * retract_;
          motion_->queue_move(back, goto_speed_, Trajectory::kNoCap, now);
        }
        phase_ = 2;
        return false;
      }
    }
  }
  return motion_->moving(now) ? false : finish();
}

void IppDmeEmulator::serve_client(int fd, std::stop_token& stop) {
  client_fd_ = fd;
  char buf[4096];
  while (!stop.stop_requested() && client_fd_ >= 0) {
    {
      std::unique_lock lock(mutex_);
      const int code = std::exchange(pending_error_, 0);
      const int severity = pending_severity_;
      const bool unknown = std::exchange(pending_unknown_, false);
      const bool drop = std::exchange(pending_drop_, false);
      lock.unlock();
      if (drop) {
        close_client();
        return;
      }
      if (code != 0) {
        motion_->abort(drivers::monotonic_now());
        queue_.clear();
        running_head_ = false;
        char number[8];
        std::snprintf(number, sizeof number, "%04d", code);
        send("E0000 ! Error(" + std::to_string(severity) + ", " + number +
             ", \"Machine\", \"raised by the emulator\")");
        error_state_ = severity >= 2;
      }
      if (unknown) send("54321 %");
    }
    pollfd p{client_fd_, POLLIN, 0};
    const int r = ::poll(&p, 1, 2);
    const Timestamp now = drivers::monotonic_now();
    if (r > 0 && (p.revents & (POLLIN | POLLHUP | POLLERR))) {
      const ssize_t n = ::recv(client_fd_, buf, sizeof buf, 0);
      if (n <= 0) {
        close_client();
        return;
      }
      pending_in_.append(buf, static_cast<std::size_t>(n));
      std::size_t nl;
      while ((nl = pending_in_.find('\n')) != std::string::npos) {
        std::string line = pending_in_.substr(0, nl);
        pending_in_.erase(0, nl + 1);
        while (!line.empty() && line.back() == '\r') line.pop_back();
        if (!line.empty()) on_line(line, now);
      }
      if (pending_in_.size() > 65536) pending_in_.clear();  // a flood without line ends
    }
    while (step_queue(now)) {
    }
    if (report_period_s_ > 0 && now >= next_report_) {
      next_report_ = now + std::chrono::nanoseconds(static_cast<std::int64_t>(report_period_s_ * 1e9));
      if (motion_->moving(now) || motion_->homing(now)) send("E0001 # " + position_data(now));
    }
  }
}

void IppDmeEmulator::run(std::stop_token stop) {
  while (!stop.stop_requested()) {
    pollfd p{listen_fd_, POLLIN, 0};
    if (::poll(&p, 1, 20) <= 0) continue;
    const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
    if (fd < 0) continue;
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    error_state_ = false;
    serve_client(fd, stop);
    close_client();
  }
}

}  // namespace scanmesh::sim
