// Panasonic HL-G1 request encoding and reply parsing (see panasonic_hlg1/codec.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/panasonic_hlg1/codec.hpp"

namespace scanmesh::drivers::panasonic_hlg1 {

namespace {

constexpr char kHex[] = "0123456789ABCDEF";


int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

}  // namespace

std::uint8_t bcc(std::string_view text) {
  std::uint8_t x = 0;
  for (const char c : text) x ^= static_cast<std::uint8_t>(c);
  return x;
}

std::string_view error_text(int code) {
  // [unverified] general MEWTOCOL-COM codes; the HL-G1 manual excerpt gives none.
  switch (code) {
    case 40:
      return "BCC error";
    case 41:
      return "format error";
    case 42:
      return "command not supported";
    case 60:
      return "parameter error";
    case 61:
      return "data error";
    default:
      return "undocumented error code";
  }
}

std::size_t encode_request(int unit, std::string_view command, std::string_view data, bool use_bcc,
                           std::span<char> out) {
  if (unit < 0 || unit > 99 || command.size() != 3) return 0;
  const std::size_t size = 1 + 2 + 1 + 3 + data.size() + 2 + 1;
  if (size > out.size()) return 0;
  std::size_t n = 0;
  out[n++] = '%';
  out[n++] = static_cast<char>('0' + unit / 10);
  out[n++] = static_cast<char>('0' + unit % 10);
  out[n++] = '#';
  for (char c : command) out[n++] = c;
  for (char c : data) out[n++] = c;
  if (use_bcc) {
    const std::uint8_t x = bcc(std::string_view(out.data(), n));
    out[n++] = kHex[x >> 4];
    out[n++] = kHex[x & 0xF];
  } else {
    out[n++] = '*';  // documented: ** in place of the BCC
    out[n++] = '*';
  }
  out[n++] = '\r';
  return n;
}

std::string ReadMeasurement::encode(int unit, bool use_bcc) {
  char buf[16];
  return std::string(buf, encode_request(unit, kCommand, {}, use_bcc, buf));
}

std::string ReadSamplingCycle::encode(int unit, bool use_bcc) {
  char buf[16];
  return std::string(buf, encode_request(unit, kCommand, {}, use_bcc, buf));
}

bool parse_counts(std::string_view field, std::int32_t& counts) {
  if (field.size() != kValueWidth || (field[0] != '+' && field[0] != '-')) return false;
  std::int32_t v = 0;
  for (std::size_t i = 1; i < field.size(); ++i) {
    if (!is_ascii_digit(field[i])) return false;
    v = v * 10 + (field[i] - '0');
  }
  counts = field[0] == '-' ? -v : v;
  return true;
}

const char* parse_reply(std::string_view line, Reply& reply) {
  // Shortest frame: %nn!cc + BCC = 8 characters.
  if (line.size() < 8) return "frame too short";
  if (line[0] != '%') return "frame does not start with %";
  if (!is_ascii_digit(line[1]) || !is_ascii_digit(line[2])) return "unit number is not 2 digits";
  const char type = line[3];
  if (type != '$' && type != '!') return "neither $ reply nor ! error";
  // Quirk: ** in place of the BCC is accepted; otherwise the BCC must match.
  const std::string_view body = line.substr(0, line.size() - 2);
  const char b0 = line[line.size() - 2];
  const char b1 = line[line.size() - 1];
  if (b0 == '*' && b1 == '*') {
    reply.bcc_checked = false;
  } else {
    const int hi = hex_value(b0);
    const int lo = hex_value(b1);
    if (hi < 0 || lo < 0) return "BCC is not 2 hex digits";
    if (static_cast<std::uint8_t>(hi * 16 + lo) != bcc(body)) return "bad BCC";
    reply.bcc_checked = true;
  }
  reply.unit = static_cast<std::uint8_t>((line[1] - '0') * 10 + (line[2] - '0'));
  const std::string_view rest = body.substr(4);
  if (type == '!') {
    if (rest.size() != 2 || !is_ascii_digit(rest[0]) || !is_ascii_digit(rest[1]))
      return "error code is not 2 digits";
    reply.kind = ReplyKind::kError;
    reply.error_code = static_cast<std::uint8_t>((rest[0] - '0') * 10 + (rest[1] - '0'));
    return nullptr;
  }
  if (rest.size() < 3) return "command missing";
  for (std::size_t i = 0; i < 3; ++i) {
    const char c = rest[i];
    if (c < 'A' || c > 'Z') return "command is not 3 capital letters";
    reply.command[i] = c;
  }
  const std::string_view data = rest.substr(3);
  if (data.size() > kMaxData) return "data field too long";
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (data[i] == '%' || data[i] == '$' || data[i] == '#' || data[i] == '!')
      return "frame character inside data";
    reply.data[i] = data[i];
  }
  reply.data_size = static_cast<std::uint8_t>(data.size());
  reply.kind = ReplyKind::kData;
  reply.has_value = false;
  if (reply.command_view() == ReadMeasurement::kCommand) {
    // RMD: sign + 7 digits in 0.1 µm; anything else in an RMD reply is malformed.
    if (!parse_counts(data, reply.counts)) return "RMD value is not sign + 7 digits";
    reply.has_value = true;
  }
  return nullptr;
}

}  // namespace scanmesh::drivers::panasonic_hlg1
