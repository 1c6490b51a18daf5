// Panasonic HL-G1 emulator (see panasonic_hlg1.hpp). Written apart from the driver's codec on
// purpose, so the tests check two independent readings of the protocol against each other.
// SPDX-License-Identifier: MIT
#include "scanmesh/sim/emulators/panasonic_hlg1.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace scanmesh::sim {

namespace {

unsigned xor_of(std::string_view s) {
  unsigned x = 0;
  for (char c : s) x ^= static_cast<unsigned char>(c);
  return x;
}

std::string hex2(unsigned v) {
  char buf[4];
  std::snprintf(buf, sizeof buf, "%02X", v & 0xFF);
  return buf;
}

std::string dec2(int v) {
  char buf[4];
  std::snprintf(buf, sizeof buf, "%02d", v % 100);
  return buf;
}

}  // namespace

PanasonicHlg1Emulator::PanasonicHlg1Emulator(std::string link_path, ValueSource values,
                                             PanasonicHlg1EmulatorOptions options)
    : SerialEmulator(std::move(link_path), std::move(values)), options_(options) {}

PanasonicHlg1Emulator::~PanasonicHlg1Emulator() { stop(); }  // before our members go away

std::string PanasonicHlg1Emulator::frame(std::string body, const SerialFaults& faults) const {
  if (!options_.reply_bcc && !faults.bad_checksum) return body + "**\r";
  unsigned x = xor_of(body);
  if (faults.bad_checksum) x ^= 0x5A;
  return body + hex2(x) + "\r";
}

std::string PanasonicHlg1Emulator::answer(std::string_view request) {
  const SerialFaults f = faults();
  // %nn#CMD[data]BB
  if (request.size() < 9 || request[0] != '%' || request[3] != '#') return {};
  const int unit = std::atoi(std::string(request.substr(1, 2)).c_str());
  if (unit != options_.unit) return {};  // another head on the bus
  std::string head(1, '%');              // (no "lit" + string: GCC 12 -Wrestrict false positive)
  head += dec2(options_.unit);
  const std::string_view body = request.substr(0, request.size() - 2);
  const std::string_view check = request.substr(request.size() - 2);
  if (check != "**" && check != hex2(xor_of(body))) return frame(head + "!40", f);
  if (f.error_reply) return frame(head + "!" + dec2(options_.error_code), f);
  const std::string_view command = body.substr(4, 3);
  if (command == "RMD") {
    const drivers::SensorSample s = next_value();
    const double counts = std::round(s.value_mm * 1e4);  // 0.1 µm
    if (s.status != drivers::SensorStatus::kOk || !(std::fabs(counts) <= 9999999))
      return frame(head + "!" + dec2(options_.no_value_code), f);
    char value[32];
    std::snprintf(value, sizeof value, "%c%07lld", counts < 0 ? '-' : '+',
                  static_cast<long long>(std::fabs(counts)));
    return frame(head + "$RMD" + value, f);
  }
  if (command == "RSP") return frame(head + "$RSP+00001", f);
  return frame(head + "!42", f);
}

std::string PanasonicHlg1Emulator::on_input(std::string_view bytes) {
  return answer_lines(bytes, pending_,
                      [this](std::string_view request) { return answer(request); });
}

}  // namespace scanmesh::sim
