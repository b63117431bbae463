// Block grid geometry, block summaries (stand-in surfaces made by the approximation tree's node
// strategies, their blob format) and the active region (paper section 4.1-4.2, Eq. 2); see
// active_region.hpp.
#include "terralod/blocks/active_region.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "terralod/blocks/node_strategy.hpp"
#include "terralod/pm/byte_io.hpp"
#include "terralod/pm/linf_error.hpp"
#include "tin_error.hpp"

namespace terralod::blocks {

BlockGrid::BlockGrid(int grid_width, int grid_height, int block_size, const pm::GridTransform& transform)
    : w_(grid_width), h_(grid_height), b_(block_size), t_(transform) {
  if (grid_width < 2 || grid_height < 2)
    throw std::invalid_argument("BlockGrid: terrain needs at least 2 x 2 samples, not " +
                                std::to_string(grid_width) + " x " + std::to_string(grid_height));
  if (block_size < 3)
    throw std::invalid_argument("BlockGrid: block_size must be >= 3, not " + std::to_string(block_size));
  if (!(transform.determinant() != 0.0) || !std::isfinite(transform.determinant()))
    throw std::invalid_argument("BlockGrid: the grid transform is singular");
  // ceil((w - 1) / (b - 1)) in 64 bits: w - 1 + b - 2 overflows an int near INT_MAX.
  cols_ = int((std::int64_t(w_) - 1 + b_ - 2) / (b_ - 1));
  rows_ = int((std::int64_t(h_) - 1 + b_ - 2) / (b_ - 1));
}

BlockGrid BlockGrid::from_info(const DatabaseInfo& info) {
  if (info.block_size == 0) throw std::invalid_argument("the database is not blocked (block_size 0)");
  return BlockGrid(info.grid_width, info.grid_height, info.block_size, info.transform);
}

SampleRect BlockGrid::domain(BlockKey k) const {
  assert(contains(k));
  SampleRect r;
  r.col0 = k.col * (b_ - 1);
  r.row0 = k.row * (b_ - 1);
  r.col1 = std::min(r.col0 + b_ - 1, w_ - 1);
  r.row1 = std::min(r.row0 + b_ - 1, h_ - 1);
  return r;
}

double BlockGrid::block_extent_m() const { return (b_ - 1) * std::min(t_.spacing_x(), t_.spacing_y()); }

std::pair<double, double> BlockGrid::to_grid(double x, double y) const {
  const double det = t_.determinant();
  const double dx = x - t_.x0, dy = y - t_.y0;
  return {(t_.yr * dx - t_.xr * dy) / det, (-t_.yc * dx + t_.xc * dy) / det};
}

BlockKey BlockGrid::block_at(double x, double y) const {
  const auto [col, row] = to_grid(x, y);
  auto clampi = [](double v, int hi) {
    if (!(v >= 0)) return 0;  // NaN too
    if (v >= hi) return hi - 1;
    return int(v);
  };
  return {clampi(std::floor(col / (b_ - 1)), cols_), clampi(std::floor(row / (b_ - 1)), rows_)};
}

pm::Vec3 BlockGrid::world(int col, int row, double z) const {
  const auto [x, y] = t_.to_world(col, row);
  return {x, y, z};
}

const char* standin_kind_name(StandinKind k) {
  switch (k) {
    case StandinKind::TwoTriangles:
      return "two-triangle";
    case StandinKind::Grid:
      return "grid";
    case StandinKind::Tin:
      return "tin";
    case StandinKind::NonRegularGrid:
      return "nonregular";
  }
  return "unknown";
}

StandinKind parse_standin_kind(const std::string& name) {
  for (StandinKind k :
       {StandinKind::TwoTriangles, StandinKind::Grid, StandinKind::Tin, StandinKind::NonRegularGrid})
    if (name == standin_kind_name(k)) return k;
  throw std::invalid_argument("unknown stand-in '" + name + "' (tin, grid, nonregular or two-triangle)");
}

void set_two_triangle_standin(BlockSummary& s, int width, int height) {
  assert(width >= 2 && height >= 2);
  s.standin = StandinKind::TwoTriangles;
  s.standin_error = s.tm_error;
  s.points = {{0, 0, s.z00}, {width - 1, 0, s.z10}, {0, height - 1, s.z01}, {width - 1, height - 1, s.z11}};
  s.triangles = {{0, 1, 3}, {0, 3, 2}};  // split along (0,0)-(w-1,h-1), CCW in (col,row)
  s.triangle_errors = {s.tm_error, s.tm_error};
}

namespace {

/// The smallest float >= e (as a double): per-triangle errors are stored as f32.
double round_up_to_float(double e) {
  float f = static_cast<float>(e);
  if (double(f) < e) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return double(f);
}

/// The stand-in surface of a complete block heightfield (its own local grid) by `o`.
void make_standin(const pm::Heightfield& hf, const StandinOptions& o, BlockSummary& s) {
  assert(o.max_points >= 4);
  const int w = hf.width(), h = hf.height();
  std::unique_ptr<NodeStrategy> strategy;
  switch (o.kind) {
    case StandinKind::TwoTriangles:
      break;
    case StandinKind::Grid: {
      int p = 1;
      while (std::size_t(p + 2) * std::size_t(p + 2) <= o.max_points) ++p;
      strategy = make_grid_strategy(p);
      break;
    }
    case StandinKind::Tin:
      strategy = make_tin_strategy(o.max_points, o.metric);
      break;
    case StandinKind::NonRegularGrid:
      strategy = make_nonregular_strategy(o.max_points, o.metric);
      break;
  }
  if (strategy) {
    const NodeSurface n = strategy->approximate(hf, SampleRect{0, 0, w - 1, h - 1});
    s.standin = o.kind;
    s.points.clear();
    for (const auto& p : n.points) s.points.push_back({int(p[0]), int(p[1]), p[2]});
    s.triangles = n.triangles;
  } else {
    set_two_triangle_standin(s, w, h);
  }
  const pm::LInfError err(hf, o.metric);
  s.standin_error = 0;
  s.triangle_errors.clear();
  for (const auto& t : s.triangles) {
    const StandinPoint &a = s.points[t[0]], &b = s.points[t[1]], &c = s.points[t[2]];
    const double e =
        detail::triangle_error(err, hf, o.metric, {a.col, a.row}, {b.col, b.row}, {c.col, c.row});
    s.standin_error = std::max(s.standin_error, e);
    s.triangle_errors.push_back(round_up_to_float(e));
  }
}

}  // namespace

BlockSummary summarize_block(const pm::ProgressiveMesh& pm, BlockKey /*k*/, const StandinOptions& standin) {
  const pm::Heightfield& hf = pm.heightfield();
  const int w = hf.width(), h = hf.height();
  BlockSummary s;
  // Heights of the existing samples only: holes (the warped edges of a DEM, kept voids) take no
  // part in the range or in any error, and a block without any sample has no stand-in.
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i)) lo = std::min(lo, hf[i]), hi = std::max(hi, hf[i]);
  if (lo > hi) {
    s.empty = true;
    return s;
  }
  s.z00 = hf.at(0, 0);
  s.z10 = hf.at(w - 1, 0);
  s.z01 = hf.at(0, h - 1);
  s.z11 = hf.at(w - 1, h - 1);
  const pm::LInfError err(hf, pm::ErrorMetric::Continuous);
  s.tm_error = std::max(
      detail::triangle_error(err, hf, pm::ErrorMetric::Continuous, {0, 0}, {w - 1, 0}, {w - 1, h - 1}),
      detail::triangle_error(err, hf, pm::ErrorMetric::Continuous, {0, 0}, {w - 1, h - 1}, {0, h - 1}));
  const pm::TriangleMesh base = pm.extract_after(pm.vsplit_count());
  if (base.triangles.size() == 2) {
    const std::uint32_t c00 = 0, c10 = std::uint32_t(w - 1), c01 = std::uint32_t((h - 1) * w),
                        c11 = c01 + c10;
    auto sorted = [&](const std::array<std::uint32_t, 3>& t) {
      std::array<std::uint32_t, 3> v{base.vertices[t[0]], base.vertices[t[1]], base.vertices[t[2]]};
      std::sort(v.begin(), v.end());
      return v;
    };
    std::array<std::uint32_t, 3> a{c00, c10, c11}, b{c00, c01, c11};
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    const auto t0 = sorted(base.triangles[0]), t1 = sorted(base.triangles[1]);
    s.base_is_tm = (t0 == a && t1 == b) || (t0 == b && t1 == a);
  }
  make_standin(hf, standin, s);
  // The range holds the existing samples and the stand-in's points (a corner may be a hole).
  s.zmin = lo, s.zmax = hi;
  for (const StandinPoint& p : s.points) s.zmin = std::min(s.zmin, p.z), s.zmax = std::max(s.zmax, p.z);
  return s;
}

namespace {

constexpr std::size_t kRecordV1 = 7 * 8 + 8;

using pm::load_f32;
using pm::load_f64;
using pm::load_u16;
using pm::load_u32;

std::uint32_t crc(const std::uint8_t* p, std::size_t n) { return pm::crc32_of({p, n}); }

}  // namespace

// The "block_summaries" blob, format version 2. All numbers little-endian; f64 = IEEE-754
// binary64, u16/u32 unsigned.
//   header, 16 bytes:
//     0  u32 magic 0x53424C54 ("TLBS" in memory)
//     4  u32 version = 2
//     8  u32 cols   (BlockGrid::cols())
//    12  u32 rows   (BlockGrid::rows())
//   then one record per block in BlockGrid::index order (row * cols + col), variable size:
//     0  f64 zmin              height range of the block's samples, metres
//     8  f64 zmax
//    16  f64 tm_error          exact error of the two-triangle mesh (continuous metric), metres
//    24  f64 standin_error     exact error of the stand-in surface, metres
//    32  u8  kind              StandinKind: 0 two-triangle, 1 grid, 2 tin, 3 nonregular
//    33  u8  flags             bit 0: base_is_tm; bit 1: empty (the block has no valid sample:
//                              every field then 0, n = m = 0, no stand-in follows); bits 2-7 zero
//    34  u16 n                 stand-in points, 4..65535
//    36  u16 m                 stand-in triangles, 1..65535
//    38  u16 reserved = 0
//    40  n x 12 bytes          points: u16 col, u16 row (block-local sample), f64 z (the sample's
//                              height, bit for bit); the 4 block corners must be among them and
//                              give z00, z10, z01, z11
//    40 + 12 n                 m x 3 vertex indices, CCW in (col,row): u8 each when n <= 256,
//                              else u16 each (so 3 or 6 bytes per triangle); their areas sum to
//                              the block's
//    40 + 12 n + 3m (or 6m)    m x f32 per-triangle error, metres, rounded up to a float (so
//                              their max >= standin_error, which is exact)
//   trailer: u32 CRC-32 (zlib) of every byte before it.
// A two-triangle block at v2 takes 40 + 48 + 6 + 8 = 102 bytes; an n-point TIN 40 + 12 n + 7 m
// (m ~ 2 n).
// Version 1 (still decoded): the same header with version 1, then per block 64 bytes:
// 7 x f64 (z00 z10 z01 z11 zmin zmax tm_error), u8 base_is_tm, 7 zero bytes; then the CRC.
namespace {

void check_summary_grid(const BlockGrid& grid) {
  if (grid.block_size() > 65537)
    throw std::invalid_argument("block_summaries: stand-in coordinates need block_size <= 65537, not " +
                                std::to_string(grid.block_size()));
}

void write_header(pm::ByteWriter& o, const BlockGrid& grid) {
  o.u32(kBlockSummariesMagic);
  o.u32(kBlockSummariesVersion);
  o.u32(std::uint32_t(grid.cols()));
  o.u32(std::uint32_t(grid.rows()));
}

void write_record(pm::ByteWriter& o, const BlockSummary& b) {
  if (b.empty) {  // 40 bytes: no range, no errors, no stand-in
    for (int i = 0; i < 4; ++i) o.f64(0.0);
    o.u8(0);
    o.u8(2);
    o.u16(0), o.u16(0), o.u16(0);
    return;
  }
  assert(b.points.size() >= 4 && !b.triangles.empty());
  if (b.points.size() > 65535 || b.triangles.size() > 65535)
    throw std::invalid_argument("block_summaries: a stand-in has more than 65535 points or triangles");
  for (double d : {b.zmin, b.zmax, b.tm_error, b.standin_error}) o.f64(d);
  o.u8(std::uint8_t(b.standin));
  o.u8(b.base_is_tm ? 1 : 0);
  o.u16(std::uint16_t(b.points.size()));
  o.u16(std::uint16_t(b.triangles.size()));
  o.u16(0);
  for (const StandinPoint& p : b.points) {
    o.u16(std::uint16_t(p.col));
    o.u16(std::uint16_t(p.row));
    o.f64(p.z);
  }
  const bool small = b.points.size() <= 256;
  for (const auto& t : b.triangles)
    for (std::uint32_t v : t) small ? o.u8(std::uint8_t(v)) : o.u16(std::uint16_t(v));
  assert(b.triangle_errors.size() == b.triangles.size());
  for (double e : b.triangle_errors) {
    const float f = static_cast<float>(e);
    assert(double(f) == e);  // rounded up to a float when computed
    o.f32(f);
  }
}

}  // namespace

std::vector<std::uint8_t> encode_block_summaries(const BlockGrid& grid, std::span<const BlockSummary> s) {
  assert(s.size() == grid.block_count());
  check_summary_grid(grid);
  pm::ByteWriter o;
  o.bytes.reserve(16 + s.size() * 600 + 4);
  write_header(o, grid);
  for (const BlockSummary& b : s) write_record(o, b);
  o.u32(crc(o.bytes.data(), o.bytes.size()));
  return std::move(o.bytes);
}

std::vector<std::uint8_t> encode_block_summary_record(const BlockSummary& s) {
  pm::ByteWriter o;
  // Its exact size: a build may hold 10^5 of them.
  const std::size_t n = s.points.size(), m = s.triangles.size();
  o.bytes.reserve(s.empty ? 40 : 40 + 12 * n + (n <= 256 ? 3 : 6) * m + 4 * m);
  write_record(o, s);
  assert(o.bytes.size() == o.bytes.capacity());
  return std::move(o.bytes);
}

void join_block_summary_records(const BlockGrid& grid,
                                const std::function<std::vector<std::uint8_t>(std::size_t)>& record,
                                const std::function<void(std::span<const std::uint8_t>)>& write) {
  check_summary_grid(grid);
  pm::ByteWriter o;
  write_header(o, grid);
  std::uint32_t c = pm::crc32_of(o.bytes);
  write(o.bytes);
  for (std::size_t i = 0; i < grid.block_count(); ++i) {
    const std::vector<std::uint8_t> r = record(i);
    if (r.size() < 40)
      throw std::invalid_argument("block_summaries: block record " + std::to_string(i) + " has " +
                                  std::to_string(r.size()) + " bytes (at least 40)");
    c = pm::crc32_of(r, c);
    write(r);
  }
  o.bytes.clear();
  o.u32(c);
  write(o.bytes);
}

namespace {

// Decodes record i (format `version`) at p into b, records ending at `end`; returns the byte
// after it. Throws DatabaseError naming the blob and the record.
const std::uint8_t* decode_record(const BlockGrid& grid, std::uint32_t version, std::size_t i,
                                  const std::uint8_t* p, const std::uint8_t* const end,
                                  const std::string& name_for_errors, BlockSummary& b) {
  auto fail = [&](const std::string& what) {
    throw DatabaseError(name_for_errors, std::string(kBlockSummariesBlob) + ": " + what);
  };
  const SampleRect d = grid.domain(grid.key(i));
  const int w = d.width(), h = d.height();
  auto bad = [&](const std::string& what) { fail("block record " + std::to_string(i) + ": " + what); };
  if (version == 1) {
    b.z00 = load_f64(p);
    b.z10 = load_f64(p + 8);
    b.z01 = load_f64(p + 16);
    b.z11 = load_f64(p + 24);
    b.zmin = load_f64(p + 32);
    b.zmax = load_f64(p + 40);
    b.tm_error = load_f64(p + 48);
    b.base_is_tm = p[56] != 0;
    if (!(b.zmin <= b.zmax) || !(b.tm_error >= 0) ||
        !std::isfinite(b.zmax - b.zmin + b.tm_error + b.z00 + b.z10 + b.z01 + b.z11))
      fail("block record " + std::to_string(i) + " is inconsistent");
    for (double z : {b.z00, b.z10, b.z01, b.z11})  // corners are samples: inside the height range
      if (!(z >= b.zmin && z <= b.zmax))
        fail("block record " + std::to_string(i) + ": a corner outside zmin..zmax");
    set_two_triangle_standin(b, w, h);
    p += kRecordV1;
    return p;
  }
  if (end - p < 40) bad("truncated");
  b.zmin = load_f64(p);
  b.zmax = load_f64(p + 8);
  b.tm_error = load_f64(p + 16);
  b.standin_error = load_f64(p + 24);
  const std::uint8_t kind = p[32], flags = p[33];
  const std::uint32_t n = load_u16(p + 34), m = load_u16(p + 36);
  if (kind > 3 || flags > 2 || load_u16(p + 38) != 0) bad("bad kind or flags");
  if (flags == 2) {  // empty: a block without any valid sample
    if (kind != 0 || n != 0 || m != 0 || b.zmin != 0 || b.zmax != 0 || b.tm_error != 0 ||
        b.standin_error != 0)
      bad("an empty block with a stand-in or heights");
    b.empty = true;
    p += 40;
    return p;
  }
  if (!(b.zmin <= b.zmax) || !(b.tm_error >= 0) || !(b.standin_error >= 0) ||
      !std::isfinite(b.zmax - b.zmin + b.tm_error + b.standin_error))
    bad("inconsistent heights or errors");
  b.standin = StandinKind(kind);
  b.base_is_tm = flags != 0;
  const std::size_t isize = n <= 256 ? 1 : 2;
  if (n < 4 || m < 1 || std::size_t(end - p) < 40 + 12 * std::size_t(n) + (3 * isize + 4) * m)
    bad("truncated stand-in");
  p += 40;
  unsigned corners = 0;
  b.points.resize(n);
  for (StandinPoint& q : b.points) {
    q.col = int(load_u16(p));
    q.row = int(load_u16(p + 2));
    q.z = load_f64(p + 4);
    if (q.col >= w || q.row >= h || !(q.z >= b.zmin && q.z <= b.zmax))
      bad("stand-in point outside the block");
    const bool c0 = q.col == 0, c1 = q.col == w - 1, r0 = q.row == 0, r1 = q.row == h - 1;
    if ((c0 || c1) && (r0 || r1)) {
      (c0 ? (r0 ? b.z00 : b.z01) : (r0 ? b.z10 : b.z11)) = q.z;
      corners |= 1u << ((c0 ? 0 : 1) + (r0 ? 0 : 2));
    }
    p += 12;
  }
  if (corners != 15) bad("the stand-in lacks a block corner");
  b.triangles.resize(m);
  std::int64_t area2 = 0;
  for (auto& t : b.triangles) {
    for (std::uint32_t& v : t) {
      v = isize == 1 ? p[0] : load_u16(p);
      p += isize;
      if (v >= n) bad("stand-in triangle index out of range");
    }
    const StandinPoint &a = b.points[t[0]], &e = b.points[t[1]], &c = b.points[t[2]];
    const std::int64_t o =
        std::int64_t(e.col - a.col) * (c.row - a.row) - std::int64_t(e.row - a.row) * (c.col - a.col);
    if (o <= 0) bad("stand-in triangle not counter-clockwise");
    area2 += o;
  }
  if (area2 != 2 * std::int64_t(w - 1) * (h - 1)) bad("stand-in triangles do not cover the block");
  b.triangle_errors.resize(m);
  double emax = 0;
  for (double& e : b.triangle_errors) {
    e = double(load_f32(p));
    p += 4;
    if (!(e >= 0) || !std::isfinite(e)) bad("bad stand-in triangle error");
    emax = std::max(emax, e);
  }
  if (!(emax >= b.standin_error)) bad("stand-in triangle errors below the stand-in's error");
  return p;
}

}  // namespace

std::size_t block_summary_record_bytes(std::span<const std::uint8_t, kBlockSummaryRecordHeader> header) {
  const std::uint8_t* p = header.data();
  const std::uint8_t kind = p[32], flags = p[33];
  const std::size_t n = load_u16(p + 34), m = load_u16(p + 36);
  if (kind > 3 || flags > 2 || load_u16(p + 38) != 0) return 0;
  if (flags == 2) return 40;
  if (n < 4 || m < 1) return 0;
  return 40 + 12 * n + (3 * (n <= 256 ? 1 : 2) + 4) * m;
}

std::uint32_t check_block_summaries_header(const BlockGrid& grid, std::span<const std::uint8_t> head,
                                           std::uint64_t blob_size, const std::string& name_for_errors) {
  auto fail = [&](const std::string& what) {
    throw DatabaseError(name_for_errors, std::string(kBlockSummariesBlob) + ": " + what);
  };
  if (blob_size < kBlockSummariesFraming || head.size() < kBlockSummariesHeader)
    fail("truncated (" + std::to_string(blob_size) + " bytes)");
  const std::uint8_t* p = head.data();
  if (load_u32(p) != kBlockSummariesMagic) fail("bad magic");
  const std::uint32_t version = load_u32(p + 4);
  if (version != 1 && version != kBlockSummariesVersion)
    fail("unsupported version " + std::to_string(version));
  if (load_u32(p + 8) != std::uint32_t(grid.cols()) || load_u32(p + 12) != std::uint32_t(grid.rows()))
    fail("block grid " + std::to_string(load_u32(p + 8)) + " x " + std::to_string(load_u32(p + 12)) +
         " does not match the database's " + std::to_string(grid.cols()) + " x " +
         std::to_string(grid.rows()));
  // The blob's size against the grid's, before anything is allocated for its blocks: version 1
  // records are 64 bytes; a version 2 record takes at least its header (an empty block's record
  // is no more).
  if (version == 1 && blob_size != 16 + grid.block_count() * kRecordV1 + 4)
    fail("size " + std::to_string(blob_size) + " bytes, expected " +
         std::to_string(16 + grid.block_count() * kRecordV1 + 4));
  if (version == 2 && (blob_size - kBlockSummariesFraming) / kBlockSummaryRecordHeader < grid.block_count())
    fail("size " + std::to_string(blob_size) + " bytes, too small for " + std::to_string(grid.block_count()) +
         " block records");
  return version;
}

BlockSummary decode_block_summary_record(const BlockGrid& grid, std::size_t index,
                                         std::span<const std::uint8_t> record,
                                         const std::string& name_for_errors) {
  if (index >= grid.block_count())
    throw DatabaseError(name_for_errors, std::string(kBlockSummariesBlob) + ": block record " +
                                             std::to_string(index) + " is not a block of the grid");
  BlockSummary b;
  const std::uint8_t* const end = record.data() + record.size();
  if (decode_record(grid, kBlockSummariesVersion, index, record.data(), end, name_for_errors, b) != end)
    throw DatabaseError(name_for_errors, std::string(kBlockSummariesBlob) + ": block record " +
                                             std::to_string(index) + " has bytes after its end");
  return b;
}

void for_each_block_summary(const BlockGrid& grid, std::span<const std::uint8_t> bytes,
                            const std::string& name_for_errors,
                            const std::function<void(std::size_t, BlockSummary&&)>& visit) {
  auto fail = [&](const std::string& what) {
    throw DatabaseError(name_for_errors, std::string(kBlockSummariesBlob) + ": " + what);
  };
  const std::uint32_t version = check_block_summaries_header(grid, bytes, bytes.size(), name_for_errors);
  if (crc(bytes.data(), bytes.size() - 4) != load_u32(bytes.data() + bytes.size() - 4))
    fail("checksum mismatch");
  const std::uint8_t* p = bytes.data() + 16;
  const std::uint8_t* const end = bytes.data() + bytes.size() - 4;
  for (std::size_t i = 0; i < grid.block_count(); ++i) {
    BlockSummary b;
    p = decode_record(grid, version, i, p, end, name_for_errors, b);
    visit(i, std::move(b));
  }
  if (p != end)
    fail("size " + std::to_string(bytes.size()) + " bytes, expected " + std::to_string(p - bytes.data() + 4));
}

std::vector<BlockSummary> decode_block_summaries(const BlockGrid& grid, std::span<const std::uint8_t> bytes,
                                                 const std::string& name_for_errors) {
  // Allocated at the first record, after the blob's size is checked against the grid's (a
  // corrupt header must not allocate a huge grid's summaries).
  std::vector<BlockSummary> out;
  for_each_block_summary(grid, bytes, name_for_errors, [&](std::size_t i, BlockSummary&& b) {
    if (out.empty()) out.resize(grid.block_count());
    out[i] = std::move(b);
  });
  return out;
}

double tm_height(const BlockGrid& grid, BlockKey k, const BlockSummary& s, double col, double row) {
  const SampleRect d = grid.domain(k);
  const double u = (col - d.col0) / (d.col1 - d.col0), v = (row - d.row0) / (d.row1 - d.row0);
  // Lower triangle (0,0),(1,0),(1,1) where u >= v; upper (0,0),(1,1),(0,1) otherwise.
  if (u >= v) return s.z00 + u * (s.z10 - s.z00) + v * (s.z11 - s.z10);
  return s.z00 + v * (s.z01 - s.z00) + u * (s.z11 - s.z01);
}

double standin_height(const BlockSummary& s, double col, double row) {
  assert(!s.triangles.empty());
  double best = 0, best_out = -1e300;
  for (const auto& t : s.triangles) {
    const StandinPoint &a = s.points[t[0]], &b = s.points[t[1]], &c = s.points[t[2]];
    const double det = double(b.col - a.col) * (c.row - a.row) - double(b.row - a.row) * (c.col - a.col);
    const double l1 = ((col - a.col) * (c.row - a.row) - (row - a.row) * (c.col - a.col)) / det;
    const double l2 = ((b.col - a.col) * (row - a.row) - (b.row - a.row) * (col - a.col)) / det;
    const double l0 = 1 - l1 - l2;
    const double inside = std::min({l0, l1, l2});
    const double z = l0 * a.z + l1 * b.z + l2 * c.z;
    if (inside >= 0) return z;
    if (inside > best_out) best_out = inside, best = z;  // rounding at an edge: the nearest triangle
  }
  return best;
}

double standin_bound_px(const BlockGrid& grid, BlockKey k, const BlockSummary& s, const pm::View& view) {
  assert(s.triangle_errors.size() == s.triangles.size());
  const SampleRect d = grid.domain(k);
  double bound = 0;
  for (std::size_t i = 0; i < s.triangles.size(); ++i) {
    const double e = s.triangle_errors[i];
    pm::Box b{{1e300, 1e300, 1e300}, {-1e300, -1e300, -1e300}};
    for (std::uint32_t v : s.triangles[i]) {
      const StandinPoint& q = s.points[v];
      const pm::Vec3 w = grid.world(d.col0 + q.col, d.row0 + q.row, q.z);
      b.lo = {std::min(b.lo.x, w.x), std::min(b.lo.y, w.y), std::min(b.lo.z, w.z - e)};
      b.hi = {std::max(b.hi.x, w.x), std::max(b.hi.y, w.y), std::max(b.hi.z, w.z + e)};
    }
    if (!view.outside(b)) bound = std::max(bound, view.vertical_error_px(b, e));
  }
  return bound;
}

pm::Box block_box(const BlockGrid& grid, BlockKey k, const BlockSummary& s) {
  const SampleRect d = grid.domain(k);
  pm::Box b{{1e300, 1e300, s.zmin}, {-1e300, -1e300, s.zmax}};
  for (auto [c, r] : {std::pair{d.col0, d.row0}, {d.col1, d.row0}, {d.col0, d.row1}, {d.col1, d.row1}}) {
    const pm::Vec3 p = grid.world(c, r, 0);
    b.lo.x = std::min(b.lo.x, p.x);
    b.lo.y = std::min(b.lo.y, p.y);
    b.hi.x = std::max(b.hi.x, p.x);
    b.hi.y = std::max(b.hi.y, p.y);
  }
  return b;
}

bool ActiveRegion::is_inner(BlockKey k) const { return std::binary_search(inner.begin(), inner.end(), k); }
bool ActiveRegion::is_active(BlockKey k) const {
  return k.col >= col0 && k.col <= col1 && k.row >= row0 && k.row <= row1;
}

int inner_radius(double height_m, double block_extent_m, const ActiveRegionOptions& opt) {
  assert(opt.theta_deg > 0 && opt.theta_deg < 90 && opt.n_min >= 0 && opt.n_min <= opt.n_max &&
         block_extent_m > 0);
  const double b = std::max(height_m, 0.0) / std::tan(opt.theta_deg * M_PI / 180.0);
  // 1e-9 absorbs the rounding of cot (cot 45 deg is not exactly 1 in doubles).
  const double n = std::ceil(b / block_extent_m - 1e-9);
  if (!(n < opt.n_max)) return opt.n_max;  // also NaN
  return std::max(opt.n_min, int(n));
}

ActiveRegion active_region(const BlockGrid& grid, std::span<const BlockSummary> summaries,
                           const pm::Vec3& eye, const ActiveRegionOptions& opt) {
  assert(summaries.size() == grid.block_count() && opt.p >= 0);
  ActiveRegion r;
  r.centre = grid.block_at(eye.x, eye.y);
  const SampleRect d = grid.domain(r.centre);
  auto [col, row] = grid.to_grid(eye.x, eye.y);
  col = std::clamp(col, double(d.col0), double(d.col1));
  row = std::clamp(row, double(d.row0), double(d.row1));
  const double ground = tm_height(grid, r.centre, summaries[grid.index(r.centre)], col, row);
  r.height_m = std::max(0.0, eye.z - ground);
  r.visible_m = r.height_m / std::tan(opt.theta_deg * M_PI / 180.0);
  r.n = inner_radius(r.height_m, grid.block_extent_m(), opt);
  r.p = opt.p;
  const int reach = r.n + r.p;
  r.col0 = std::max(0, r.centre.col - reach);
  r.col1 = std::min(grid.cols() - 1, r.centre.col + reach);
  r.row0 = std::max(0, r.centre.row - reach);
  r.row1 = std::min(grid.rows() - 1, r.centre.row + reach);
  for (int c = r.col0; c <= r.col1; ++c)
    for (int w = r.row0; w <= r.row1; ++w) {
      const bool inner = std::abs(c - r.centre.col) <= r.n && std::abs(w - r.centre.row) <= r.n;
      (inner ? r.inner : r.outer).push_back({c, w});
    }
  // (col, row) loops produce BlockKey order already (operator<=> compares col, then row).
  return r;
}

}  // namespace terralod::blocks
