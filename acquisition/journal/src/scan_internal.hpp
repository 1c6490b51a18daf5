// The scanner's results that only the recovery needs: the message index records a chunk should
// have, the data section's CRC up to the cut, and where the metadata records are.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <map>
#include <vector>

#include "file.hpp"
#include "records.hpp"
#include "scanmesh/acquisition/mcap.hpp"

namespace scanmesh::acq::mcap::detail {

struct ScanExtras {
  /// By index into ScanReport::chunks: the message index records regenerated from the chunk,
  /// for each chunk whose own are missing or wrong.
  std::map<std::size_t, std::vector<std::byte>> missing_indexes;
  std::uint32_t crc_at_good_end = 0;  ///< CRC of the file's bytes [0, good_end)
  std::uint32_t crc_at_data_end = 0;  ///< CRC of [0, data end) when there is a Data End
  std::vector<MetadataRef> metadata_refs;
};

ScanReport scan_file(const acq::detail::File& file, ScanVisitor* visitor, ScanOptions options,
                     ScanExtras* extras);

/// (channel, file offset) of each Message Index record in `bytes`, which start at `base`.
std::vector<std::pair<std::uint16_t, std::uint64_t>> index_layout(std::span<const std::byte> bytes,
                                                                  std::uint64_t base);

}  // namespace scanmesh::acq::mcap::detail
