// The CRC-32 of byte_io.hpp, through zlib (kept out of the header so that zlib stays private).
#include "terralod/pm/byte_io.hpp"

#include <zlib.h>

#include <algorithm>

namespace terralod::pm {

std::uint32_t crc32_of(std::span<const std::uint8_t> bytes, std::uint32_t crc) {
  uLong c = crc;
  for (std::size_t off = 0; off < bytes.size();) {
    const std::size_t len = std::min<std::size_t>(bytes.size() - off, std::size_t(1) << 30);
    c = ::crc32(c, bytes.data() + off, uInt(len));
    off += len;
  }
  return std::uint32_t(c);
}

}  // namespace terralod::pm
