// mcap::recover: cuts a file after its last good record and appends what a crash left
// unwritten (message indexes of good chunks that lack them, data end, summary, footer).
// SPDX-License-Identifier: MIT
#include "crc.hpp"
#include "file.hpp"
#include "records.hpp"
#include "scan_internal.hpp"
#include "scanmesh/acquisition/mcap.hpp"

namespace scanmesh::acq::mcap {

using acq::detail::crc32_combine;
using acq::detail::crc32_update;
using acq::detail::errno_text;
using acq::detail::File;
using namespace detail;

namespace {

RecoveryReport recover_file(File& file, ScanVisitor* visitor) {
  ScanExtras extras;
  RecoveryReport rr;
  rr.before = scan_file(file, visitor, {}, &extras);
  const ScanReport& s = rr.before;
  rr.kept_chunks = s.chunks.size();
  rr.kept_messages = s.messages;
  const bool indexes_intact = extras.missing_indexes.empty();
  if (s.complete() && indexes_intact) {
    rr.already_complete = true;
    rr.cut_offset = s.file_bytes;
    rr.file_bytes_after = s.file_bytes;
    return rr;
  }
  if (!s.header_ok && s.good_end > kMagic.size())
    throw InputError("journal " + s.file + ": the Header record is damaged and data follows it; " +
                     "recover cannot repair that in place (journal check lists what is readable)");

  // Cut after the last good record: at the Data End when there is one (a summary that does not
  // match is rewritten), else at the end of the good data (the torn tail goes).
  std::uint64_t cut = s.data_end_offset.value_or(s.good_end);
  std::uint32_t crc = s.data_end_offset ? extras.crc_at_data_end : extras.crc_at_good_end;
  ByteBuffer out;
  if (!s.header_ok) {  // cut inside the magic or the header: start the file again
    cut = 0;
    crc = 0;
    out.append(std::as_bytes(std::span(kMagic)));
    put_header(out, "x-scanmesh", "scanmesh journal 2 (recovered)");
  }
  std::vector<ChunkInfo> chunks = s.chunks;
  // The chunk that ends at the cut gets its message indexes first, right after it (where a
  // reader looks for them); the others follow in chunk order.
  std::vector<std::size_t> order;
  for (const auto& [i, bytes] : extras.missing_indexes) {
    if (chunks[i].offset + chunks[i].length == cut)
      order.insert(order.begin(), i);
    else
      order.push_back(i);
  }
  for (const std::size_t i : order) {
    const std::vector<std::byte>& bytes = extras.missing_indexes.at(i);
    ChunkInfo& c = chunks[i];
    const std::uint64_t at = cut + out.size();
    c.message_index_offsets = index_layout(bytes, at);
    c.message_index_length = bytes.size();
    c.index_intact = true;
    out.append(bytes);
    ++rr.reindexed_chunks;
  }
  crc = crc32_combine(crc, crc32_update(0, out.span()), out.size());

  // Damaged regions before the cut become application records that span them, so that a
  // streaming reader steps over them; the data section's CRC is then not available.
  std::vector<std::pair<std::uint64_t, ByteBuffer>> wraps;
  for (const Damage& d : s.damage) {
    if (d.offset + d.length > cut || d.length < kRecordPrefix) continue;
    ByteBuffer prefix;
    prefix.put(kDamagedRegionOpcode);
    prefix.put(static_cast<std::uint64_t>(d.length - kRecordPrefix));
    wraps.emplace_back(d.offset, std::move(prefix));
  }
  if (!wraps.empty()) crc = 0;

  SummaryInput in;
  in.data_end_offset = cut + out.size();
  in.data_section_crc = crc;
  in.schemas = &s.schemas;
  in.channels = &s.channels;
  in.chunks = chunks;
  in.metadata = extras.metadata_refs;
  in.messages = s.messages;
  in.message_start_time = s.message_start_time;
  in.message_end_time = s.message_end_time;
  in.channel_messages = &s.channel_messages;
  put_tail(out, in);

  auto fail = [&](int e, const std::string& what) {
    throw JournalWriteError("journal " + s.file + ": recovery: " + what + " failed: " +
                                errno_text(e) + " (run recover again: it starts from the scan)",
                            e);
  };
  for (const auto& [offset, prefix] : wraps) {
    if (const int e = file.write_at(offset, prefix.span()); e != 0)
      fail(e, "marking the damaged region at byte " + std::to_string(offset));
    ++rr.wrapped_regions;
  }
  if (const int e = file.truncate(cut); e != 0)
    fail(e, "cutting the file at byte " + std::to_string(cut));
  if (const int e = file.seek(cut); e != 0) fail(e, "seeking to byte " + std::to_string(cut));
  if (const int e = file.write_all(std::array{out.span()}); e != 0) {
    (void)file.truncate(cut);
    fail(e, "writing the summary at byte " + std::to_string(cut));
  }
  if (const int e = file.datasync(); e != 0) fail(e, "fdatasync");
  rr.cut_offset = cut;
  rr.cut_bytes = s.file_bytes - cut;
  rr.file_bytes_after = cut + out.size();
  return rr;
}

}  // namespace

RecoveryReport recover(const std::filesystem::path& file, ScanVisitor* visitor) {
  File f = File::open_update(file);
  return recover_file(f, visitor);
}

RecoveryReport recover_fd(int fd, const std::string& name, ScanVisitor* visitor) {
  File f = File::borrow(fd, name);
  return recover_file(f, visitor);
}

}  // namespace scanmesh::acq::mcap
