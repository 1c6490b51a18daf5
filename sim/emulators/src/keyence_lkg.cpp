// KEYENCE LK-G controller emulator (see keyence_lkg.hpp). Written apart from the driver's codec
// on purpose, so the tests check two independent readings of the protocol against each other.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/keyence_lkg.hpp"

#include <cmath>
#include <cstdio>

namespace scanmesh::sim {

namespace {

std::string upper(std::string_view s) {
  std::string out(s);
  for (char& c : out)
    if (c >= 'a' && c <= 'z') c = static_cast<char>(c - 'a' + 'A');
  return out;
}

std::string two_digits(int code) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%02d", code % 100);
  return buf;
}

}  // namespace

KeyenceLkgEmulator::KeyenceLkgEmulator(std::string link_path, ValueSource values,
                                       KeyenceLkgEmulatorOptions options)
    : SerialEmulator(std::move(link_path), std::move(values)),
      options_(options),
      auto_output_(options.auto_output) {}

KeyenceLkgEmulator::~KeyenceLkgEmulator() { stop(); }  // before our members go away

std::string KeyenceLkgEmulator::format_value(const drivers::SensorSample& sample, int decimals) {
  using drivers::SensorStatus;
  switch (sample.status) {
    case SensorStatus::kOk:
      break;
    case SensorStatus::kOverRange:
      return sample.value_mm < 0 ? "-FFFFFFF" : "+FFFFFFF";
    case SensorStatus::kNoTarget:
      return "--------";
    default:
      return "XXXXXXXX";
  }
  const double v = sample.value_mm;
  const int width = 7;  // digits and point after the sign
  char body[32];
  std::snprintf(body, sizeof body, "%0*.*f", width, decimals, std::fabs(v));
  if (std::string_view(body).size() > static_cast<std::size_t>(width))
    return v < 0 ? "-FFFFFFF" : "+FFFFFFF";  // does not fit: the controller shows over range
  return std::string(1, v < 0 ? '-' : '+') + body;
}

std::string KeyenceLkgEmulator::answer(std::string_view command) {
  const std::string cmd = upper(command);
  const SerialFaults f = faults();
  if (cmd == "Q0") {
    setting_mode_.store(true);
    return std::string(command) + "\r";
  }
  if (cmd == "R0") {
    setting_mode_.store(false);
    return std::string(command) + "\r";
  }
  if (cmd == "M0" || cmd == "MS") {
    if (f.error_reply)
      return "ER," + std::string(command) + "," + two_digits(options_.error_code) + "\r";
    if (setting_mode_.load()) return "ER," + std::string(command) + ",01\r";
    const std::string v = format_value(next_value(), options_.decimals);
    if (cmd == "M0") return std::string(command) + "," + v + "," + v + "\r";
    return std::string(command) + ",00," + v + ",00," + v + "\r";
  }
  return "ER," + std::string(command.substr(0, 2)) + ",00\r";
}

std::string KeyenceLkgEmulator::on_input(std::string_view bytes) {
  return answer_lines(bytes, pending_,
                      [this](std::string_view request) { return answer(request); });
}

std::string KeyenceLkgEmulator::on_tick() {
  if (!auto_output_.load() || setting_mode_.load()) return {};
  const std::string v = format_value(next_value(), options_.decimals);
  // [unverified] record layout T<out>,<value>: one record per OUT.
  return "T1," + v + "\rT2," + v + "\r";
}

}  // namespace scanmesh::sim
