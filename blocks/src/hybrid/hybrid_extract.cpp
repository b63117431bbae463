// Extraction of hybrid grid + TIN meshes from the stored encoding: GC list, VC list, TB
// connectivity (Fig. 7 decoder), corner tessellation, the sub-cell tree of section 5, mixed
// levels with T-junction removal, and the Table 2 storage report.
// Memory: the output mesh plus a hash of its vertices and per-grid-line vertex lists.
#include <algorithm>
#include <bit>
#include <cassert>
#include <map>
#include <string>
#include <unordered_map>

#include "hybrid_internal.hpp"

namespace terralod::blocks::hybrid {

using detail::kScale;
using detail::LPoint;
using detail::orient;

std::uint32_t Extractor::next_tb(const HybridTerrain& h, std::uint32_t t) {
  const auto& rb = h.ring_begin_;
  const std::size_t r = std::size_t(std::upper_bound(rb.begin(), rb.end(), t) - rb.begin() - 1);
  return t + 1 == rb[r + 1] ? rb[r] : t + 1;
}

CellTessellation Extractor::tessellate(const HybridTerrain& h, int level, const PcCell& pc) {
  const LevelEncoding& enc = h.levels_[std::size_t(level)];
  const std::int64_t cs = std::int64_t(enc.cell_size) * kScale;
  const std::int64_t x0 = std::int64_t(pc.cell % std::uint32_t(enc.cells_x)) * cs;
  const std::int64_t y0 = std::int64_t(pc.cell / std::uint32_t(enc.cells_x)) * cs;
  const LPoint corner[4] = {{x0, y0}, {x0 + cs, y0}, {x0 + cs, y0 + cs}, {x0, y0 + cs}};
  const std::uint32_t n = std::uint32_t(h.tb_.size());
  auto bad = [&](const std::string& why) {
    return HybridError("hybrid encoding: level " + std::to_string(level) + " cell " +
                       std::to_string(pc.cell) + ": " + why);
  };
  CellTessellation out;
  std::vector<std::uint32_t> seq;
  std::vector<std::size_t> gaps;
  for (const SectionCode& s : pc.sections) {
    if (s.A >= n || s.L < 2 || s.L > n + 1) throw bad("section out of range");
    std::uint32_t t = s.A;
    if (!seq.empty() && seq.back() != t) gaps.push_back(seq.size() - 1);
    for (std::uint32_t q = 0; q < s.L; ++q, t = next_tb(h, t))
      if (q > 0 || seq.empty() || seq.back() != t)
        seq.push_back(t);  // a touch vertex ends one section and starts the next
    if (!s.closes) continue;
    if (s.C > 3 || s.I > 4) throw bad("corner code out of range");
    const CavityDecode d = decode_cavities(seq, h.conn_, false, gaps);
    for (const FanTriangle& f : d.triangles) {
      std::array<std::uint32_t, 3> tri{f.apex, f.current, f.previous};
      const auto o = orient(tb_lpoint(h, tri[0]), tb_lpoint(h, tri[1]), tb_lpoint(h, tri[2]));
      if (o == 0) throw bad("degenerate convexification triangle");
      if (o < 0) std::swap(tri[1], tri[2]);
      out.fill.push_back(tri);
    }
    // Largest cavity closed inside the cell.
    std::unordered_map<std::uint32_t, std::size_t> pos;
    for (std::size_t p = 0; p < seq.size(); ++p) pos.emplace(seq[p], p);
    for (std::size_t p = 0; p < seq.size(); ++p) {
      const std::uint32_t c = h.conn_[seq[p]];
      if (c <= 1 || std::binary_search(gaps.begin(), gaps.end(), p)) continue;
      auto it = pos.find(std::uint32_t((std::uint64_t(seq[p]) + c) % n));
      if (it != pos.end() && it->second > p) out.max_connectivity = std::max(out.max_connectivity, c);
    }
    std::vector<PlanPoint> hp, cp;
    for (std::uint32_t t2 : d.hull) {
      const LPoint p = tb_lpoint(h, t2);
      hp.push_back({double(p.x), double(p.y)});
    }
    std::vector<LPoint> poly;
    for (std::uint32_t t2 : seq) poly.push_back(tb_lpoint(h, t2));
    for (int q = 0; q < s.I; ++q) {
      const LPoint c = corner[(s.C + q) % 4];
      cp.push_back({double(c.x), double(c.y)});
    }
    for (int q = s.I - 1; q >= 0; --q) poly.push_back(corner[(s.C + q) % 4]);
    out.uncovered_area2.push_back(-detail::area2(poly));
    const auto ct = corner_tessellation(hp, cp);
    const std::uint32_t m = std::uint32_t(hp.size());
    for (const auto& tri : ct) {
      std::array<CellRef, 3> r;
      for (int k = 0; k < 3; ++k)
        r[k] = tri[k] < m ? CellRef{false, d.hull[tri[k]]}
                          : CellRef{true, std::uint32_t((s.C + tri[k] - m) % 4)};
      out.corner_tris.push_back(r);
    }
    out.hulls.push_back(d.hull);
    out.sequences.push_back(seq);
    seq.clear();
    gaps.clear();
  }
  if (!seq.empty()) throw bad("the last section does not close its cycle");
  return out;
}

std::vector<std::array<std::uint32_t, 3>> HybridTerrain::decoded_fill(int level, std::uint32_t cell) const {
  const LevelEncoding& enc = levels_.at(std::size_t(level));
  auto it = std::lower_bound(enc.vc.begin(), enc.vc.end(), cell,
                             [](const PcCell& p, std::uint32_t c) { return p.cell < c; });
  if (it == enc.vc.end() || it->cell != cell) return {};
  return Extractor::tessellate(*this, level, *it).fill;
}

namespace {

struct MeshBuilder {
  const HybridTerrain& h;
  HybridMesh mesh;
  std::vector<LPoint> lp;
  std::unordered_map<std::uint64_t, std::uint32_t> index;
  std::vector<std::uint32_t> tin_out;

  static std::uint64_t key(const LPoint& p) { return (std::uint64_t(p.x) << 32) ^ std::uint64_t(p.y); }
  std::uint32_t add(const LPoint& p, double z) {
    auto [it, fresh] = index.emplace(key(p), std::uint32_t(lp.size()));
    if (fresh) {
      lp.push_back(p);
      mesh.points.push_back({double(p.x) / kScale, double(p.y) / kScale, z});
    }
    return it->second;
  }
};

}  // namespace

std::size_t split_t_junctions(const std::vector<LPoint>& lp, std::vector<std::array<std::uint32_t, 3>>& tris,
                              std::int64_t ks) {
  // T-junction removal: split every triangle edge that runs along a grid line at the output
  // vertices lying on it (neighbours at other levels, grid nodes next to TIN vertices).
  std::size_t splits = 0;
  std::map<std::int64_t, std::vector<std::pair<std::int64_t, std::uint32_t>>> vl, hl;
  for (std::uint32_t v = 0; v < lp.size(); ++v) {
    if (lp[v].x % ks == 0) vl[lp[v].x].push_back({lp[v].y, v});
    if (lp[v].y % ks == 0) hl[lp[v].y].push_back({lp[v].x, v});
  }
  for (auto* m : {&vl, &hl})
    for (auto& [k, list] : *m) std::sort(list.begin(), list.end());
  const std::size_t count = tris.size();
  for (std::size_t ti = 0; ti < count; ++ti) {
    const auto t = tris[ti];
    std::vector<std::uint32_t> poly;
    bool split = false;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k], b = t[(k + 1) % 3];
      poly.push_back(a);
      const LPoint A = lp[a], B = lp[b];
      const std::vector<std::pair<std::int64_t, std::uint32_t>>* line = nullptr;
      std::int64_t lo = 0, hi = 0;
      if (A.x == B.x && A.x % ks == 0) {
        line = &vl[A.x];
        lo = A.y, hi = B.y;
      } else if (A.y == B.y && A.y % ks == 0) {
        line = &hl[A.y];
        lo = A.x, hi = B.x;
      }
      if (!line) continue;
      const bool up = lo < hi;
      auto first =
          std::upper_bound(line->begin(), line->end(), std::make_pair(std::min(lo, hi), std::uint32_t(-1)));
      std::vector<std::uint32_t> mid;
      for (auto it = first; it != line->end() && it->first < std::max(lo, hi); ++it)
        mid.push_back(it->second);
      if (!up) std::reverse(mid.begin(), mid.end());
      if (!mid.empty()) split = true;
      poly.insert(poly.end(), mid.begin(), mid.end());
    }
    if (!split) continue;
    std::vector<std::array<std::uint32_t, 3>> pieces;
    if (!detail::ear_clip(lp, poly, pieces))
      throw HybridError("hybrid extraction: a T-junction could not be removed");
    tris[ti] = pieces[0];
    for (std::size_t p = 1; p < pieces.size(); ++p) tris.push_back(pieces[p]);
    ++splits;
  }
  return splits;
}

HybridMesh Extractor::extract(const HybridTerrain& h, const std::vector<int>& coarse_levels, Scheme scheme,
                              bool remove_t_junctions) {
  const int L = h.levels();
  const LevelEncoding& top = h.levels_.back();
  assert(coarse_levels.size() == std::size_t(top.cells_x) * top.cells_y);
  MeshBuilder mb{h, {}, {}, {}, {}};
  mb.index.reserve(h.vertices_.size() * 2 + h.grid_z_.size());
  for (const auto& v : h.vertices_) mb.tin_out.push_back(mb.add({v.x, v.y}, v.z));
  const std::int64_t ks = std::int64_t(h.step_) * kScale;
  const int nx = h.domain_w_ / h.step_ + 1;
  auto node = [&](std::int64_t x, std::int64_t y) {
    const std::size_t gi = std::size_t(x / ks), gj = std::size_t(y / ks);
    return mb.add({x, y}, h.grid_z_[gj * std::size_t(nx) + gi]);
  };
  auto& tris = mb.mesh.triangles;
  auto quad = [&](int level, std::uint32_t i, std::uint32_t j) {
    const std::int64_t cs = ks << level, x0 = std::int64_t(i) * cs, y0 = std::int64_t(j) * cs;
    const std::uint32_t c0 = node(x0, y0), c1 = node(x0 + cs, y0), c2 = node(x0 + cs, y0 + cs),
                        c3 = node(x0, y0 + cs);
    tris.push_back({c0, c1, c2});
    tris.push_back({c0, c2, c3});
    mb.mesh.grid_triangles += 2;
  };
  auto find_pc = [&](int level, std::uint32_t cell) -> const PcCell& {
    const auto& vc = h.levels_[std::size_t(level)].vc;
    auto it = std::lower_bound(vc.begin(), vc.end(), cell,
                               [](const PcCell& p, std::uint32_t c) { return p.cell < c; });
    if (it == vc.end() || it->cell != cell)
      throw HybridError("hybrid encoding: level " + std::to_string(level) + " cell " + std::to_string(cell) +
                        " is PC in the GC list but has no VC entry");
    return *it;
  };
  auto triangles_pc = [&](int level, const PcCell& pc) {
    const LevelEncoding& enc = h.levels_[std::size_t(level)];
    const std::int64_t cs = ks << level;
    const std::int64_t x0 = std::int64_t(pc.cell % std::uint32_t(enc.cells_x)) * cs;
    const std::int64_t y0 = std::int64_t(pc.cell / std::uint32_t(enc.cells_x)) * cs;
    const CellTessellation t = tessellate(h, level, pc);
    for (const auto& f : t.fill)
      tris.push_back({mb.tin_out[h.tb_[f[0]]], mb.tin_out[h.tb_[f[1]]], mb.tin_out[h.tb_[f[2]]]});
    mb.mesh.convexification_triangles += t.fill.size();
    for (const auto& c : t.corner_tris) {
      std::array<std::uint32_t, 3> tri;
      for (int k = 0; k < 3; ++k) {
        if (!c[k].corner) {
          tri[k] = mb.tin_out[h.tb_[c[k].id]];
        } else {
          const std::uint32_t q = c[k].id;
          tri[k] = node(x0 + ((q == 1 || q == 2) ? cs : 0), y0 + ((q >= 2) ? cs : 0));
        }
      }
      tris.push_back(tri);
    }
    mb.mesh.corner_triangles += t.corner_tris.size();
  };
  auto emit_cell = [&](int level, std::uint32_t i, std::uint32_t j) {
    const LevelEncoding& enc = h.levels_[std::size_t(level)];
    const std::uint32_t cell = j * std::uint32_t(enc.cells_x) + i;
    const CellClass cc = enc.gc[cell];
    if (cc == CellClass::NC) return quad(level, i, j);
    if (cc == CellClass::CC) return;
    const PcCell& pc = find_pc(level, cell);
    if (scheme == Scheme::Triangles || level == 0) return triangles_pc(level, pc);
    // Section 5: the sub-cell tree, breadth first, four codes per PC (sub-)cell.
    const std::size_t v = std::size_t(&pc - enc.vc.data());
    const std::uint32_t b = enc.tree_offset.at(v), e = enc.tree_offset.at(v + 1);
    std::vector<std::pair<int, std::uint32_t>> queue{{level, cell}};
    std::uint32_t at = b;
    for (std::size_t qi = 0; qi < queue.size(); ++qi) {
      const auto [ql, qc] = queue[qi];
      const LevelEncoding& up = h.levels_[std::size_t(ql)];
      const LevelEncoding& dn = h.levels_[std::size_t(ql - 1)];
      const std::uint32_t pi = qc % std::uint32_t(up.cells_x), pj = qc / std::uint32_t(up.cells_x);
      for (std::uint32_t q = 0; q < 4; ++q) {
        if (at >= e)
          throw HybridError("hybrid encoding: sub-cell tree of level " + std::to_string(level) + " cell " +
                            std::to_string(cell) + " is truncated");
        const CellClass code = CellClass(enc.tree[at++]);
        const std::uint32_t ci = 2 * pi + (q & 1), cj = 2 * pj + (q >> 1);
        if (code == CellClass::NC) {
          quad(ql - 1, ci, cj);
        } else if (code == CellClass::PC) {
          if (ql - 1 == 0)
            triangles_pc(0, find_pc(0, cj * std::uint32_t(dn.cells_x) + ci));
          else
            queue.push_back({ql - 1, cj * std::uint32_t(dn.cells_x) + ci});
        }
      }
    }
  };
  for (int J = 0; J < top.cells_y; ++J)
    for (int I = 0; I < top.cells_x; ++I) {
      const int lv = coarse_levels[std::size_t(J) * top.cells_x + I];
      assert(lv >= 0 && lv < L);
      const int f = 1 << (L - 1 - lv);
      for (int j = J * f; j < (J + 1) * f; ++j)
        for (int i = I * f; i < (I + 1) * f; ++i) emit_cell(lv, std::uint32_t(i), std::uint32_t(j));
    }
  for (const auto& t : h.tin_) tris.push_back({mb.tin_out[t[0]], mb.tin_out[t[1]], mb.tin_out[t[2]]});
  mb.mesh.tin_triangles = h.tin_.size();

  if (remove_t_junctions) mb.mesh.split_edges = split_t_junctions(mb.lp, tris, ks);
  return std::move(mb.mesh);
}

HybridMesh HybridTerrain::extract(int level, Scheme scheme) const {
  assert(level >= 0 && level < levels());
  const LevelEncoding& top = levels_.back();
  std::vector<int> lv(std::size_t(top.cells_x) * top.cells_y, level);
  return Extractor::extract(*this, lv, scheme);
}

HybridMesh HybridTerrain::extract_mixed(std::span<const int> coarse_levels, Scheme scheme) const {
  return Extractor::extract(*this, std::vector<int>(coarse_levels.begin(), coarse_levels.end()), scheme);
}

StorageReport HybridTerrain::storage_report() const {
  StorageReport r;
  r.tb_vertices = tb_.size();
  r.rings = ring_begin_.size() - 1;
  r.tin_vertices = vertices_.size();
  r.tin_triangles = tin_.size();
  for (std::uint32_t c : conn_) r.max_connectivity = std::max(r.max_connectivity, c);
  r.connectivity_bits = int(std::bit_width(r.max_connectivity));
  r.address_bits = int(std::bit_width(std::uint64_t(tb_.empty() ? 0 : tb_.size() - 1)));
  for (int l = 0; l < levels(); ++l) {
    const LevelEncoding& enc = levels_[std::size_t(l)];
    LevelReport lr;
    lr.level = l;
    lr.cells = int(enc.gc.size());
    for (CellClass c : enc.gc) {
      if (c == CellClass::NC)
        ++lr.nc, lr.gc_bits += 1;
      else if (c == CellClass::CC)
        ++lr.cc, lr.gc_bits += 2;
      else
        ++lr.pc, lr.gc_bits += 2;
    }
    lr.pc_percent = lr.cells ? 100.0 * lr.pc / lr.cells : 0.0;
    for (const PcCell& pc : enc.vc) {
      lr.sections += pc.sections.size();
      for (const SectionCode& s : pc.sections) lr.l_max = std::max(lr.l_max, s.L);
      lr.max_connectivity =
          std::max(lr.max_connectivity, Extractor::tessellate(*this, l, pc).max_connectivity);
    }
    lr.bits_per_section = r.address_bits + int(std::bit_width(lr.l_max)) + 2 + 2;
    lr.vc_bits = std::uint64_t(lr.bits_per_section) * lr.sections;
    std::uint64_t total = 0;
    for (std::size_t v = 0; v + 1 < enc.tree_offset.size(); ++v) {
      std::uint64_t bits = 0;
      for (std::uint32_t k = enc.tree_offset[v]; k < enc.tree_offset[v + 1]; ++k)
        bits += enc.tree[k] == std::uint8_t(CellClass::NC) ? 1 : 2;
      total += bits;
      lr.tree_bits_max = std::max(lr.tree_bits_max, bits);
    }
    lr.tree_bits_per_pc = enc.vc.empty() ? 0.0 : double(total) / double(enc.vc.size());
    r.levels.push_back(lr);
  }
  return r;
}

}  // namespace terralod::blocks::hybrid
