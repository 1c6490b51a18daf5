// ILD1420 codec: block layout checks, scaling, error codes, command encoding, the reply parser
// with binary demultiplexing, and GETINFO parsing (see codec.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/microepsilon_ild1420/codec.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>

#include "scanmesh/drivers/common/line_framer.hpp"

namespace scanmesh::drivers::microepsilon_ild1420 {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool is_l(std::uint8_t b) { return (b & 0xC0U) == 0x00U; }
bool is_m(std::uint8_t b) { return (b & 0xC0U) == 0x40U; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

bool coded_line(const std::string& line, char letter) {
  return line.size() >= 4 && line[0] == letter &&
         std::isdigit(static_cast<unsigned char>(line[1])) &&
         std::isdigit(static_cast<unsigned char>(line[2])) &&
         std::isdigit(static_cast<unsigned char>(line[3])) &&
         (line.size() == 4 || line[4] == ' ' || line[4] == ':');
}

}  // namespace

std::string BlockLayout::check() const {
  if (values.empty() || values.size() > kMaxBlockValues) return "the block must have 1..8 values";
  const auto n = [&](BlockValue v) { return std::count(values.begin(), values.end(), v); };
  if (n(BlockValue::kDistance) != 1) return "the block must have exactly one distance";
  for (auto v : {BlockValue::kCounter, BlockValue::kTimestampLow, BlockValue::kTimestampHigh}) {
    if (n(v) > 1) return "counter and timestamp words may appear once each";
  }
  if (n(BlockValue::kTimestampLow) != n(BlockValue::kTimestampHigh))
    return "the timestamp needs both words";
  return {};
}

std::string_view to_string(Malformed m) {
  switch (m) {
    case Malformed::kBrokenValue:
      return "broken value (L/M/H out of order)";
    case Malformed::kOrphanValue:
      return "additional value without block start";
    case Malformed::kShortBlock:
      return "block shorter than the layout";
    case Malformed::kLongBlock:
      return "block longer than the layout";
  }
  return "?";
}

std::array<std::uint8_t, 3> encode_word(std::uint32_t word, bool first_of_block) {
  return {
      static_cast<std::uint8_t>(word & 0x3FU),
      static_cast<std::uint8_t>(0x40U | ((word >> 6) & 0x3FU)),
      static_cast<std::uint8_t>(0x80U | (first_of_block ? 0U : 0x40U) | ((word >> 12) & 0x3FU))};
}

void decode_distance(std::uint32_t raw, const Scaling& scaling, DecodedBlock& out) {
  out.device_code = 0;
  out.value_mm = kNaN;
  if (raw >= kFirstErrorCode) {
    out.device_code = raw;
    if (raw == kNoPeak) {
      out.status = SensorStatus::kNoTarget;
    } else if (raw == kPeakBeforeRange || raw == kPeakAfterRange) {
      out.status = SensorStatus::kOverRange;
    } else {
      out.status = SensorStatus::kDeviceError;  // 262075, 262080..262082 and undocumented codes
    }
    return;
  }
  if (!scaling.mastering && raw > kMaxDistanceRaw) {
    // Not a 16-bit distance and not a documented code: report it, never invent a value.
    out.status = SensorStatus::kDeviceError;
    out.device_code = raw;
    return;
  }
  // SMR/EMR reserve values (x < 643, x > 64877) are still measurements: kOk with their value.
  const double k = scaling.mastering ? 0.51 : 0.01;
  out.status = SensorStatus::kOk;
  out.value_mm = (1.02 * static_cast<double>(raw) / 65520.0 - k) * scaling.measuring_range_mm;
}

DecodedBlock decode_block(const RawBlock& block, const BlockLayout& layout,
                          const Scaling& scaling) {
  DecodedBlock out;
  out.value_mm = kNaN;
  std::optional<std::uint32_t> ts_lo, ts_hi;
  const std::size_t n = std::min<std::size_t>(block.count, layout.values.size());
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t w = block.words[i];
    switch (layout.values[i]) {
      case BlockValue::kDistance:
        decode_distance(w, scaling, out);
        break;
      case BlockValue::kCounter:
        out.counter = w & 0x3FFFFU;
        break;
      case BlockValue::kTimestampLow:
        ts_lo = w & 0xFFFFU;
        break;
      case BlockValue::kTimestampHigh:
        ts_hi = w & 0xFFFFU;
        break;
      case BlockValue::kOther:
        break;
    }
  }
  if (ts_lo && ts_hi) {
    const std::int64_t ticks = (static_cast<std::int64_t>(*ts_hi) << 16) | *ts_lo;
    out.t_device = Timestamp{ticks * 10'000};  // 10 µs per tick: t[ms] = ticks / 100
  }
  return out;
}

std::uint32_t encode_distance(double value_mm, const Scaling& scaling) {
  const double k = scaling.mastering ? 0.51 : 0.01;
  const double x = (value_mm / scaling.measuring_range_mm + k) * 65520.0 / 1.02;
  const double hi = scaling.mastering ? kFirstErrorCode - 1 : kMaxDistanceRaw;
  if (!(x > 0)) return 0;
  return static_cast<std::uint32_t>(std::lround(std::min(x, hi)));
}

Command output(OutputTarget target) {
  switch (target) {
    case OutputTarget::kNone:
      return {"OUTPUT NONE"};
    case OutputTarget::kRs422:
      return {"OUTPUT RS422"};
    case OutputTarget::kAnalog:
      return {"OUTPUT ANALOG"};
  }
  return {"OUTPUT NONE"};
}

Command meas_rate(double khz) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "MEASRATE %g", khz);
  return {buf};
}

// ---- ReplyParser -------------------------------------------------------------------------------

std::size_t ReplyParser::feed(std::span<const std::uint8_t> bytes) {
  if (done_) return 0;
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const std::uint8_t b = bytes[i];
    if ((b & 0x80U) != 0) {
      // An H byte is never text. With an L, M right before it, the three are one value.
      if (npending_ == 2 && is_l(pending_[0]) && is_m(pending_[1])) {
        binary_removed_ += 3;
        npending_ = 0;
      } else {
        ++binary_removed_;  // a lone H (its L/M were lost): drop it alone
      }
      continue;
    }
    if (npending_ == 2) {
      const std::uint8_t oldest = pending_[0];
      pending_[0] = pending_[1];
      npending_ = 1;
      text(oldest);
      if (done_) {
        after_.assign(pending_.begin(), pending_.begin() + npending_);
        after_.push_back(b);
        npending_ = 0;
        return i + 1;
      }
    }
    pending_[npending_++] = b;
  }
  return bytes.size();
}

void ReplyParser::flush() {
  std::size_t k = 0;
  while (k < npending_ && !done_) text(pending_[k++]);
  if (done_) after_.insert(after_.end(), pending_.begin() + k, pending_.begin() + npending_);
  npending_ = 0;
}

std::vector<std::uint8_t> ReplyParser::take_after_prompt() {
  std::vector<std::uint8_t> out;
  out.swap(after_);
  return out;
}

void ReplyParser::reset() {
  npending_ = 0;
  line_.clear();
  overflow_ = false;
  done_ = false;
  reply_ = {};
  after_.clear();
}

void ReplyParser::text(std::uint8_t c) {
  if (c == '\r' || c == '\n') {
    end_line();
    return;
  }
  if (c < 0x20 || c > 0x7E) {
    ++noise_;
    return;
  }
  if (overflow_) return;
  if (line_.size() >= max_line_) {
    overflow_ = true;
    line_.clear();
    return;
  }
  line_.push_back(static_cast<char>(c));
  if (line_ == "->") {  // the prompt: the reply is complete
    line_.clear();
    done_ = true;
  }
}

void ReplyParser::end_line() {
  if (overflow_) {
    overflow_ = false;
    ++overlong_;
    line_.clear();
    return;
  }
  if (line_.empty()) return;
  if (coded_line(line_, 'E')) {
    if (reply_.error.empty()) reply_.error = line_;
  } else if (coded_line(line_, 'W')) {
    if (reply_.warnings.size() < max_lines_) reply_.warnings.push_back(line_);
  } else if (reply_.lines.size() < max_lines_) {
    reply_.lines.push_back(line_);
  }
  line_.clear();
}

Info parse_info(const Reply& reply) {
  Info info;
  info.identity.vendor = "Micro-Epsilon";
  for (const std::string& line : reply.lines) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string key(trim(std::string_view(line).substr(0, colon)));
    for (char& c : key) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    const std::string_view value = trim(std::string_view(line).substr(colon + 1));
    if (key == "name") {
      info.identity.model = value;
    } else if (key == "serial") {
      info.identity.serial = value;
    } else if (key == "article") {
      info.article = value;
    } else if (key == "version") {
      info.identity.firmware = value;
    } else if (key == "measuring range") {
      std::size_t n = 0;
      while (n < value.size() &&
             (std::isdigit(static_cast<unsigned char>(value[n])) || value[n] == '.'))
        ++n;
      double mr = 0;
      if (n > 0 && parse_fixed_decimal(value.substr(0, n), mr) && mr > 0) {
        info.measuring_range_mm = mr;
      }
    }
  }
  return info;
}

}  // namespace scanmesh::drivers::microepsilon_ild1420
