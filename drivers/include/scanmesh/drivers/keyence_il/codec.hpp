// Pure codec of the KEYENCE DL-RS1A RS-232C protocol for IL-series amplifiers: command encoding
// and reply decoding (M0, MS, SR, SW/AW acknowledgements, DR records, ER errors).
// SPDX-License-Identifier: MIT
//
// Models: KEYENCE IL series amplifiers (IL-1000/1050/1500/1550) with IL-S025, IL-030, IL-065,
// IL-100, IL-300, IL-600, IL-2000 heads, connected through a DL-RS1A RS-232C unit.
// Document: KEYENCE DL-RS1A/IL User Manual p. 9; DL-RS1A User Manual pp. 8, 10
// (PROTOCOLS.md §1.2).
// Transport: RS-232C 8N1, 9600..115200 baud (default 38400).
// Framing: `<CMD:2>[,<ID:2>,<data no:3>[,<value>]]` + CR or CR LF (any other last byte gives
// error 00); replies end in CR LF.
// Quirks (each also commented where it is handled):
// - M0 returns one value per connected amplifier (ID00, ID01, ...); MS returns a 2-digit
//   control-output bit field before each value; SR returns up to 10 characters of data.
// - The value format depends on the head: `±**.***` (IL-S025/030/065/100), `±***.**`
//   (IL-300/600), `±****.*` (IL-2000). The point is part of the field, so the parser takes it
//   from the field; value_scale in the device options covers other unit settings.
// - [unverified] Over range / alarm values are assumed to follow the KEYENCE LK-G convention
//   (`±FFFFFFF`, dashes, `XXXXXXX`): the DL-RS1A excerpt does not give them.
// - [unverified] The bit assignment of the MS control output (HIGH/LOW/GO/alarm) is not in the
//   excerpt: the raw 2-digit number is passed on unchanged.
// - [unverified] SW/AW acknowledgements are assumed to echo `SW,<ID>,<no>` / `AW,<no>`.
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

namespace scanmesh::drivers::keyence_il {

/// Width of a numeric value field: sign + 6 characters (digits and the point).
inline constexpr std::size_t kValueWidth = 7;
/// Most amplifiers one DL-RS1A reports in one M0/MS reply.
inline constexpr std::size_t kMaxAmplifiers = 16;
/// Longest SR data field (documented: up to 10 characters).
inline constexpr std::size_t kMaxData = 10;
/// Longest line the decoder accepts (MS with 16 amplifiers is 2 + 16 * 12 characters).
inline constexpr std::size_t kMaxLine = 256;

/// Text of the documented error codes (00: command error / bad terminator, 22: invalid
/// parameter / write to a read-only item); "undocumented error code" otherwise.
std::string_view error_text(int code);

struct Reading {
  SensorStatus status = SensorStatus::kNoTarget;
  double value = std::numeric_limits<double>::quiet_NaN();  ///< NaN unless status is kOk
};
/// Parses one value field (`+12.345`, `-123.45`, `+1234.5`, `+012345`: always sign + 6
/// characters; [unverified] `±FFFFFF`, dashes, `XXXXXXX`). False when it is none of these.
bool parse_value(std::string_view field, Reading& reading);

enum class ReplyKind : std::uint8_t {
  kM0,        ///< values of every amplifier
  kMs,        ///< control output + value of every amplifier
  kDr,        ///< pushed after a DRQ input pulse, MS layout
  kSr,        ///< one setting/state item of one amplifier
  kWriteAck,  ///< SW / AW acknowledged [unverified layout]
  kError,     ///< ER,<cmd>,<code>
};

struct Reply {
  ReplyKind kind = ReplyKind::kM0;
  std::uint8_t count = 0;  ///< amplifiers in M0/MS/DR
  std::array<Reading, kMaxAmplifiers> readings{};
  std::array<std::uint8_t, kMaxAmplifiers> control{};  ///< MS/DR: raw 2-digit control output
  std::uint8_t id = 0;                                 ///< SR/SW: amplifier ID
  std::uint16_t data_number = 0;                       ///< SR/SW/AW: data number
  std::array<char, kMaxData> data{};
  std::uint8_t data_size = 0;
  std::array<char, 2> command{};  ///< kError: rejected command; kWriteAck: SW or AW
  std::uint8_t error_code = 0;

  std::string_view data_view() const { return {data.data(), data_size}; }
  std::string_view command_view() const { return {command.data(), command.size()}; }
};

/// Parses one line without its terminator: nullptr on success, else the reason (static text).
const char* parse_reply(std::string_view line, Reply& reply);

/// Commands (complete requests with the CR LF terminator).
struct M0 {
  static constexpr std::string_view kCommand = "M0";
  static constexpr std::string_view encode() { return "M0\r\n"; }
};
struct Ms {
  static constexpr std::string_view kCommand = "MS";
  static constexpr std::string_view encode() { return "MS\r\n"; }
};
struct Sr {
  static constexpr std::string_view kCommand = "SR";
  /// `SR,<id>,<data number>` CR LF; empty when id > 99 or data_number > 999.
  static std::string encode(int id, int data_number);
};

/// The IL reply syntax for LineDecoder.
struct LineSyntax {
  using Reply = keyence_il::Reply;
  static constexpr std::size_t kMaxLine = keyence_il::kMaxLine;
  static constexpr bool kReuseReply = true;  // reused: a Reply with 16 readings is ~400 bytes
  static const char* parse(std::string_view line, Reply& reply) { return parse_reply(line, reply); }
  static std::size_t resync(std::string_view line, std::size_t from) {
    return resync_any_header(line, from);
  }
};

/// Stream decoder: feed any chunks; gets whole replies back. Never throws on device input.
/// A reply found behind garbage in the same line comes first, then the garbage is reported.
using Decoder = LineDecoder<LineSyntax>;

}  // namespace scanmesh::drivers::keyence_il
