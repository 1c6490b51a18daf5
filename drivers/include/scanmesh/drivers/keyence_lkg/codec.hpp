// Pure codec of the KEYENCE LK-G RS-232C ASCII protocol: command encoding and reply decoding
// (M0, MS, Q0/R0, ER errors, timed auto-output records) from any byte chunking.
// SPDX-License-Identifier: MIT
//
// Models: LK-G3000 / LK-G5000 controllers with LK-G / LK-H heads.
// Document: KEYENCE LK-G Series User Manual, ch. 5 "RS-232C", pp. 5-5 (command format, error
// codes), 5-6 (measured-value format), 5-24 (auto-output format); see PROTOCOLS.md §1.1.
// Transport: RS-232C, 8N1, 9600..115200 baud; every line ends in CR.
// Quirks (each is also commented where it is handled):
// - The reply header repeats the received command (same case); upper/lower case are accepted.
// - Values are fixed width: sign + 7 characters (digits and an optional decimal point, whose
//   position depends on the unit setting). Over range is `+FFFFFFF` / `-FFFFFFF`; alarm or
//   invalid values are dashes or `XXXXXXX`. They are statuses, not errors.
// - [unverified] `M0` answers `M0,<OUT1>,<OUT2>`; `MS` answers values with status, assumed
//   here as `MS,<st1>,<OUT1>,<st2>,<OUT2>` with a 2-character status per OUT; `Q0` / `R0`
//   enter/leave setting mode and are echoed.
// - [unverified] The auto-output record layout is read from a garbled copy of p. 5-24 as
//   `T<out>,<value>` (out 1 = OUT1, 2 = OUT2); it arrives without a request.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <string_view>

#include "scanmesh/drivers/common/line_decoder.hpp"
#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::drivers::keyence_lkg {

/// Width of a measured-value field: one sign character plus seven characters.
inline constexpr std::size_t kValueWidth = 8;
/// Longest reply line the decoder accepts (MS with two OUTs is 23 characters).
inline constexpr std::size_t kMaxLine = 64;

/// Documented error codes of `ER,<cmd>,<code>` (p. 5-5).
enum class ErrorCode : std::uint8_t {
  kCommand = 0,            ///< 00 command error
  kStatus = 1,             ///< 01 status error (wrong mode)
  kCommandLength = 20,     ///< 20 command length error
  kParameterCount = 21,    ///< 21 parameter count error
  kInvalidParameter = 22,  ///< 22 invalid parameter
  kTimeout = 88,           ///< 88 timeout error
  kOther = 99,             ///< 99 other errors
};
/// Text of a documented code ("status error"); "undocumented error code" otherwise.
std::string_view error_text(int code);

/// One measured-value field, in the controller's display unit (mm by default).
struct Reading {
  SensorStatus status = SensorStatus::kNoTarget;
  double value = std::numeric_limits<double>::quiet_NaN();  ///< NaN unless status is kOk
};

/// Parses one value field (`+01.2345`, `+FFFFFFF`, `-------`, `XXXXXXX`). Returns false when
/// the field is none of the documented forms (the reply is then malformed).
bool parse_value(std::string_view field, Reading& reading);
/// Writes a value field of exactly kValueWidth characters with `decimals` digits after the
/// point (0..5). NaN gives `XXXXXXXX` (alarm); +/-inf or a value too wide gives `+FFFFFFF` /
/// `-FFFFFFF` (over range). Used by the emulator and the benchmark.
void format_value(double value, int decimals, char (&out)[kValueWidth]);

enum class ReplyKind : std::uint8_t {
  kM0,            ///< measured values of OUT1 (and OUT2)
  kMs,            ///< measured values with status per OUT
  kEnterSetting,  ///< echo of Q0
  kExitSetting,   ///< echo of R0
  kAutoOutput,    ///< pushed record of one OUT (timed output mode)
  kError,         ///< ER,<cmd>,<code>
};

struct Reply {
  ReplyKind kind = ReplyKind::kM0;
  std::uint8_t count = 0;                       ///< readings used (M0/MS: OUTs, T: 1)
  std::array<Reading, 2> readings{};            ///< M0/MS: OUT1, OUT2; kAutoOutput: [0]
  std::array<std::array<char, 2>, 2> status{};  ///< MS: raw status characters per OUT
  std::uint8_t out = 0;                         ///< kAutoOutput: 1 = OUT1, 2 = OUT2
  std::array<char, 4> error_command{};          ///< kError: the command the device rejected
  std::uint8_t error_command_size = 0;
  std::uint8_t error_code = 0;  ///< kError: 00..99
  std::string_view error_command_view() const { return {error_command.data(), error_command_size}; }
};

/// Parses one line without its terminator. Returns nullptr on success, otherwise the reason
/// (a static string) why the line is malformed.
const char* parse_reply(std::string_view line, Reply& reply);

/// Commands. Each is a complete request including the CR terminator.
struct M0 {
  static constexpr std::string_view kCommand = "M0";
  static constexpr std::string_view encode() { return "M0\r"; }
};
struct Ms {
  static constexpr std::string_view kCommand = "MS";
  static constexpr std::string_view encode() { return "MS\r"; }
};
struct EnterSetting {
  static constexpr std::string_view kCommand = "Q0";
  static constexpr std::string_view encode() { return "Q0\r"; }
};
struct ExitSetting {
  static constexpr std::string_view kCommand = "R0";
  static constexpr std::string_view encode() { return "R0\r"; }
};

/// The LK-G reply syntax for LineDecoder.
struct LineSyntax {
  using Reply = keyence_lkg::Reply;
  static constexpr std::size_t kMaxLine = keyence_lkg::kMaxLine;
  static constexpr bool kReuseReply = false;
  static const char* parse(std::string_view line, Reply& reply) { return parse_reply(line, reply); }
  /// A reply header further on in a line is still usable (noise glued to its front).
  static std::size_t resync(std::string_view line, std::size_t from) {
    return resync_any_header(line, from);
  }
};

/// Stream decoder: feed any chunks; gets whole replies back. Never throws on device input.
/// Rejected lines: garbage, over-long, unknown header, bad value field.
using Decoder = LineDecoder<LineSyntax>;

}  // namespace scanmesh::drivers::keyence_lkg
