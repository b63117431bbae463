// Little-endian bytes of the binary formats blocks/ writes itself (the block summaries blob,
// the approximation tree blob, the database's info checksum and georeference blob): unsigned
// integers and IEEE-754 binary64 doubles appended and read byte by byte, least significant
// first, so the bytes do not depend on the host's byte order.
//
// Contract: put_*(out, v) appends 2, 4 or 8 bytes to out; get_*(p) reads them from p, which
// must point at that many readable bytes (the callers check the length first).
#pragma once

#include <bit>
#include <cstdint>
#include <vector>

namespace terralod::blocks::detail {

template <int Bytes>
void put_le(std::vector<std::uint8_t>& out, std::uint64_t v) {
  for (int i = 0; i < Bytes; ++i) out.push_back(std::uint8_t(v >> (8 * i)));
}

template <int Bytes>
std::uint64_t get_le(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < Bytes; ++i) v |= std::uint64_t(p[i]) << (8 * i);
  return v;
}

inline void put_u16(std::vector<std::uint8_t>& out, std::uint32_t v) { put_le<2>(out, v); }
inline void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) { put_le<4>(out, v); }
inline void put_u64(std::vector<std::uint8_t>& out, std::uint64_t v) { put_le<8>(out, v); }
inline void put_f64(std::vector<std::uint8_t>& out, double d) {
  put_u64(out, std::bit_cast<std::uint64_t>(d));
}

inline std::uint32_t get_u16(const std::uint8_t* p) { return std::uint32_t(get_le<2>(p)); }
inline std::uint32_t get_u32(const std::uint8_t* p) { return std::uint32_t(get_le<4>(p)); }
inline std::uint64_t get_u64(const std::uint8_t* p) { return get_le<8>(p); }
inline double get_f64(const std::uint8_t* p) { return std::bit_cast<double>(get_u64(p)); }

}  // namespace terralod::blocks::detail
