// mcap::scan: reads an MCAP file record by record through a sliding window, verifies every
// chunk's CRC, checks the message indexes after each chunk against the chunk, skips damage by
// searching for the next chunk whose CRC matches, finds a torn tail, and checks the summary
// against what the data section holds.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <cstring>
#include <limits>
#include <optional>

#include "bytes.hpp"
#include "crc.hpp"
#include "file.hpp"
#include "records.hpp"
#include "scan_internal.hpp"
#include "scanmesh/acquisition/mcap.hpp"

namespace scanmesh::acq::mcap::detail {

using acq::detail::File;
using acq::detail::load;

namespace {

constexpr std::size_t kWindowBytes = std::size_t{4} << 20;
/// Records larger than this are not read whole (none of ours comes near; a damaged length is
/// the likely cause): they count as damage.
constexpr std::uint64_t kMaxRecordBytes = std::uint64_t{1} << 30;
/// Message Index records larger than this are not ours (a 64 KiB chunk indexes a few thousand
/// messages at 16 bytes each).
constexpr std::uint64_t kMaxIndexRecordBytes = std::uint64_t{64} << 20;

std::string at(std::uint64_t offset) { return "byte " + std::to_string(offset); }

std::string opname(std::uint8_t op) {
  switch (static_cast<Opcode>(op)) {
    case Opcode::kHeader:
      return "Header";
    case Opcode::kFooter:
      return "Footer";
    case Opcode::kSchema:
      return "Schema";
    case Opcode::kChannel:
      return "Channel";
    case Opcode::kMessage:
      return "Message";
    case Opcode::kChunk:
      return "Chunk";
    case Opcode::kMessageIndex:
      return "Message Index";
    case Opcode::kChunkIndex:
      return "Chunk Index";
    case Opcode::kAttachment:
      return "Attachment";
    case Opcode::kAttachmentIndex:
      return "Attachment Index";
    case Opcode::kStatistics:
      return "Statistics";
    case Opcode::kMetadata:
      return "Metadata";
    case Opcode::kMetadataIndex:
      return "Metadata Index";
    case Opcode::kSummaryOffset:
      return "Summary Offset";
    case Opcode::kDataEnd:
      return "Data End";
  }
  return "opcode 0x" + [op] {
    char b[4];
    std::snprintf(b, sizeof b, "%02x", op);
    return std::string(b);
  }();
}

/// A sliding read window over the file, plus the running CRC of its bytes in file order.
class Window {
 public:
  Window(const File& f, std::uint64_t size) : file_(f), size_(size) {}

  /// The n bytes at pos (pos + n <= file size); valid until the next get().
  std::span<const std::byte> get(std::uint64_t pos, std::size_t n) {
    if (pos >= start_ && pos + n <= start_ + len_) return {buf_.data() + (pos - start_), n};
    const std::size_t want =
        static_cast<std::size_t>(std::min<std::uint64_t>(std::max(n, kWindowBytes), size_ - pos));
    if (buf_.size() < want) {
      std::vector<std::byte> bigger(want);
      if (pos >= start_ && pos < start_ + len_) {
        const std::size_t keep = static_cast<std::size_t>(start_ + len_ - pos);
        std::memcpy(bigger.data(), buf_.data() + (pos - start_), keep);
        buf_ = std::move(bigger);
        fill(pos, keep, want);
        return {buf_.data(), n};
      }
      buf_ = std::move(bigger);
      fill(pos, 0, want);
      return {buf_.data(), n};
    }
    std::size_t keep = 0;
    if (pos >= start_ && pos < start_ + len_) {
      keep = static_cast<std::size_t>(start_ + len_ - pos);
      std::memmove(buf_.data(), buf_.data() + (pos - start_), keep);
    }
    fill(pos, keep, want);
    return {buf_.data(), n};
  }

  /// Advances the running CRC over the bytes [crc_pos, pos).
  void crc_to(std::uint64_t pos) {
    while (crc_pos_ < pos) {
      if (crc_pos_ >= start_ && crc_pos_ < start_ + len_) {
        const auto n = static_cast<std::size_t>(std::min(pos, start_ + len_) - crc_pos_);
        crc_ = acq::detail::crc32_update(crc_, {buf_.data() + (crc_pos_ - start_), n});
        crc_pos_ += n;
        continue;
      }
      const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(pos - crc_pos_, 1 << 20));
      scratch_.resize(n);
      const std::size_t got = file_.read_at(crc_pos_, scratch_.data(), n);
      if (got != n) throw InputError("journal " + file_.name() + ": the file shrank while read");
      crc_ = acq::detail::crc32_update(crc_, scratch_);
      crc_pos_ += n;
    }
  }
  /// The bytes [crc_pos, crc_pos + len) have the CRC `crc`: fold it in without reading them.
  void crc_skip(std::uint32_t crc, std::uint64_t len) {
    crc_ = acq::detail::crc32_combine(crc_, crc, len);
    crc_pos_ += len;
  }
  [[nodiscard]] std::uint32_t crc() const noexcept { return crc_; }
  [[nodiscard]] std::uint64_t crc_pos() const noexcept { return crc_pos_; }

 private:
  void fill(std::uint64_t pos, std::size_t keep, std::size_t want) {
    const std::size_t got = keep + file_.read_at(pos + keep, buf_.data() + keep, want - keep);
    start_ = pos;
    len_ = got;
    if (got < want) throw InputError("journal " + file_.name() + ": the file shrank while read");
  }

  const File& file_;
  std::uint64_t size_;
  std::vector<std::byte> buf_;
  std::uint64_t start_ = 0;
  std::size_t len_ = 0;
  std::vector<std::byte> scratch_;
  std::uint32_t crc_ = 0;
  std::uint64_t crc_pos_ = 0;
};

struct Footer {
  bool ok = false;
  std::uint64_t summary_start = 0;
  std::uint64_t summary_offset_start = 0;
  std::uint32_t summary_crc = 0;
};

class Scanner {
 public:
  Scanner(const File& f, ScanVisitor* v, ScanOptions o, ScanExtras* extras)
      : file_(f), size_(f.size()), win_(f, size_), visitor_(v), options_(o), extras_(extras) {
    r_.file = f.name();
    r_.file_bytes = size_;
  }

  ScanReport run() {
    if (!read_magic()) return std::move(r_);
    footer_ = read_footer();
    std::uint64_t pos = read_header();
    scan_data(pos);
    finish();
    return std::move(r_);
  }

 private:
  [[noreturn]] void fail_strict(const std::string& what) const {
    throw InputError("journal " + r_.file + ": " + what +
                     " (`scanmesh journal check` reports every problem; `scanmesh journal "
                     "recover` keeps every good chunk)");
  }

  bool read_magic() {
    const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(size_, kMagic.size()));
    const auto head = n > 0 ? win_.get(0, n) : std::span<const std::byte>{};
    if (n > 0 && std::memcmp(head.data(), kMagic.data(), n) != 0)
      throw InputError("journal " + r_.file + ": not an MCAP file (it does not start with the " +
                       "MCAP magic bytes)");
    if (n < kMagic.size()) {  // cut before the header was written
      r_.torn_tail = true;
      r_.torn_offset = 0;
      r_.torn_bytes = size_;
      if (options_.strict)
        fail_strict("the file ends inside the MCAP magic (" + std::to_string(size_) + " bytes)");
      return false;
    }
    return true;
  }

  Footer read_footer() {
    Footer f;
    if (size_ < kMagic.size() * 2 + kFooterRecord) return f;
    const std::uint64_t fpos = size_ - kMagic.size() - kFooterRecord;
    const auto b = win_.get(fpos, kFooterRecord + kMagic.size());
    if (std::memcmp(b.data() + kFooterRecord, kMagic.data(), kMagic.size()) != 0) return f;
    if (load<std::uint8_t>(b.data()) != static_cast<std::uint8_t>(Opcode::kFooter) ||
        load<std::uint64_t>(b.data() + 1) != 20)
      return f;
    f.summary_start = load<std::uint64_t>(b.data() + 9);
    f.summary_offset_start = load<std::uint64_t>(b.data() + 17);
    f.summary_crc = load<std::uint32_t>(b.data() + 25);
    f.ok = f.summary_start <= fpos && f.summary_offset_start <= fpos;
    return f;
  }

  std::uint64_t read_header() {
    const std::uint64_t pos = kMagic.size();
    r_.good_end = pos;
    win_.crc_to(pos);
    extras_crc_good();
    if (size_ - pos < kRecordPrefix) return pos;  // torn inside the header: finish() says so
    const auto pre = win_.get(pos, kRecordPrefix);
    const auto op = load<std::uint8_t>(pre.data());
    const auto len = load<std::uint64_t>(pre.data() + 1);
    if (op != static_cast<std::uint8_t>(Opcode::kHeader) || len > (1u << 20)) {
      damage(pos, "the first record is not a Header");
      return pos;
    }
    if (len > size_ - pos - kRecordPrefix) return pos;  // torn inside the header
    ByteReader rd(win_.get(pos + kRecordPrefix, static_cast<std::size_t>(len)));
    r_.profile = rd.string();
    r_.library = rd.string();
    if (!rd.ok()) {
      damage(pos, "the Header record does not parse");
      return pos;
    }
    r_.header_ok = true;
    good(pos + kRecordPrefix + len);
    return r_.good_end;
  }

  void good(std::uint64_t end) {
    r_.good_end = end;
    win_.crc_to(end);
    extras_crc_good();
  }
  void extras_crc_good() {
    if (extras_ != nullptr) extras_->crc_at_good_end = win_.crc();
  }

  /// Records a skipped region starting at `pos` (its end is set when the scan finds the next
  /// good record); merges with a region that ends where this one starts.
  void damage(std::uint64_t pos, std::string what) {
    if (!r_.damage.empty()) {
      Damage& last = r_.damage.back();
      if (last.length == 0 && last.offset <= pos) return;  // still open: the same region
      if (last.offset + last.length == pos) {              // adjacent: reopen it
        last.length = 0;
        return;
      }
    }
    r_.damage.push_back({pos, 0, std::move(what)});
  }
  void close_damage(std::uint64_t end) {
    if (!r_.damage.empty() && r_.damage.back().length == 0)
      r_.damage.back().length = end - r_.damage.back().offset;
  }

  /// Records damage at pos and moves to the next good chunk (or the data end); nullopt when none
  /// follows. Strict: throws when one follows (damage in the middle).
  std::optional<std::uint64_t> skip_damage(std::uint64_t pos, std::string what) {
    damage(pos, what);
    auto next = resync(pos + 1);
    if (next) {
      close_damage(*next);
      if (options_.strict) fail_strict(what + " at " + at(pos));
    }
    return next;
  }

  /// Whether a CRC-checked chunk (or the Data End the footer points to) starts at q. `pre` holds
  /// the bytes at q that are already in memory (at least 9).
  bool resync_target(std::uint64_t q, std::span<const std::byte> pre) {
    const auto op = load<std::uint8_t>(pre.data());
    const auto len = load<std::uint64_t>(pre.data() + 1);
    if (op == static_cast<std::uint8_t>(Opcode::kDataEnd)) {
      return len == 4 && footer_.ok && footer_.summary_start == q + kDataEndRecord;
    }
    if (len < kChunkHeader - kRecordPrefix || len > size_ - q - kRecordPrefix ||
        len > kMaxRecordBytes)
      return false;
    std::byte head[kChunkHeader];
    if (pre.size() >= kChunkHeader) {
      std::memcpy(head, pre.data(), kChunkHeader);
    } else if (file_.read_at(q, head, kChunkHeader) != kChunkHeader) {
      return false;
    }
    const auto usize = load<std::uint64_t>(head + 25);
    const auto crc = load<std::uint32_t>(head + 33);
    const auto comp = load<std::uint32_t>(head + 37);
    const auto rlen = load<std::uint64_t>(head + 41);
    if (comp != 0 || rlen != usize || len != kChunkHeader - kRecordPrefix + rlen) return false;
    scratch_.resize(static_cast<std::size_t>(rlen));
    if (file_.read_at(q + kChunkHeader, scratch_.data(), scratch_.size()) != scratch_.size())
      return false;
    return crc == 0 || acq::detail::crc32_update(0, scratch_) == crc;
  }

  std::optional<std::uint64_t> resync(std::uint64_t from) {
    std::uint64_t q = from;
    while (q + kRecordPrefix <= size_) {
      const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(size_ - q, kWindowBytes));
      auto s = win_.get(q, n);
      std::size_t i = 0;
      for (; i + kRecordPrefix <= n; ++i) {
        const auto b = static_cast<std::uint8_t>(s[i]);
        if (b != static_cast<std::uint8_t>(Opcode::kChunk) &&
            b != static_cast<std::uint8_t>(Opcode::kDataEnd))
          continue;
        const std::size_t have = std::min<std::size_t>(n - i, kChunkHeader);
        // resync_target reads with pread only: s stays valid.
        if (resync_target(q + i, s.subspan(i, have))) return q + i;
      }
      q += i;
      if (i == 0) break;
    }
    return std::nullopt;
  }

  /// Whether a record that the scan can continue with starts at q (or the file ends there).
  bool plausible(std::uint64_t q) {
    if (q == size_) return true;
    if (size_ - q < kRecordPrefix) return false;
    const auto pre = win_.get(q, kRecordPrefix);
    const auto op = load<std::uint8_t>(pre.data());
    const auto len = load<std::uint64_t>(pre.data() + 1);
    if (len > size_ - q - kRecordPrefix) return false;
    switch (static_cast<Opcode>(op)) {
      case Opcode::kSchema:
      case Opcode::kChannel:
      case Opcode::kMessage:
      case Opcode::kChunk:
      case Opcode::kMessageIndex:
      case Opcode::kMetadata:
      case Opcode::kAttachment:
        return true;
      case Opcode::kDataEnd:
        return len == 4;
      default:
        return op >= 0x80;
    }
  }

  /// The end of the Message Index records starting at q (q itself when there are none); stops
  /// once `limit` bytes are covered.
  std::uint64_t skip_index_records(
      std::uint64_t q, std::uint64_t limit = std::numeric_limits<std::uint64_t>::max()) {
    const std::uint64_t from = q;
    while (size_ - q >= kRecordPrefix && q - from < limit) {
      const auto pre = win_.get(q, kRecordPrefix);
      const auto op = load<std::uint8_t>(pre.data());
      const auto len = load<std::uint64_t>(pre.data() + 1);
      if (op != static_cast<std::uint8_t>(Opcode::kMessageIndex) || len < 6 ||
          len > kMaxIndexRecordBytes || len > size_ - q - kRecordPrefix)
        break;
      q += kRecordPrefix + len;
    }
    return q;
  }

  void register_schema(const Schema& s, bool& conflict) {
    auto [it, inserted] = r_.schemas.emplace(s.id, s);
    if (!inserted) {
      conflict = it->second != s;
      return;
    }
    if (visitor_ != nullptr) visitor_->on_schema(s);
  }
  void register_channel(const Channel& c, bool& conflict) {
    auto [it, inserted] = r_.channels.emplace(c.id, c);
    if (!inserted) {
      conflict = it->second != c;
      return;
    }
    if (visitor_ != nullptr) visitor_->on_channel(c);
  }

  void count_message(const MessageHeader& h) {
    if (r_.messages == 0) {
      r_.message_start_time = r_.message_end_time = h.log_time;
    } else {
      if (h.log_time < last_log_time_) ++r_.out_of_order_messages;
      r_.message_start_time = std::min(r_.message_start_time, h.log_time);
      r_.message_end_time = std::max(r_.message_end_time, h.log_time);
    }
    last_log_time_ = h.log_time;
    ++r_.messages;
    ++r_.channel_messages[h.channel_id];
  }

  void deliver(const Message& m) {
    count_message(m.header);
    if (r_.channels.count(m.header.channel_id) == 0) {
      ++r_.unknown_channel_messages;
      return;
    }
    if (visitor_ != nullptr) visitor_->on_message(m);
  }

  static std::optional<MessageHeader> parse_message_header(std::span<const std::byte> body) {
    if (body.size() < 22) return std::nullopt;
    MessageHeader h;
    h.channel_id = load<std::uint16_t>(body.data());
    h.sequence = load<std::uint32_t>(body.data() + 2);
    h.log_time = load<std::uint64_t>(body.data() + 6);
    h.publish_time = load<std::uint64_t>(body.data() + 14);
    return h;
  }

  struct Rec {
    std::uint8_t op;
    std::size_t at;  // of the record in the chunk's records
    std::size_t body;
    std::size_t len;
  };

  /// Checks the records of a chunk whose CRC matched; fills recs. Empty string: good.
  std::string parse_chunk_records(std::span<const std::byte> records) {
    recs_.clear();
    std::size_t p = 0;
    while (p < records.size()) {
      if (records.size() - p < kRecordPrefix) return "a record is cut at its end";
      const auto op = load<std::uint8_t>(records.data() + p);
      const auto len = load<std::uint64_t>(records.data() + p + 1);
      if (len > records.size() - p - kRecordPrefix) return "a record runs past the chunk";
      const auto body = records.subspan(p + kRecordPrefix, static_cast<std::size_t>(len));
      switch (static_cast<Opcode>(op)) {
        case Opcode::kSchema:
          if (!parse_schema(body)) return "a Schema record does not parse";
          break;
        case Opcode::kChannel:
          if (!parse_channel(body)) return "a Channel record does not parse";
          break;
        case Opcode::kMessage:
          if (body.size() < 22) return "a Message record is too short";
          break;
        default:
          if (op < 0x80) return "a " + opname(op) + " record inside a chunk";
      }
      recs_.push_back({op, p, p + kRecordPrefix, static_cast<std::size_t>(len)});
      p += kRecordPrefix + static_cast<std::size_t>(len);
    }
    return {};
  }

  /// The Message Index records a chunk should have, in the writer's order (by channel id, then
  /// by message), into expected_.
  void build_expected_index(std::span<const std::byte> records) {
    by_channel_.clear();
    for (const Rec& rec : recs_) {
      if (rec.op != static_cast<std::uint8_t>(Opcode::kMessage)) continue;
      const auto h = *parse_message_header(records.subspan(rec.body, rec.len));
      by_channel_.emplace_back(h.channel_id, rec.at, h.log_time);
    }
    std::stable_sort(by_channel_.begin(), by_channel_.end(),
                     [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });
    expected_.clear();
    std::size_t i = 0;
    while (i < by_channel_.size()) {
      const std::uint16_t ch = std::get<0>(by_channel_[i]);
      std::size_t j = i;
      while (j < by_channel_.size() && std::get<0>(by_channel_[j]) == ch) ++j;
      const std::size_t rec =
          expected_.begin_record(static_cast<std::uint8_t>(Opcode::kMessageIndex));
      expected_.put(ch);
      expected_.put(static_cast<std::uint32_t>((j - i) * 16));
      for (std::size_t k = i; k < j; ++k) {
        expected_.put(std::get<2>(by_channel_[k]));
        expected_.put(static_cast<std::uint64_t>(std::get<1>(by_channel_[k])));
      }
      expected_.end_record(rec);
      i = j;
    }
  }

  /// A Chunk record at pos with body length len. Returns where the scan goes on, or nullopt.
  std::optional<std::uint64_t> handle_chunk(std::uint64_t pos, std::uint64_t len) {
    const std::uint64_t end = pos + kRecordPrefix + len;
    if (len < kChunkHeader - kRecordPrefix) return skip_damage(pos, "a Chunk record too short");
    auto body = win_.get(pos + kRecordPrefix, static_cast<std::size_t>(len));
    ByteReader rd(body);
    const auto start_time = rd.get<std::uint64_t>();
    const auto end_time = rd.get<std::uint64_t>();
    const auto usize = rd.get<std::uint64_t>();
    const auto crc = rd.get<std::uint32_t>();
    const std::string compression = rd.string();
    const auto rlen = rd.get<std::uint64_t>();
    const std::size_t records_at = rd.pos();
    const auto records = rd.bytes(static_cast<std::size_t>(std::min<std::uint64_t>(rlen, len)));
    if (!rd.ok() || (compression.empty() && usize != rlen))
      return skip_damage(pos, "a Chunk record whose sizes do not agree");
    if (!compression.empty()) {
      return skip_bad_chunk(
          pos, end,
          "a chunk compressed with '" + compression + "', which this reader does not decompress");
    }
    const std::uint32_t computed = acq::detail::crc32_update(0, records);
    if (crc != 0 && computed != crc) {
      ++r_.crc_failures;
      return skip_bad_chunk(pos, end,
                            "a chunk whose CRC does not match (stored " + std::to_string(crc) +
                                ", computed " + std::to_string(computed) + ")");
    }
    if (auto bad = parse_chunk_records(records); !bad.empty())
      return skip_bad_chunk(pos, end,
                            "a chunk whose CRC matches but whose records do not parse: " + bad);
    // Schemas and channels first, checked for conflicts, then the messages.
    for (const Rec& rec : recs_) {
      bool conflict = false;
      const auto rb = records.subspan(rec.body, rec.len);
      if (rec.op == static_cast<std::uint8_t>(Opcode::kSchema)) {
        register_schema(*parse_schema(rb), conflict);
      } else if (rec.op == static_cast<std::uint8_t>(Opcode::kChannel)) {
        register_channel(*parse_channel(rb), conflict);
      }
      if (conflict)
        return skip_bad_chunk(pos, end, "a chunk redefining a schema or channel differently");
    }
    ChunkInfo info;
    info.offset = pos;
    info.length = kRecordPrefix + len;
    info.message_start_time = start_time;
    info.message_end_time = end_time;
    info.records_bytes = rlen;
    build_expected_index(records);
    for (const Rec& rec : recs_) {
      if (rec.op != static_cast<std::uint8_t>(Opcode::kMessage)) continue;
      const auto rb = records.subspan(rec.body, rec.len);
      Message m{*parse_message_header(rb), rb.subspan(22)};
      deliver(m);
      ++info.messages;
    }
    for (std::size_t i = 0; i < by_channel_.size();) {
      std::size_t j = i;
      while (j < by_channel_.size() && std::get<0>(by_channel_[j]) == std::get<0>(by_channel_[i]))
        ++j;
      info.channel_messages.emplace_back(std::get<0>(by_channel_[i]), j - i);
      i = j;
    }
    // Data section CRC: the chunk header, then the records whose CRC is known, then the rest.
    win_.crc_to(pos + kRecordPrefix + records_at);
    win_.crc_skip(computed, rlen);
    win_.crc_to(end);

    // The Message Index records after it must be exactly those the chunk implies.
    const std::uint64_t index_end = skip_index_records(end, expected_.size());
    const std::uint64_t region = index_end - end;
    bool intact = region == expected_.size();
    if (intact && region > 0) {
      const auto found = win_.get(end, static_cast<std::size_t>(region));
      intact = std::memcmp(found.data(), expected_.data(), expected_.size()) == 0;
    }
    if (intact) {
      info.index_intact = true;
      info.message_index_offsets = index_layout(expected_.span(), end);
      info.message_index_length = region;
      r_.chunks.push_back(std::move(info));
      close_damage(pos);
      good(index_end);
      return index_end;
    }
    pending_.emplace_back(
        r_.chunks.size(),
        std::vector<std::byte>(expected_.data(), expected_.data() + expected_.size()));
    r_.chunks.push_back(std::move(info));
    close_damage(pos);
    good(end);
    if (region > 0) {
      damage(end, "Message Index records that do not match the chunk at " + at(pos));
      if (plausible(index_end)) {
        close_damage(index_end);
        if (options_.strict) fail_strict(r_.damage.back().what + " at " + at(end));
        return index_end;
      }
      auto next = resync(index_end);
      if (next) {
        close_damage(*next);
        if (options_.strict) fail_strict(r_.damage.back().what + " at " + at(end));
      }
      return next;
    }
    return end;
  }

  /// A chunk whose length is sound but whose content is not: skips it and the index records
  /// after it, and goes on there if a record follows (else searches for the next chunk).
  std::optional<std::uint64_t> skip_bad_chunk(std::uint64_t pos, std::uint64_t end,
                                              const std::string& what) {
    damage(pos, what);
    const std::uint64_t after = skip_index_records(end);
    if (after < size_ && plausible(after)) {
      close_damage(after);
      if (options_.strict) fail_strict(what + " at " + at(pos));
      return after;
    }
    auto next = resync(end);
    if (next) {
      close_damage(*next);
      if (options_.strict) fail_strict(what + " at " + at(pos));
    }
    return next;
  }

  void scan_data(std::uint64_t pos) {
    while (pos < size_) {
      if (size_ - pos < kRecordPrefix) break;  // torn: finish() reports it
      const auto pre = win_.get(pos, kRecordPrefix);
      const auto op = load<std::uint8_t>(pre.data());
      const auto len = load<std::uint64_t>(pre.data() + 1);
      if (len > size_ - pos - kRecordPrefix || len > kMaxRecordBytes) {
        auto next =
            skip_damage(pos, "a " + opname(op) + " record longer than the rest of the file");
        if (!next) return;
        pos = *next;
        continue;
      }
      const std::uint64_t end = pos + kRecordPrefix + len;
      std::optional<std::uint64_t> next = end;
      switch (static_cast<Opcode>(op)) {
        case Opcode::kChunk:
          next = handle_chunk(pos, len);
          break;
        case Opcode::kSchema:
        case Opcode::kChannel:
        case Opcode::kMetadata:
        case Opcode::kMessage:
          next = handle_plain(pos, op, len);
          break;
        case Opcode::kAttachment:
          close_damage(pos);
          good(end);
          break;
        case Opcode::kDataEnd:
          if (len == 4) {
            close_damage(pos);
            handle_data_end(pos);
            return;
          }
          next = skip_damage(pos, "a Data End record of the wrong size");
          break;
        case Opcode::kMessageIndex:
          next = handle_relocated_indexes(pos);
          break;
        default:
          if (op == kDamagedRegionOpcode) {
            r_.wrapped_damage.push_back(
                {pos, kRecordPrefix + len, "damaged bytes wrapped by recover"});
          }
          if (op >= 0x80) {  // application records: skipped as the spec says
            close_damage(pos);
            good(end);
          } else {
            next = skip_damage(pos, "a " + opname(op) + " record in the data section");
          }
      }
      if (!next) return;
      pos = *next;
    }
  }

  /// Message Index records that follow no chunk: those recover wrote at the end of the data
  /// section for chunks whose own were missing or damaged (all of them, in chunk order).
  std::optional<std::uint64_t> handle_relocated_indexes(std::uint64_t pos) {
    const std::uint64_t q = skip_index_records(pos);
    std::uint64_t total = 0;
    for (const auto& [i, bytes] : pending_) total += bytes.size();
    if (!pending_.empty() && q - pos == total && total <= kMaxRecordBytes) {
      const auto found = win_.get(pos, static_cast<std::size_t>(total));
      std::size_t off = 0;
      bool same = true;
      for (const auto& [i, bytes] : pending_) {
        same = same && std::memcmp(found.data() + off, bytes.data(), bytes.size()) == 0;
        off += bytes.size();
      }
      if (same) {
        std::uint64_t base = pos;
        for (const auto& [i, bytes] : pending_) {
          ChunkInfo& c = r_.chunks[i];
          c.message_index_offsets = index_layout(bytes, base);
          c.message_index_length = bytes.size();
          c.index_intact = true;
          base += bytes.size();
        }
        pending_.clear();
        close_damage(pos);
        good(q);
        return q;
      }
    }
    return skip_damage(pos, "Message Index records after no good chunk");
  }

  std::optional<std::uint64_t> handle_plain(std::uint64_t pos, std::uint8_t op, std::uint64_t len) {
    const std::uint64_t end = pos + kRecordPrefix + len;
    const auto body = win_.get(pos + kRecordPrefix, static_cast<std::size_t>(len));
    bool conflict = false;
    switch (static_cast<Opcode>(op)) {
      case Opcode::kSchema: {
        auto s = parse_schema(body);
        if (!s) return skip_damage(pos, "a Schema record that does not parse");
        register_schema(*s, conflict);
        break;
      }
      case Opcode::kChannel: {
        auto c = parse_channel(body);
        if (!c) return skip_damage(pos, "a Channel record that does not parse");
        register_channel(*c, conflict);
        break;
      }
      case Opcode::kMetadata: {
        auto m = parse_metadata(body);
        if (!m) return skip_damage(pos, "a Metadata record that does not parse");
        if (extras_ != nullptr)
          extras_->metadata_refs.push_back({pos, kRecordPrefix + len, m->name});
        r_.metadata.push_back(std::move(*m));
        break;
      }
      default: {  // a message outside a chunk
        auto h = parse_message_header(body);
        if (!h) return skip_damage(pos, "a Message record too short");
        deliver(Message{*h, body.subspan(22)});
        break;
      }
    }
    if (conflict)
      return skip_damage(pos, "a " + opname(op) + " record redefining an id differently");
    close_damage(pos);
    good(end);
    return end;
  }

  void handle_data_end(std::uint64_t pos) {
    r_.data_end_offset = pos;
    win_.crc_to(pos);
    if (extras_ != nullptr) extras_->crc_at_data_end = win_.crc();
    const auto b = win_.get(pos + kRecordPrefix, 4);
    r_.data_section_crc = load<std::uint32_t>(b.data());
    r_.data_section_crc_ok = r_.data_section_crc != 0 && r_.data_section_crc == win_.crc();
    check_summary(pos + kDataEndRecord);
  }

  void problem(std::string p) { r_.summary_problems.push_back(std::move(p)); }

  void check_summary(std::uint64_t summary_at) {
    if (!footer_.ok) {
      problem("no valid footer and closing magic after the Data End");
      return;
    }
    r_.footer_ok = true;
    const std::uint64_t footer_pos = size_ - kMagic.size() - kFooterRecord;
    if (footer_.summary_start != 0 && footer_.summary_start != summary_at) {
      problem("the footer's summary start (" + std::to_string(footer_.summary_start) +
              ") is not right after the Data End (" + std::to_string(summary_at) + ")");
      return;
    }
    if (summary_at > footer_pos) {
      problem("the summary overlaps the footer");
      return;
    }
    const std::uint64_t n = footer_pos - summary_at;
    if (n > kMaxRecordBytes) {
      problem("the summary is larger than this reader reads (" + std::to_string(n) + " bytes)");
      return;
    }
    const auto bytes = win_.get(summary_at, static_cast<std::size_t>(n + 25));
    if (footer_.summary_crc != 0 && acq::detail::crc32_update(0, bytes) != footer_.summary_crc) {
      problem("the summary's CRC does not match");
      return;
    }
    std::map<std::uint16_t, Schema> schemas;
    std::map<std::uint16_t, Channel> channels;
    std::vector<ChunkInfo> index;
    std::optional<std::uint64_t> stat_messages;
    std::uint32_t stat_chunks = 0;
    std::uint64_t stat_start = 0;
    std::uint64_t stat_end = 0;
    std::map<std::uint16_t, std::uint64_t> stat_channels;
    ByteReader rd(bytes.first(static_cast<std::size_t>(n)));
    while (rd.ok() && rd.remaining() > 0) {
      const auto op = rd.get<std::uint8_t>();
      const auto len = rd.get<std::uint64_t>();
      if (!rd.ok() || len > rd.remaining()) {
        problem("a summary record runs past the footer");
        return;
      }
      const auto body = rd.bytes(static_cast<std::size_t>(len));
      ByteReader b(body);
      switch (static_cast<Opcode>(op)) {
        case Opcode::kSchema:
          if (auto s = parse_schema(body))
            schemas.emplace(s->id, *s);
          else
            problem("a Schema record of the summary does not parse");
          break;
        case Opcode::kChannel:
          if (auto c = parse_channel(body))
            channels.emplace(c->id, *c);
          else
            problem("a Channel record of the summary does not parse");
          break;
        case Opcode::kChunkIndex: {
          ChunkInfo c;
          c.message_start_time = b.get<std::uint64_t>();
          c.message_end_time = b.get<std::uint64_t>();
          c.offset = b.get<std::uint64_t>();
          c.length = b.get<std::uint64_t>();
          ByteReader m(b.bytes(b.get<std::uint32_t>()));
          while (m.ok() && m.remaining() > 0) {
            const auto ch = m.get<std::uint16_t>();
            const auto off = m.get<std::uint64_t>();
            c.message_index_offsets.emplace_back(ch, off);
          }
          c.message_index_length = b.get<std::uint64_t>();
          const std::string comp = b.string();
          const auto csize = b.get<std::uint64_t>();
          c.records_bytes = b.get<std::uint64_t>();
          if (!b.ok() || !m.ok() || !comp.empty() || csize != c.records_bytes) {
            problem("a Chunk Index record of the summary does not parse");
            break;
          }
          std::sort(c.message_index_offsets.begin(), c.message_index_offsets.end());
          index.push_back(std::move(c));
          break;
        }
        case Opcode::kStatistics: {
          stat_messages = b.get<std::uint64_t>();
          (void)b.get<std::uint16_t>();
          (void)b.get<std::uint32_t>();
          (void)b.get<std::uint32_t>();
          (void)b.get<std::uint32_t>();
          stat_chunks = b.get<std::uint32_t>();
          stat_start = b.get<std::uint64_t>();
          stat_end = b.get<std::uint64_t>();
          ByteReader m(b.bytes(b.get<std::uint32_t>()));
          while (m.ok() && m.remaining() > 0) {
            const auto ch = m.get<std::uint16_t>();
            stat_channels[ch] = m.get<std::uint64_t>();
          }
          if (!b.ok() || !m.ok()) problem("the Statistics record of the summary does not parse");
          break;
        }
        default:
          break;  // metadata, attachment indexes, summary offsets: not compared
      }
    }
    if (!rd.ok()) problem("the summary does not parse");
    if (schemas != r_.schemas) problem("the summary's schemas differ from the data section's");
    if (channels != r_.channels) problem("the summary's channels differ from the data section's");
    if (index.size() != r_.chunks.size()) {
      problem("the summary indexes " + std::to_string(index.size()) + " chunks, the data " +
              "section holds " + std::to_string(r_.chunks.size()) + " good ones");
    } else {
      for (std::size_t i = 0; i < index.size(); ++i) {
        const ChunkInfo& a = index[i];
        const ChunkInfo& c = r_.chunks[i];
        if (a.offset != c.offset || a.length != c.length ||
            a.message_start_time != c.message_start_time ||
            a.message_end_time != c.message_end_time || a.records_bytes != c.records_bytes ||
            a.message_index_offsets != c.message_index_offsets ||
            a.message_index_length != c.message_index_length) {
          problem("the summary's index of chunk " + std::to_string(i + 1) + " (at " + at(c.offset) +
                  ") does not match the chunk");
          break;
        }
      }
    }
    if (!stat_messages) {
      problem("the summary has no Statistics record");
    } else if (*stat_messages != r_.messages || stat_chunks != r_.chunks.size() ||
               stat_channels != r_.channel_messages ||
               (r_.messages > 0 &&
                (stat_start != r_.message_start_time || stat_end != r_.message_end_time))) {
      problem("the summary's statistics (" + std::to_string(*stat_messages) + " messages in " +
              std::to_string(stat_chunks) + " chunks) differ from the data section's (" +
              std::to_string(r_.messages) + " in " + std::to_string(r_.chunks.size()) + ")");
    }
    r_.summary_ok = r_.summary_problems.empty();
  }

  void finish() {
    if (extras_ != nullptr)
      for (auto& [i, bytes] : pending_) extras_->missing_indexes[i] = std::move(bytes);
    if (r_.data_end_offset) return;
    // No Data End: whatever follows the last good record is the torn tail of a write that was
    // cut short (damage found there is part of it).
    if (r_.good_end < size_) {
      r_.torn_tail = true;
      r_.torn_offset = r_.good_end;
      r_.torn_bytes = size_ - r_.good_end;
      while (!r_.damage.empty() && r_.damage.back().offset >= r_.good_end) r_.damage.pop_back();
      if (options_.strict)
        fail_strict("a torn tail of " + std::to_string(r_.torn_bytes) + " bytes at " +
                    at(r_.torn_offset) + " (a write cut short)");
    }
    if (!r_.damage.empty() && r_.damage.back().length == 0) close_damage(r_.good_end);
  }

  const File& file_;
  std::uint64_t size_;
  Window win_;
  ScanVisitor* visitor_;
  ScanOptions options_;
  ScanExtras* extras_;
  ScanReport r_;
  Footer footer_;
  std::uint64_t last_log_time_ = 0;
  std::vector<Rec> recs_;
  std::vector<std::tuple<std::uint16_t, std::size_t, std::uint64_t>> by_channel_;
  ByteBuffer expected_;
  std::vector<std::byte> scratch_;
  /// Good chunks whose message indexes were not found after them: the records they imply.
  std::vector<std::pair<std::size_t, std::vector<std::byte>>> pending_;
};

}  // namespace

std::vector<std::pair<std::uint16_t, std::uint64_t>> index_layout(std::span<const std::byte> bytes,
                                                                  std::uint64_t base) {
  std::vector<std::pair<std::uint16_t, std::uint64_t>> out;
  std::size_t p = 0;
  while (p + kRecordPrefix + 2 <= bytes.size()) {
    const auto len = load<std::uint64_t>(bytes.data() + p + 1);
    out.emplace_back(load<std::uint16_t>(bytes.data() + p + kRecordPrefix), base + p);
    p += kRecordPrefix + static_cast<std::size_t>(len);
  }
  return out;
}

ScanReport scan_file(const File& file, ScanVisitor* visitor, ScanOptions options,
                     ScanExtras* extras) {
  return Scanner(file, visitor, options, extras).run();
}

}  // namespace scanmesh::acq::mcap::detail

namespace scanmesh::acq::mcap {

ScanReport scan(const std::filesystem::path& file, ScanVisitor* visitor, ScanOptions options) {
  const auto f = acq::detail::File::open_read(file);
  return detail::scan_file(f, visitor, options, nullptr);
}

ScanReport scan_fd(int fd, const std::string& name, ScanVisitor* visitor, ScanOptions options) {
  const auto f = acq::detail::File::borrow(fd, name);
  return detail::scan_file(f, visitor, options, nullptr);
}

}  // namespace scanmesh::acq::mcap
