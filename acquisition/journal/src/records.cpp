// MCAP record encoding and parsing shared by the writer and the recovery (see records.hpp).
// SPDX-License-Identifier: MIT
#include "records.hpp"

#include "crc.hpp"

namespace scanmesh::acq::mcap::detail {

namespace {
constexpr auto op(Opcode o) { return static_cast<std::uint8_t>(o); }
}  // namespace

void put_header(ByteBuffer& out, const std::string& profile, const std::string& library) {
  const auto r = out.begin_record(op(Opcode::kHeader));
  out.put_string(profile);
  out.put_string(library);
  out.end_record(r);
}

void put_schema(ByteBuffer& out, const Schema& s) {
  const auto r = out.begin_record(op(Opcode::kSchema));
  out.put(s.id);
  out.put_string(s.name);
  out.put_string(s.encoding);
  out.put_string(s.data);
  out.end_record(r);
}

void put_channel(ByteBuffer& out, const Channel& c) {
  const auto r = out.begin_record(op(Opcode::kChannel));
  out.put(c.id);
  out.put(c.schema_id);
  out.put_string(c.topic);
  out.put_string(c.message_encoding);
  out.put_string_map(c.metadata);
  out.end_record(r);
}

void put_metadata(ByteBuffer& out, const Metadata& m) {
  const auto r = out.begin_record(op(Opcode::kMetadata));
  out.put_string(m.name);
  out.put_string_map(m.metadata);
  out.end_record(r);
}

std::optional<Schema> parse_schema(std::span<const std::byte> body) {
  ByteReader r(body);
  Schema s;
  s.id = r.get<std::uint16_t>();
  s.name = r.string();
  s.encoding = r.string();
  s.data = r.string();
  if (!r.ok() || s.id == 0) return std::nullopt;
  return s;
}

std::optional<Channel> parse_channel(std::span<const std::byte> body) {
  ByteReader r(body);
  Channel c;
  c.id = r.get<std::uint16_t>();
  c.schema_id = r.get<std::uint16_t>();
  c.topic = r.string();
  c.message_encoding = r.string();
  c.metadata = r.string_map();
  if (!r.ok()) return std::nullopt;
  return c;
}

std::optional<Metadata> parse_metadata(std::span<const std::byte> body) {
  ByteReader r(body);
  Metadata m;
  m.name = r.string();
  m.metadata = r.string_map();
  if (!r.ok()) return std::nullopt;
  return m;
}

void put_tail(ByteBuffer& out, const SummaryInput& in) {
  {
    const auto r = out.begin_record(op(Opcode::kDataEnd));
    out.put(in.data_section_crc);
    out.end_record(r);
  }
  const std::size_t summary_at = out.size();  // index in `out` of the summary's first byte
  const std::uint64_t summary_start = in.data_end_offset + kDataEndRecord;
  auto file_offset = [&](std::size_t index) { return summary_start + (index - summary_at); };

  struct Group {
    Opcode opcode;
    std::size_t start;
    std::size_t end;
  };
  std::vector<Group> groups;
  auto group = [&](Opcode o, auto&& body) {
    const std::size_t start = out.size();
    body();
    if (out.size() > start) groups.push_back({o, start, out.size()});
  };

  group(Opcode::kSchema, [&] {
    for (const auto& [id, s] : *in.schemas) put_schema(out, s);
  });
  group(Opcode::kChannel, [&] {
    for (const auto& [id, c] : *in.channels) put_channel(out, c);
  });
  group(Opcode::kStatistics, [&] {
    const auto r = out.begin_record(op(Opcode::kStatistics));
    out.put(in.messages);
    out.put(static_cast<std::uint16_t>(in.schemas->size()));
    out.put(static_cast<std::uint32_t>(in.channels->size()));
    out.put(std::uint32_t{0});  // attachments
    out.put(static_cast<std::uint32_t>(in.metadata.size()));
    out.put(static_cast<std::uint32_t>(in.chunks.size()));
    out.put(in.message_start_time);
    out.put(in.message_end_time);
    out.put(static_cast<std::uint32_t>(in.channel_messages->size() * 10));
    for (const auto& [id, n] : *in.channel_messages) {
      out.put(id);
      out.put(n);
    }
    out.end_record(r);
  });
  group(Opcode::kChunkIndex, [&] {
    for (const ChunkInfo& c : in.chunks) {
      const auto r = out.begin_record(op(Opcode::kChunkIndex));
      out.put(c.message_start_time);
      out.put(c.message_end_time);
      out.put(c.offset);
      out.put(c.length);
      out.put(static_cast<std::uint32_t>(c.message_index_offsets.size() * 10));
      for (const auto& [id, off] : c.message_index_offsets) {
        out.put(id);
        out.put(off);
      }
      out.put(c.message_index_length);
      out.put_string("");
      out.put(c.records_bytes);  // compressed size: uncompressed chunks
      out.put(c.records_bytes);
      out.end_record(r);
    }
  });
  group(Opcode::kMetadataIndex, [&] {
    for (const MetadataRef& m : in.metadata) {
      const auto r = out.begin_record(op(Opcode::kMetadataIndex));
      out.put(m.offset);
      out.put(m.length);
      out.put_string(m.name);
      out.end_record(r);
    }
  });

  const std::size_t offsets_at = out.size();
  for (const Group& g : groups) {
    const auto r = out.begin_record(op(Opcode::kSummaryOffset));
    out.put(static_cast<std::uint8_t>(g.opcode));
    out.put(file_offset(g.start));
    out.put(static_cast<std::uint64_t>(g.end - g.start));
    out.end_record(r);
  }
  const bool any_summary = out.size() > summary_at;
  out.put(op(Opcode::kFooter));
  out.put(std::uint64_t{20});
  out.put(any_summary ? summary_start : std::uint64_t{0});
  out.put(groups.empty() ? std::uint64_t{0} : file_offset(offsets_at));
  // The summary CRC covers the summary, the summary offsets and the footer up to this field.
  const std::uint32_t crc = acq::detail::crc32_update(
      0, std::span<const std::byte>(out.data() + summary_at, out.size() - summary_at));
  out.put(crc);
  out.append(std::as_bytes(std::span(kMagic)));
}

}  // namespace scanmesh::acq::mcap::detail
