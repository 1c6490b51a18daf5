// Micro-Epsilon optoNCDT ILD1420 codec: the binary 3-byte L/M/H measurement stream (pure,
// resynchronising decoder, scaling, error codes) and the ASCII command side (command encoding,
// `->`-prompted replies separated from interleaved binary values, GETINFO parsing).
// SPDX-License-Identifier: MIT
//
// Models: optoNCDT ILD1420 (ILD1420-10 .. -500); the ILD1320/1220 share the format.
// Vendor documents: optoNCDT 1420 manual §8 p. 84, §7.5.2 pp. 65-66, App. A3 pp. 94, 97; ILD1320
//   manual pp. 75, 82 (PROTOCOLS.md §1.3).
// Transport: RS422 serial byte stream, 8N1, factory setting 921600 baud (max 1 MBaud), up to
//   4 kHz measuring rate. Binary values out, ASCII commands in, ASCII replies out.
// Quirks:
//   - Each 18-bit output word is sent as 3 bytes L, M, H; the top bits mark them: L = 00xxxxxx
//     (D5..D0), M = 01xxxxxx (D11..D6), H = 1Fxxxxxx (D17..D12). The decoder resynchronises
//     from these marker bits alone (after garbage or a dropped byte the broken value is
//     counted as malformed and the next L byte starts afresh).
//   - F, the "first value of block" flag: 0 for the first value of an output block, 1 for the
//     others. The manual calls it "bit 7" but its table puts it next to the leading 1, i.e.
//     bit 6 of the H byte; we use bit 6. [unverified on hardware]
//   - The values of a block and their order come from the output configuration
//     (GETOUTINFO_RS422); here they are a configured list (default: distance only). The order of
//     the distance+counter+timestamp preset and of the two timestamp words is [unverified].
//   - Distance (16 bit): d = (1.02 x / 65520 - 0.01) MR; with mastering
//     d = (1.02 x / 65520 - 0.51) MR. x < 643 (SMR reserve) and x > 64877 (EMR reserve) are
//     outside the nominal range but still valid readings: reported kOk with their value.
//   - Codes 262075..262082 replace the distance: 262076 no peak -> kNoTarget; 262077/262078
//     peak before/after the range -> kOverRange; the others (262075 data rate too high,
//     262080 cannot be calculated, 262081 peak too large, 262082 laser off, unknown ones)
//     -> kDeviceError; device_code is always the raw code.
//   - Counter: 18 bit, wraps. Timestamp: two 16-bit words, t = (65536 hi + lo) * 10 µs.
//   - The sensor keeps streaming while it answers commands, and ASCII bytes (< 0x80) look like
//     L/M bytes. Strategy: stop the stream first (OUTPUT NONE, as the manual suggests); as a
//     fallback the reply parser removes every complete L,M,H triple (an H byte >= 0x80 can
//     never be ASCII) with a two-byte look-behind, so values still in flight never reach the
//     text. Only a lone H byte after a dropped L/M could eat two reply characters.
//   - Replies: lines ending CR LF, then the prompt "->"; "Exxx ..." errors and "Wxxx ..."
//     warnings come before the prompt (after a warning the command still runs).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "scanmesh/drivers/displacement_sensor.hpp"
#include "scanmesh/drivers/samples.hpp"

namespace scanmesh::drivers::microepsilon_ild1420 {

/// One 18-bit output word of a block.
enum class BlockValue : std::uint8_t { kDistance, kCounter, kTimestampLow, kTimestampHigh, kOther };

/// The configured output block (what GETOUTINFO_RS422 reports). 1..8 values, exactly one
/// kDistance, at most one of each of kCounter/kTimestampLow/kTimestampHigh.
struct BlockLayout {
  std::vector<BlockValue> values{BlockValue::kDistance};
  static BlockLayout distance_only() { return {}; }
  /// distance, counter, timestamp low word, timestamp high word. [unverified order]
  static BlockLayout distance_counter_timestamp() {
    return {{BlockValue::kDistance, BlockValue::kCounter, BlockValue::kTimestampLow,
             BlockValue::kTimestampHigh}};
  }
  /// Empty string when valid, else what is wrong.
  std::string check() const;
};

/// Factory baud rate of the RS422 link (8N1); the maximum is 1 MBaud.
constexpr unsigned kDefaultBaud = 921600;
constexpr std::size_t kMaxBlockValues = 8;
constexpr std::uint32_t kFirstErrorCode = 262075;
constexpr std::uint32_t kLastErrorCode = 262082;
constexpr std::uint32_t kNoPeak = 262076;
constexpr std::uint32_t kPeakBeforeRange = 262077;
constexpr std::uint32_t kPeakAfterRange = 262078;
/// Largest 16-bit distance value (x/65520 = 1 at the end of the EMR reserve).
constexpr std::uint32_t kMaxDistanceRaw = 65520;
constexpr std::uint32_t kSmrReserveBelow = 643;
constexpr std::uint32_t kEmrReserveAbove = 64877;

/// One complete output block: the raw 18-bit words in configured order.
struct RawBlock {
  std::array<std::uint32_t, kMaxBlockValues> words{};
  std::uint8_t count = 0;
};

/// Why bytes were thrown away.
enum class Malformed : std::uint8_t {
  kBrokenValue,  ///< L/M/H out of order (garbage, a dropped or corrupted byte)
  kOrphanValue,  ///< an "additional value" with no block start before it (after resync)
  kShortBlock,   ///< a new block started before the current one was complete
  kLongBlock,    ///< more values than the layout has
};
constexpr std::size_t kMalformedKinds = 4;
std::string_view to_string(Malformed m);

/// Pure, allocation-free streaming decoder of the binary output. Feed any chunks; complete
/// blocks are passed to on_block(const RawBlock&). Never throws.
class StreamDecoder {
 public:
  explicit StreamDecoder(std::size_t values_per_block = 1)
      : per_block_(values_per_block == 0 || values_per_block > kMaxBlockValues ? 1
                                                                               : values_per_block) {
  }

  template <class F>
  void feed(std::span<const std::uint8_t> bytes, F&& on_block) {
    const std::uint8_t* p = bytes.data();
    const std::size_t n = bytes.size();
    std::size_t i = 0;
    while (i < n) {
      // Fast path: a whole, well-formed L, M, H triple at a value boundary.
      if (phase_ == 0 && i + 3 <= n && (p[i] & 0xC0U) == 0x00U && (p[i + 1] & 0xC0U) == 0x40U &&
          (p[i + 2] & 0x80U) != 0) {
        const std::uint32_t w = (p[i] & 0x3FU) | ((p[i + 1] & 0x3FU) << 6) |
                                (static_cast<std::uint32_t>(p[i + 2] & 0x3FU) << 12);
        const bool additional = (p[i + 2] & 0x40U) != 0;
        i += 3;
        complete(w, additional, on_block);
        continue;
      }
      const std::uint8_t b = p[i++];
      if ((b & 0xC0U) == 0x00U) {  // L: always starts a value
        if (phase_ != 0) broken();
        word_ = b & 0x3FU;
        phase_ = 1;
      } else if ((b & 0xC0U) == 0x40U) {  // M
        if (phase_ != 1) {
          broken();
          phase_ = 0;
        } else {
          word_ |= (b & 0x3FU) << 6;
          phase_ = 2;
        }
      } else if (phase_ != 2) {  // H out of order
        broken();
        phase_ = 0;
      } else {
        phase_ = 0;
        complete(word_ | (static_cast<std::uint32_t>(b & 0x3FU) << 12), (b & 0x40U) != 0, on_block);
      }
    }
  }

  /// Forget a partial value/block (after a reconnect).
  void reset() {
    phase_ = 0;
    quiet_ = false;
    in_block_ = false;
    block_.count = 0;
  }
  std::uint64_t malformed() const {
    std::uint64_t n = 0;
    for (auto c : malformed_) n += c;
    return n;
  }
  std::uint64_t malformed(Malformed why) const { return malformed_[static_cast<int>(why)]; }
  std::uint64_t values() const { return values_; }
  std::size_t values_per_block() const { return per_block_; }

 private:
  void bad(Malformed why) { ++malformed_[static_cast<int>(why)]; }
  /// One complete 18-bit word: place it in the current block, emit full blocks.
  template <class F>
  void complete(std::uint32_t word, bool additional, F& on_block) {
    quiet_ = false;
    ++values_;
    if (!additional) {
      if (block_.count != 0) bad(Malformed::kShortBlock);
      block_.count = 0;
      in_block_ = true;
    } else if (!in_block_) {
      bad(Malformed::kOrphanValue);
      return;
    } else if (block_.count >= per_block_) {
      bad(Malformed::kLongBlock);
      in_block_ = false;
      block_.count = 0;
      return;
    }
    block_.words[block_.count++] = word;
    if (block_.count == per_block_) {
      on_block(static_cast<const RawBlock&>(block_));
      block_.count = 0;
      in_block_ = false;
    }
  }
  // A run of out-of-order bytes (garbage, a dropped byte) counts once, until a value completes.
  void broken() {
    if (!quiet_) bad(Malformed::kBrokenValue);
    quiet_ = true;
  }

  std::size_t per_block_;
  int phase_ = 0;  // 0 expect L, 1 expect M, 2 expect H
  bool quiet_ = false;
  bool in_block_ = false;
  std::uint32_t word_ = 0;
  RawBlock block_;
  std::uint64_t values_ = 0;
  std::array<std::uint64_t, kMalformedKinds> malformed_{};
};

/// Encodes one 18-bit word as L, M, H (first = the block-start flag clear). For emulators,
/// tests and benchmarks.
std::array<std::uint8_t, 3> encode_word(std::uint32_t word, bool first_of_block);

/// Scaling of the distance word. MR in mm (10, 25, 50, 100, 200, 500).
struct Scaling {
  double measuring_range_mm = 10;
  bool mastering = false;
};

/// A decoded block.
struct DecodedBlock {
  SensorStatus status = SensorStatus::kNoTarget;
  double value_mm = 0;  ///< NaN unless kOk
  std::uint32_t device_code = 0;
  std::optional<std::uint32_t> counter;  ///< 18-bit measurement counter
  std::optional<Timestamp> t_device;     ///< device clock (10 µs ticks)
};

/// Distance word -> status/value (see the header comment for the rules).
void decode_distance(std::uint32_t raw, const Scaling& scaling, DecodedBlock& out);
/// Whole block per layout. Pure.
DecodedBlock decode_block(const RawBlock& block, const BlockLayout& layout, const Scaling& scaling);
/// Inverse scaling for emulators: distance -> raw word (clamped to 0..65520).
std::uint32_t encode_distance(double value_mm, const Scaling& scaling);

// ---- ASCII command side ----------------------------------------------------------------------

/// One command line; encode() appends the CR terminator.
struct Command {
  std::string text;
  std::string encode() const { return text + "\r"; }
};
inline Command get_info() { return {"GETINFO"}; }
inline Command get_out_info_rs422() { return {"GETOUTINFO_RS422"}; }
enum class OutputTarget { kNone, kRs422, kAnalog };
Command output(OutputTarget target);  // "OUTPUT NONE" / "OUTPUT RS422" / "OUTPUT ANALOG"
/// MEASRATE <kHz> (0.25, 0.5, 1, 2, 4). [unverified: parameter format taken from ILD2300]
Command meas_rate(double khz);

/// A complete reply: the lines before the prompt.
struct Reply {
  std::vector<std::string> lines;     ///< every line except errors/warnings
  std::string error;                  ///< "E104 Timeout" (empty when none)
  std::vector<std::string> warnings;  ///< "W...." lines
  bool ok() const { return error.empty(); }
};

/// Collects reply lines up to the "->" prompt from a byte stream that may carry binary
/// measurement values too (see the header comment for the demultiplexing). Pure, never throws.
class ReplyParser {
 public:
  explicit ReplyParser(std::size_t max_line = 256, std::size_t max_lines = 64)
      : max_line_(max_line), max_lines_(max_lines) {}

  /// Consumes bytes until a reply completes; returns how many were consumed. When a reply is
  /// complete, done() is true, reply() holds it, and take_after_prompt() returns the (0..2)
  /// look-behind bytes that followed the prompt: they and bytes[consumed..] belong to the
  /// binary stream.
  std::size_t feed(std::span<const std::uint8_t> bytes);
  /// The line went quiet (a read timed out): commit the look-behind bytes as text.
  void flush();
  bool done() const { return done_; }
  const Reply& reply() const { return reply_; }
  std::vector<std::uint8_t> take_after_prompt();
  /// Starts waiting for the next reply.
  void reset();

  std::uint64_t binary_bytes_removed() const { return binary_removed_; }
  std::uint64_t noise_bytes() const { return noise_; }
  std::uint64_t overlong_lines() const { return overlong_; }

 private:
  void text(std::uint8_t c);
  void end_line();

  std::size_t max_line_, max_lines_;
  std::array<std::uint8_t, 2> pending_{};
  std::size_t npending_ = 0;
  std::string line_;
  bool overflow_ = false;
  bool done_ = false;
  Reply reply_;
  std::vector<std::uint8_t> after_;
  std::uint64_t binary_removed_ = 0, noise_ = 0, overlong_ = 0;
};

/// What GETINFO says.
struct Info {
  DeviceIdentity identity;  ///< vendor "Micro-Epsilon", model = Name, serial, firmware = Version
  std::string article;
  double measuring_range_mm = 0;  ///< 0 when the reply has no "Measuring range" line
};
/// Parses "Name: ILD1420-10", "Serial: 1234", "Article: 4120123", "Measuring range: 10.00mm",
/// "Version: 001.002.003" lines (key case-insensitive, any spacing). Unknown lines are ignored.
Info parse_info(const Reply& reply);

}  // namespace scanmesh::drivers::microepsilon_ild1420
