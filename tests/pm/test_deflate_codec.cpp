// deflate_codec: libdeflate's zlib and gzip streams are the standard ones (zlib reads what it
// writes and the other way round), and a damaged, truncated or mis-sized stream is refused.
#include <gtest/gtest.h>
#include <zlib.h>

#include <cstdint>
#include <random>
#include <span>
#include <thread>
#include <vector>

#include "terralod/pm/deflate_codec.hpp"

namespace pm = terralod::pm;

namespace {

// Compressible bytes: small numbers with runs, like a PM's residuals.
std::vector<std::uint8_t> sample_bytes(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<std::uint8_t> b(n);
  for (std::size_t i = 0; i < n; ++i) b[i] = std::uint8_t(i % 97 < 60 ? rng() % 4 : rng() % 256);
  return b;
}

// zlib's own inflate of a zlib (window bits 15) or gzip (31) stream into `size` bytes; empty on failure.
std::vector<std::uint8_t> zlib_inflate(std::span<const std::uint8_t> in, std::size_t size, int window_bits) {
  z_stream zs{};
  if (inflateInit2(&zs, window_bits) != Z_OK) return {};
  std::vector<std::uint8_t> out(size + 1);
  zs.next_in = const_cast<Bytef*>(in.data());
  zs.avail_in = uInt(in.size());
  zs.next_out = out.data();
  zs.avail_out = uInt(out.size());
  const int rc = inflate(&zs, Z_FINISH);
  const std::size_t got = zs.total_out;
  inflateEnd(&zs);
  if (rc != Z_STREAM_END || got != size) return {};
  out.resize(got);
  return out;
}

}  // namespace

TEST(DeflateCodec, ZlibStreamsAreReadByZlibAndZlibsAreReadBack) {
  for (std::size_t n : {std::size_t(0), std::size_t(1), std::size_t(1000), std::size_t(300000)}) {
    SCOPED_TRACE(n);
    const std::vector<std::uint8_t> raw = sample_bytes(n, unsigned(n));
    for (int level : {1, 4, 6, 12}) {
      std::vector<std::uint8_t> z = {7, 7};  // appended after what is there
      const std::size_t len = pm::zlib_compress(raw, level, z);
      ASSERT_GT(len, 0u);
      ASSERT_EQ(z.size(), 2 + len);
      EXPECT_EQ(z[0], 7);
      const std::span<const std::uint8_t> stream(z.data() + 2, len);
      EXPECT_EQ(zlib_inflate(stream, n, 15), raw) << "level " << level;
      std::vector<std::uint8_t> back(n, 0xAB);
      EXPECT_TRUE(pm::zlib_decompress(stream, back));
      EXPECT_EQ(back, raw);
    }
    // zlib's deflate read by the codec.
    std::vector<std::uint8_t> z(compressBound(uLong(n)));
    uLongf zlen = uLongf(z.size());
    ASSERT_EQ(compress2(z.data(), &zlen, raw.data(), uLong(n), 6), Z_OK);
    std::vector<std::uint8_t> back(n);
    EXPECT_TRUE(pm::zlib_decompress(std::span(z.data(), zlen), back));
    EXPECT_EQ(back, raw);
  }
}

TEST(DeflateCodec, GzipStreamsAreGzip) {
  const std::vector<std::uint8_t> raw = sample_bytes(50000, 3);
  std::vector<std::uint8_t> gz;
  const std::size_t len = pm::gzip_compress(raw, 6, gz);
  ASSERT_GT(len, 18u);
  EXPECT_EQ(gz[0], 0x1f);
  EXPECT_EQ(gz[1], 0x8b);
  EXPECT_EQ(zlib_inflate(gz, raw.size(), 15 + 16), raw);
}

TEST(DeflateCodec, DamagedTruncatedOrMisSizedStreamsAreRefused) {
  const std::vector<std::uint8_t> raw = sample_bytes(20000, 9);
  std::vector<std::uint8_t> z;
  ASSERT_GT(pm::zlib_compress(raw, 6, z), 0u);
  std::vector<std::uint8_t> out(raw.size());
  std::vector<std::uint8_t> damaged = z;
  damaged[damaged.size() / 2] ^= 0x10;
  EXPECT_FALSE(pm::zlib_decompress(damaged, out));
  std::vector<std::uint8_t> checksum = z;
  checksum.back() ^= 1;  // the Adler-32 of the data
  EXPECT_FALSE(pm::zlib_decompress(checksum, out));
  EXPECT_FALSE(pm::zlib_decompress(std::span(z).first(z.size() - 5), out));
  std::vector<std::uint8_t> shorter(raw.size() - 1), longer(raw.size() + 1);
  EXPECT_FALSE(pm::zlib_decompress(z, shorter));
  EXPECT_FALSE(pm::zlib_decompress(z, longer));
  EXPECT_FALSE(pm::zlib_decompress({}, out));
}

TEST(DeflateCodec, ThreadsCompressAtOnceWithTheirOwnCompressors) {
  const std::vector<std::uint8_t> raw = sample_bytes(100000, 4);
  std::vector<std::uint8_t> expect;
  ASSERT_GT(pm::zlib_compress(raw, 6, expect), 0u);
  std::vector<std::vector<std::uint8_t>> got(4);
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < got.size(); ++t)
    threads.emplace_back([&, t] {
      for (int k = 0; k < 20; ++k) {
        got[t].clear();
        pm::zlib_compress(raw, 6, got[t]);
      }
    });
  for (auto& t : threads) t.join();
  for (const auto& g : got) EXPECT_EQ(g, expect);  // deterministic, whichever thread made it
}
