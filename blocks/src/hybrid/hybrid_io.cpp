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
#include <zlib.h>

#include <cstring>
#include <string>

#include "hybrid_internal.hpp"

namespace terralod::blocks::hybrid {

namespace {

constexpr char kMagic[8] = {'T', 'L', 'H', 'Y', 'B', 'R', 'I', 'D'};
constexpr std::uint32_t kVersion = 1;

struct Writer {
  std::vector<std::uint8_t> b;
  template <class T>
  void put(T v) {
    std::uint8_t raw[sizeof(T)];
    std::memcpy(raw, &v, sizeof(T));
    b.insert(b.end(), raw, raw + sizeof(T));
  }
  void codes(const std::vector<CellClass>& c) {
    put<std::uint64_t>(c.size());
    std::uint8_t cur = 0;
    int nbits = 0;
    auto bit = [&](int v) {
      cur = std::uint8_t(cur | (v << (7 - nbits)));
      if (++nbits == 8) b.push_back(cur), cur = 0, nbits = 0;
    };
    for (CellClass k : c) {
      if (k == CellClass::NC)
        bit(0);
      else
        bit(1), bit(k == CellClass::PC ? 1 : 0);
    }
    if (nbits) b.push_back(cur);
  }
};

struct Reader {
  std::span<const std::uint8_t> b;
  std::size_t at = 0;
  const std::string& what;
  [[noreturn]] void fail(const std::string& why) const { throw HybridError(what + ": hybrid blob: " + why); }
  template <class T>
  T get() {
    if (b.size() - at < sizeof(T)) fail("truncated at byte " + std::to_string(at));
    T v;
    std::memcpy(&v, b.data() + at, sizeof(T));
    at += sizeof(T);
    return v;
  }
  std::size_t count(std::size_t item_size) {
    const std::uint64_t n = get<std::uint64_t>();
    if (item_size && n > (b.size() - at) / item_size)
      fail("count " + std::to_string(n) + " exceeds the blob");
    return std::size_t(n);
  }
  std::vector<CellClass> codes() {
    const std::uint64_t n = get<std::uint64_t>();
    if (n > (b.size() - at) * 8) fail("code list exceeds the blob");
    std::vector<CellClass> out;
    out.reserve(n);
    std::size_t bitpos = 0;
    auto bit = [&]() -> int {
      if (at + bitpos / 8 >= b.size()) fail("code list truncated");
      const int v = (b[at + bitpos / 8] >> (7 - bitpos % 8)) & 1;
      ++bitpos;
      return v;
    };
    for (std::uint64_t i = 0; i < n; ++i) {
      if (bit() == 0)
        out.push_back(CellClass::NC);
      else
        out.push_back(bit() ? CellClass::PC : CellClass::CC);
    }
    at += (bitpos + 7) / 8;
    return out;
  }
};

}  // namespace

std::vector<std::uint8_t> HybridTerrain::encode() const {
  Writer w;
  w.b.reserve(4096);  // (also keeps GCC 12's -Wstringop-overflow false positive away in sanitizer builds)
  w.b.insert(w.b.end(), kMagic, kMagic + 8);
  w.put(kVersion);
  w.put<std::int32_t>(step_);
  w.put<std::int32_t>(levels());
  w.put<std::int32_t>(domain_w_);
  w.put<std::int32_t>(domain_h_);
  w.put<std::uint64_t>(grid_z_.size());
  for (double z : grid_z_) w.put(z);
  w.put<std::uint64_t>(vertices_.size());
  for (const Vertex& v : vertices_) w.put(v.x), w.put(v.y), w.put(v.z);
  w.put<std::uint64_t>(tin_.size());
  for (const auto& t : tin_) w.put(t[0]), w.put(t[1]), w.put(t[2]);
  w.put<std::uint64_t>(ring_begin_.size());
  for (std::uint32_t r : ring_begin_) w.put(r);
  w.put<std::uint64_t>(tb_.size());
  for (std::uint32_t t : tb_) w.put(t);
  for (std::uint32_t c : conn_) w.put(c);
  for (const LevelEncoding& e : levels_) {
    w.put<std::int32_t>(e.cells_x);
    w.put<std::int32_t>(e.cells_y);
    w.put<std::int32_t>(e.cell_size);
    w.codes(e.gc);
    w.put<std::uint64_t>(e.vc.size());
    for (const PcCell& pc : e.vc) {
      w.put(pc.cell);
      w.put<std::uint32_t>(std::uint32_t(pc.sections.size()));
      for (const SectionCode& s : pc.sections)
        w.put(s.A), w.put(s.L), w.put(s.C), w.put(s.I), w.put<std::uint8_t>(s.closes);
    }
    std::vector<CellClass> tree;
    for (std::uint8_t c : e.tree) tree.push_back(CellClass(c));
    w.codes(tree);
    for (std::uint32_t o : e.tree_offset) w.put(o);
  }
  w.put(std::uint32_t(crc32(0L, w.b.data(), uInt(w.b.size()))));
  return std::move(w.b);
}

HybridTerrain HybridTerrain::decode(std::span<const std::uint8_t> blob, const std::string& what) {
  Reader r{blob, 0, what};
  if (blob.size() < 12 || std::memcmp(blob.data(), kMagic, 8) != 0) r.fail("not a hybrid model (bad magic)");
  const std::size_t body = blob.size() - 4;
  std::uint32_t stored;
  std::memcpy(&stored, blob.data() + body, 4);
  uLong crc = crc32(0L, Z_NULL, 0);
  for (std::size_t off = 0; off < body; off += (1u << 30))
    crc = crc32(crc, blob.data() + off, uInt(std::min<std::size_t>(body - off, 1u << 30)));
  if (std::uint32_t(crc) != stored) r.fail("checksum mismatch");
  r.b = blob.first(body);
  r.at = 8;
  const std::uint32_t version = r.get<std::uint32_t>();
  if (version != kVersion) r.fail("format version " + std::to_string(version) + " (this build reads 1)");
  HybridTerrain h;
  h.step_ = r.get<std::int32_t>();
  const int levels = r.get<std::int32_t>();
  h.domain_w_ = r.get<std::int32_t>();
  h.domain_h_ = r.get<std::int32_t>();
  if (h.step_ < 1 || levels < 1 || levels > 16 || h.domain_w_ < 1 || h.domain_h_ < 1) r.fail("bad header");
  h.grid_z_.resize(r.count(8));
  for (double& z : h.grid_z_) z = r.get<double>();
  if (h.grid_z_.size() != std::size_t(h.domain_w_ / h.step_ + 1) * std::size_t(h.domain_h_ / h.step_ + 1))
    r.fail("grid size does not match the domain");
  h.vertices_.resize(r.count(24));
  for (Vertex& v : h.vertices_)
    v.x = r.get<std::int64_t>(), v.y = r.get<std::int64_t>(), v.z = r.get<double>();
  h.tin_.resize(r.count(12));
  for (auto& t : h.tin_)
    for (auto& v : t) {
      v = r.get<std::uint32_t>();
      if (v >= h.vertices_.size()) r.fail("triangle vertex out of range");
    }
  h.ring_begin_.resize(r.count(4));
  for (auto& v : h.ring_begin_) v = r.get<std::uint32_t>();
  h.tb_.resize(r.count(8));
  for (auto& v : h.tb_) {
    v = r.get<std::uint32_t>();
    if (v >= h.vertices_.size()) r.fail("TB vertex out of range");
  }
  h.conn_.resize(h.tb_.size());
  for (auto& c : h.conn_) {
    c = r.get<std::uint32_t>();
    if (c < 1 || c > h.tb_.size()) r.fail("connectivity out of range");
  }
  if (h.ring_begin_.size() < 2 || h.ring_begin_.front() != 0 || h.ring_begin_.back() != h.tb_.size())
    r.fail("ring offsets do not match the TB array");
  for (std::size_t i = 1; i < h.ring_begin_.size(); ++i)
    if (h.ring_begin_[i] <= h.ring_begin_[i - 1]) r.fail("empty or unordered ring");
  for (int l = 0; l < levels; ++l) {
    LevelEncoding e;
    e.cells_x = r.get<std::int32_t>();
    e.cells_y = r.get<std::int32_t>();
    e.cell_size = r.get<std::int32_t>();
    if (e.cell_size != (h.step_ << l) || std::int64_t(e.cells_x) * e.cell_size != h.domain_w_ ||
        std::int64_t(e.cells_y) * e.cell_size != h.domain_h_)
      r.fail("level " + std::to_string(l) + " does not match the domain");
    e.gc = r.codes();
    if (e.gc.size() != std::size_t(e.cells_x) * e.cells_y)
      r.fail("GC list of level " + std::to_string(l) + " has a wrong size");
    e.vc.resize(r.count(8));
    std::uint32_t prev = 0;
    for (PcCell& pc : e.vc) {
      pc.cell = r.get<std::uint32_t>();
      if (pc.cell >= e.gc.size() || e.gc[pc.cell] != CellClass::PC || (&pc != e.vc.data() && pc.cell <= prev))
        r.fail("VC entry of level " + std::to_string(l) + " does not match the GC list");
      prev = pc.cell;
      pc.sections.resize(r.get<std::uint32_t>());
      if (pc.sections.empty() || pc.sections.size() > (r.b.size() - r.at) / 11) r.fail("bad section count");
      for (SectionCode& s : pc.sections) {
        s.A = r.get<std::uint32_t>();
        s.L = r.get<std::uint32_t>();
        s.C = r.get<std::uint8_t>();
        s.I = r.get<std::uint8_t>();
        s.closes = r.get<std::uint8_t>() != 0;
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
      o = r.get<std::uint32_t>();
      if (o > e.tree.size() || (&o != e.tree_offset.data() && o < *(&o - 1)))
        r.fail("bad sub-cell tree offsets");
    }
    h.levels_.push_back(std::move(e));
  }
  if (r.at != r.b.size()) r.fail(std::to_string(r.b.size() - r.at) + " trailing bytes");
  return h;
}

}  // namespace terralod::blocks::hybrid
