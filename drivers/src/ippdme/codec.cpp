// I++ DME line decoding and command encoding (see ippdme/codec.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/ippdme/codec.hpp"

#include <cmath>
#include <cstdio>

namespace scanmesh::drivers::ippdme {

namespace {

bool digit(char c) { return c >= '0' && c <= '9'; }
bool alpha(char c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'); }

void skip_spaces(std::string_view s, std::size_t& i) {
  while (i < s.size() && s[i] == ' ') ++i;
}

bool parse_tag(std::string_view s, Tag& tag) {
  if (s.size() != 5) return false;
  const bool event = s[0] == 'E';
  std::uint32_t n = 0;
  for (std::size_t i = event ? 1 : 0; i < 5; ++i) {
    if (!digit(s[i])) return false;
    n = n * 10 + static_cast<std::uint32_t>(s[i] - '0');
  }
  if (!event && n == 0) return false;  // 00000 is reserved
  tag = {event, n};
  return true;
}

/// A quoted string (ASCII 32-126 except '"'); i at the opening quote.
bool parse_string(std::string_view s, std::size_t& i, std::string_view& out) {
  if (i >= s.size() || s[i] != '"') return false;
  const std::size_t close = s.find('"', i + 1);
  if (close == std::string_view::npos) return false;
  out = s.substr(i + 1, close - i - 1);
  i = close + 1;
  return true;
}

/// A number token: the longest run of number characters.
bool parse_number_at(std::string_view s, std::size_t& i, double& out) {
  const std::size_t start = i;
  while (i < s.size() && (digit(s[i]) || s[i] == '.' || s[i] == '+' || s[i] == '-' ||
                          s[i] == 'E' || s[i] == 'e'))
    ++i;
  return parse_number(s.substr(start, i - start), out);
}

/// `Name(args)` or a bare number; i at its first character.
const char* parse_item(std::string_view s, std::size_t& i, Item& item) {
  item = Item{};
  skip_spaces(s, i);
  if (i >= s.size()) return "empty item";
  if (!alpha(s[i])) {
    double v = 0;
    if (!parse_number_at(s, i, v)) return "bad number";
    item.count = 1;
    item.v[0] = v;
    return nullptr;
  }
  const std::size_t start = i;
  while (i < s.size() && (alpha(s[i]) || digit(s[i]) || s[i] == '.')) ++i;
  item.name = s.substr(start, i - start);
  skip_spaces(s, i);
  if (i >= s.size() || s[i] != '(') {
    // A bare name (an enumeration value such as MachineCsy).
    return nullptr;
  }
  ++i;
  skip_spaces(s, i);
  if (i < s.size() && s[i] == ')') {
    ++i;
    return nullptr;
  }
  for (;;) {
    skip_spaces(s, i);
    if (i >= s.size()) return "unterminated item";
    if (s[i] == '"') {
      std::string_view text;
      if (!parse_string(s, i, text)) return "bad string";
      if (item.text.empty()) item.text = text;
    } else {
      double v = 0;
      if (!parse_number_at(s, i, v)) return "bad number";
      if (item.count >= kMaxArgs) return "too many arguments";
      item.v[item.count++] = v;
    }
    skip_spaces(s, i);
    if (i >= s.size()) return "unterminated item";
    if (s[i] == ')') {
      ++i;
      return nullptr;
    }
    if (s[i] != ',') return "expected ',' or ')'";
    ++i;
  }
}

const char* parse_error(std::string_view s, Reply& r) {
  // Error(F1, F2, "F3", "text")
  std::size_t i = 0;
  skip_spaces(s, i);
  if (s.substr(i, 6) != "Error(") return "error without Error(...)";
  i += 6;
  skip_spaces(s, i);
  if (i >= s.size() || !digit(s[i])) return "error: bad severity";
  r.severity = s[i++] - '0';
  skip_spaces(s, i);
  if (i >= s.size() || s[i++] != ',') return "error: expected ','";
  skip_spaces(s, i);
  if (i + 4 > s.size()) return "error: bad number";
  int code = 0;
  for (std::size_t k = 0; k < 4; ++k) {
    if (!digit(s[i + k])) return "error: bad number";
    code = code * 10 + (s[i + k] - '0');
  }
  r.code = code;
  i += 4;
  for (std::string_view* field : {&r.cause, &r.text}) {
    skip_spaces(s, i);
    if (i >= s.size() || s[i++] != ',') return "error: expected ','";
    skip_spaces(s, i);
    if (!parse_string(s, i, *field)) return "error: bad string";
  }
  skip_spaces(s, i);
  if (i + 1 != s.size() || s[i] != ')') return "error: expected ')'";
  return nullptr;
}

}  // namespace

std::string to_string(Tag tag) {
  char buf[8];
  if (tag.event)
    std::snprintf(buf, sizeof buf, "E%04u", tag.number % 10000);
  else
    std::snprintf(buf, sizeof buf, "%05u", tag.number % 100000);
  return buf;
}

const Item* Reply::find(std::string_view name) const {
  for (std::uint8_t k = 0; k < item_count; ++k)
    if (items[k].name == name) return &items[k];
  return nullptr;
}

bool parse_number(std::string_view t, double& out) {
  if (t.empty() || t.size() > 16) return false;
  std::size_t i = 0;
  bool negative = false;
  if (t[i] == '+' || t[i] == '-') negative = t[i++] == '-';
  std::int64_t mantissa = 0;
  int digits = 0, decimals = 0;
  bool point = false;
  for (; i < t.size(); ++i) {
    const char c = t[i];
    if (digit(c)) {
      mantissa = mantissa * 10 + (c - '0');
      ++digits;
      if (point) ++decimals;
    } else if (c == '.' && !point) {
      point = true;
    } else {
      break;
    }
  }
  if (digits == 0) return false;
  int exponent = 0;
  if (i < t.size()) {
    if (t[i] != 'E' && t[i] != 'e') return false;
    ++i;
    bool neg_exp = false;
    if (i < t.size() && (t[i] == '+' || t[i] == '-')) neg_exp = t[i++] == '-';
    int n = 0, e = 0;
    for (; i < t.size() && digit(t[i]); ++i, ++n) e = e * 10 + (t[i] - '0');
    if (n == 0 || n > 3 || i != t.size()) return false;
    exponent = neg_exp ? -e : e;
  }
  static constexpr double kPow10[] = {1, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9,
                                      1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16};
  double v = static_cast<double>(mantissa);
  const int e = exponent - decimals;
  if (e >= 0 && e <= 16)
    v *= kPow10[e];
  else if (e < 0 && e >= -16)
    v /= kPow10[-e];
  else
    v *= std::pow(10.0, e);
  if (!std::isfinite(v)) return false;
  out = negative ? -v : v;
  return true;
}

std::string format_number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6f", v);
  std::string s(buf);
  while (!s.empty() && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  if (s == "-0") s = "0";
  if (s.size() > 16) {
    std::snprintf(buf, sizeof buf, "%.9E", v);  // huge values: mantissa and exponent
    s = buf;
  }
  return s;
}

std::string command_line(Tag tag, std::string_view method) {
  std::string line = to_string(tag);
  line += ' ';
  line += method;
  line += "\r\n";
  return line;
}

const char* Syntax::parse(std::string_view line, Reply& r) {
  if (line.size() < 7) return "line too short";
  if (!parse_tag(line.substr(0, 5), r.tag)) return "bad tag";
  if (line[5] != ' ') return "no space at position 6";
  r.item_count = 0;
  r.data = {};
  r.severity = r.code = 0;
  r.cause = r.text = {};
  switch (line[6]) {
    case '&':
      r.marker = Marker::kAck;
      return line.size() == 7 ? nullptr : "text after '&'";
    case '%':
      r.marker = Marker::kComplete;
      return line.size() == 7 ? nullptr : "text after '%'";
    case '!':
      r.marker = Marker::kError;
      return parse_error(line.substr(7), r);
    case '#': {
      r.marker = Marker::kData;
      std::string_view s = line.substr(7);
      std::size_t i = 0;
      skip_spaces(s, i);
      r.data = s.substr(i);
      if (r.data.empty()) return "empty data";
      if (r.data[0] == '"' || r.data[0] == '<') return nullptr;  // a string or XML value
      for (;;) {
        if (r.item_count >= kMaxItems) return "too many items";
        if (const char* why = parse_item(s, i, r.items[r.item_count])) return why;
        ++r.item_count;
        skip_spaces(s, i);
        if (i == s.size()) return nullptr;
        if (s[i] != ',') return "expected ',' between items";
        ++i;
      }
    }
    default:
      return "unknown marker";
  }
}

std::size_t Syntax::resync(std::string_view line, std::size_t from) {
  for (std::size_t i = from; i + 7 <= line.size(); ++i)
    if (digit(line[i]) || line[i] == 'E') return i;
  return std::string_view::npos;
}

std::string_view error_text(int code) {
  switch (code) {
    case 0: return "Buffer full";
    case 1: return "Illegal tag";
    case 2: return "No space at pos. 6";
    case 6: return "Transaction aborted (Use ClearAllErrors To Continue)";
    case 7: return "Illegal character";
    case 8: return "Protocol error";
    case 500: return "Emergency stop";
    case 501: return "Unsupported command";
    case 502: return "Incorrect arguments";
    case 503: return "Controller communications failure";
    case 504: return "Argument out of range";
    case 505: return "Argument not recognized";
    case 506: return "Argument not supported";
    case 507: return "Illegal command";
    case 508: return "Bad context";
    case 509: return "Bad argument";
    case 510: return "Bad property";
    case 511: return "Error processing method";
    case 514: return "Use ClearAllErrors to continue";
    case 1000: return "Machine in error state";
    case 1001: return "Illegal touch";
    case 1002: return "Axis does not exist";
    case 1003: return "No touch";
    case 1005: return "Error during home";
    case 1006: return "Surface not found";
    case 1008: return "Target position out of machine volume";
    case 1010: return "Vector has no norm";
    case 1011: return "Unable to move";
    case 1501: return "Probe not armed";
    case 1502: return "Tool not found";
    case 2000: return "Tool not calibrated";
    case 2001: return "Head error excessive force";
    case 2500: return "Machine limit encountered [Move Out Of Limits]";
    case 2501: return "Axis not active";
    case 2502: return "Axis position error";
    case 2503: return "Scale read head failure";
    case 2504: return "Collision";
    default: return "unknown error";
  }
}

}  // namespace scanmesh::drivers::ippdme
