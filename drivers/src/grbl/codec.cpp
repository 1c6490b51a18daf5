// GRBL line protocol: decoding of everything the controller sends, G-code line encoding, and
// the error/alarm tables (see grbl/codec.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/grbl/codec.hpp"

#include <cmath>
#include <cstdio>

#include "scanmesh/common/error.hpp"
#include "scanmesh/drivers/common/line_framer.hpp"

namespace scanmesh::drivers::grbl {

namespace {

bool starts_with(std::string_view s, std::string_view p) { return s.substr(0, p.size()) == p; }

/// Non-negative decimal integer of 1..9 digits.
bool parse_uint(std::string_view text, long& out) {
  if (text.empty() || text.size() > 9) return false;
  long v = 0;
  for (const char c : text) {
    if (!is_ascii_digit(c)) return false;
    v = v * 10 + (c - '0');
  }
  out = v;
  return true;
}

bool parse_state(std::string_view word, StatusReport& s) {
  std::string_view name = word;
  s.substate = -1;
  const std::size_t colon = word.find(':');
  if (colon != std::string_view::npos) {
    name = word.substr(0, colon);
    long sub = 0;
    if (!parse_uint(word.substr(colon + 1), sub) || sub > 9) return false;
    s.substate = static_cast<int>(sub);
  }
  // Ordered by how often they occur in a stream of reports.
  static constexpr std::pair<std::string_view, MachineState> kStates[] = {
      {"Idle", MachineState::kIdle},   {"Run", MachineState::kRun},
      {"Jog", MachineState::kJog},     {"Hold", MachineState::kHold},
      {"Home", MachineState::kHome},   {"Alarm", MachineState::kAlarm},
      {"Door", MachineState::kDoor},   {"Check", MachineState::kCheck},
      {"Sleep", MachineState::kSleep},
  };
  for (const auto& [text, state] : kStates) {
    if (name == text) {
      // Only Hold and Door carry a substate.
      if (s.substate >= 0 && state != MachineState::kHold && state != MachineState::kDoor)
        return false;
      s.state = state;
      return true;
    }
  }
  return false;
}

bool parse_pins(std::string_view text, std::uint16_t& pins) {
  pins = 0;
  for (const char c : text) {
    switch (c) {
      case 'X': pins |= kPinX; break;
      case 'Y': pins |= kPinY; break;
      case 'Z': pins |= kPinZ; break;
      case 'A': pins |= kPinA; break;
      case 'P': pins |= kPinProbe; break;
      case 'D': pins |= kPinDoor; break;
      case 'H': pins |= kPinHold; break;
      case 'R': pins |= kPinReset; break;
      case 'S': pins |= kPinStart; break;
      default:
        // grblHAL reports more pins (B, C, E ...): not an error, just not one of ours.
        if (c < 'A' || c > 'Z') return false;
    }
  }
  return true;
}

const char* parse_status(std::string_view body, StatusReport& s) {
  std::string_view rest = body;
  std::string_view field;
  s = StatusReport{};
  auto next = [&]() -> bool {
    if (rest.empty()) return false;
    const std::size_t bar = rest.find('|');
    field = rest.substr(0, bar);
    rest = bar == std::string_view::npos ? std::string_view{} : rest.substr(bar + 1);
    return true;
  };
  if (!next() || !parse_state(field, s)) return "status report: unknown state";
  bool have_pos = false;
  while (next()) {
    const std::size_t colon = field.find(':');
    if (colon == std::string_view::npos) return "status report: field without ':'";
    const std::string_view key = field.substr(0, colon);
    const std::string_view value = field.substr(colon + 1);
    if (key == "MPos" || key == "WPos") {
      if (have_pos) return "status report: two position fields";
      if (!parse_axes(value, s.pos)) return "status report: bad position";
      s.machine_pos = key[0] == 'M';
      have_pos = true;
    } else if (key == "FS" || key == "F") {
      AxisValues v;
      if (!parse_axes(value, v) || v.count != (key.size() == 2 ? 2 : 1))
        return "status report: bad feed";
      s.has_feed = true;
      s.feed = v.v[0];
      s.spindle = key.size() == 2 ? v.v[1] : 0;
    } else if (key == "WCO") {
      if (!parse_axes(value, s.wco)) return "status report: bad WCO";
      s.has_wco = true;
    } else if (key == "Bf") {
      const std::size_t comma = value.find(',');
      long a = 0, b = 0;
      if (comma == std::string_view::npos || !parse_uint(value.substr(0, comma), a) ||
          !parse_uint(value.substr(comma + 1), b))
        return "status report: bad Bf";
      s.has_buffer = true;
      s.planner_free = static_cast<int>(a);
      s.rx_free = static_cast<int>(b);
    } else if (key == "Ln") {
      if (!parse_uint(value, s.line)) return "status report: bad Ln";
    } else if (key == "Pn") {
      if (!parse_pins(value, s.pins)) return "status report: bad Pn";
      s.has_pins = true;
    } else if (key == "Ov") {
      AxisValues v;
      if (!parse_axes(value, v) || v.count != 3) return "status report: bad Ov";
      s.has_overrides = true;
      for (int k = 0; k < 3; ++k) s.overrides[k] = static_cast<int>(v.v[k]);
    }
    // Other fields (A: accessories, grblHAL's own) carry nothing the driver uses.
  }
  if (!have_pos) return "status report: no MPos or WPos";
  return nullptr;
}

const char* parse_code(std::string_view digits, int& code) {
  long v = 0;
  if (!parse_uint(digits, v) || v > 9999) return "bad code";
  code = static_cast<int>(v);
  return nullptr;
}

}  // namespace

std::string_view to_string(MachineState state) {
  switch (state) {
    case MachineState::kIdle: return "Idle";
    case MachineState::kRun: return "Run";
    case MachineState::kHold: return "Hold";
    case MachineState::kJog: return "Jog";
    case MachineState::kAlarm: return "Alarm";
    case MachineState::kDoor: return "Door";
    case MachineState::kCheck: return "Check";
    case MachineState::kHome: return "Home";
    case MachineState::kSleep: return "Sleep";
  }
  return "?";
}

bool parse_axes(std::string_view text, AxisValues& out) {
  out.count = 0;
  std::string_view rest = text;
  std::string_view field;
  while (next_field(rest, field)) {
    if (out.count >= kMaxAxes) return false;
    if (!parse_fixed_decimal(field, out.v[out.count])) return false;
    ++out.count;
  }
  // "1,2," leaves an empty last field, which next_field does not report: refuse it.
  return out.count > 0 && text.back() != ',';
}

const char* Syntax::parse(std::string_view line, Reply& r) {
  if (line.empty()) return "empty line";
  switch (line[0]) {
    case 'o':
      if (line == "ok") {
        r.kind = ReplyKind::kOk;
        return nullptr;
      }
      break;
    case 'e':
      if (starts_with(line, "error:")) {
        r.kind = ReplyKind::kError;
        return parse_code(line.substr(6), r.code) ? "error: bad code" : nullptr;
      }
      break;
    case 'A':
      if (starts_with(line, "ALARM:")) {
        r.kind = ReplyKind::kAlarm;
        return parse_code(line.substr(6), r.code) ? "ALARM: bad code" : nullptr;
      }
      break;
    case '<':
      if (line.back() != '>') return "status report without '>'";
      r.kind = ReplyKind::kStatus;
      return parse_status(line.substr(1, line.size() - 2), r.status);
    case '[': {
      if (line.back() != ']') return "message without ']'";
      const std::string_view body = line.substr(1, line.size() - 2);
      if (starts_with(body, "PRB:")) {
        // [PRB:x,y,z:1]
        const std::size_t colon = body.rfind(':');
        if (colon <= 4 || colon + 2 != body.size() || (body[colon + 1] != '0' && body[colon + 1] != '1'))
          return "PRB: bad flag";
        if (!parse_axes(body.substr(4, colon - 4), r.probe.pos)) return "PRB: bad position";
        r.kind = ReplyKind::kProbe;
        r.probe.success = body[colon + 1] == '1';
        return nullptr;
      }
      const std::size_t colon = body.find(':');
      // A tag is a short upper-case word (MSG, GC, VER, OPT, HLP, G54, TLO, G28 ...) or "echo";
      // "[Caution: Unlocked]" of Grbl 0.9 has none.
      bool tagged = colon != std::string_view::npos && colon > 0 && colon <= 8;
      if (tagged && body.substr(0, colon) != "echo") {
        for (std::size_t i = 0; tagged && i < colon; ++i) {
          const char c = body[i];
          tagged = (c >= 'A' && c <= 'Z') || is_ascii_digit(c) || c == '.';
        }
      }
      r.kind = ReplyKind::kMessage;
      r.tag = tagged ? body.substr(0, colon) : std::string_view{};
      r.text = tagged ? body.substr(colon + 1) : body;
      return nullptr;
    }
    case 'G':
      if (starts_with(line, "Grbl ") || starts_with(line, "GrblHAL ")) {
        r.kind = ReplyKind::kWelcome;
        r.text = line;
        return nullptr;
      }
      break;
    case '$': {
      const std::size_t eq = line.find('=');
      if (eq == std::string_view::npos) break;
      r.kind = ReplyKind::kSetting;
      r.text = line.substr(eq + 1);
      return parse_code(line.substr(1, eq - 1), r.code) ? "setting: bad number" : nullptr;
    }
    case '>':
      if (line.size() >= 4 && line.substr(line.size() - 3) == ":ok") {
        r.kind = ReplyKind::kStartup;
        r.text = line.substr(1, line.size() - 4);
        return nullptr;
      }
      break;
    default:
      break;
  }
  return "unknown reply";
}

std::size_t Syntax::resync(std::string_view line, std::size_t from) {
  const std::size_t at = line.find_first_of("<[oeAG$>", from);
  return at == std::string_view::npos ? std::string_view::npos : at;
}

// ---- encoding ----

namespace {

void append_word(std::string& out, char letter, double value) {
  if (!std::isfinite(value))
    throw ConfigError(std::string("grbl: axis ") + letter + " value is not finite");
  char buf[40];
  std::snprintf(buf, sizeof buf, "%c%.4f", letter, value);
  out += buf;
}

std::string with_words(std::string line, const AxisWords& w, double feed) {
  if (!w.x && !w.y && !w.z && !w.a) throw ConfigError("grbl: a move needs at least one axis");
  if (!(feed > 0) || !std::isfinite(feed)) throw ConfigError("grbl: the feed must be > 0");
  if (w.x) append_word(line, 'X', *w.x);
  if (w.y) append_word(line, 'Y', *w.y);
  if (w.z) append_word(line, 'Z', *w.z);
  if (w.a) append_word(line, 'A', *w.a);
  char buf[40];
  std::snprintf(buf, sizeof buf, "F%.1f\n", feed);
  line += buf;
  if (line.size() > kMaxLineLength)
    throw ConfigError("grbl: line longer than " + std::to_string(kMaxLineLength) +
                      " characters: " + line);
  return line;
}

}  // namespace

std::string move_line(bool absolute, const AxisWords& words, double feed) {
  return with_words(absolute ? "G90G1" : "G91G1", words, feed);
}

std::string jog_line(const AxisWords& words, double feed) {
  return with_words("$J=G91", words, feed);
}

std::string probe_line(const AxisWords& words, double feed) {
  return with_words("G91G38.2", words, feed);
}

std::string_view error_text(int code) {
  switch (code) {
    case 1: return "G-code words consist of a letter and a value. Letter was not found.";
    case 2: return "Numeric value format is not valid or missing an expected value.";
    case 3: return "Grbl '$' system command was not recognized or supported.";
    case 4: return "Negative value received for an expected positive value.";
    case 5: return "Homing cycle is not enabled via settings.";
    case 6: return "Minimum step pulse time must be greater than 3usec.";
    case 7: return "EEPROM read failed. Reset and restored to default values.";
    case 8: return "Grbl '$' command cannot be used unless Grbl is IDLE.";
    case 9: return "G-code locked out during alarm or jog state.";
    case 10: return "Soft limits cannot be enabled without homing also enabled.";
    case 11: return "Max characters per line exceeded. Line was not processed and executed.";
    case 12: return "Grbl '$' setting value exceeds the maximum step rate supported.";
    case 13: return "Safety door detected as opened and door state initiated.";
    case 14: return "Build info or startup line exceeded EEPROM line length limit.";
    case 15: return "Jog target exceeds machine travel. Command ignored.";
    case 16: return "Jog command with no '=' or contains prohibited g-code.";
    case 17: return "Laser mode requires PWM output.";
    case 20: return "Unsupported or invalid g-code command found in block.";
    case 21: return "More than one g-code command from same modal group found in block.";
    case 22: return "Feed rate has not yet been set or is undefined.";
    case 23: return "G-code command in block requires an integer value.";
    case 24: return "Two G-code commands that both require the use of the XYZ axis words were "
                    "detected in the block.";
    case 25: return "A G-code word was repeated in the block.";
    case 26: return "A G-code command implicitly or explicitly requires XYZ axis words in the "
                    "block, but none were detected.";
    case 27: return "N line number value is not within the valid range of 1 - 9,999,999.";
    case 28: return "A G-code command was sent, but is missing some required P or L value words "
                    "in the line.";
    case 29: return "Grbl supports six work coordinate systems G54-G59. G59.1, G59.2, and G59.3 "
                    "are not supported.";
    case 30: return "The G53 G-code command requires either a G0 seek or G1 feed motion mode to "
                    "be active. A different motion was active.";
    case 31: return "There are unused axis words in the block and G80 motion mode cancel is "
                    "active.";
    case 32: return "A G2 or G3 arc was commanded but there are no XYZ axis words in the "
                    "selected plane to trace the arc.";
    case 33: return "The motion command has an invalid target. G2, G3, and G38.2 generates this "
                    "error, if the arc is impossible to generate or if the probe target is the "
                    "current position.";
    case 34: return "A G2 or G3 arc, traced with the radius definition, had a mathematical error "
                    "when computing the arc geometry.";
    case 35: return "A G2 or G3 arc, traced with the offset definition, is missing the IJK "
                    "offset word in the selected plane to trace the arc.";
    case 36: return "There are unused, leftover G-code words that aren't used by any command in "
                    "the block.";
    case 37: return "The G43.1 dynamic tool length offset command cannot apply an offset to an "
                    "axis other than its configured axis.";
    case 38: return "Tool number greater than max supported value.";
    default: return "unknown error";
  }
}

std::string_view alarm_text(int code) {
  switch (code) {
    case 1: return "Hard limit triggered. Machine position is likely lost due to sudden and "
                   "immediate halt. Re-homing is highly recommended.";
    case 2: return "G-code motion target exceeds machine travel. Machine position safely "
                   "retained. Alarm may be unlocked.";
    case 3: return "Reset while in motion. Grbl cannot guarantee position. Lost steps are likely. "
                   "Re-homing is highly recommended.";
    case 4: return "Probe fail. The probe is not in the expected initial state before starting "
                   "probe cycle, where G38.2 and G38.3 is not triggered and G38.4 and G38.5 is "
                   "triggered.";
    case 5: return "Probe fail. Probe did not contact the workpiece within the programmed travel "
                   "for G38.2 and G38.4.";
    case 6: return "Homing fail. Reset during active homing cycle.";
    case 7: return "Homing fail. Safety door was opened during active homing cycle.";
    case 8: return "Homing fail. Cycle failed to clear limit switch when pulling off. Try "
                   "increasing pull-off setting or check wiring.";
    case 9: return "Homing fail. Could not find limit switch within search distance. Defined as "
                   "1.5 * max_travel on search and 5 * pulloff on locate phases.";
    case 10: return "Homing fail. On dual axis machines, could not find the second limit switch "
                    "for self-squaring.";
    default: return "unknown alarm";
  }
}

}  // namespace scanmesh::drivers::grbl
