// Step 2 of the hybrid model's build (hybrid_builder.hpp), per level: the sections of the TIN
// boundary rings in each cell (runs of ring edges inside one open cell), the classification of
// every cell (PC: crossed by the boundary; CC / NC: covered or not, by the parity of its
// centre), the cycles of sections that bound each uncovered region of a PC cell with the
// corners between them (the paper's C and I codes), and the local convexification of each cycle
// (hybrid_build_convexification.cpp). Memory: the level's sections and cycles, O(TB vertices).
#include <algorithm>
#include <cstdint>
#include <map>
#include <vector>

#include "hybrid_builder.hpp"
#include "hybrid_geometry.hpp"

namespace terralod::blocks::hybrid {

using detail::kScale;
using detail::LPoint;
using detail::orient;

void Builder::process_level(int l) {
  const std::int64_t cs = ks << l;
  LevelEncoding& enc = h.levels_[std::size_t(l)];
  enc.cell_size = h.step_ << l;
  enc.cells_x = h.domain_w_ / enc.cell_size;
  enc.cells_y = h.domain_h_ / enc.cell_size;
  const int cx = enc.cells_x, cy = enc.cells_y;
  enc.gc.assign(std::size_t(cx) * cy, CellClass::NC);
  // Sections: runs of ring edges in the same open cell.
  std::map<std::uint32_t, CellWork> cells;
  const std::uint32_t nrings = std::uint32_t(h.ring_begin_.size() - 1);
  for (std::uint32_t r = 0; r < nrings; ++r) {
    const std::uint32_t b = h.ring_begin_[r], e = h.ring_begin_[r + 1];
    std::int64_t cur = -2;
    Section s;
    for (std::uint32_t t = b; t < e; ++t) {
      const std::int64_t c = edge_cell(TP(t), TP(next_tb(t)), cs);
      // A vertex that touches the cell border from inside also ends a section (the
      // uncovered part of the cell is split there).
      const bool touch = c >= 0 && c == cur && (TP(t).x % cs == 0 || TP(t).y % cs == 0);
      if (c != cur || touch) {
        if (cur >= 0) close_section(cells, s, cur, cx);
        cur = c;
        s = Section{};
        s.A = t;
        s.L = 1;
      }
      if (c >= 0) ++s.L;
    }
    if (cur >= 0) close_section(cells, s, cur, cx);
  }
  // Classification of the cells without sections: parity of the centre (scanline per row).
  for (int j = 0; j < cy; ++j) {
    const std::int64_t yc = (2 * j + 1) * cs / 2;
    std::vector<double> xs;
    for (std::uint32_t t = 0; t < h.tb_.size(); ++t) {
      const LPoint a = TP(t), b = TP(next_tb(t));
      if ((a.y <= yc) != (b.y <= yc))
        xs.push_back(double(a.x) + double(yc - a.y) * double(b.x - a.x) / double(b.y - a.y));
    }
    std::sort(xs.begin(), xs.end());
    for (int i = 0; i < cx; ++i) {
      const double xc = double((2 * i + 1) * cs / 2);
      const std::size_t left = std::size_t(std::lower_bound(xs.begin(), xs.end(), xc) - xs.begin());
      enc.gc[std::size_t(j) * cx + i] = (left % 2 == 1) ? CellClass::CC : CellClass::NC;
    }
  }
  cur_group_last_.assign(h.tb_.size(), -1);
  for (auto& [cell, work] : cells) {
    enc.gc[cell] = CellClass::PC;
    build_cycles(l, work, cs, cx);
    PcCell pc;
    pc.cell = cell;
    int cyc_index = 0;
    for (Cycle& cyc : work.cycles) {
      for (std::size_t k = 0; k < cyc.sections.size(); ++k) {
        const Section& s = work.sections[std::size_t(cyc.sections[k])];
        SectionCode code{s.A, s.L, s.C, s.I, k + 1 == cyc.sections.size()};
        pc.sections.push_back(code);
      }
      for (std::size_t p = 0; p + 1 < cyc.seq.size(); ++p)
        if (!std::binary_search(cyc.gaps.begin(), cyc.gaps.end(), p))
          cur_group_last_[cyc.seq[p]] = cyc.seq.back();
      convexify(l, cell, cx, cyc);
      hulls_[{l, cell, cyc_index++}] = cyc.hull;
    }
    enc.vc.push_back(std::move(pc));
  }
  prev_group_last_ = cur_group_last_;
}

void Builder::close_section(std::map<std::uint32_t, CellWork>& cells, const Section& s, std::int64_t packed,
                            int cx) {
  const std::uint32_t cell = std::uint32_t((packed >> 31) * cx + (packed & ((std::int64_t(1) << 31) - 1)));
  CellWork& w = cells[cell];
  w.cell = cell;
  w.sections.push_back(s);
}

/// At the common point v of exit(si) and entry(sj): is the border direction of decreasing tau
/// inside the TIN wedge at v (between sj's first edge and si's last edge, TIN on the left)?
bool Builder::border_behind_covered(const Section& si, const Section& sj, std::int64_t x0, std::int64_t y0,
                                    std::int64_t cs) {
  const LPoint v = TP(sj.A), prev = TP(section_tb(si, si.L - 2)), next = TP(next_tb(sj.A));
  const std::int64_t t = tau(v, x0, y0, cs);
  const std::int64_t side = ((t - 1 + 4 * cs) % (4 * cs)) / cs;  // edge holding tau - epsilon
  static const LPoint dir[4] = {{-1, 0}, {0, -1}, {1, 0}, {0, 1}};
  const LPoint w{v.x + dir[side].x, v.y + dir[side].y};
  const bool l1 = orient(v, next, w) > 0, l2 = orient(prev, v, w) > 0;
  return orient(prev, v, next) > 0 ? (l1 && l2) : (l1 || l2);
}

void Builder::build_cycles(int l, CellWork& w, std::int64_t cs, int cx) {
  const std::int64_t x0 = std::int64_t(w.cell % std::uint32_t(cx)) * cs,
                     y0 = std::int64_t(w.cell / std::uint32_t(cx)) * cs;
  const LPoint corner[4] = {{x0, y0}, {x0 + cs, y0}, {x0 + cs, y0 + cs}, {x0, y0 + cs}};
  auto& S = w.sections;
  for (Section& s : S) {
    const LPoint a = TP(s.A), b = TP(section_tb(s, s.L - 1));
    auto on_border = [&](const LPoint& p) {
      return p.x == x0 || p.x == x0 + cs || p.y == y0 || p.y == y0 + cs;
    };
    if (!on_border(a) || !on_border(b))
      throw HybridError(src + ": " + cell_name(l, w.cell, cx) +
                        ": a TIN boundary section does not end on the cell border");
    s.tau_a = tau(a, x0, y0, cs);
    s.tau_b = tau(b, x0, y0, cs);
  }
  const std::int64_t perim = 4 * cs;
  for (std::size_t i = 0; i < S.size(); ++i) {
    // Walk the border from the exit against the positive direction (uncovered side on the
    // right) to the first entry.
    std::int64_t best = -1;
    int which = -1;
    for (std::size_t j = 0; j < S.size(); ++j) {
      std::int64_t d = (S[i].tau_b - S[j].tau_a + perim) % perim;
      // An entry at the exit point itself: the walk reaches it at once if the border just
      // behind the exit is covered (the ring touches the border from the uncovered side),
      // else last.
      if (d == 0) d = border_behind_covered(S[i], S[j], x0, y0, cs) ? 0 : perim;
      if (which < 0 || d < best) best = d, which = int(j);
    }
    S[i].next = which;
    // Corners strictly inside the walked arc (tau_a, tau_b), listed in positive order.
    const std::int64_t ta = S[std::size_t(which)].tau_a;
    int first = -1, count = 0;
    for (int k = 0; k < 4; ++k) {
      const std::int64_t tc = k * cs;
      const std::int64_t dc = (S[i].tau_b - tc + perim) % perim;
      if (dc > 0 && dc < best) ++count;
    }
    // The corner right after the entry in positive order starts the list.
    for (int k = 0; k < 4 && count > 0; ++k) {
      const std::int64_t tc = ((ta / cs) + 1 + k) * cs % perim;
      const std::int64_t dc = (S[i].tau_b - tc + perim) % perim;
      if (dc > 0 && dc < best) {
        first = int(tc / cs);
        break;
      }
    }
    S[i].C = std::uint8_t(first < 0 ? 0 : first);
    S[i].I = std::uint8_t(count);
  }
  std::vector<bool> seen(S.size(), false);
  for (std::size_t i = 0; i < S.size(); ++i) {
    if (seen[i]) continue;
    std::vector<int> cyc;
    int k = int(i);
    while (!seen[std::size_t(k)]) {
      seen[std::size_t(k)] = true;
      cyc.push_back(k);
      k = S[std::size_t(k)].next;
    }
    if (k != int(i))
      throw HybridError(src + ": " + cell_name(l, w.cell, cx) + ": TIN boundary sections do not form cycles");
    int arcs = 0, arc_at = -1;
    for (std::size_t q = 0; q < cyc.size(); ++q)
      if (S[std::size_t(cyc[q])].I > 0) ++arcs, arc_at = int(q);
    if (arcs > 1)
      throw HybridError(
          src + ": " + cell_name(l, w.cell, cx) +
          ": an uncovered region bounded by several TIN sections reaches two separate groups of "
          "corners (the paper's Fig. 16 case) - not supported; use fewer levels");
    if (arc_at >= 0)
      std::rotate(cyc.begin(), cyc.begin() + (arc_at + 1) % std::ptrdiff_t(cyc.size()), cyc.end());
    Cycle c;
    c.sections = cyc;
    for (int si : cyc) {
      const Section& s = S[std::size_t(si)];
      std::uint32_t t = s.A;
      if (!c.seq.empty() && c.seq.back() != t) c.gaps.push_back(c.seq.size() - 1);
      for (std::uint32_t q = 0; q < s.L; ++q, t = next_tb(t))
        if (q > 0 || c.seq.empty() || c.seq.back() != t) c.seq.push_back(t);  // touch vertex once
    }
    const Section& last = S[std::size_t(cyc.back())];
    for (int q = 0; q < last.I; ++q) c.corners.push_back(corner[(last.C + q) % 4]);
    w.cycles.push_back(std::move(c));
  }
}

}  // namespace terralod::blocks::hybrid
