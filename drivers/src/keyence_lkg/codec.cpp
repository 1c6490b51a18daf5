// KEYENCE LK-G reply parsing and value formatting (see keyence_lkg/codec.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/keyence_lkg/codec.hpp"

#include <cmath>
#include <cstdio>

namespace scanmesh::drivers::keyence_lkg {

namespace {

char upper(char c) { return (c >= 'a' && c <= 'z') ? static_cast<char>(c - 'a' + 'A') : c; }

/// Header match, case-insensitive: the reply repeats the command as the host sent it.
bool header_is(std::string_view line, std::string_view header) {
  if (line.size() < header.size()) return false;
  for (std::size_t i = 0; i < header.size(); ++i)
    if (upper(line[i]) != header[i]) return false;
  return true;
}

}  // namespace

std::string_view error_text(int code) {
  switch (code) {
    case 0:
      return "command error";
    case 1:
      return "status error (wrong mode)";
    case 20:
      return "command length error";
    case 21:
      return "parameter count error";
    case 22:
      return "invalid parameter";
    case 88:
      return "timeout error";
    case 99:
      return "other error";
    default:
      return "undocumented error code";
  }
}

bool parse_value(std::string_view field, Reading& reading) {
  if (field.empty() || field.size() > kValueWidth) return false;
  // Alarm / invalid value: all dashes (the sign position is a dash too) or X, optionally after
  // a sign. Quirk: these are statuses of a valid reply, not errors.
  {
    const std::size_t i = (field[0] == '+' || field[0] == '-') ? 1 : 0;
    const bool all_dash = field.size() >= kValueWidth - 1 && all_chars_are(field, '-');
    const bool all_x = field.size() - i >= kValueWidth - 1 && all_chars_are(field.substr(i), 'X');
    if (all_dash || all_x) {
      reading.status = SensorStatus::kAlarm;
      reading.value = std::numeric_limits<double>::quiet_NaN();
      return true;
    }
  }
  // Fixed width from here on: sign + 7 characters.
  if (field.size() != kValueWidth || (field[0] != '+' && field[0] != '-')) return false;
  // Over range: sign + FFFFFFF (quirk: the sign tells the side, the value is meaningless).
  if (all_chars_are(field.substr(1), 'F')) {
    reading.status = SensorStatus::kOverRange;
    reading.value = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  double v = 0;  // parse_fixed_decimal: sign, digits and at most one point, nothing else
  if (!parse_fixed_decimal(field, v)) return false;
  reading.status = SensorStatus::kOk;
  reading.value = v;
  return true;
}

void format_value(double value, int decimals, char (&out)[kValueWidth]) {
  if (std::isnan(value)) {
    for (char& c : out) c = 'X';
    return;
  }
  const char sign = value < 0 ? '-' : '+';
  if (decimals < 0) decimals = 0;
  if (decimals > 5) decimals = 5;
  const int digits = decimals > 0 ? 6 : 7;  // the point takes one of the 7 characters
  double limit = 1;
  for (int k = 0; k < digits; ++k) limit *= 10;
  double scaled = std::fabs(value);
  for (int k = 0; k < decimals; ++k) scaled *= 10;
  scaled = std::round(scaled);
  out[0] = sign;
  if (!std::isfinite(value) || scaled >= limit) {
    for (std::size_t k = 1; k < kValueWidth; ++k) out[k] = 'F';
    return;
  }
  auto n = static_cast<std::uint64_t>(scaled);
  // Right-aligned, zero-padded; fill from the end.
  int pos = static_cast<int>(kValueWidth) - 1;
  for (int k = 0; k < decimals; ++k) {
    out[pos--] = static_cast<char>('0' + n % 10);
    n /= 10;
  }
  if (decimals > 0) out[pos--] = '.';
  while (pos >= 1) {
    out[pos--] = static_cast<char>('0' + n % 10);
    n /= 10;
  }
}

const char* parse_reply(std::string_view line, Reply& reply) {
  if (line.size() < 2) return "line too short";
  if (line.back() == ',') return "trailing comma";  // a field is missing
  if (header_is(line, "ER")) {
    // ER,<cmd>,<code>
    if (line.size() < 3 || line[2] != ',') return "ER without fields";
    std::string_view rest = line.substr(3);
    std::string_view cmd;
    std::string_view code;
    if (!next_field(rest, cmd) || !next_field(rest, code) || !rest.empty())
      return "ER reply needs <cmd>,<code>";
    if (cmd.empty() || cmd.size() > reply.error_command.size()) return "ER command field size";
    if (code.size() != 2 || !is_ascii_digit(code[0]) || !is_ascii_digit(code[1]))
      return "ER code is not 2 digits";
    reply.kind = ReplyKind::kError;
    reply.error_command_size = static_cast<std::uint8_t>(cmd.size());
    for (std::size_t i = 0; i < cmd.size(); ++i) reply.error_command[i] = upper(cmd[i]);
    reply.error_code = static_cast<std::uint8_t>((code[0] - '0') * 10 + (code[1] - '0'));
    return nullptr;
  }
  if (line.size() == 2 && header_is(line, "Q0")) {
    reply.kind = ReplyKind::kEnterSetting;
    return nullptr;
  }
  if (line.size() == 2 && header_is(line, "R0")) {
    reply.kind = ReplyKind::kExitSetting;
    return nullptr;
  }
  if (line.size() < 3 || line[2] != ',') return "unknown reply header";
  std::string_view rest = line.substr(3);
  std::string_view field;
  if (header_is(line, "M0")) {
    // M0,<OUT1>[,<OUT2>]
    reply.kind = ReplyKind::kM0;
    reply.count = 0;
    while (next_field(rest, field)) {
      if (reply.count == 2) return "M0 has more than 2 values";
      if (!parse_value(field, reply.readings[reply.count])) return "M0 value field invalid";
      ++reply.count;
    }
    if (!rest.empty() || reply.count == 0) return "M0 value missing";
    return nullptr;
  }
  if (header_is(line, "MS")) {
    // [unverified] MS,<st>,<value>[,<st>,<value>]
    reply.kind = ReplyKind::kMs;
    reply.count = 0;
    while (next_field(rest, field)) {
      if (reply.count == 2) return "MS has more than 2 OUTs";
      if (field.size() != 2) return "MS status is not 2 characters";
      reply.status[reply.count] = {field[0], field[1]};
      if (!next_field(rest, field)) return "MS value missing";
      if (!parse_value(field, reply.readings[reply.count])) return "MS value field invalid";
      ++reply.count;
    }
    if (!rest.empty() || reply.count == 0) return "MS value missing";
    return nullptr;
  }
  if (upper(line[0]) == 'T' && (line[1] == '1' || line[1] == '2')) {
    // [unverified] T<out>,<value>: timed auto-output record
    reply.kind = ReplyKind::kAutoOutput;
    reply.out = static_cast<std::uint8_t>(line[1] - '0');
    if (!next_field(rest, field) || !rest.empty()) return "auto-output record needs one value";
    if (!parse_value(field, reply.readings[0])) return "auto-output value field invalid";
    reply.count = 1;
    return nullptr;
  }
  return "unknown reply header";
}

}  // namespace scanmesh::drivers::keyence_lkg
