#pragma once
// CRC-32 (IEEE 802.3 / ISO-HDLC, zlib's crc32) of a byte span of any length (zlib takes at most UINT_MAX
// bytes per call). Host code only: the target links ZLIB::ZLIB.
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <span>

namespace fs {

inline std::uint32_t crc32_ieee(std::span<const std::uint8_t> data) {
  uLong crc = crc32(0L, Z_NULL, 0);
  for (std::size_t at = 0; at < data.size();) {
    const auto n = static_cast<uInt>(std::min<std::size_t>(data.size() - at, std::size_t{1} << 30));
    crc = crc32(crc, data.data() + at, n);
    at += n;
  }
  return static_cast<std::uint32_t>(crc);
}

}  // namespace fs
