// mcap::Writer: chunks built in one buffer and written with one writev each, message indexes
// after each chunk, the summary on close (see mcap.hpp and acquisition/JOURNAL.md).
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <array>
#include <cstring>
#include <limits>

#include "bytes.hpp"
#include "crc.hpp"
#include "file.hpp"
#include "records.hpp"
#include "scanmesh/acquisition/mcap.hpp"

namespace scanmesh::acq::mcap {

using acq::detail::ByteBuffer;
using acq::detail::crc32_combine;
using acq::detail::crc32_update;
using acq::detail::errno_text;
using acq::detail::store;
using namespace detail;

std::vector<std::string> WriterOptions::validate() const {
  std::vector<std::string> bad;
  if (chunk_bytes < 1024 || chunk_bytes > (std::size_t{256} << 20))
    bad.push_back("chunk_bytes must be between 1 KiB and 256 MiB, got " +
                  std::to_string(chunk_bytes));
  if (chunk_duration.count() <= 0)
    bad.push_back("chunk_duration must be more than 0, got " +
                  std::to_string(chunk_duration.count()) + " ns");
  if (fsync_interval.count() < 0)
    bad.push_back("fsync_interval must be 0 (off) or more, got " +
                  std::to_string(fsync_interval.count()) + " ns");
  return bad;
}

struct Writer::Impl {
  std::filesystem::path path;
  WriterOptions opt;
  acq::detail::File file;

  // The open chunk: kChunkHeader bytes reserved for the chunk record's header, then its records;
  // the message index records are appended when it is written.
  ByteBuffer chunk;
  struct IndexEntry {  // one entry of a Message Index record, as stored
    std::uint64_t log_time;
    std::uint64_t offset;
  };
  static_assert(sizeof(IndexEntry) == 16);
  std::vector<std::vector<IndexEntry>> index;  // by channel id
  std::vector<std::uint16_t> chunk_channels;
  bool chunk_open = false;
  std::uint64_t chunk_start = 0;
  std::uint64_t chunk_end = 0;
  std::uint64_t chunk_units = 0;

  // The file so far.
  std::uint64_t offset = 0;  // bytes written (always ends on a whole record)
  std::uint32_t data_crc = 0;
  std::map<std::uint16_t, Schema> schemas;
  std::map<std::uint16_t, Channel> channels;
  std::vector<ChunkInfo> chunks;
  std::vector<MetadataRef> metadata;
  std::vector<std::uint64_t> channel_counts;  // by channel id
  std::uint64_t messages = 0;
  std::uint64_t start_time = 0;
  std::uint64_t end_time = 0;

  std::atomic<std::uint64_t> acked{0};
  std::atomic<std::uint64_t> durable{0};
  std::uint64_t acked_plain = 0;
  std::uint64_t bytes_since_sync = 0;
  std::uint64_t last_sync_time = 0;
  bool sync_time_set = false;
  WriterStats stats;
  bool failed = false;
  bool closed = false;
  std::string failure;

  [[nodiscard]] std::size_t chunk_used() const noexcept {
    return chunk_open ? chunk.size() - kChunkHeader : 0;
  }
  [[nodiscard]] bool expired(std::uint64_t t) const noexcept {
    return chunk_open && t >= chunk_start &&
           t - chunk_start >= static_cast<std::uint64_t>(opt.chunk_duration.count());
  }

  void check_usable() const {
    if (failed) {
      throw JournalWriteError("journal " + path.string() +
                                  ": refusing to write after an earlier "
                                  "error (" +
                                  failure + ")",
                              0);
    }
    if (closed) throw JournalWriteError("journal " + path.string() + ": already closed", 0);
  }

  /// Marks the writer failed and throws. After a failed write the file is cut back to the end
  /// of the last whole record, so no partial chunk stays behind.
  [[noreturn]] void fail(int e, const std::string& what, bool cut_back) {
    failed = true;
    std::string msg = "journal " + path.string() + ": " + what + " failed: " + errno_text(e) +
                      "; the file ends after its last whole chunk (" + std::to_string(offset) +
                      " bytes, " + std::to_string(acked_plain) + " samples recorded)";
    if (cut_back) {
      if (const int te = file.truncate(offset); te != 0)
        msg += "; cutting off the partial write failed too: " + errno_text(te);
      (void)file.seek(offset);
    }
    failure = msg;
    throw JournalWriteError(msg, e);
  }

  void write_parts(std::initializer_list<std::span<const std::byte>> parts,
                   const std::string& what) {
    std::uint64_t n = 0;
    for (const auto& p : parts) n += p.size();
    const std::vector<std::span<const std::byte>> v(parts);
    if (const int e = file.write_all(v); e != 0) {
      fail(e,
           "write of " + std::to_string(n) + " bytes (" + what + ") at byte " +
               std::to_string(offset),
           true);
    }
    for (const auto& p : parts) data_crc = crc32_update(data_crc, p);
    offset += n;
    stats.bytes = offset;
    bytes_since_sync += n;
  }

  void write_record(const ByteBuffer& rec, const std::string& what) {
    write_parts({rec.span()}, what);
  }

  void sync(std::uint64_t now) {
    if (const int e = file.datasync(); e != 0) fail(e, "fdatasync", false);
    durable.store(acked_plain, std::memory_order_relaxed);
    bytes_since_sync = 0;
    last_sync_time = now;
    sync_time_set = true;
    ++stats.fsyncs;
  }

  void maybe_sync(std::uint64_t now) {
    if (bytes_since_sync == 0) return;
    if (!sync_time_set) {
      last_sync_time = now;
      sync_time_set = true;
    }
    const bool by_bytes = opt.fsync_bytes > 0 && bytes_since_sync >= opt.fsync_bytes;
    const bool by_time =
        opt.fsync_interval.count() > 0 && now >= last_sync_time &&
        now - last_sync_time >= static_cast<std::uint64_t>(opt.fsync_interval.count());
    if (by_bytes || by_time) sync(now);
  }

  void write_chunk() {
    if (!chunk_open) return;
    const std::uint64_t records = chunk.size() - kChunkHeader;
    const std::uint32_t records_crc =
        crc32_update(0, std::span<const std::byte>(chunk.data() + kChunkHeader, records));
    std::byte* h = chunk.data();
    store(h, static_cast<std::uint8_t>(Opcode::kChunk));
    store(h + 1, static_cast<std::uint64_t>(kChunkHeader - kRecordPrefix + records));
    store(h + 9, chunk_start);
    store(h + 17, chunk_end);
    store(h + 25, records);
    store(h + 33, records_crc);
    store(h + 37, std::uint32_t{0});  // compression: "" (none)
    store(h + 41, records);
    const std::uint64_t chunk_length = chunk.size();

    ChunkInfo info;
    info.offset = offset;
    info.length = chunk_length;
    info.message_start_time = chunk_start;
    info.message_end_time = chunk_end;
    info.records_bytes = records;
    info.index_intact = true;
    std::sort(chunk_channels.begin(), chunk_channels.end());
    for (const std::uint16_t ch : chunk_channels) {
      auto& entries = index[ch];
      info.message_index_offsets.emplace_back(ch, offset + chunk.size());
      info.channel_messages.emplace_back(ch, entries.size());
      info.messages += entries.size();
      const std::size_t bytes = entries.size() * 16;
      std::byte* p = chunk.grow(kRecordPrefix + 2 + 4 + bytes);
      store(p, static_cast<std::uint8_t>(Opcode::kMessageIndex));
      store(p + 1, static_cast<std::uint64_t>(2 + 4 + bytes));
      store(p + 9, ch);
      store(p + 11, static_cast<std::uint32_t>(bytes));
      std::memcpy(p + 15, entries.data(), bytes);
      entries.clear();
    }
    info.message_index_length = chunk.size() - chunk_length;

    const std::uint64_t at = offset;
    if (const int e = file.write_all(std::array{chunk.span()}); e != 0) {
      fail(e,
           "write of chunk " + std::to_string(chunks.size() + 1) + " (" +
               std::to_string(chunk.size()) + " bytes) at byte " + std::to_string(at),
           true);
    }
    // Data section CRC: the chunk header, the records (their CRC is known), the indexes.
    data_crc = crc32_update(data_crc, std::span<const std::byte>(chunk.data(), kChunkHeader));
    data_crc = crc32_combine(data_crc, records_crc, records);
    data_crc = crc32_update(data_crc, std::span<const std::byte>(chunk.data() + chunk_length,
                                                                 chunk.size() - chunk_length));
    offset += chunk.size();
    stats.bytes = offset;
    bytes_since_sync += chunk.size();
    ++stats.chunks;
    chunks.push_back(std::move(info));
    acked_plain += chunk_units;
    acked.store(acked_plain, std::memory_order_relaxed);
    chunk_open = false;
    chunk.clear();
    chunk_channels.clear();
    chunk_units = 0;
    maybe_sync(chunk_end);
  }
};

Writer::Writer(std::filesystem::path path, WriterOptions options, const Metadata* metadata)
    : impl_(std::make_unique<Impl>()) {
  Impl& w = *impl_;
  if (auto bad = options.validate(); !bad.empty()) {
    std::string msg = "journal " + path.string() + ": bad writer options:";
    for (const auto& b : bad) msg += " " + b + ";";
    msg.pop_back();
    throw ConfigError(msg);
  }
  w.path = std::move(path);
  w.opt = std::move(options);
  w.index.resize(1);
  w.channel_counts.resize(1);
  w.chunk.reserve(w.opt.chunk_bytes + kChunkHeader + 64 * 1024);
  w.file = acq::detail::File::create_new(w.path);

  ByteBuffer head;
  head.append(std::as_bytes(std::span(kMagic)));
  put_header(head, w.opt.profile, w.opt.library);
  if (metadata != nullptr) {
    const std::size_t at = head.size();
    put_metadata(head, *metadata);
    w.metadata.push_back({at, head.size() - at, metadata->name});
  }
  w.write_record(head, "header");
}

Writer::~Writer() {
  if (impl_ && !impl_->closed && !impl_->failed) {
    try {
      close();
    } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor must not throw; the file
                     // stays recoverable (it ends on a whole chunk)
    }
  }
}

std::uint16_t Writer::add_schema(std::string name, std::string encoding, std::string data) {
  Impl& w = *impl_;
  w.check_usable();
  if (w.schemas.size() >= std::numeric_limits<std::uint16_t>::max() - 1)
    throw ConfigError("journal " + w.path.string() + ": too many schemas");
  Schema s{static_cast<std::uint16_t>(w.schemas.size() + 1), std::move(name), std::move(encoding),
           std::move(data)};
  ByteBuffer rec;
  put_schema(rec, s);
  w.write_record(rec, "schema " + s.name);
  const auto id = s.id;
  w.schemas.emplace(id, std::move(s));
  return id;
}

std::uint16_t Writer::add_channel(std::uint16_t schema_id, std::string topic,
                                  std::string message_encoding, StringMap metadata) {
  Impl& w = *impl_;
  w.check_usable();
  if (schema_id != 0 && w.schemas.count(schema_id) == 0)
    throw ConfigError("journal " + w.path.string() + ": channel " + topic + ": unknown schema id " +
                      std::to_string(schema_id));
  if (w.channels.size() >= std::numeric_limits<std::uint16_t>::max() - 1)
    throw ConfigError("journal " + w.path.string() + ": too many channels");
  Channel c{static_cast<std::uint16_t>(w.channels.size() + 1), schema_id, std::move(topic),
            std::move(message_encoding), std::move(metadata)};
  ByteBuffer rec;
  put_channel(rec, c);
  w.write_record(rec, "channel " + c.topic);
  const auto id = c.id;
  w.channels.emplace(id, std::move(c));
  w.index.resize(std::size_t{id} + 1);
  w.channel_counts.resize(std::size_t{id} + 1);
  return id;
}

std::size_t Writer::room() const noexcept {
  const Impl& w = *impl_;
  const std::size_t used = w.chunk_used() + kMessageOverhead;
  return used >= w.opt.chunk_bytes ? 0 : w.opt.chunk_bytes - used;
}

bool Writer::chunk_expired(std::uint64_t log_time) const noexcept {
  return impl_->expired(log_time);
}

std::optional<std::uint64_t> Writer::open_chunk_start() const noexcept {
  if (!impl_->chunk_open) return std::nullopt;
  return impl_->chunk_start;
}

std::span<std::byte> Writer::add_message(const MessageHeader& h, std::size_t size,
                                         std::uint64_t units) {
  Impl& w = *impl_;
  w.check_usable();
  if (h.channel_id == 0 || h.channel_id >= w.index.size())
    throw ConfigError("journal " + w.path.string() + ": message on unknown channel " +
                      std::to_string(h.channel_id));
  const std::size_t rec = kMessageOverhead + size;
  if (w.chunk_open && (w.chunk_used() + rec > w.opt.chunk_bytes || w.expired(h.log_time)))
    w.write_chunk();
  if (!w.chunk_open) {
    w.chunk.resize(kChunkHeader);
    w.chunk_start = w.chunk_end = h.log_time;
    w.chunk_open = true;
  }
  const std::uint64_t at = w.chunk.size() - kChunkHeader;
  std::byte* p = w.chunk.grow(rec);
  store(p, static_cast<std::uint8_t>(Opcode::kMessage));
  store(p + 1, static_cast<std::uint64_t>(22 + size));
  store(p + 9, h.channel_id);
  store(p + 11, h.sequence);
  store(p + 15, h.log_time);
  store(p + 23, h.publish_time);
  auto& entries = w.index[h.channel_id];
  if (entries.empty()) w.chunk_channels.push_back(h.channel_id);
  entries.push_back({h.log_time, at});
  w.chunk_start = std::min(w.chunk_start, h.log_time);
  w.chunk_end = std::max(w.chunk_end, h.log_time);
  w.chunk_units += units;
  ++w.channel_counts[h.channel_id];
  if (w.messages == 0) {
    w.start_time = w.end_time = h.log_time;
  } else {
    w.start_time = std::min(w.start_time, h.log_time);
    w.end_time = std::max(w.end_time, h.log_time);
  }
  ++w.messages;
  ++w.stats.messages;
  return {p + kMessageOverhead, size};
}

void Writer::write_message(const MessageHeader& header, std::span<const std::byte> data,
                           std::uint64_t units) {
  auto dst = add_message(header, data.size(), units);
  if (!data.empty()) std::memcpy(dst.data(), data.data(), data.size());
}

void Writer::flush_if_due() {
  Impl& w = *impl_;
  w.check_usable();
  if (w.chunk_open && (w.chunk_used() >= w.opt.chunk_bytes || w.expired(w.chunk_end)))
    w.write_chunk();
}

void Writer::tick(std::uint64_t now_ns) {
  Impl& w = *impl_;
  w.check_usable();
  if (w.expired(now_ns)) w.write_chunk();
  if (w.bytes_since_sync > 0 && w.opt.fsync_interval.count() > 0 && w.sync_time_set &&
      now_ns >= w.last_sync_time &&
      now_ns - w.last_sync_time >= static_cast<std::uint64_t>(w.opt.fsync_interval.count()))
    w.sync(now_ns);
}

void Writer::flush() {
  Impl& w = *impl_;
  w.check_usable();
  w.write_chunk();
}

void Writer::sync() {
  Impl& w = *impl_;
  w.check_usable();
  w.write_chunk();
  w.sync(w.end_time);
}

void Writer::close() {
  Impl& w = *impl_;
  if (w.closed) return;
  w.check_usable();
  w.write_chunk();
  std::map<std::uint16_t, std::uint64_t> counts;
  for (std::size_t id = 1; id < w.channel_counts.size(); ++id)
    if (w.channel_counts[id] > 0)
      counts.emplace(static_cast<std::uint16_t>(id), w.channel_counts[id]);
  ByteBuffer tail;
  SummaryInput in;
  in.data_end_offset = w.offset;
  in.data_section_crc = w.data_crc;
  in.schemas = &w.schemas;
  in.channels = &w.channels;
  in.chunks = w.chunks;
  in.metadata = w.metadata;
  in.messages = w.messages;
  in.message_start_time = w.start_time;
  in.message_end_time = w.end_time;
  in.channel_messages = &counts;
  put_tail(tail, in);
  w.write_record(tail, "summary and footer");
  w.sync(w.end_time);
  w.closed = true;
  w.file = acq::detail::File();
}

std::uint64_t Writer::acknowledged_units() const noexcept {
  return impl_->acked.load(std::memory_order_relaxed);
}
std::uint64_t Writer::durable_units() const noexcept {
  return impl_->durable.load(std::memory_order_relaxed);
}
WriterStats Writer::stats() const noexcept { return impl_->stats; }
const std::filesystem::path& Writer::path() const noexcept { return impl_->path; }
bool Writer::failed() const noexcept { return impl_->failed; }

}  // namespace scanmesh::acq::mcap
