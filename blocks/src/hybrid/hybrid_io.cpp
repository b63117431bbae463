// Serialisation of the hybrid grid + TIN model (the "hybrid" blob of a hybrid.db).
//
// Format version 1, little-endian, every count checked against the remaining bytes on read:
//   off  size  field
//   0    8     magic "TLHYBRID"
//   8    4     u32 format version (1)
//   12   16    i32 grid_step, i32 levels, i32 domain_width, i32 domain_height (samples)
//   28   8+8n  u64 n, f64 grid node heights (finest level, row-major, domain/step + 1 per row)
//   ..   8+24n u64 n, TIN vertices: i64 x, i64 y (1/65536 sample), f64 z (metres)
//   ..   8+12n u64 n, TIN triangles: 3 x u32 vertex ids, CCW in (col,row)
//   ..   8+4n  u64 n, ring_begin: u32 TB offsets (rings + 1 entries)
//   ..   8+8n  u64 n, TB array: u32 vertex id, then n x u32 connectivity
//   then per level:
//         12   i32 cells_x, cells_y, cell_size
//         8+.. u64 number of codes, GC bitstream: 0 = NC, 10 = CC, 11 = PC, MSB first, row order
//         8    u64 number of PC cells; per PC cell: u32 cell, u32 sections, per section:
//              u32 A, u32 L, u8 C, u8 I, u8 closes
//         8+.. u64 number of codes, sub-cell tree bitstream (same code), then (PC cells + 1) x u32
//              offsets (in codes) of each PC cell's tree
//   end-4 4    u32 CRC-32 (zlib, polynomial 0xEDB88320) of every byte before it

#include <cstring>
#include <string>

#include "hybrid_internal.hpp"
#include "terralod/pm/byte_io.hpp"

namespace terralod::blocks::hybrid {

namespace {

constexpr std::uint8_t kMagic[8] = {'T', 'L', 'H', 'Y', 'B', 'R', 'I', 'D'};
constexpr std::uint32_t kVersion = 1;

[[noreturn]] void fail(const std::string& what, const std::string& why) {
  throw HybridError(what + ": hybrid blob: " + why);
}

/// A code list: u64 count, then the codes as bits, MSB first, zero-padded to a byte.
void put_codes(pm::ByteWriter& w, const std::vector<CellClass>& c) {
  w.u64(c.size());
  std::uint8_t cur = 0;
  int nbits = 0;
  auto bit = [&](int v) {
    cur = std::uint8_t(cur | (v << (7 - nbits)));
    if (++nbits == 8) w.u8(cur), cur = 0, nbits = 0;
  };
  for (CellClass k : c) {
    if (k == CellClass::NC)
      bit(0);
    else
      bit(1), bit(k == CellClass::PC ? 1 : 0);
  }
  if (nbits) w.u8(cur);
}

/// The blob's reads; every error names the blob.
struct Reader : pm::ByteReader {
  const std::string& what;
  Reader(std::span<const std::uint8_t> bytes, const std::string& blob_what)
      : pm::ByteReader(bytes,
                       [&blob_what](const pm::ByteReadFailure& f) {
                         hybrid::fail(blob_what, "truncated at byte " + std::to_string(f.position));
                       }),
        what(blob_what) {}
  [[noreturn]] void fail(const std::string& why) const { hybrid::fail(what, why); }
  std::size_t count(std::size_t item_size) {
    const std::uint64_t n = u64();
    if (item_size && n > left() / item_size) fail("count " + std::to_string(n) + " exceeds the blob");
    return std::size_t(n);
  }
  std::vector<CellClass> codes() {
    const std::uint64_t n = u64();
    if (n > left() * 8) fail("code list exceeds the blob");
    std::vector<CellClass> out;
    out.reserve(n);
    const std::span<const std::uint8_t> b = rest();
    std::size_t bitpos = 0;
    auto bit = [&]() -> int {
      if (bitpos / 8 >= b.size()) fail("code list truncated");
      const int v = (b[bitpos / 8] >> (7 - bitpos % 8)) & 1;
      ++bitpos;
      return v;
    };
    for (std::uint64_t i = 0; i < n; ++i) {
      if (bit() == 0)
        out.push_back(CellClass::NC);
      else
        out.push_back(bit() ? CellClass::PC : CellClass::CC);
    }
    raw((bitpos + 7) / 8);
    return out;
  }
};

}  // namespace

std::vector<std::uint8_t> HybridTerrain::encode() const {
  pm::ByteWriter w;
  w.bytes.reserve(4096);  // (also keeps GCC 12's -Wstringop-overflow false positive away in sanitizer builds)
  w.raw(kMagic);
  w.u32(kVersion);
  w.i32(step_);
  w.i32(levels());
  w.i32(domain_w_);
  w.i32(domain_h_);
  w.u64(grid_z_.size());
  for (double z : grid_z_) w.f64(z);
  w.u64(vertices_.size());
  for (const Vertex& v : vertices_) w.i64(v.x), w.i64(v.y), w.f64(v.z);
  w.u64(tin_.size());
  for (const auto& t : tin_) w.u32(t[0]), w.u32(t[1]), w.u32(t[2]);
  w.u64(ring_begin_.size());
  for (std::uint32_t r : ring_begin_) w.u32(r);
  w.u64(tb_.size());
  for (std::uint32_t t : tb_) w.u32(t);
  for (std::uint32_t c : conn_) w.u32(c);
  for (const LevelEncoding& e : levels_) {
    w.i32(e.cells_x);
    w.i32(e.cells_y);
    w.i32(e.cell_size);
    put_codes(w, e.gc);
    w.u64(e.vc.size());
    for (const PcCell& pc : e.vc) {
      w.u32(pc.cell);
      w.u32(std::uint32_t(pc.sections.size()));
      for (const SectionCode& s : pc.sections) w.u32(s.A), w.u32(s.L), w.u8(s.C), w.u8(s.I), w.u8(s.closes);
    }
    std::vector<CellClass> tree;
    for (std::uint8_t c : e.tree) tree.push_back(CellClass(c));
    put_codes(w, tree);
    for (std::uint32_t o : e.tree_offset) w.u32(o);
  }
  w.u32(pm::crc32_of(w.bytes));
  return std::move(w.bytes);
}

HybridTerrain HybridTerrain::decode(std::span<const std::uint8_t> blob, const std::string& what) {
  if (blob.size() < 12 || std::memcmp(blob.data(), kMagic, 8) != 0)
    fail(what, "not a hybrid model (bad magic)");
  const std::size_t body = blob.size() - 4;
  const std::uint32_t stored = pm::load_u32(blob.data() + body);
  if (pm::crc32_of(blob.first(body)) != stored) fail(what, "checksum mismatch");
  Reader r(blob.first(body), what);
  r.raw(8);  // the magic
  const std::uint32_t version = r.u32();
  if (version != kVersion) r.fail("format version " + std::to_string(version) + " (this build reads 1)");
  HybridTerrain h;
  h.step_ = r.i32();
  const int levels = r.i32();
  h.domain_w_ = r.i32();
  h.domain_h_ = r.i32();
  if (h.step_ < 1 || levels < 1 || levels > 16 || h.domain_w_ < 1 || h.domain_h_ < 1) r.fail("bad header");
  h.grid_z_.resize(r.count(8));
  for (double& z : h.grid_z_) z = r.f64();
  if (h.grid_z_.size() != std::size_t(h.domain_w_ / h.step_ + 1) * std::size_t(h.domain_h_ / h.step_ + 1))
    r.fail("grid size does not match the domain");
  h.vertices_.resize(r.count(24));
  for (Vertex& v : h.vertices_) v.x = r.i64(), v.y = r.i64(), v.z = r.f64();
  h.tin_.resize(r.count(12));
  for (auto& t : h.tin_)
    for (auto& v : t) {
      v = r.u32();
      if (v >= h.vertices_.size()) r.fail("triangle vertex out of range");
    }
  h.ring_begin_.resize(r.count(4));
  for (auto& v : h.ring_begin_) v = r.u32();
  h.tb_.resize(r.count(8));
  for (auto& v : h.tb_) {
    v = r.u32();
    if (v >= h.vertices_.size()) r.fail("TB vertex out of range");
  }
  h.conn_.resize(h.tb_.size());
  for (auto& c : h.conn_) {
    c = r.u32();
    if (c < 1 || c > h.tb_.size()) r.fail("connectivity out of range");
  }
  if (h.ring_begin_.size() < 2 || h.ring_begin_.front() != 0 || h.ring_begin_.back() != h.tb_.size())
    r.fail("ring offsets do not match the TB array");
  for (std::size_t i = 1; i < h.ring_begin_.size(); ++i)
    if (h.ring_begin_[i] <= h.ring_begin_[i - 1]) r.fail("empty or unordered ring");
  for (int l = 0; l < levels; ++l) {
    LevelEncoding e;
    e.cells_x = r.i32();
    e.cells_y = r.i32();
    e.cell_size = r.i32();
    if (e.cell_size != (h.step_ << l) || std::int64_t(e.cells_x) * e.cell_size != h.domain_w_ ||
        std::int64_t(e.cells_y) * e.cell_size != h.domain_h_)
      r.fail("level " + std::to_string(l) + " does not match the domain");
    e.gc = r.codes();
    if (e.gc.size() != std::size_t(e.cells_x) * e.cells_y)
      r.fail("GC list of level " + std::to_string(l) + " has a wrong size");
    e.vc.resize(r.count(8));
    std::uint32_t prev = 0;
    for (PcCell& pc : e.vc) {
      pc.cell = r.u32();
      if (pc.cell >= e.gc.size() || e.gc[pc.cell] != CellClass::PC || (&pc != e.vc.data() && pc.cell <= prev))
        r.fail("VC entry of level " + std::to_string(l) + " does not match the GC list");
      prev = pc.cell;
      pc.sections.resize(r.u32());
      if (pc.sections.empty() || pc.sections.size() > r.left() / 11) r.fail("bad section count");
      for (SectionCode& s : pc.sections) {
        s.A = r.u32();
        s.L = r.u32();
        s.C = r.u8();
        s.I = r.u8();
        s.closes = r.u8() != 0;
        if (s.A >= h.tb_.size() || s.L < 2 || s.L > h.tb_.size() + 1 || s.C > 3 || s.I > 4)
          r.fail("section out of range");
      }
      if (!pc.sections.back().closes) r.fail("last section of a cell does not close its cycle");
    }
    std::size_t pcs = 0;
    for (CellClass c : e.gc) pcs += c == CellClass::PC;
    if (pcs != e.vc.size()) r.fail("GC and VC lists of level " + std::to_string(l) + " disagree");
    for (CellClass c : r.codes()) e.tree.push_back(std::uint8_t(c));
    e.tree_offset.resize(e.vc.size() + 1);
    for (auto& o : e.tree_offset) {
      o = r.u32();
      if (o > e.tree.size() || (&o != e.tree_offset.data() && o < *(&o - 1)))
        r.fail("bad sub-cell tree offsets");
    }
    h.levels_.push_back(std::move(e));
  }
  if (r.left() != 0) r.fail(std::to_string(r.left()) + " trailing bytes");
  return h;
}

}  // namespace terralod::blocks::hybrid
