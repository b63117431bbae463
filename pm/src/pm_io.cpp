// Binary PM file format (version 1): writer, hostile-input-safe reader, and the byte layout.
//
// ============================================================================================
// terralod PM file, format version 1. All integers little-endian; f64 = IEEE-754 binary64
// stored as its 8 bytes little-endian. varint = unsigned LEB128 (7 bits per byte, low group
// first, high bit set on every byte but the last, at most 10 bytes); zz(v) = zigzag mapping of
// a signed integer: (v << 1) ^ (v >> 63), so 0,-1,1,-2,... become 0,1,2,3,...
//
//  offset size  field
//  0      8     magic: 'T' 'L' 'O' 'D' 'P' 'M' '\r' '\n'  (54 4C 4F 44 50 4D 0D 0A)
//  8      4     u32 format version = 1
//  12     8     u64 file size in bytes, including the trailing checksum
//  20     4     u32 grid width  W >= 2
//  24     4     u32 grid height H >= 2;  W * H <= 2^28
//  28     48    6 x f64 GridTransform: x0, xc, xr, y0, yc, yr; all finite, and so that
//               2 (|x0| + (W-1)|xc| + (H-1)|xr|) and the same for y are finite
//  76     1     u8  metric: 0 = ErrorMetric::Samples, 1 = ErrorMetric::Continuous
//  77     1     u8  flags: bit 0 = a void mask is present (Heightfield::has_holes());
//                          bit 1 = heights are quantized (see section H); other bits 0
//  78     4     i32 height exponent eh: heights are integers times 2^eh (0 if not quantized)
//  82     4     i32 error exponent eq: error_quantum() = 2^eq, -1074 <= eq <= 1023
//  86     8     u64 VoidReport::voids
//  94     8     u64 VoidReport::filled
//  102    4     u32 collapse count C <= W * H
//  106    4     u32 dropped face count D <= 2 (W-1)(H-1)
//  110    ...   three strings, each u32 byte length (<= 16 MiB) then the bytes (no NUL):
//               Heightfield::source, Heightfield::frame, Heightfield::crs_wkt
//  ...    ...   sections, in this order (M only when flag bit 0 is set):
//               H heights, M mask, U collapse u, V collapse w, E collapse errors, F dropped faces
//  end-4  4     u32 CRC-32 (zlib crc32, polynomial 0xEDB88320) of every byte before it
//
// Section framing: u8 codec (0 = stored, 1 = zlib stream, RFC 1950), u64 raw size, u64 stored
// size, then `stored size` bytes that inflate to exactly `raw size` bytes. The writer uses
// codec 1 (libdeflate's level 6, deflate_codec.hpp; files written by zlib's deflate read the
// same) unless it does not make the section smaller. Raw contents:
//
//  H  heights, W * H values in row-major order (row 0 first), holes included.
//     Quantized (flag bit 1): every sample z = k * 2^eh with k an integer, |k| < 2^31, and z
//     never -0.0 or non-finite. Each k is predicted from its already-decoded neighbours,
//       pred = left + up - upleft   (inside the grid)
//       pred = left                 (row 0)        pred = up   (column 0)     pred = 0 (first)
//     and stored as varint(zz(k - pred)). Otherwise the samples' exact bits as 8 byte planes:
//     byte b of sample i (b = 0 least significant) is at offset b * W * H + i (8 W H bytes in
//     all; grouping sign/exponent bytes together saves 15-25 % after deflate).
//  M  void mask, W * H bits, sample i in bit (i % 8) of byte i / 8; 1 = valid, 0 = hole.
//     Unused high bits of the last byte are 0.
//  U  for each collapse c_j in performed order: varint(zz(u_j - u_{j-1})), u_{-1} = 0.
//  V  for each collapse, the offset dx = col(w) - col(u), dy = row(w) - row(u): one byte
//     zz(dx) * 16 + zz(dy) when -7 <= dx <= 7 and -8 <= dy <= 7 (always < 0xF0), otherwise
//     the byte 0xFF followed by varint(zz(dx)), varint(zz(dy)).
//  E  for each collapse: k_j = error_j / 2^eq (an exact integer, 0 <= k_j <= 2^53),
//     varint(zz(k_j - k_{j-1})), k_{-1} = 0.
//  F  dropped faces (ascending): varint(f_0), then varint(f_j - f_{j-1}).
// ============================================================================================
//
// Why this shape: SRTM heights are whole metres, so the planar predictor leaves residuals of a
// few metres (one byte, deflated further); collapses happen mostly between grid neighbours (V is
// almost always one of a dozen small pairs, so one byte per pair), and errors grow slowly along
// the sequence (E deltas are small). Deflating each stream separately lets deflate model each
// alphabet. What remains is mostly U: which vertex collapses next. Measured on the SRTM tile
// N44W072 (1201 x 1201, 1.44M vertices): H 0.50, U 1.41, V 0.49, E 0.27 bytes per vertex,
// 2.67 in all (3.85 MB).

#include "terralod/pm/pm_io.hpp"

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>

#include "terralod/pm/atomic_file.hpp"
#include "terralod/pm/byte_io.hpp"
#include "terralod/pm/deflate_codec.hpp"

namespace terralod::pm {

namespace {

constexpr std::uint8_t kMagic[8] = {'T', 'L', 'O', 'D', 'P', 'M', '\r', '\n'};
constexpr std::uint8_t kFlagMask = 1, kFlagQuantized = 2;
constexpr std::uint8_t kCodecStored = 0, kCodecZlib = 1;
// libdeflate's level 6: on N44W072's PM (terralod pm --crs native) the same bytes as zlib's
// level 6 with Z_FILTERED heights (4,069,041 against 4,069,882) written in 220 ms against 692 ms;
// level 10 is 3.5 % smaller in zlib's time, level 12 3.8 % in twice it.
constexpr int kDeflateLevel = 6;
constexpr std::size_t kFixedHeader = 110;
constexpr std::uint32_t kMaxString = 16u << 20;
// Beside kMaxDeflateRatio (deflate_codec.hpp): the zlib header and tiny streams.
constexpr std::uint64_t kInflateSlack = 1024;

// ---------------------------------------------------------------------------------- writing

/// A string: u32 byte length, then the bytes (the caller has checked the length limit).
void put_string(ByteWriter& out, const std::string& s) {
  out.u32(std::uint32_t(s.size()));
  out.raw(s.data(), s.size());
}

/// Deflates `raw` into a zlib stream (deflate_codec.hpp) at kDeflateLevel and appends the
/// section; stored when that does not make it smaller.
void put_section(ByteWriter& out, const std::vector<std::uint8_t>& raw) {
  std::vector<std::uint8_t> z;
  const std::size_t zlen = zlib_compress(raw, kDeflateLevel, z);
  const bool use_z = zlen > 0 && zlen < raw.size();
  out.u8(use_z ? kCodecZlib : kCodecStored);
  out.u64(raw.size());
  out.u64(use_z ? zlen : raw.size());
  out.raw(use_z ? std::span<const std::uint8_t>(z) : std::span<const std::uint8_t>(raw));
}

/// x * 2^e, bit for bit what std::ldexp(x, e) gives: one multiplication by 2^e where that is a
/// double (an IEEE product is the exact product correctly rounded, as ldexp's result is),
/// std::ldexp beyond. The per-sample ldexp calls were a third of decoding a block's heights.
class Pow2Scale {
 public:
  explicit Pow2Scale(int e) : e_(e), p_(e >= -1074 && e <= 1023 ? std::ldexp(1.0, e) : 0.0) {}
  double operator()(double x) const { return p_ != 0.0 ? x * p_ : std::ldexp(x, e_); }

 private:
  int e_;
  double p_;
};

/// Exponent e such that every sample is k * 2^e with k an integer, |k| < 2^31; nullopt when
/// there is none (a fractional height with many bits, -0.0, a non-finite value).
std::optional<int> height_exponent(const std::vector<double>& z) {
  int e = std::numeric_limits<int>::max();
  double max_abs = 0.0;
  for (double h : z) {
    if (!std::isfinite(h) || (h == 0.0 && std::signbit(h))) return std::nullopt;
    if (h == 0.0) continue;
    int ex = 0;
    const double f = std::frexp(std::fabs(h), &ex);  // f in [0.5, 1), exactly 53 bits
    const auto m = std::uint64_t(f * 0x1p53);
    e = std::min(e, ex - 53 + std::countr_zero(m));
    max_abs = std::max(max_abs, std::fabs(h));
  }
  if (e == std::numeric_limits<int>::max()) return 0;  // all zero
  if (!(max_abs < std::ldexp(1.0, 31 + e))) return std::nullopt;
  const Pow2Scale down(-e), up(e);
  for (double h : z)  // the exactness test, bit for bit
    if (std::bit_cast<std::uint64_t>(up(std::round(down(h)))) != std::bit_cast<std::uint64_t>(h))
      return std::nullopt;
  return e;
}

// Planar predictor shared by writer and reader: `up` is the previous row's integers, `cur`
// the current row's (valid left of `col`).
inline std::int64_t predict(const std::int64_t* up, const std::int64_t* cur, std::size_t col,
                            std::size_t row) {
  if (row == 0) return col == 0 ? 0 : cur[col - 1];
  if (col == 0) return up[0];
  return cur[col - 1] + up[col] - up[col - 1];
}

/// True when every sample's world position, and every difference of two of them, is finite:
/// the largest |x| and |y| any to_world(col, row) can reach, doubled, stay finite. (The vertex
/// hierarchy subtracts positions; an infinite one would make its radii NaN.)
bool finite_over_grid(const GridTransform& t, std::uint64_t W, std::uint64_t H) {
  const double c = double(W - 1), r = double(H - 1);
  const double mx = std::fabs(t.x0) + c * std::fabs(t.xc) + r * std::fabs(t.xr);
  const double my = std::fabs(t.y0) + c * std::fabs(t.yc) + r * std::fabs(t.yr);
  return std::isfinite(2.0 * mx) && std::isfinite(2.0 * my);
}

// ---------------------------------------------------------------------------------- reading

[[noreturn]] void fail(const std::string& name, const std::string& what) {
  throw PmFormatError(name + ": " + what);
}

/// The message of a failed read, naming what was being read.
[[noreturn]] void fail_read(const std::string& name, const ByteReadFailure& f) {
  if (f.kind == ByteReadFailure::Kind::Truncated)
    fail(name, "truncated: expected " + std::to_string(f.wanted) + " bytes of " + f.what + ", found " +
                   std::to_string(f.left));
  if (f.kind == ByteReadFailure::Kind::VarintTruncated)
    fail(name, std::string("truncated: ") + f.what + " ends inside a number");
  // VarintTooLong (the readers accept every form of a varint, VarintForm::Any).
  fail(name, std::string("corrupt ") + f.what + ": a number does not fit in 64 bits");
}

/// Bounds-checked reads over `bytes`; every read names what it was reading.
ByteReader reader(std::span<const std::uint8_t> bytes, const std::string& name) {
  return ByteReader(bytes, [&name](const ByteReadFailure& f) { fail_read(name, f); });
}

/// A string: u32 byte length (<= 16 MiB), then the bytes.
std::string get_string(ByteReader& c, const std::string& name, const char* what) {
  const std::uint32_t len = c.u32(what);
  if (len > kMaxString)
    fail(name, std::string(what) + " is " + std::to_string(len) + " bytes long (limit 16 MiB)");
  const std::span<const std::uint8_t> s = c.raw(len, what);
  return std::string(reinterpret_cast<const char*>(s.data()), s.size());
}

/// Reads one section and inflates it. `max_raw` caps the raw size the caller can accept.
std::vector<std::uint8_t> get_section(ByteReader& c, const std::string& name, const char* what,
                                      std::uint64_t max_raw) {
  const std::uint8_t codec = c.u8(what);
  const std::uint64_t raw = c.u64(what), stored = c.u64(what);
  if (codec != kCodecStored && codec != kCodecZlib)
    fail(name, std::string("unknown compression ") + std::to_string(codec) + " for " + what);
  const std::span<const std::uint8_t> src = c.raw(stored, what);
  if (raw > max_raw)
    fail(name, std::string("corrupt ") + what + ": " + std::to_string(raw) +
                   " bytes is more than the grid can need (" + std::to_string(max_raw) + ")");
  if (codec == kCodecStored ? stored != raw : raw > stored * kMaxDeflateRatio + kInflateSlack)
    fail(name, std::string("corrupt ") + what + ": " + std::to_string(stored) + " stored bytes cannot hold " +
                   std::to_string(raw) + " bytes");
  std::vector<std::uint8_t> out(raw);
  if (codec == kCodecStored) {
    std::copy(src.begin(), src.end(), out.begin());
  } else {
    if (!zlib_decompress(src, out))
      fail(name, std::string("corrupt ") + what + ": it does not inflate to the " + std::to_string(raw) +
                     " bytes the file promises");
  }
  return out;
}

}  // namespace

// ====================================================================================== write

std::vector<std::uint8_t> encode_pm(const ProgressiveMesh& pm) {
  const Heightfield& hf = pm.heightfield();
  const auto W = std::size_t(hf.width()), H = std::size_t(hf.height()), n = hf.size();
  const auto& cs = pm.collapses();

  // Error quantum: a power of two, and every error an exact multiple of it.
  int eq = 0;
  if (std::frexp(pm.error_quantum(), &eq) != 0.5)
    throw std::invalid_argument("encode_pm: error quantum " + std::to_string(pm.error_quantum()) +
                                " is not a power of two");
  eq -= 1;
  if (n > kMaxPmSamples)
    throw std::invalid_argument("encode_pm: " + std::to_string(n) +
                                " samples is more than the format allows (2^28)");
  for (std::size_t i = 0; i < n; ++i)
    if (hf.valid(i) && !std::isfinite(hf[i]))
      throw std::invalid_argument("encode_pm: height " + std::to_string(i) + " is not finite");
  for (double v :
       {hf.transform.x0, hf.transform.xc, hf.transform.xr, hf.transform.y0, hf.transform.yc, hf.transform.yr})
    if (!std::isfinite(v)) throw std::invalid_argument("encode_pm: the grid transform is not finite");
  if (!finite_over_grid(hf.transform, W, H))
    throw std::invalid_argument("encode_pm: the grid transform maps samples to non-finite world coordinates");
  if (hf.has_holes()) {
    if (hf.mask().size() != n)
      throw std::invalid_argument("encode_pm: void mask size differs from the grid size");
    for (std::uint8_t m : hf.mask())
      if (m > 1) throw std::invalid_argument("encode_pm: void mask values must be 0 or 1");
  }

  const std::optional<int> eh = height_exponent(hf.samples());
  std::uint8_t flags = 0;
  if (hf.has_holes()) flags |= kFlagMask;
  if (eh) flags |= kFlagQuantized;

  ByteWriter out;
  out.bytes.reserve(1024);
  out.raw(kMagic);
  out.u32(kPmFormatVersion);
  out.u64(0);  // file size, patched below
  out.u32(std::uint32_t(W));
  out.u32(std::uint32_t(H));
  const GridTransform& t = hf.transform;
  for (double v : {t.x0, t.xc, t.xr, t.y0, t.yc, t.yr}) out.f64(v);
  out.u8(std::uint8_t(pm.metric()));
  out.u8(flags);
  out.i32(eh.value_or(0));
  out.i32(eq);
  out.u64(hf.voids.voids);
  out.u64(hf.voids.filled);
  out.u32(std::uint32_t(cs.size()));
  out.u32(std::uint32_t(pm.dropped_faces().size()));
  for (const std::string* s : {&hf.source, &hf.frame, &hf.crs_wkt}) {
    if (s->size() > kMaxString)
      throw std::invalid_argument("encode_pm: heightfield string longer than 16 MiB");
    put_string(out, *s);
  }

  // H: heights.
  {
    ByteWriter raw;
    if (eh) {
      std::vector<std::int64_t> up(W), cur(W);
      raw.bytes.reserve(n + n / 4);
      const Pow2Scale down(-*eh);
      for (std::size_t row = 0, i = 0; row < H; ++row, up.swap(cur))
        for (std::size_t col = 0; col < W; ++col, ++i) {
          cur[col] = std::int64_t(down(hf[i]));
          raw.svarint(cur[col] - predict(up.data(), cur.data(), col, row));
        }
    } else {
      raw.bytes.resize(8 * n);
      for (std::size_t i = 0; i < n; ++i) {
        const auto bits = std::bit_cast<std::uint64_t>(hf[i]);
        for (std::size_t b = 0; b < 8; ++b) raw.bytes[b * n + i] = std::uint8_t(bits >> (8 * b));
      }
    }
    put_section(out, raw.bytes);
  }
  // M: mask bits.
  if (hf.has_holes()) {
    std::vector<std::uint8_t> bits((n + 7) / 8, 0);
    for (std::size_t i = 0; i < n; ++i)
      if (hf.mask()[i]) bits[i / 8] |= std::uint8_t(1u << (i % 8));
    put_section(out, bits);
  }
  // U, V, E: collapses.
  {
    ByteWriter u, v, e;
    u.bytes.reserve(3 * cs.size());
    v.bytes.reserve(2 * cs.size());
    e.bytes.reserve(2 * cs.size());
    std::int64_t prev_u = 0, prev_k = 0;
    const Pow2Scale to_quanta(-eq), from_quanta(eq);
    for (std::size_t j = 0; j < cs.size(); ++j) {
      const Collapse& c = cs[j];
      u.svarint(std::int64_t(c.u) - prev_u);
      prev_u = c.u;
      const std::uint64_t zx = zigzag(std::int64_t(c.w % W) - std::int64_t(c.u % W));
      const std::uint64_t zy = zigzag(std::int64_t(c.w / W) - std::int64_t(c.u / W));
      if (zx <= 14 && zy <= 15) {
        v.u8(std::uint8_t(zx << 4 | zy));
      } else {
        v.u8(0xff);
        v.varint(zx);
        v.varint(zy);
      }
      const double kd = to_quanta(c.error);
      if (!(kd >= 0.0 && kd <= 9007199254740992.0 && kd == std::floor(kd)) ||
          std::bit_cast<std::uint64_t>(from_quanta(kd)) != std::bit_cast<std::uint64_t>(c.error))
        throw std::invalid_argument("encode_pm: error of collapse " + std::to_string(j) +
                                    " is not a multiple of the error quantum");
      const auto k = std::int64_t(kd);
      e.svarint(k - prev_k);
      prev_k = k;
    }
    put_section(out, u.bytes);
    put_section(out, v.bytes);
    put_section(out, e.bytes);
  }
  // F: dropped faces.
  {
    ByteWriter f;
    std::uint32_t prev = 0;
    for (std::uint32_t face : pm.dropped_faces()) {
      f.varint(face - prev);
      prev = face;
    }
    put_section(out, f.bytes);
  }

  out.u64_at(12, out.bytes.size() + 4);
  out.u32(crc32_of(out.bytes));
  return std::move(out.bytes);
}

void write_pm(const ProgressiveMesh& pm, const std::string& path) {
  write_file_atomically(path, encode_pm(pm));
}

// ======================================================================================= read

namespace {

// What decode_pm reads before the collapses: the heightfield (heights, mask, frame, strings),
// the header fields the collapse sections are checked against, and where they begin.
struct HeightsPart {
  Heightfield hf;
  std::uint8_t metric = 0;
  std::int32_t eq = 0;
  std::uint32_t C = 0, D = 0;
  std::uint64_t n = 0, face_slots = 0;
  std::span<const std::uint8_t> rest;  // the sections after H and M, up to the checksum
};

HeightsPart decode_heights(std::span<const std::uint8_t> bytes, const std::string& name) {
  if (bytes.size() < sizeof kMagic) {
    if (bytes.empty() || !std::equal(bytes.begin(), bytes.end(), kMagic))
      fail(name, "not a terralod PM file (bad magic)");
    fail(name, "truncated: expected 8 bytes of magic, found " + std::to_string(bytes.size()));
  }
  if (!std::equal(std::begin(kMagic), std::end(kMagic), bytes.begin()))
    fail(name, "not a terralod PM file (bad magic)");
  ByteReader head = reader(bytes.subspan(sizeof kMagic), name);
  const std::uint32_t version = head.u32("header");
  if (version != kPmFormatVersion)
    fail(name, "format version " + std::to_string(version) + " is not supported (this build reads version " +
                   std::to_string(kPmFormatVersion) + ")");
  const std::uint64_t file_size = head.u64("header");
  if (file_size > bytes.size())
    fail(name, "truncated: expected " + std::to_string(file_size) +
                   " bytes (the size in the header), found " + std::to_string(bytes.size()));
  if (file_size < bytes.size())
    fail(name, std::to_string(bytes.size() - file_size) +
                   " unexpected bytes after the end of the PM (size in the header: " +
                   std::to_string(file_size) + ")");
  if (file_size < kFixedHeader + 12 + 4)
    fail(name, "truncated: " + std::to_string(file_size) + " bytes cannot hold a PM header");
  const std::size_t body = bytes.size() - 4;
  const std::uint32_t stored_crc = load_u32(bytes.data() + body);
  if (crc32_of(bytes.first(body)) != stored_crc) fail(name, "checksum mismatch (the file is corrupt)");
  // The rest of the header and the sections, which must end before the checksum.
  ByteReader c = reader(bytes.first(body).subspan(head.position() + sizeof kMagic), name);

  const std::uint32_t W = c.u32("header"), H = c.u32("header");
  if (W < 2 || H < 2 || std::uint64_t(W) * H > kMaxPmSamples)
    fail(name, "grid of " + std::to_string(W) + " x " + std::to_string(H) +
                   " samples is out of range (2 x 2 to 2^28 samples)");
  const std::uint64_t n = std::uint64_t(W) * H;
  const std::uint64_t face_slots = 2 * std::uint64_t(W - 1) * (H - 1);
  GridTransform t;
  for (double* v : {&t.x0, &t.xc, &t.xr, &t.y0, &t.yc, &t.yr}) {
    *v = c.f64("header");
    if (!std::isfinite(*v)) fail(name, "corrupt header: the grid transform is not finite");
  }
  if (!finite_over_grid(t, W, H))
    fail(name, "corrupt header: the grid transform maps samples to non-finite world coordinates");
  const std::uint8_t metric = c.u8("header"), flags = c.u8("header");
  if (metric > 1) fail(name, "unknown error metric " + std::to_string(metric));
  if (flags & ~(kFlagMask | kFlagQuantized)) fail(name, "unknown flags " + std::to_string(flags));
  const std::int32_t eh = c.i32("header"), eq = c.i32("header");
  if (eh < -1074 || eh > 1023) fail(name, "height exponent " + std::to_string(eh) + " is out of range");
  if (eq < -1074 || eq > 1023) fail(name, "error exponent " + std::to_string(eq) + " is out of range");
  VoidReport voids;
  voids.voids = std::size_t(c.u64("header"));
  voids.filled = std::size_t(c.u64("header"));
  const std::uint32_t C = c.u32("header"), D = c.u32("header");
  if (C > n) fail(name, std::to_string(C) + " collapses is more than the " + std::to_string(n) + " samples");
  if (D > face_slots) fail(name, std::to_string(D) + " dropped faces is more than the grid has");
  std::string source = get_string(c, name, "source name"), frame = get_string(c, name, "frame description"),
              crs = get_string(c, name, "CRS");

  // H: heights. Each quantized value takes at least one byte, each raw one 8.
  const bool quantized = flags & kFlagQuantized;
  const std::vector<std::uint8_t> hraw = get_section(c, name, "height data", quantized ? 10 * n : 8 * n);
  if (quantized ? hraw.size() < n : hraw.size() != 8 * n)
    fail(name, "truncated: expected " + std::string(quantized ? "at least " : "") +
                   std::to_string(quantized ? n : 8 * n) + " bytes of height data, found " +
                   std::to_string(hraw.size()));
  Heightfield hf{int(W), int(H)};
  if (quantized) {
    ByteReader h = reader(hraw, name);
    std::vector<std::int64_t> up(W), cur(W);
    constexpr std::int64_t kLim = std::int64_t(1) << 31;
    const Pow2Scale scale(eh);
    for (std::size_t row = 0, i = 0; row < H; ++row, up.swap(cur))
      for (std::size_t col = 0; col < W; ++col, ++i) {
        const std::int64_t r = h.svarint("height data");
        const std::int64_t p = predict(up.data(), cur.data(), col, row);  // |p| < 3 * 2^31
        if (r <= -4 * kLim || r >= 4 * kLim || p + r <= -kLim || p + r >= kLim)
          fail(name, "corrupt height data: sample " + std::to_string(i) + " is out of range");
        cur[col] = p + r;
        hf[i] = scale(double(cur[col]));
        if (!std::isfinite(hf[i]))
          fail(name, "corrupt height data: sample " + std::to_string(i) + " is not finite");
      }
    if (h.left() != 0) fail(name, "corrupt height data: " + std::to_string(h.left()) + " bytes left over");
  } else {  // byte planes: exactly 8 n bytes, checked above
    for (std::size_t i = 0; i < n; ++i) {
      std::uint64_t bits = 0;
      for (std::size_t b = 0; b < 8; ++b) bits |= std::uint64_t(hraw[b * n + i]) << (8 * b);
      hf[i] = std::bit_cast<double>(bits);
    }
  }
  // M: mask.
  if (flags & kFlagMask) {
    const std::vector<std::uint8_t> bits = get_section(c, name, "void mask", (n + 7) / 8);
    if (bits.size() != (n + 7) / 8)
      fail(name, "truncated: expected " + std::to_string((n + 7) / 8) + " bytes of void mask, found " +
                     std::to_string(bits.size()));
    if (n % 8 && (bits.back() >> (n % 8)) != 0) fail(name, "corrupt void mask: padding bits are set");
    std::vector<std::uint8_t> mask(n);
    for (std::size_t i = 0; i < n; ++i) mask[i] = (bits[i / 8] >> (i % 8)) & 1;
    hf.set_mask(std::move(mask));
  }
  if (!quantized)
    for (std::size_t i = 0; i < n; ++i)
      if (hf.valid(i) && !std::isfinite(hf[i]))
        fail(name, "corrupt height data: sample " + std::to_string(i) + " is not finite");
  hf.transform = t;
  hf.voids = voids;
  hf.source = std::move(source);
  hf.frame = std::move(frame);
  hf.crs_wkt = std::move(crs);
  return HeightsPart{std::move(hf), metric, eq, C, D, n, face_slots, c.rest()};
}

}  // namespace

Heightfield decode_pm_heightfield(std::span<const std::uint8_t> bytes, const std::string& name) {
  return decode_heights(bytes, name).hf;
}

ProgressiveMesh decode_pm(std::span<const std::uint8_t> bytes, const std::string& name) {
  HeightsPart part = decode_heights(bytes, name);
  Heightfield& hf = part.hf;
  const std::uint8_t metric = part.metric;
  const std::int32_t eq = part.eq;
  const Pow2Scale from_quanta(eq);
  const std::uint32_t C = part.C, D = part.D, W = std::uint32_t(hf.width()), H = std::uint32_t(hf.height());
  const std::uint64_t n = part.n, face_slots = part.face_slots;
  ByteReader c = reader(part.rest, name);

  // U, V, E: collapses. Every stream holds at least one byte per number.
  const std::vector<std::uint8_t> us = get_section(c, name, "collapse vertex data", 10 * std::uint64_t(C));
  const std::vector<std::uint8_t> vs = get_section(c, name, "collapse target data", 21 * std::uint64_t(C));
  const std::vector<std::uint8_t> es = get_section(c, name, "collapse error data", 10 * std::uint64_t(C));
  if (us.size() < C || vs.size() < C || es.size() < C)
    fail(name, "truncated: expected at least " + std::to_string(3 * std::uint64_t(C)) +
                   " bytes of collapse data, found " + std::to_string(us.size() + vs.size() + es.size()));
  std::vector<Collapse> collapses(C);
  {
    ByteReader cu = reader(us, name), cv = reader(vs, name), ce = reader(es, name);
    std::int64_t u = 0, k = 0;
    constexpr std::int64_t kMaxK = std::int64_t(1) << 53;
    for (std::uint32_t j = 0; j < C; ++j) {
      const std::int64_t du = cu.svarint("collapse vertex data");
      if (du <= -std::int64_t(n) || du >= std::int64_t(n) || u + du < 0 || u + du >= std::int64_t(n))
        fail(name, "corrupt collapse data: vertex of collapse " + std::to_string(j) + " is outside the grid");
      u += du;
      std::int64_t dx = 0, dy = 0;
      const std::uint8_t pair = cv.u8("collapse target data");
      if (pair == 0xff) {
        dx = cv.svarint("collapse target data");
        dy = cv.svarint("collapse target data");
      } else if (pair < 0xf0) {
        dx = unzigzag(pair >> 4);
        dy = unzigzag(pair & 15);
      } else {
        fail(name, "corrupt collapse data: bad target code of collapse " + std::to_string(j));
      }
      const auto Wi = std::int64_t(W), Hi = std::int64_t(H);
      const std::int64_t col = u % Wi + dx, row = u / Wi + dy;
      if (dx <= -Wi || dx >= Wi || dy <= -Hi || dy >= Hi || col < 0 || col >= Wi || row < 0 || row >= Hi)
        fail(name, "corrupt collapse data: target of collapse " + std::to_string(j) + " is outside the grid");
      const std::int64_t dk = ce.svarint("collapse error data");
      if (dk < -kMaxK || dk > kMaxK || k + dk < 0 || k + dk > kMaxK)
        fail(name, "corrupt collapse data: error of collapse " + std::to_string(j) + " is out of range");
      k += dk;
      const double err = from_quanta(double(k));
      if (!std::isfinite(err))
        fail(name, "corrupt collapse data: error of collapse " + std::to_string(j) + " overflows");
      collapses[j] = Collapse{std::uint32_t(u), std::uint32_t(row * Wi + col), err};
    }
    if (cu.left() || cv.left() || ce.left()) fail(name, "corrupt collapse data: bytes left over");
  }
  // F: dropped faces.
  const std::vector<std::uint8_t> fs = get_section(c, name, "dropped face data", 10 * std::uint64_t(D));
  if (fs.size() < D)
    fail(name, "truncated: expected at least " + std::to_string(D) + " bytes of dropped face data, found " +
                   std::to_string(fs.size()));
  std::vector<std::uint32_t> dropped(D);
  {
    ByteReader cf = reader(fs, name);
    std::uint64_t f = 0;
    for (std::uint32_t j = 0; j < D; ++j) {
      const std::uint64_t d = cf.varint("dropped face data");
      if (d >= face_slots || f + d >= face_slots)
        fail(name, "corrupt dropped face data: face outside the grid");
      f += d;
      dropped[j] = std::uint32_t(f);
    }
    if (cf.left()) fail(name, "corrupt dropped face data: bytes left over");
  }
  if (c.left() != 0) fail(name, std::to_string(c.left()) + " unexpected bytes after the last section");

  try {
    return ProgressiveMesh::from_parts(std::move(hf), ErrorMetric(metric), std::ldexp(1.0, eq),
                                       std::move(collapses), std::move(dropped));
  } catch (const std::invalid_argument& e) {
    fail(name, std::string("inconsistent contents: ") + e.what());
  }
}

ProgressiveMesh read_pm(const std::string& path) {
  // Only regular files: opening a FIFO would block, and a device may never end.
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (std::filesystem::exists(st) && !std::filesystem::is_regular_file(st))
    fail(path, "cannot read: not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, std::string("cannot open: ") + std::strerror(errno));
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) fail(path, "cannot read: not a regular file");
  in.seekg(0, std::ios::beg);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  if (!in.read(reinterpret_cast<char*>(bytes.data()), size))
    fail(path, std::string("cannot read: ") + std::strerror(errno));
  return decode_pm(bytes, path);
}

}  // namespace terralod::pm
