// CRC-32 (ISO-HDLC, the one MCAP uses) through zlib: update over bytes, and the combination of
// two CRCs of adjacent ranges without reading the bytes again.
// SPDX-License-Identifier: MIT
#pragma once

#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <span>

namespace scanmesh::acq::detail {

inline std::uint32_t crc32_update(std::uint32_t crc, std::span<const std::byte> bytes) {
  return static_cast<std::uint32_t>(
      ::crc32_z(crc, reinterpret_cast<const Bytef*>(bytes.data()), bytes.size()));
}

/// CRC of A followed by B, from crc(A), crc(B) and B's length.
inline std::uint32_t crc32_combine(std::uint32_t crc_a, std::uint32_t crc_b, std::uint64_t len_b) {
  return static_cast<std::uint32_t>(::crc32_combine64(crc_a, crc_b, static_cast<z_off64_t>(len_b)));
}

}  // namespace scanmesh::acq::detail
