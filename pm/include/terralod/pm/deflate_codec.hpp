// Deflate streams through libdeflate, for every format the project writes compressed: the
// sections of a progressive mesh (pm_io), texture tiles (zlib streams, RFC 1950) and
// quantized-mesh tiles (gzip, RFC 1952).
//
// Usage:
//   std::vector<std::uint8_t> out = header;                      // compressed bytes are appended
//   const std::size_t n = terralod::pm::zlib_compress(raw, 6, out);  // 0: failed, out unchanged
//   std::vector<std::uint8_t> back(raw.size());
//   bool ok = terralod::pm::zlib_decompress(std::span(out).subspan(header.size()), back);
//
// The streams are the standard ones: whatever zlib (or any inflater) reads, these read, and the
// other way round. libdeflate compresses a whole buffer at once, 2-5x faster than zlib at equal
// size; each thread keeps one compressor per level and one decompressor (a compressor holds
// about 0.5-1 MiB of tables), so that compressing many small buffers allocates nothing.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace terralod::pm {

/// A deflate stream cannot expand its data more than 1032:1 (RFC 1951: a 258-byte match costs at
/// least 2 bits). Readers bound the size a stream's header claims by it (plus a small slack for
/// the zlib header and tiny streams) before they allocate for it.
inline constexpr std::uint64_t kMaxDeflateRatio = 1032;

/// Appends the zlib stream of `in`, at libdeflate's `level` (1 fastest .. 12 smallest), to
/// `out` and returns its size; 0 when no compressor could be had (`out` is then unchanged).
std::size_t zlib_compress(std::span<const std::uint8_t> in, int level, std::vector<std::uint8_t>& out);

/// The same as a gzip stream (the members of a .gz file).
std::size_t gzip_compress(std::span<const std::uint8_t> in, int level, std::vector<std::uint8_t>& out);

/// Inflates the zlib stream `in` into `out`, which it must fill exactly; false when the stream
/// is damaged (checksum included), truncated, or inflates to another size.
bool zlib_decompress(std::span<const std::uint8_t> in, std::span<std::uint8_t> out);

}  // namespace terralod::pm
