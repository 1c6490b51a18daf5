// Pure codec of the Panasonic HL-G1 MEWTOCOL-style ASCII protocol: request encoding with BCC,
// and decoding of `$` replies and `!` error replies from any byte chunking.
// SPDX-License-Identifier: MIT
//
// Models: Panasonic HL-G1 series (HL-G103/105/108/112/125 heads, -A-C5 / -S-J variants).
// Document: HL-G1 manual ch. 4 §4-2 "Communication", pp. 4-6 .. 4-9 (PROTOCOLS.md §1.4).
// Transport: RS-422 / RS-485 (several heads on one bus, addressed by a 2-digit unit number),
// 8N1 ... 9600..115200 baud (default 38400); every frame ends in CR.
// Frames:
//   request   `%` <unit:2> `#` <command:3> <data> <BCC:2> CR
//   reply     `%` <unit:2> `$` <command:3> <data> <BCC:2> CR
//   error     `%` <unit:2> `!` <code:2> <BCC:2> CR                      [unverified]
// Quirks (each also commented where it is handled):
// - BCC = XOR of every character from `%` to the end of the data, as 2 hex digits [unverified
//   MEWTOCOL convention]; `**` may be sent in place of the BCC (documented) and is accepted in
//   replies too. A reply whose BCC is wrong is malformed.
// - Values (RMD): sign + 7 digits, no decimal point, in units of 0.1 µm (`+0025000` = 2.5 mm).
// - The error codes' meanings are the general MEWTOCOL-COM ones [unverified for the HL-G1].
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "scanmesh/drivers/common/line_decoder.hpp"

namespace scanmesh::drivers::panasonic_hlg1 {

/// One count of a measured value in mm (0.1 µm).
inline constexpr double kMmPerCount = 1e-4;
/// Width of a measured-value field: sign + 7 digits.
inline constexpr std::size_t kValueWidth = 8;
/// Longest data field kept in a Reply (RLA buffer reads are longer and not decoded here).
inline constexpr std::size_t kMaxData = 32;
/// Longest line the decoder accepts.
inline constexpr std::size_t kMaxLine = 64;

/// XOR of the bytes, the MEWTOCOL block check.
std::uint8_t bcc(std::string_view text);
/// Text of a MEWTOCOL-COM error code [unverified]; "undocumented error code" otherwise.
std::string_view error_text(int code);

/// Encodes a request `%<unit>#<command><data><BCC>CR` into out and returns its size, or 0 when
/// unit is not 0..99, the command is not 3 characters or it does not fit. With use_bcc false
/// the BCC is sent as `**` (documented as accepted by the sensor).
std::size_t encode_request(int unit, std::string_view command, std::string_view data, bool use_bcc,
                           std::span<char> out);

/// The commands the driver uses. Each is a small struct naming its command code.
struct ReadMeasurement {  ///< RMD: the present measured value
  static constexpr std::string_view kCommand = "RMD";
  static std::string encode(int unit, bool use_bcc = true);
};
struct ReadSamplingCycle {  ///< RSP: the sampling-cycle setting (an index code)
  static constexpr std::string_view kCommand = "RSP";
  static std::string encode(int unit, bool use_bcc = true);
};

enum class ReplyKind : std::uint8_t { kData, kError };

struct Reply {
  ReplyKind kind = ReplyKind::kData;
  std::uint8_t unit = 0;
  std::array<char, 3> command{};  ///< kData: the command answered ("RMD")
  std::array<char, kMaxData> data{};
  std::uint8_t data_size = 0;
  bool has_value = false;       ///< kData with a sign + 7 digit value field (RMD)
  std::int32_t counts = 0;      ///< that value in 0.1 µm
  std::uint8_t error_code = 0;  ///< kError: 2-digit code
  bool bcc_checked = false;     ///< false when the device sent `**`

  std::string_view command_view() const { return {command.data(), command.size()}; }
  std::string_view data_view() const { return {data.data(), data_size}; }
  double value_mm() const { return counts * kMmPerCount; }
};

/// Parses one line without its terminator. nullptr on success, else the reason (static text).
const char* parse_reply(std::string_view line, Reply& reply);
/// Parses a sign + 7 digit value field. False for anything else.
bool parse_counts(std::string_view field, std::int32_t& counts);

/// The HL-G1 frame syntax for LineDecoder.
struct LineSyntax {
  using Reply = panasonic_hlg1::Reply;
  static constexpr std::size_t kMaxLine = panasonic_hlg1::kMaxLine;
  static constexpr bool kReuseReply = false;
  static const char* parse(std::string_view line, Reply& reply) { return parse_reply(line, reply); }
  /// Resynchronise on a later `%`: noise glued to the front of a frame.
  static std::size_t resync(std::string_view line, std::size_t from) {
    return line.find('%', from);
  }
};

/// Stream decoder: feed any chunks; gets whole replies back. Never throws on device input.
/// Rejected lines: bad BCC, garbage, over-long, wrong layout.
using Decoder = LineDecoder<LineSyntax>;

}  // namespace scanmesh::drivers::panasonic_hlg1
