// I++ DME (VDMA 8722) client protocol: the pure decoder of server lines (`tag &`, `tag %`,
// `tag # data`, `tag ! Error(...)`, E-tagged events) into tags, markers and data items, and the
// encoders of command lines.
// SPDX-License-Identifier: MIT
//
// Models: CMM controllers with an I++ DME server (any vendor).
// Documents: I++ DME 1.4 / VDMA 8722 as read from the open implementations aschet/pyippdme
//   (protocol/parser.py grammar, protocol/errors.py Annex B table, server/motion.py PtMeas
//   cycle) and the NIST I++ DME test suite (PROTOCOLS.md §3.4) [partly verified].
// Transport: TCP (port 1294 in the examples), ASCII 32-126 lines ended by CR LF.
// Quirks:
//   - Tags: 00001-99999 for the normal queue, E0001-E9999 for the fast queue (AbortE, the
//     OnMoveReportE daemon, GetErrStatusE), E0000 for unsolicited server events.
//   - Position 6 of every line is a space; the standard sets no line length limit: this
//     decoder refuses lines longer than kMaxLine (a peer flooding one line cannot grow memory).
//   - Data items are `Name(args)` groups separated by commas; names may be dotted
//     (Tool.PtMeasPar.Speed); args are numbers (16 characters at most) or "strings".
//   - Error: `tag ! Error(F1, F2, "F3", "text")`: severity 0-9, 4-digit number, cause (the
//     method), text. Severity >= 2 needs ClearAllErrors() before the server continues.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "scanmesh/drivers/common/line_decoder.hpp"

namespace scanmesh::drivers::ippdme {

struct Tag {
  bool event = false;        ///< E-tag (fast queue / events)
  std::uint32_t number = 0;  ///< 1..99999, or 0..9999 for an E-tag
  friend constexpr bool operator==(const Tag&, const Tag&) = default;
};
/// "00012" / "E0001".
std::string to_string(Tag tag);

enum class Marker : std::uint8_t {
  kAck,       ///< `&`: the command was received
  kComplete,  ///< `%`: the transaction is complete
  kData,      ///< `#`: a data line (items)
  kError,     ///< `!`: an error
};

inline constexpr int kMaxItems = 8;
inline constexpr int kMaxArgs = 4;

/// One `Name(args)` group of a data line (an empty name for bare numeric data "1, 2, 3").
struct Item {
  std::string_view name;
  std::uint8_t count = 0;  ///< numeric arguments in v
  std::array<double, kMaxArgs> v{};
  std::string_view text;  ///< the first "string" argument, without quotes
};

/// One decoded line. String views point into the decoder's buffer: valid inside the callback.
struct Reply {
  Tag tag;
  Marker marker = Marker::kAck;
  std::array<Item, kMaxItems> items{};
  std::uint8_t item_count = 0;
  std::string_view data;  ///< the whole data text after `# `
  int severity = 0;       ///< kError: F1
  int code = 0;           ///< kError: F2
  std::string_view cause; ///< kError: F3
  std::string_view text;  ///< kError: the text

  /// The item named `name` (nullptr when absent).
  const Item* find(std::string_view name) const;
};

/// LineDecoder syntax of server lines (see common/line_decoder.hpp).
struct Syntax {
  using Reply = ippdme::Reply;
  static constexpr std::size_t kMaxLine = 4096;
  static constexpr bool kReuseReply = true;
  static const char* parse(std::string_view line, Reply& reply);
  /// Where a line may start again after noise glued to its front: a digit or 'E'.
  static std::size_t resync(std::string_view line, std::size_t from);
};

using Decoder = LineDecoder<Syntax>;

/// Parses an I++ number ([+-]digits[.digits][E[+-]ddd], 16 characters at most).
bool parse_number(std::string_view text, double& out);
/// Formats a number for a command (at most 16 characters, no exponent for usual values).
std::string format_number(double v);
/// "<tag> <method>\r\n".
std::string command_line(Tag tag, std::string_view method);

/// Annex B meaning of an error number ("Surface not found"), or "unknown error".
std::string_view error_text(int code);

}  // namespace scanmesh::drivers::ippdme
