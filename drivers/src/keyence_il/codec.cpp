// KEYENCE DL-RS1A / IL reply parsing (see keyence_il/codec.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/keyence_il/codec.hpp"

namespace scanmesh::drivers::keyence_il {

namespace {

/// M0: values; MS/DR: control output + value pairs.
const char* parse_values(std::string_view rest, bool with_control, Reply& reply) {
  std::string_view field;
  reply.count = 0;
  while (next_field(rest, field)) {
    if (reply.count == kMaxAmplifiers) return "more than 16 amplifiers";
    if (with_control) {
      int control = 0;
      // Quirk: the control output is 2 ASCII digits forming a bit field; passed on raw.
      if (!parse_digits(field, 2, control)) return "control output is not 2 digits";
      reply.control[reply.count] = static_cast<std::uint8_t>(control);
      if (!next_field(rest, field)) return "value missing after control output";
    }
    if (!parse_value(field, reply.readings[reply.count])) return "value field invalid";
    ++reply.count;
  }
  if (reply.count == 0) return "no values";
  return nullptr;
}

}  // namespace

std::string_view error_text(int code) {
  switch (code) {
    case 0:
      return "command error (unknown command or terminator)";
    case 22:
      return "invalid parameter (e.g. write to a read-only item)";
    default:
      return "undocumented error code";
  }
}

bool parse_value(std::string_view field, Reading& reading) {
  if (field.size() < 2 || field.size() > 10) return false;
  // [unverified] alarm: all dashes, or X after an optional sign.
  {
    const std::size_t i = (field[0] == '+' || field[0] == '-') ? 1 : 0;
    const bool all_dash = all_chars_are(field, '-');
    const bool all_x = field.size() - i >= 2 && all_chars_are(field.substr(i), 'X');
    if (all_dash || all_x) {
      reading.status = SensorStatus::kAlarm;
      reading.value = std::numeric_limits<double>::quiet_NaN();
      return true;
    }
  }
  if (field[0] != '+' && field[0] != '-') return false;
  // [unverified] over range: sign + F...
  if (all_chars_are(field.substr(1), 'F')) {
    reading.status = SensorStatus::kOverRange;
    reading.value = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  // Quirk: the point position depends on the head (±**.***, ±***.**, ±****.*), the width
  // does not: sign + 6 characters. A shorter or longer field is a corrupted one.
  if (field.size() != kValueWidth) return false;
  double v = 0;  // parse_fixed_decimal: sign, digits and at most one point, nothing else
  if (!parse_fixed_decimal(field, v)) return false;
  reading.status = SensorStatus::kOk;
  reading.value = v;
  return true;
}

std::string Sr::encode(int id, int data_number) {
  if (id < 0 || id > 99 || data_number < 0 || data_number > 999) return {};
  char buf[16] = {'S',
                  'R',
                  ',',
                  static_cast<char>('0' + id / 10),
                  static_cast<char>('0' + id % 10),
                  ',',
                  static_cast<char>('0' + data_number / 100),
                  static_cast<char>('0' + data_number / 10 % 10),
                  static_cast<char>('0' + data_number % 10),
                  '\r',
                  '\n'};
  return std::string(buf, 11);
}

const char* parse_reply(std::string_view line, Reply& reply) {
  if (line.size() < 2) return "line too short";
  if (line.back() == ',') return "trailing comma";
  const std::string_view cmd = line.substr(0, 2);
  if (line.size() > 2 && line[2] != ',') return "unknown reply header";
  std::string_view rest = line.size() > 2 ? line.substr(3) : std::string_view{};
  std::string_view field;
  if (cmd == "M0") {
    reply.kind = ReplyKind::kM0;
    return parse_values(rest, false, reply);
  }
  if (cmd == "MS" || cmd == "DR") {
    reply.kind = cmd == "MS" ? ReplyKind::kMs : ReplyKind::kDr;
    return parse_values(rest, true, reply);
  }
  if (cmd == "ER") {
    std::string_view command;
    int code = 0;
    if (!next_field(rest, command) || !next_field(rest, field) || !rest.empty())
      return "ER reply needs <cmd>,<code>";
    if (command.size() != 2) return "ER command is not 2 characters";
    if (!parse_digits(field, 2, code)) return "ER code is not 2 digits";
    reply.kind = ReplyKind::kError;
    reply.command = {command[0], command[1]};
    reply.error_code = static_cast<std::uint8_t>(code);
    return nullptr;
  }
  if (cmd == "SR" || cmd == "SW") {
    int id = 0;
    int number = 0;
    if (!next_field(rest, field) || !parse_digits(field, 2, id)) return "ID is not 2 digits";
    if (!next_field(rest, field) || !parse_digits(field, 3, number))
      return "data number is not 3 digits";
    reply.id = static_cast<std::uint8_t>(id);
    reply.data_number = static_cast<std::uint16_t>(number);
    if (cmd == "SW") {
      if (!rest.empty()) return "SW acknowledgement has extra fields";
      reply.kind = ReplyKind::kWriteAck;
      reply.command = {'S', 'W'};
      return nullptr;
    }
    // SR data: up to 10 characters (may itself hold no comma).
    if (rest.empty()) return "SR data missing";
    if (rest.size() > kMaxData || rest.find(',') != std::string_view::npos)
      return "SR data longer than 10 characters";
    reply.kind = ReplyKind::kSr;
    reply.data_size = static_cast<std::uint8_t>(rest.size());
    for (std::size_t i = 0; i < rest.size(); ++i) reply.data[i] = rest[i];
    return nullptr;
  }
  if (cmd == "AW") {
    int number = 0;
    if (!next_field(rest, field) || !parse_digits(field, 3, number) || !rest.empty())
      return "AW acknowledgement needs a 3-digit data number";
    reply.kind = ReplyKind::kWriteAck;
    reply.command = {'A', 'W'};
    reply.data_number = static_cast<std::uint16_t>(number);
    return nullptr;
  }
  return "unknown reply header";
}

}  // namespace scanmesh::drivers::keyence_il
