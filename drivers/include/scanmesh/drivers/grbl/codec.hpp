// GRBL (and derivatives: grblHAL, the Horus/Ciclop board) line protocol: the pure decoder of
// everything the controller sends (ok / error:N, ALARM:N, <status reports>, [PRB:...],
// [MSG:...] and other bracketed messages, the welcome banner, $ settings) and the encoders of the
// G-code lines and real-time bytes the driver sends.
// SPDX-License-Identifier: MIT
//
// Models: Grbl 1.1 (gnea/grbl), grblHAL, GRBL-derived firmwares such as the Horus board.
// Documents: gnea/grbl doc/markdown/interface.md (status report fields, push messages,
//   real-time commands), doc/csv/error_codes_en_US.csv and alarm_codes_en_US.csv, grbl/probe.c;
//   grblHAL grbl/report.c (PROTOCOLS.md §3.2).
// Transport: serial (USB CDC or USB-serial), 115200 8N1, lines ending in CR LF.
// Quirks:
//   - Status report fields other than the state come in any order and only some of them in a
//     given report (WCO: intermittently, Ov: and A: when they change): absent = unchanged.
//   - Fields this parser does not know are skipped (grblHAL adds its own), not rejected.
//   - MPos or WPos is sent depending on $10; WPos = MPos - WCO.
//   - [PRB:x,y,z:1] are machine coordinates; the trailing flag is 0 when the probing move ended
//     without contact.
//   - Grbl 0.9 sends messages without a tag ("[Caution: Unlocked]"): reported with an empty tag.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "scanmesh/drivers/common/line_decoder.hpp"

namespace scanmesh::drivers::grbl {

/// Real-time commands: single bytes, no newline, bypassing the receive buffer.
inline constexpr char kStatusQuery = '?';
inline constexpr char kFeedHold = '!';
inline constexpr char kCycleStart = '~';
inline constexpr char kSoftReset = 0x18;
inline constexpr unsigned char kJogCancel = 0x85;  ///< Grbl 1.1

/// Serial receive buffer of a stock Grbl (Arduino Uno); grblHAL reports more in [OPT:].
inline constexpr int kDefaultRxBufferBytes = 128;
/// Longest G-code line Grbl accepts (LINE_BUFFER_SIZE); longer ones get error:11.
inline constexpr std::size_t kMaxLineLength = 80;

enum class MachineState : std::uint8_t { kIdle, kRun, kHold, kJog, kAlarm, kDoor, kCheck, kHome, kSleep };
std::string_view to_string(MachineState state);  ///< "Idle", "Run", ... as Grbl spells them

inline constexpr int kMaxAxes = 6;
struct AxisValues {
  std::array<double, kMaxAxes> v{};
  std::uint8_t count = 0;  ///< how many values the controller sent (3 on a stock Grbl)
};

/// Pins of the Pn: field.
enum PinBits : std::uint16_t {
  kPinX = 1, kPinY = 2, kPinZ = 4, kPinA = 8, kPinProbe = 16, kPinDoor = 32, kPinHold = 64,
  kPinReset = 128, kPinStart = 256,
};

/// One `<...>` status report.
struct StatusReport {
  MachineState state = MachineState::kIdle;
  int substate = -1;        ///< Hold:n / Door:n, -1 when absent
  bool machine_pos = true;  ///< pos is MPos (true) or WPos (false)
  AxisValues pos;
  bool has_wco = false;
  AxisValues wco;
  bool has_feed = false;
  double feed = 0;     ///< current feed rate (F: or FS:)
  double spindle = 0;  ///< FS: only
  bool has_buffer = false;
  int planner_free = 0;  ///< Bf: free planner blocks
  int rx_free = 0;       ///< Bf: free receive-buffer bytes
  long line = -1;        ///< Ln:
  bool has_pins = false;
  std::uint16_t pins = 0;  ///< PinBits; Pn: is absent when no pin is active
  bool has_overrides = false;
  std::array<int, 3> overrides{};  ///< Ov: feed, rapid, spindle %
};

struct ProbeReport {
  AxisValues pos;  ///< machine coordinates at the trigger (or at the end of the travel)
  bool success = false;
};

enum class ReplyKind : std::uint8_t {
  kOk,       ///< `ok`
  kError,    ///< `error:N` (code)
  kAlarm,    ///< `ALARM:N` (code)
  kStatus,   ///< `<...>` (status)
  kProbe,    ///< `[PRB:...]` (probe)
  kMessage,  ///< any other `[TAG:text]` (tag, text): MSG, GC, VER, OPT, HLP, echo, G54 ...
  kWelcome,  ///< `Grbl 1.1h ['$' for help]` (text = the banner)
  kSetting,  ///< `$N=value` (code = N, text = value)
  kStartup,  ///< `>line:ok` startup-block echo (text = the line)
};

/// One decoded line. The string views point into the decoder's line buffer: valid only inside
/// the reply callback.
struct Reply {
  ReplyKind kind = ReplyKind::kOk;
  int code = 0;
  StatusReport status;
  ProbeReport probe;
  std::string_view tag;
  std::string_view text;
};

/// LineDecoder syntax of Grbl's output (see common/line_decoder.hpp).
struct Syntax {
  using Reply = grbl::Reply;
  static constexpr std::size_t kMaxLine = 256;
  static constexpr bool kReuseReply = true;
  static const char* parse(std::string_view line, Reply& reply);
  /// Where a reply may start again after noise glued to the front of a line.
  static std::size_t resync(std::string_view line, std::size_t from);
};

/// Decoder: feed(bytes, on_reply(const Reply&), on_malformed(const char*)). Pure; no allocation
/// per reply.
using Decoder = LineDecoder<Syntax>;

/// Parses "x,y,z[,a,b,c]" (1..6 fixed-decimal numbers); false for anything else.
bool parse_axes(std::string_view text, AxisValues& out);

// ---- encoding ----

/// Axis words of a line: absent axes are not written. A is in degrees (Grbl's rotary unit).
struct AxisWords {
  std::optional<double> x, y, z, a;
};

/// "G90G1X10.0000Y-2.5000F600.0\n" (absolute) or "G91G1..." (relative). feed > 0 in units/min.
/// Throws ConfigError when no axis is given, a value is not finite, or feed <= 0.
std::string move_line(bool absolute, const AxisWords& words, double feed);
/// "$J=G91X10.0000F600.0\n": a jog the controller cancels at once on a feed hold or 0x85.
std::string jog_line(const AxisWords& words, double feed);
/// "G91G38.2Z-10.0000F100.0\n": probe toward the surface, stop on contact, error on no contact
/// (ALARM:5).
std::string probe_line(const AxisWords& words, double feed);

/// Meaning of error:N and ALARM:N (Grbl 1.1 tables); "unknown error" / "unknown alarm" else.
std::string_view error_text(int code);
std::string_view alarm_text(int code);

}  // namespace scanmesh::drivers::grbl
