// Deflate streams through libdeflate (deflate_codec.hpp).
#include "terralod/pm/deflate_codec.hpp"

#include <libdeflate.h>

#include <array>
#include <memory>

namespace terralod::pm {
namespace {

struct FreeCompressor {
  void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
};
struct FreeDecompressor {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

// This thread's compressor at `level` (clamped to 1 .. 12), made on first use; null when
// libdeflate cannot allocate one.
libdeflate_compressor* compressor(int level) {
  thread_local std::array<std::unique_ptr<libdeflate_compressor, FreeCompressor>, 13> at;
  level = level < 1 ? 1 : level > 12 ? 12 : level;
  auto& c = at[std::size_t(level)];
  if (!c) c.reset(libdeflate_alloc_compressor(level));
  return c.get();
}

template <class Bound, class Compress>
std::size_t append(std::span<const std::uint8_t> in, int level, std::vector<std::uint8_t>& out, Bound bound,
                   Compress compress) {
  libdeflate_compressor* c = compressor(level);
  if (!c) return 0;
  const std::size_t head = out.size();
  out.resize(head + bound(c, in.size()));
  const std::size_t n = compress(c, in.data(), in.size(), out.data() + head, out.size() - head);
  out.resize(head + n);  // n > 0: the bound always leaves room
  return n;
}

}  // namespace

std::size_t zlib_compress(std::span<const std::uint8_t> in, int level, std::vector<std::uint8_t>& out) {
  return append(in, level, out, libdeflate_zlib_compress_bound, libdeflate_zlib_compress);
}

std::size_t gzip_compress(std::span<const std::uint8_t> in, int level, std::vector<std::uint8_t>& out) {
  return append(in, level, out, libdeflate_gzip_compress_bound, libdeflate_gzip_compress);
}

bool zlib_decompress(std::span<const std::uint8_t> in, std::span<std::uint8_t> out) {
  thread_local std::unique_ptr<libdeflate_decompressor, FreeDecompressor> d(libdeflate_alloc_decompressor());
  if (!d) return false;
  return libdeflate_zlib_decompress(d.get(), in.data(), in.size(), out.data(), out.size(), nullptr) ==
         LIBDEFLATE_SUCCESS;
}

}  // namespace terralod::pm
