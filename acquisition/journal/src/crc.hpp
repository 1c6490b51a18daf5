// CRC-32 (ISO-HDLC, the one MCAP uses): ISA-L's folding implementation to update over bytes
// (about 30 GB/s here against zlib's 2.4, the journal's largest cost per byte otherwise), zlib
// to combine the CRCs of two adjacent ranges without reading the bytes again.
// SPDX-License-Identifier: MIT
#pragma once

#include <isa-l/crc.h>
#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <span>

namespace scanmesh::acq::detail {

inline std::uint32_t crc32_update(std::uint32_t crc, std::span<const std::byte> bytes) {
  return ::crc32_gzip_refl(crc, reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size());
}

/// CRC of A followed by B, from crc(A), crc(B) and B's length.
inline std::uint32_t crc32_combine(std::uint32_t crc_a, std::uint32_t crc_b, std::uint64_t len_b) {
  return static_cast<std::uint32_t>(::crc32_combine64(crc_a, crc_b, static_cast<z_off64_t>(len_b)));
}

}  // namespace scanmesh::acq::detail
