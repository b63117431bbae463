// The little-endian byte codec under every binary format terralod writes itself (PM files, the
// database's blobs, hybrid models, texture tiles, quantized-mesh and glb tiles, PLY and glTF
// meshes): ByteWriter appends values, ByteReader reads them back with bounds checks, and load_*
// read at an offset the caller has checked.
//
//   terralod::pm::ByteWriter w;
//   w.u32(1);       // 01 00 00 00
//   w.svarint(-3);  // 05
//   w.f64(0.5);     // 00 00 00 00 00 00 E0 3F
//   terralod::pm::ByteReader r(w.bytes, [&](const terralod::pm::ByteReadFailure& f) {
//     throw MyFormatError(name + ": truncated " + f.what + " at byte " + std::to_string(f.position));
//   });
//   const std::uint32_t version = r.u32("header");
//   const std::int64_t delta = r.svarint("deltas");
//   const double x = r.f64("header");
//   if (r.left() != 0) throw MyFormatError(name + ": bytes left over");  // the format's own rule
//
// Contract:
//   - Byte order: every fixed-size value is stored least significant byte first, whatever the
//     host's: uN and iN as N / 8 bytes (iN in two's complement), f32 and f64 as the 4 or 8 bytes
//     of their IEEE-754 binary32 / binary64 bit pattern, bit for bit (-0.0 and NaN payloads kept).
//   - varint(v): unsigned LEB128, 7 bits per byte, low group first, the high bit set on every
//     byte but the last; 1 to 10 bytes, and the writer always writes the shortest form.
//     svarint(v) = varint(zigzag(v)), zigzag(v) = (v << 1) ^ (v >> 63), which maps
//     0, -1, 1, -2, ... to 0, 1, 2, 3, ...; unzigzag is its inverse.
//   - ByteWriter appends to its public `bytes`, which callers may reserve, append to or patch
//     directly (u64_at overwrites 8 bytes written earlier: a length known only at the end);
//     chars() views them as characters, for outputs kept in a std::string.
//     pad_to(a), a >= 1, appends zero bytes until bytes.size() is a multiple of a.
//   - ByteReader reads `bytes` (not owned: they must outlive the reader) from position 0 on.
//     Reads past the end, a varint cut off by the end, a varint of more than 64 bits (a tenth
//     byte above 1) and, with VarintForm::Shortest, a varint that is not in its shortest form
//     (a last byte of 0 after others) read nothing further and call `fail` with a
//     ByteReadFailure; `fail` must throw the format's own error (the program aborts if it
//     returns). Each read takes a label, `what`, handed back in the failure for the message.
//     raw(n) returns a view of the next n bytes, valid while `bytes` is.
//   - load_u16 / load_u32 / load_u64 / load_f32 / load_f64(p) read 2, 4 or 8 bytes at p with no
//     check: for formats that check a record's length as a whole first.
// Cost: reads and writes are inline; a failure is one call through std::function.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <functional>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

namespace terralod::pm {

constexpr std::uint64_t zigzag(std::int64_t v) { return (std::uint64_t(v) << 1) ^ std::uint64_t(v >> 63); }
constexpr std::int64_t unzigzag(std::uint64_t v) { return std::int64_t(v >> 1) ^ -std::int64_t(v & 1); }

namespace detail {

template <int N>
std::uint64_t load_le(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < N; ++i) v |= std::uint64_t(p[i]) << (8 * i);
  return v;
}

template <int N>
void append_le(std::vector<std::uint8_t>& out, std::uint64_t v) {
  std::uint8_t b[N];
  for (int i = 0; i < N; ++i) b[i] = std::uint8_t(v >> (8 * i));
  out.insert(out.end(), b, b + N);
}

}  // namespace detail

inline std::uint16_t load_u16(const std::uint8_t* p) { return std::uint16_t(detail::load_le<2>(p)); }
inline std::uint32_t load_u32(const std::uint8_t* p) { return std::uint32_t(detail::load_le<4>(p)); }
inline std::uint64_t load_u64(const std::uint8_t* p) { return detail::load_le<8>(p); }
inline float load_f32(const std::uint8_t* p) { return std::bit_cast<float>(load_u32(p)); }
inline double load_f64(const std::uint8_t* p) { return std::bit_cast<double>(load_u64(p)); }

/// Appends little-endian values to `bytes` (see the contract above).
struct ByteWriter {
  std::vector<std::uint8_t> bytes;

  void u8(std::uint8_t v) { bytes.push_back(v); }
  void u16(std::uint16_t v) { detail::append_le<2>(bytes, v); }
  void u32(std::uint32_t v) { detail::append_le<4>(bytes, v); }
  void u64(std::uint64_t v) { detail::append_le<8>(bytes, v); }
  void i8(std::int8_t v) { u8(std::uint8_t(v)); }
  void i16(std::int16_t v) { u16(std::uint16_t(v)); }
  void i32(std::int32_t v) { u32(std::uint32_t(v)); }
  void i64(std::int64_t v) { u64(std::uint64_t(v)); }
  void f32(float v) { u32(std::bit_cast<std::uint32_t>(v)); }
  void f64(double v) { u64(std::bit_cast<std::uint64_t>(v)); }
  void varint(std::uint64_t v) {
    while (v >= 0x80) {
      bytes.push_back(std::uint8_t(v | 0x80));
      v >>= 7;
    }
    bytes.push_back(std::uint8_t(v));
  }
  void svarint(std::int64_t v) { varint(zigzag(v)); }
  void raw(std::span<const std::uint8_t> b) { bytes.insert(bytes.end(), b.begin(), b.end()); }
  /// `size` bytes at `data` (text, a magic number): no terminator is looked for or written.
  void raw(const char* data, std::size_t size) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(data);
    bytes.insert(bytes.end(), p, p + size);
  }
  void pad_to(std::size_t a) { bytes.resize((bytes.size() + a - 1) / a * a, 0); }
  /// The bytes as characters, for outputs held in a std::string (valid until the next append).
  std::string_view chars() const { return {reinterpret_cast<const char*>(bytes.data()), bytes.size()}; }
  /// Overwrites bytes[at, at + 8) (written earlier) with v.
  void u64_at(std::size_t at, std::uint64_t v) {
    for (int i = 0; i < 8; ++i) bytes[at + std::size_t(i)] = std::uint8_t(v >> (8 * i));
  }
};

/// Why a ByteReader read failed: what `fail` receives.
struct ByteReadFailure {
  enum class Kind {
    Truncated,          ///< a fixed-size read or raw(n) needed `wanted` bytes, `left` were left
    VarintTruncated,    ///< the bytes ended inside a varint
    VarintTooLong,      ///< a varint of more than 64 bits
    VarintNotShortest,  ///< VarintForm::Shortest and a varint with a redundant last byte
  };
  Kind kind;
  std::size_t position;  ///< the reader's position then: where a fixed-size read began; past the
                         ///< bytes of a varint read so far (the bad byte included)
  std::uint64_t wanted;  ///< Truncated: bytes the read needed (0 otherwise)
  std::size_t left;      ///< bytes left at `position`
  const char* what;      ///< the label the read was given ("" when none)
};

/// Which varints a ByteReader accepts: any of the 1 to 10 byte forms of a value, or only the
/// shortest (so that decoding is one-to-one).
enum class VarintForm { Any, Shortest };

/// Bounds-checked little-endian reads over a byte range (see the contract above).
class ByteReader {
 public:
  using Fail = std::function<void(const ByteReadFailure&)>;

  ByteReader(std::span<const std::uint8_t> bytes, Fail fail, VarintForm varints = VarintForm::Any)
      : bytes_(bytes), fail_(std::move(fail)), varints_(varints) {}

  std::size_t position() const { return pos_; }
  std::size_t left() const { return bytes_.size() - pos_; }
  /// The bytes not read yet.
  std::span<const std::uint8_t> rest() const { return bytes_.subspan(pos_); }

  std::uint8_t u8(const char* what = "") { return *take(1, what); }
  std::uint16_t u16(const char* what = "") { return load_u16(take(2, what)); }
  std::uint32_t u32(const char* what = "") { return load_u32(take(4, what)); }
  std::uint64_t u64(const char* what = "") { return load_u64(take(8, what)); }
  std::int8_t i8(const char* what = "") { return std::int8_t(u8(what)); }
  std::int16_t i16(const char* what = "") { return std::int16_t(u16(what)); }
  std::int32_t i32(const char* what = "") { return std::int32_t(u32(what)); }
  std::int64_t i64(const char* what = "") { return std::int64_t(u64(what)); }
  float f32(const char* what = "") { return load_f32(take(4, what)); }
  double f64(const char* what = "") { return load_f64(take(8, what)); }
  std::span<const std::uint8_t> raw(std::uint64_t n, const char* what = "") {
    const std::uint8_t* p = take(n, what);
    return {p, std::size_t(n)};
  }
  std::uint64_t varint(const char* what = "") {
    std::uint64_t v = 0;
    for (int shift = 0;; shift += 7) {
      if (pos_ == bytes_.size()) failed(ByteReadFailure::Kind::VarintTruncated, 0, what);
      const std::uint8_t b = bytes_[pos_++];
      if (shift == 63 && b > 1) failed(ByteReadFailure::Kind::VarintTooLong, 0, what);
      v |= std::uint64_t(b & 0x7f) << shift;
      if (!(b & 0x80)) {
        if (b == 0 && shift > 0 && varints_ == VarintForm::Shortest)
          failed(ByteReadFailure::Kind::VarintNotShortest, 0, what);
        return v;
      }
    }
  }
  std::int64_t svarint(const char* what = "") { return unzigzag(varint(what)); }

 private:
  const std::uint8_t* take(std::uint64_t n, const char* what) {
    if (n > left()) failed(ByteReadFailure::Kind::Truncated, n, what);
    const std::uint8_t* p = bytes_.data() + pos_;
    pos_ += std::size_t(n);
    return p;
  }
  [[noreturn, gnu::noinline, gnu::cold]] void failed(ByteReadFailure::Kind kind, std::uint64_t wanted,
                                                     const char* what) const {
    fail_(ByteReadFailure{kind, pos_, wanted, left(), what});
    std::abort();  // `fail` returned: a misuse of the contract
  }

  std::span<const std::uint8_t> bytes_;
  std::size_t pos_ = 0;
  Fail fail_;
  VarintForm varints_;
};

/// CRC-32 of `bytes` as zlib's crc32 computes it (polynomial 0xEDB88320, as in PNG and gzip),
/// continued from `crc` (0 starts one): crc32_of(b, crc32_of(a)) == crc32_of(a then b). Any
/// length (zlib takes 32-bit lengths; this feeds it in pieces). The one checksum of every format
/// terralod writes (PM files, database blocks and blobs, hybrid models, texture tiles).
std::uint32_t crc32_of(std::span<const std::uint8_t> bytes, std::uint32_t crc = 0);

}  // namespace terralod::pm
