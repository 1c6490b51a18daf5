// PtyPair and the SerialEmulator base (see serial_emulator.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/serial_emulator.hpp"

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <utility>

#include "scanmesh/common/error.hpp"

namespace scanmesh::sim {

namespace {

std::string errno_text(const char* what) { return std::string(what) + ": " + std::strerror(errno); }

}  // namespace

PtyPair::PtyPair(std::string link_path) : link_path_(std::move(link_path)) {
  int master = -1;
  int slave = -1;
  char name[256] = {};
  termios tio{};
  cfmakeraw(&tio);
  if (::openpty(&master, &slave, name, &tio, nullptr) != 0)
    throw Error("emulator " + link_path_ + ": " + errno_text("openpty"));
  master_ = master;
  slave_keepalive_ = slave;
  ::fcntl(master_, F_SETFD, FD_CLOEXEC);
  ::fcntl(slave_keepalive_, F_SETFD, FD_CLOEXEC);
  ::fcntl(master_, F_SETFL, ::fcntl(master_, F_GETFL) | O_NONBLOCK);
  slave_path_ = name;
  std::error_code ec;
  std::filesystem::remove(link_path_, ec);
  std::filesystem::create_symlink(slave_path_, link_path_, ec);
  if (ec) {
    reset();
    throw Error("emulator: cannot create link " + link_path_ + ": " + ec.message());
  }
}

PtyPair::PtyPair(PtyPair&& other) noexcept
    : master_(std::exchange(other.master_, -1)),
      slave_keepalive_(std::exchange(other.slave_keepalive_, -1)),
      slave_path_(std::move(other.slave_path_)),
      link_path_(std::move(other.link_path_)) {}

PtyPair& PtyPair::operator=(PtyPair&& other) noexcept {
  if (this != &other) {
    reset();
    master_ = std::exchange(other.master_, -1);
    slave_keepalive_ = std::exchange(other.slave_keepalive_, -1);
    slave_path_ = std::move(other.slave_path_);
    link_path_ = std::move(other.link_path_);
  }
  return *this;
}

PtyPair::~PtyPair() { reset(); }

void PtyPair::reset() noexcept {
  if (master_ >= 0) {
    std::error_code ec;
    std::filesystem::remove(link_path_, ec);
    ::close(master_);
  }
  if (slave_keepalive_ >= 0) ::close(slave_keepalive_);
  master_ = slave_keepalive_ = -1;
}

ValueSource scripted_values(std::vector<double> values_mm) {
  if (values_mm.empty()) throw ConfigError("scripted_values: the script is empty");
  std::uint64_t seq = 0;
  return [values = std::move(values_mm), seq]() mutable {
    drivers::SensorSample s;
    s.seq = seq;
    const double v = values[seq++ % values.size()];
    if (std::isnan(v)) {
      s.status = drivers::SensorStatus::kNoTarget;
      s.value_mm = std::numeric_limits<double>::quiet_NaN();
    } else if (std::isinf(v)) {
      s.status = drivers::SensorStatus::kOverRange;
      s.value_mm = v;
    } else {
      s.status = drivers::SensorStatus::kOk;
      s.value_mm = v;
    }
    return s;
  };
}

ValueSource sample_values(std::vector<drivers::SensorSample> samples) {
  if (samples.empty()) throw ConfigError("sample_values: no samples");
  std::size_t i = 0;
  return [samples = std::move(samples), i]() mutable {
    const drivers::SensorSample s = samples[std::min(i, samples.size() - 1)];
    ++i;
    return s;
  };
}

SerialEmulator::SerialEmulator(std::string link_path, ValueSource values)
    : link_path_(std::move(link_path)), values_(std::move(values)) {}

SerialEmulator::~SerialEmulator() { stop(); }

void SerialEmulator::start() {
  stop();
  {
    std::lock_guard lock(mutex_);
    if (pty_.empty()) pty_.emplace_back(link_path_);
  }
  thread_ = std::jthread([this](std::stop_token st) { run(st); });
}

void SerialEmulator::stop() noexcept {
  if (thread_.joinable()) {
    thread_.request_stop();
    thread_.join();
  }
}

void SerialEmulator::vanish() {
  stop();
  std::lock_guard lock(mutex_);
  pty_.clear();
}

void SerialEmulator::reappear() {
  stop();
  {
    std::lock_guard lock(mutex_);
    pty_.clear();
    pty_.emplace_back(link_path_);
  }
  thread_ = std::jthread([this](std::stop_token st) { run(st); });
}

void SerialEmulator::set_faults(const SerialFaults& faults) {
  std::lock_guard lock(mutex_);
  faults_ = faults;
}

SerialFaults SerialEmulator::faults() const {
  std::lock_guard lock(mutex_);
  return faults_;
}

std::string SerialEmulator::received() const {
  std::lock_guard lock(mutex_);
  return received_;
}

std::string SerialEmulator::answer_lines(std::string_view bytes, std::string& pending,
                                         const std::function<std::string(std::string_view)>& answer,
                                         std::size_t max_line) {
  std::string reply;
  for (const char c : bytes) {
    if (c == '\r') {
      if (!pending.empty()) reply += answer(pending);
      pending.clear();
    } else if (c != '\n' && pending.size() < max_line) {
      pending.push_back(c);
    }
  }
  return reply;
}

drivers::SensorSample SerialEmulator::next_value() {
  measurements_.fetch_add(1);
  return values_();
}

drivers::SensorSample SerialEmulator::next_value_at(const TimedValueSource& timed,
                                                    drivers::Timestamp measured) {
  measurements_.fetch_add(1);
  return timed(measured);
}

void SerialEmulator::send(int fd, const std::string& bytes, const SerialFaults& faults,
                          std::stop_token& stop) {
  if (bytes.empty() || faults.silent) return;
  if (faults.reply_delay.count() > 0) {
    const auto until = std::chrono::steady_clock::now() + faults.reply_delay;
    while (std::chrono::steady_clock::now() < until && !stop.stop_requested())
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  std::string out;
  if (faults.garbage_before_reply) out += std::string("\xFE\x13~#\x00", 5);
  out += bytes;
  const std::size_t chunk = faults.split_every_byte ? 1 : out.size();
  std::size_t done = 0;
  while (done < out.size() && !stop.stop_requested()) {
    const ssize_t n = ::write(fd, out.data() + done, std::min(chunk, out.size() - done));
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      if (faults.split_every_byte) std::this_thread::sleep_for(std::chrono::microseconds(300));
    } else if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
      pollfd p{fd, POLLOUT, 0};
      ::poll(&p, 1, 10);
    } else {
      return;  // the pty is gone
    }
  }
}

void SerialEmulator::run(std::stop_token stop) {
  int fd = -1;
  {
    std::lock_guard lock(mutex_);
    if (pty_.empty()) return;
    fd = pty_.front().master_fd();
  }
  const auto tick = tick_interval();
  auto next_tick = std::chrono::steady_clock::now() + tick;
  char buf[4096];
  while (!stop.stop_requested()) {
    int wait_ms = 10;
    if (tick.count() > 0) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          next_tick - std::chrono::steady_clock::now());
      wait_ms = static_cast<int>(std::clamp<std::int64_t>(left.count(), 0, 10));
    }
    pollfd p{fd, POLLIN, 0};
    const int r = ::poll(&p, 1, wait_ms);
    if (r > 0 && (p.revents & POLLIN)) {
      const ssize_t n = ::read(fd, buf, sizeof buf);
      if (n > 0) {
        const std::string_view chunk(buf, static_cast<std::size_t>(n));
        SerialFaults f;
        {
          std::lock_guard lock(mutex_);
          received_.append(chunk);
          f = faults_;
        }
        send(fd, on_input(chunk), f, stop);
      }
    }
    if (tick.count() > 0) {
      const auto now = std::chrono::steady_clock::now();
      // Catch up on missed ticks (a streaming device does not pause), but bounded per round.
      for (int k = 0; k < 64 && now >= next_tick; ++k) {
        next_tick += tick;
        send(fd, on_tick(), faults(), stop);
      }
      if (now >= next_tick) next_tick = now + tick;
    }
  }
}

}  // namespace scanmesh::sim
