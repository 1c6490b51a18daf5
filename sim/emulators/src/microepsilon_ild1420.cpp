// Micro-Epsilon ILD1420 emulator (see microepsilon_ild1420.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/microepsilon_ild1420.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

namespace scanmesh::sim {

MicroEpsilonIld1420Emulator::MicroEpsilonIld1420Emulator(std::string link_path, ValueSource values,
                                                         Ild1420EmulatorOptions options)
    : SerialEmulator(std::move(link_path), std::move(values)),
      options_(std::move(options)),
      streaming_(options_.streaming) {}

MicroEpsilonIld1420Emulator::~MicroEpsilonIld1420Emulator() { stop(); }

std::vector<std::string> MicroEpsilonIld1420Emulator::commands() const {
  std::lock_guard lock(mutex_);
  return commands_;
}

std::string MicroEpsilonIld1420Emulator::encode_word(std::uint32_t word, bool first) {
  std::string out(3, '\0');
  out[0] = static_cast<char>(word & 0x3FU);
  out[1] = static_cast<char>(0x40U | ((word >> 6) & 0x3FU));
  out[2] = static_cast<char>(0x80U | (first ? 0U : 0x40U) | ((word >> 12) & 0x3FU));
  return out;
}

std::uint32_t MicroEpsilonIld1420Emulator::raw_distance(double value_mm,
                                                        double measuring_range_mm) {
  const double x = (value_mm / measuring_range_mm + 0.01) * 65520.0 / 1.02;
  if (!(x > 0)) return 0;
  return static_cast<std::uint32_t>(std::lround(std::min(x, 65520.0)));
}

std::string MicroEpsilonIld1420Emulator::on_input(std::string_view bytes) {
  std::string out;
  for (const char c : bytes) {
    if (c == '\r' || c == '\n') {
      if (!line_.empty()) out += answer(line_);
      line_.clear();
    } else if (line_.size() < 256) {
      line_ += c;
    }
  }
  return out;
}

std::string MicroEpsilonIld1420Emulator::answer(const std::string& command) {
  {
    std::lock_guard lock(mutex_);
    commands_.push_back(command);
  }
  // [unverified] error numbers: the manual documents the Exxx form, not this table.
  if (faults().error_reply) return "E200 Command not allowed\r\n->";
  std::string cmd = command;
  for (char& c : cmd) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (cmd == "GETINFO") {
    char mr[64];
    std::snprintf(mr, sizeof mr, "Measuring range: %.2fmm\r\n", options_.measuring_range_mm);
    return "GETINFO\r\nName:     " + options_.name + "\r\nSerial:   " + options_.serial +
           "\r\nOption:   000\r\nArticle:  " + options_.article + "\r\n" +
           (options_.report_measuring_range ? std::string(mr) : std::string()) +
           "Version:  " + options_.version + "\r\n->";
  }
  if (cmd == "OUTPUT NONE") {
    streaming_ = false;
    return "OUTPUT NONE\r\n->";
  }
  if (cmd == "OUTPUT RS422") {
    streaming_ = true;
    return "OUTPUT RS422\r\n->";
  }
  if (cmd.rfind("MEASRATE", 0) == 0 || cmd.rfind("OUTPUT", 0) == 0) return command + "\r\n->";
  return "E100 Unknown command\r\n->";
}

std::string MicroEpsilonIld1420Emulator::block(std::optional<drivers::Timestamp> measured) {
  const drivers::SensorSample s =
      measured ? next_value_at(options_.timed_values, *measured) : next_value();
  if (measured) {  // the timestamp words carry the instant of this measurement
    device_ns_ = std::max<std::int64_t>(0, (*measured - *clock_origin_).count());
    ticks_10us_ = static_cast<std::uint64_t>(device_ns_ / 10'000);
  }
  const bool corrupt = faults().bad_checksum;
  std::uint32_t distance = 0;
  if (s.device_code >= 262075 && s.device_code <= 262082) {
    distance = s.device_code;
  } else {
    switch (s.status) {
      case drivers::SensorStatus::kOk:
        distance = raw_distance(s.value_mm, options_.measuring_range_mm);
        break;
      case drivers::SensorStatus::kNoTarget:
        distance = 262076;
        break;
      case drivers::SensorStatus::kOverRange:
        distance = s.value_mm < 0 ? 262077 : 262078;
        break;
      case drivers::SensorStatus::kAlarm:
      case drivers::SensorStatus::kDeviceError:
        distance = 262082;
        break;
    }
  }
  std::string out;
  bool first = true;
  for (const char w : options_.layout) {
    std::uint32_t word = 0;
    switch (w) {
      case 'd':
        word = distance;
        break;
      case 'c':
        word = counter_ & 0x3FFFFU;
        break;
      case 'l':
        word = static_cast<std::uint32_t>(ticks_10us_ & 0xFFFFU);
        break;
      case 'h':
        word = static_cast<std::uint32_t>((ticks_10us_ >> 16) & 0xFFFFU);
        break;
      default:
        break;
    }
    std::string bytes = encode_word(word, first);
    if (corrupt && (values_sent_ % 5) == 4) bytes.erase(1, 1);  // a dropped M byte
    ++values_sent_;
    out += bytes;
    first = false;
  }
  ++counter_;
  // The device clock: one measuring period per block (1 ms / blocks_per_tick), or the instant
  // the measurement was taken at.
  if (!measured) {
    device_ns_ += 1'000'000 / std::max(1, options_.blocks_per_tick);
    ticks_10us_ = static_cast<std::uint64_t>(device_ns_ / 10'000);
  }
  return out;
}

std::string MicroEpsilonIld1420Emulator::on_tick() {
  if (!streaming_) return {};
  std::string out;
  const int n = std::max(1, options_.blocks_per_tick);
  if (!options_.timed_values) {
    for (int i = 0; i < n; ++i) out += block(std::nullopt);
    return out;
  }
  const drivers::Timestamp now = drivers::monotonic_now();
  const std::chrono::nanoseconds period(1'000'000 / n);
  if (!clock_origin_) clock_origin_ = now - std::chrono::milliseconds(1);
  for (int i = 0; i < n; ++i) {
    drivers::Timestamp t = now - period * (n - 1 - i);
    if (last_measured_ && t < *last_measured_ + period) t = std::min(now, *last_measured_ + period);
    last_measured_ = t;
    out += block(t);
  }
  return out;
}

}  // namespace scanmesh::sim
