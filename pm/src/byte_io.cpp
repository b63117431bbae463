// The CRC-32 of byte_io.hpp, through libdeflate (kept out of the header so that it stays private;
// the same CRC as zlib's crc32, several times faster on long buffers).
#include "terralod/pm/byte_io.hpp"

#include <libdeflate.h>

namespace terralod::pm {

std::uint32_t crc32_of(std::span<const std::uint8_t> bytes, std::uint32_t crc) {
  return libdeflate_crc32(crc, bytes.data(), bytes.size());
}

}  // namespace terralod::pm
