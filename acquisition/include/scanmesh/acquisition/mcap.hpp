// The MCAP container (mcap.dev/spec, major version 0): a writer of uncompressed chunks with CRCs,
// message indexes and a summary, a scanner that reads any MCAP file record by record (verifying
// every chunk, skipping damage, finding a torn tail) and the recovery of a file cut short.
// The scan journal (journal.hpp) is built on it. See acquisition/JOURNAL.md.
// SPDX-License-Identifier: MIT
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "scanmesh/common/error.hpp"

namespace scanmesh::acq {

/// A write to a journal failed (ENOSPC, EFBIG, EIO, ...). The message names the file, the
/// operation and the system's words. What was written before stays intact: a partly written
/// chunk is cut off again, so the file ends on a whole chunk and `journal recover` finishes it.
class JournalWriteError : public OutputError {
 public:
  JournalWriteError(const std::string& message, int error_number)
      : OutputError(message), error_number_(error_number) {}
  /// The errno of the failed call (0 when the writer refused a write after an earlier error).
  [[nodiscard]] int error_number() const noexcept { return error_number_; }

 private:
  int error_number_;
};

namespace mcap {

inline constexpr std::array<std::uint8_t, 8> kMagic{0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

enum class Opcode : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

/// The application record (MCAP reserves 0x80-0xFF for them; readers skip them) that recover
/// turns a damaged region into: its content is the damaged bytes after the first nine.
inline constexpr std::uint8_t kDamagedRegionOpcode = 0x80;

using StringMap = std::map<std::string, std::string>;

struct Schema {
  std::uint16_t id = 0;
  std::string name;
  std::string encoding;  ///< e.g. "ros2msg", "jsonschema"
  std::string data;
  friend bool operator==(const Schema&, const Schema&) = default;
};

struct Channel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;  ///< e.g. "cdr", "json"
  StringMap metadata;
  friend bool operator==(const Channel&, const Channel&) = default;
};

struct Metadata {
  std::string name;
  StringMap metadata;
};

struct MessageHeader {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0;      ///< ns, when recorded
  std::uint64_t publish_time = 0;  ///< ns, when published (the first sample's time)
};

/// A message as read: `data` points into the chunk being read, valid during the callback only.
struct Message {
  MessageHeader header;
  std::span<const std::byte> data;
};

/// Chunking and durability of a Writer. Times are in log time (the messages' own clock).
struct WriterOptions {
  /// A chunk is written when its records reach this size (a single larger message gets a chunk
  /// of its own).
  std::size_t chunk_bytes = 64 * 1024;
  /// ... or when its messages span this much log time, whichever comes first.
  std::chrono::nanoseconds chunk_duration = std::chrono::milliseconds(100);
  /// fdatasync after a chunk once this much log time has passed since the last one ...
  std::chrono::nanoseconds fsync_interval = std::chrono::seconds(1);
  /// ... or once this many bytes were written since the last one. 0 in both: never (only close).
  std::uint64_t fsync_bytes = std::uint64_t{64} << 20;
  /// Start the disk's writeback of every this many bytes written (sync_file_range), so that
  /// writing and the disk overlap and an fdatasync finds little left to do. 0: never.
  std::uint64_t writeback_bytes = std::uint64_t{4} << 20;
  std::string profile = "x-scanmesh";
  std::string library = "scanmesh journal 2";

  /// Every bad field, one message each (empty: valid).
  [[nodiscard]] std::vector<std::string> validate() const;
};

struct WriterStats {
  std::uint64_t chunks = 0;
  std::uint64_t messages = 0;
  std::uint64_t bytes = 0;  ///< written to the file so far
  std::uint64_t fsyncs = 0;
};

/// Writes one MCAP file: magic, header, an optional metadata record, schema and channel records
/// as they are added, then chunks of messages each followed by its message index records, and
/// on close() the data end, summary (schemas, channels, statistics, chunk and metadata indexes,
/// summary offsets) and footer. A chunk goes to the file in one write() when it is full or old;
/// the messages in it are then acknowledged. The file holds an exclusive flock while open.
/// Not thread-safe except acknowledged_units()/durable_units(); starts no thread.
class Writer {
 public:
  /// Creates `path` (it must not exist). Throws ConfigError for bad options, JournalWriteError
  /// when the file cannot be created or written.
  Writer(std::filesystem::path path, WriterOptions options, const Metadata* metadata = nullptr);
  /// Finishes the file (close()) unless it was closed or failed; never throws.
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  std::uint16_t add_schema(std::string name, std::string encoding, std::string data);
  std::uint16_t add_channel(std::uint16_t schema_id, std::string topic,
                            std::string message_encoding, StringMap metadata);

  /// Bytes of message data that still fit in the open chunk before it reaches chunk_bytes
  /// (chunk_bytes minus the message overheads when no chunk is open).
  [[nodiscard]] std::size_t room() const noexcept;
  /// Whether a message at `log_time` would start a new chunk because of the time limit.
  [[nodiscard]] bool chunk_expired(std::uint64_t log_time) const noexcept;
  /// Log time of the open chunk's first message (nullopt: no chunk open).
  [[nodiscard]] std::optional<std::uint64_t> open_chunk_start() const noexcept;
  /// Adds a message of `size` data bytes and returns where to write them (valid until the next
  /// call). The open chunk is written first when the message does not fit in it or comes
  /// chunk_duration after its first message. `units` (samples) count toward
  /// acknowledged_units() once the chunk holding the message is written.
  std::span<std::byte> add_message(const MessageHeader& header, std::size_t size,
                                   std::uint64_t units);
  void write_message(const MessageHeader& header, std::span<const std::byte> data,
                     std::uint64_t units);
  /// Writes the open chunk if it is full or its messages span chunk_duration (call after
  /// filling a message's data, so a full chunk does not wait for the next message).
  void flush_if_due();

  /// Writes the open chunk if its first message is chunk_duration before `now_ns`, and syncs if
  /// the fsync interval has passed: for idle moments, so no message waits in memory longer.
  void tick(std::uint64_t now_ns);
  /// Writes the open chunk (its messages are then acknowledged).
  void flush();
  /// flush() and fdatasync (its messages are then durable).
  void sync();
  /// Writes the open chunk, the data end, summary and footer, syncs and closes the file.
  void close();

  /// Units of the messages written to the file (in the page cache). Any thread, relaxed.
  [[nodiscard]] std::uint64_t acknowledged_units() const noexcept;
  /// Units of the messages fdatasync'ed. Any thread, relaxed.
  [[nodiscard]] std::uint64_t durable_units() const noexcept;
  [[nodiscard]] WriterStats stats() const noexcept;
  [[nodiscard]] const std::filesystem::path& path() const noexcept;
  /// True after a write error: every later call throws JournalWriteError.
  [[nodiscard]] bool failed() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A region of the data section that was skipped: a chunk whose CRC does not match, a record
/// that does not parse, bytes between a damaged record and the next good chunk.
struct Damage {
  std::uint64_t offset = 0;
  std::uint64_t length = 0;
  std::string what;
};

/// One chunk that was read whole with a matching CRC.
struct ChunkInfo {
  std::uint64_t offset = 0;  ///< of the chunk record
  std::uint64_t length = 0;  ///< of the record, opcode and length included
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  std::uint64_t records_bytes = 0;
  std::uint64_t messages = 0;
  /// (channel, offset) of its message index records and their total length, as found after it;
  /// empty when they are missing or do not match the chunk (recovery then writes them again).
  std::vector<std::pair<std::uint16_t, std::uint64_t>> message_index_offsets;
  std::uint64_t message_index_length = 0;
  bool index_intact = false;
  /// Channels of the chunk with their message count.
  std::vector<std::pair<std::uint16_t, std::uint64_t>> channel_messages;
};

/// What a scan found. The data section is every record between the header and the data end.
struct ScanReport {
  std::string file;
  std::uint64_t file_bytes = 0;
  std::string profile;
  std::string library;
  bool header_ok = false;
  std::vector<ChunkInfo> chunks;  ///< the good ones, in file order
  std::vector<Damage> damage;     ///< skipped regions before the end of the good data
  /// Damaged regions an earlier recover wrapped in kDamagedRegionOpcode records.
  std::vector<Damage> wrapped_damage;
  std::uint64_t crc_failures = 0;
  /// Where the last whole, good record of the data section ends (recovery cuts here).
  std::uint64_t good_end = 0;
  /// An incomplete record at the end of the data (a write cut short), or trailing bytes that
  /// hold no good record: from torn_offset to the data end (or the end of the file).
  bool torn_tail = false;
  std::uint64_t torn_offset = 0;
  std::uint64_t torn_bytes = 0;
  std::optional<std::uint64_t> data_end_offset;  ///< where the Data End record is, if any
  std::uint32_t data_section_crc = 0;            ///< as stored in the Data End (0: none)
  bool data_section_crc_ok = false;              ///< stored, non-zero and equal to the bytes'
  bool footer_ok = false;   ///< footer and closing magic present and consistent
  bool summary_ok = false;  ///< summary parses, its CRC matches and it agrees with the chunks
  std::vector<std::string> summary_problems;
  std::map<std::uint16_t, Schema> schemas;
  std::map<std::uint16_t, Channel> channels;
  std::vector<Metadata> metadata;
  std::uint64_t messages = 0;
  std::map<std::uint16_t, std::uint64_t> channel_messages;
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  /// Messages whose log time is earlier than the one before them in the file.
  std::uint64_t out_of_order_messages = 0;
  /// Messages on a channel id with no Channel record before them (skipped).
  std::uint64_t unknown_channel_messages = 0;

  /// Complete: footer, summary and data end all good, no damage and no torn tail.
  [[nodiscard]] bool complete() const noexcept {
    return header_ok && footer_ok && summary_ok && damage.empty() && !torn_tail;
  }
};

/// Receives what a scan reads, in file order. Only records of chunks whose CRC matches (and
/// records outside chunks that parse) reach it.
class ScanVisitor {
 public:
  virtual ~ScanVisitor() = default;
  virtual void on_schema(const Schema&) {}
  virtual void on_channel(const Channel&) {}
  virtual void on_message(const Message&) {}
};

struct ScanOptions {
  /// Throw InputError at the first damage or torn tail instead of skipping it.
  bool strict = false;
};

/// Reads the whole file once. Throws InputError when it is not an MCAP file (bad magic), when
/// it cannot be read, or (strict) at the first damage. Cost: one sequential read and one CRC of
/// every byte.
ScanReport scan(const std::filesystem::path& file, ScanVisitor* visitor = nullptr,
                ScanOptions options = {});
/// The same on an open descriptor (read with pread; `name` names it in messages).
ScanReport scan_fd(int fd, const std::string& name, ScanVisitor* visitor = nullptr,
                   ScanOptions options = {});

struct RecoveryReport {
  ScanReport before;                   ///< what the scan found
  bool already_complete = false;       ///< nothing was changed
  std::uint64_t cut_offset = 0;        ///< where the file was cut
  std::uint64_t cut_bytes = 0;         ///< how many bytes were cut off (torn tail, old summary)
  std::uint64_t reindexed_chunks = 0;  ///< chunks whose message indexes were written again
  std::uint64_t wrapped_regions = 0;   ///< damaged regions wrapped in kDamagedRegionOpcode records
  std::uint64_t kept_chunks = 0;
  std::uint64_t kept_messages = 0;
  std::uint64_t file_bytes_after = 0;
};

/// Makes a file left by a crash readable by any MCAP reader: keeps every good chunk, cuts the
/// torn tail (or an old summary), writes message indexes a good chunk lacks, then the data end,
/// a summary of the good chunks and the footer. A damaged region in the middle stays where it
/// is, outside the index, its first nine bytes replaced by the prefix of a kDamagedRegionOpcode
/// record that spans it (so streaming readers step over it). Never rewrites a byte of a good
/// record. A complete file is left untouched; running it again changes nothing.
/// Throws InputError when the file is not MCAP or another process holds its lock (a writer),
/// JournalWriteError when it cannot be written.
RecoveryReport recover(const std::filesystem::path& file, ScanVisitor* visitor = nullptr);
/// The same on an open read-write descriptor (no locking).
RecoveryReport recover_fd(int fd, const std::string& name, ScanVisitor* visitor = nullptr);

}  // namespace mcap
}  // namespace scanmesh::acq
