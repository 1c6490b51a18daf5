// LineFramer: splits a byte stream into lines ending in CR, LF or CR LF, the framing of every
// ASCII sensor protocol here (KEYENCE, Panasonic, Micro-Epsilon commands). Pure; resynchronises
// on its own: an over-long line is dropped up to its terminator and counted.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace scanmesh::drivers {

class LineFramer {
 public:
  /// max_line: longest accepted line without terminator (longer ones are dropped as malformed).
  explicit LineFramer(std::size_t max_line = 256) : max_line_(max_line) { buffer_.reserve(64); }

  /// Feeds bytes; calls on_line(std::string_view line) for each complete line, without its
  /// terminator. Empty lines (the LF of CR LF, blank lines) are skipped. Bytes outside
  /// 0x20..0x7E (other than the terminators) are dropped and counted as noise: a device line
  /// is printable ASCII, so noise never reaches the codec.
  template <class F>
  void feed(std::string_view bytes, F&& on_line) {
    for (const char c : bytes) {
      if (c == '\r' || c == '\n') {
        if (overflow_) {
          overflow_ = false;
          ++overlong_;
        } else if (!buffer_.empty()) {
          on_line(std::string_view(buffer_));
        }
        buffer_.clear();
      } else if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7E) {
        ++noise_bytes_;
      } else if (!overflow_) {
        if (buffer_.size() >= max_line_) {
          overflow_ = true;
          buffer_.clear();
        } else {
          buffer_.push_back(c);
        }
      }
    }
  }
  template <class F>
  void feed(std::span<const std::uint8_t> bytes, F&& on_line) {
    feed(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
         std::forward<F>(on_line));
  }

  /// Bytes of an unfinished line (a partial reply; kept until its terminator arrives).
  std::string_view pending() const { return buffer_; }
  void clear() {
    buffer_.clear();
    overflow_ = false;
  }
  std::uint64_t noise_bytes() const { return noise_bytes_; }
  std::uint64_t overlong_lines() const { return overlong_; }

 private:
  std::size_t max_line_;
  std::string buffer_;
  bool overflow_ = false;
  std::uint64_t noise_bytes_ = 0;
  std::uint64_t overlong_ = 0;
};

inline bool is_ascii_digit(char c) { return c >= '0' && c <= '9'; }

/// Exactly `width` decimal digits (a 2-digit ID, a 3-digit data number, an error code).
inline bool parse_digits(std::string_view field, std::size_t width, int& value) {
  if (field.size() != width) return false;
  int v = 0;
  for (const char c : field) {
    if (!is_ascii_digit(c)) return false;
    v = v * 10 + (c - '0');
  }
  value = v;
  return true;
}

/// Whether every character of `text` is `c` (true for an empty text).
inline bool all_chars_are(std::string_view text, char c) {
  for (const char x : text)
    if (x != c) return false;
  return true;
}

/// Splits off the next comma-separated field of a reply line (KEYENCE "M0,+01.234,-FFFFFFF");
/// false when no field is left. Inline: the codecs call it per field on their hot path.
inline bool next_field(std::string_view& rest, std::string_view& field) {
  if (rest.empty()) return false;
  const std::size_t comma = rest.find(',');
  if (comma == std::string_view::npos) {
    field = rest;
    rest = {};
  } else {
    field = rest.substr(0, comma);
    rest = rest.substr(comma + 1);
  }
  return true;
}

/// Parses a decimal number of the fixed-width sensor formats ("+01.2345", "-0012.30",
/// "+0025000"): optional sign, digits with at most one '.', nothing else. Returns false for
/// anything else (dashes, X, F, spaces) without throwing. Exact for up to 15 digits.
bool parse_fixed_decimal(std::string_view text, double& value);

}  // namespace scanmesh::drivers
