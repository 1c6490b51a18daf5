// Encoding and parsing of the MCAP records the writer and the recovery share: header, schema,
// channel, metadata, message index, and the file's tail (data end, summary, footer, magic).
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "bytes.hpp"
#include "scanmesh/acquisition/mcap.hpp"

namespace scanmesh::acq::mcap::detail {

using acq::detail::ByteBuffer;
using acq::detail::ByteReader;

/// opcode (1) + length (8)
inline constexpr std::size_t kRecordPrefix = 9;
/// Message record before its data: prefix + channel (2) + sequence (4) + two times (16).
inline constexpr std::size_t kMessageOverhead = kRecordPrefix + 22;
/// Chunk record before its records: prefix + 2 times, size, crc, empty compression, length.
inline constexpr std::size_t kChunkHeader = kRecordPrefix + 8 + 8 + 8 + 4 + 4 + 8;
/// Footer record: prefix + summary_start, summary_offset_start, summary_crc.
inline constexpr std::size_t kFooterRecord = kRecordPrefix + 20;
inline constexpr std::size_t kDataEndRecord = kRecordPrefix + 4;

void put_header(ByteBuffer& out, const std::string& profile, const std::string& library);
void put_schema(ByteBuffer& out, const Schema& s);
void put_channel(ByteBuffer& out, const Channel& c);
void put_metadata(ByteBuffer& out, const Metadata& m);

std::optional<Schema> parse_schema(std::span<const std::byte> body);
std::optional<Channel> parse_channel(std::span<const std::byte> body);
std::optional<Metadata> parse_metadata(std::span<const std::byte> body);

/// (offset, length, name) of a metadata record, for the summary's metadata index.
struct MetadataRef {
  std::uint64_t offset = 0;
  std::uint64_t length = 0;
  std::string name;
};

/// What goes into the summary of a file whose data section ends at `data_end_offset`.
struct SummaryInput {
  std::uint64_t data_end_offset = 0;
  std::uint32_t data_section_crc = 0;
  const std::map<std::uint16_t, Schema>* schemas = nullptr;
  const std::map<std::uint16_t, Channel>* channels = nullptr;
  std::span<const ChunkInfo> chunks;
  std::span<const MetadataRef> metadata;
  std::uint64_t messages = 0;  ///< all messages (in chunks or not)
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  const std::map<std::uint16_t, std::uint64_t>* channel_messages = nullptr;
};

/// Data End, the summary (schemas, channels, statistics, chunk indexes, metadata indexes), the
/// summary offsets, footer (with the summary CRC) and the closing magic, appended to `out`.
void put_tail(ByteBuffer& out, const SummaryInput& in);

}  // namespace scanmesh::acq::mcap::detail
