// KEYENCE DL-RS1A + IL emulator (see keyence_il.hpp). Written apart from the driver's codec on
// purpose, so the tests check two independent readings of the protocol against each other.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/keyence_il.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace scanmesh::sim {

KeyenceIlEmulator::KeyenceIlEmulator(std::string link_path, ValueSource values,
                                     KeyenceIlEmulatorOptions options)
    : SerialEmulator(std::move(link_path), std::move(values)), options_(options) {}

KeyenceIlEmulator::~KeyenceIlEmulator() { stop(); }  // before our members go away

std::string KeyenceIlEmulator::format(const drivers::SensorSample& s, int amplifier) const {
  using drivers::SensorStatus;
  if (s.status == SensorStatus::kOverRange) return s.value_mm < 0 ? "-FFFFFF" : "+FFFFFF";
  if (s.status != SensorStatus::kOk) return "XXXXXXX";
  const double v = s.value_mm + amplifier;
  char body[48];
  std::snprintf(body, sizeof body, "%0*.*f", 6, options_.decimals, std::fabs(v));
  if (std::string_view(body).size() > 6) return v < 0 ? "-FFFFFF" : "+FFFFFF";
  std::string out(1, v < 0 ? '-' : '+');
  out += body;
  return out;
}

std::string KeyenceIlEmulator::answer(std::string_view request) {
  const SerialFaults f = faults();
  const std::string cmd(request.substr(0, 2));
  std::string out = cmd;
  if (cmd == "M0" || cmd == "MS" || cmd == "SR") {
    if (f.error_reply) {
      char code[8];
      std::snprintf(code, sizeof code, "%02d", options_.error_code % 100);
      return "ER," + cmd + "," + code + "\r\n";
    }
  }
  if ((cmd == "M0" || cmd == "MS") && request.size() == 2) {
    const drivers::SensorSample s = next_value();
    for (int a = 0; a < options_.amplifiers; ++a) {
      if (cmd == "MS") out += s.status == drivers::SensorStatus::kOk ? ",00" : ",08";
      out += ',';
      out += format(s, a);
    }
    return out + "\r\n";
  }
  if (cmd == "SR" && request.size() == 9 && request[2] == ',' && request[5] == ',') {
    const int id = std::atoi(std::string(request.substr(3, 2)).c_str());
    if (id >= options_.amplifiers) return "ER,SR,22\r\n";
    return std::string(request) + ",0\r\n";
  }
  out = "ER,";
  out += cmd.size() == 2 ? cmd : std::string("??");
  out += ",00\r\n";
  return out;
}

std::string KeyenceIlEmulator::on_input(std::string_view bytes) {
  return answer_lines(bytes, pending_,
                      [this](std::string_view request) { return answer(request); });
}

}  // namespace scanmesh::sim
