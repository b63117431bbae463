// Builder of the hybrid grid + TIN model: TIN boundary rings, intersection vertices, per-level
// cell classification (GC list), incremental local convexification encoded as one connectivity
// index per TIN-boundary vertex plus the VC list, and the sub-cell trees (Boo, Amor, Doellner,
// "Unified hybrid terrain representation based on local convexifications", sections 2-5 and the
// appendix). Memory: O(TB vertices) per level while building, plus one byte per cell per level.
#include "terralod/blocks/hybrid/hybrid_terrain.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <string>
#include <unordered_map>
#include <utility>

#include "hybrid_geometry.hpp"
#include "hybrid_internal.hpp"

namespace terralod::blocks::hybrid {

using detail::kScale;
using detail::LPoint;
using detail::orient;

namespace {

std::string cell_name(int level, std::uint32_t cell, int cells_x) {
  return "level " + std::to_string(level) + " cell (" + std::to_string(cell % std::uint32_t(cells_x)) + "," +
         std::to_string(cell / std::uint32_t(cells_x)) + ")";
}

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) { return (std::uint64_t(a) << 32) | b; }

}  // namespace

TinMesh tin_from_world(const pm::TriangleMeshData& world, const pm::GridTransform& t,
                       const std::string& source) {
  const double det = t.determinant();
  if (!(std::abs(det) > 0) || !std::isfinite(det))
    throw HybridError(source + ": grid transform is not invertible");
  TinMesh m;
  m.source = source;
  m.triangles = world.triangles;
  m.points.reserve(world.positions.size());
  for (const auto& p : world.positions) {
    const double dx = p[0] - t.x0, dy = p[1] - t.y0;
    // Inverse of [xc xr; yc yr].
    const double col = (t.yr * dx - t.xr * dy) / det, row = (-t.yc * dx + t.xc * dy) / det;
    m.points.push_back({col, row, p[2]});
  }
  return m;
}

TinMesh merge_tins(const std::vector<TinMesh>& tins) {
  TinMesh m;
  for (const TinMesh& t : tins) {
    const std::uint32_t base = std::uint32_t(m.points.size());
    m.points.insert(m.points.end(), t.points.begin(), t.points.end());
    for (auto tri : t.triangles) m.triangles.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
    m.source += (m.source.empty() ? "" : "+") + t.source;
  }
  return m;
}

pm::TriangleMeshData to_world(const HybridMesh& mesh, const pm::GridTransform& t) {
  pm::TriangleMeshData w;
  w.positions.reserve(mesh.points.size());
  for (const auto& p : mesh.points) {
    auto [x, y] = t.to_world(p[0], p[1]);
    w.positions.push_back({x, y, p[2]});
  }
  w.triangles = mesh.triangles;
  if (t.determinant() < 0)
    for (auto& tri : w.triangles) std::swap(tri[1], tri[2]);
  return w;
}

PlanPoint HybridTerrain::tb_point(std::uint32_t t) const {
  const Vertex& v = vertices_.at(tb_.at(t));
  return {double(v.x) / kScale, double(v.y) / kScale};
}

// ---------------------------------------------------------------------------------------------
// The builder.

struct Builder {
  HybridTerrain& h;
  std::string src;
  int L = 1;
  std::int64_t ks = 0;  // finest cell size in lattice units

  explicit Builder(HybridTerrain& out) : h(out) {}

  LPoint P(std::uint32_t vertex) const { return {h.vertices_[vertex].x, h.vertices_[vertex].y}; }
  LPoint TP(std::uint32_t t) const { return P(h.tb_[t]); }
  std::uint32_t ring_of(std::uint32_t t) const {
    return std::uint32_t(std::upper_bound(h.ring_begin_.begin(), h.ring_begin_.end(), t) -
                         h.ring_begin_.begin() - 1);
  }
  std::uint32_t next_tb(std::uint32_t t) const {
    const std::uint32_t r = ring_of(t);
    return t + 1 == h.ring_begin_[r + 1] ? h.ring_begin_[r] : t + 1;
  }
  std::uint32_t dist(std::uint32_t from, std::uint32_t to) const {
    const std::uint32_t n = std::uint32_t(h.tb_.size());
    return (to + n - from) % n;
  }

  // --- Step 1: the TIN, its rings and the intersection vertices. -----------------------------
  void load_tin(const TinMesh& tin) {
    const std::int64_t W = std::int64_t(h.domain_w_) * kScale, H = std::int64_t(h.domain_h_) * kScale;
    if (tin.points.empty() || tin.triangles.empty()) throw HybridError(src + ": the TIN has no triangles");
    for (std::size_t i = 0; i < tin.points.size(); ++i) {
      const auto& p = tin.points[i];
      if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
        throw HybridError(src + ": TIN vertex " + std::to_string(i) + " is not finite");
      HybridTerrain::Vertex v{std::llround(p[0] * kScale), std::llround(p[1] * kScale), p[2]};
      if (v.x < 0 || v.y < 0 || v.x > W || v.y > H)
        throw HybridError(src + ": TIN vertex " + std::to_string(i) + " at (col,row) (" +
                          std::to_string(p[0]) + "," + std::to_string(p[1]) +
                          ") lies outside the grid domain [0," + std::to_string(h.domain_w_) + "]x[0," +
                          std::to_string(h.domain_h_) + "]");
      h.vertices_.push_back(v);
    }
    for (std::size_t i = 0; i < tin.triangles.size(); ++i) {
      auto t = tin.triangles[i];
      for (auto v : t)
        if (v >= tin.points.size())
          throw HybridError(src + ": triangle " + std::to_string(i) + " has a bad index");
      const auto o = orient(P(t[0]), P(t[1]), P(t[2]));
      if (o == 0)
        throw HybridError(src + ": TIN triangle " + std::to_string(i) + " is degenerate in plan view");
      if (o < 0) std::swap(t[1], t[2]);
      h.tin_.push_back(t);
    }
    // Directed edges: each at most once (else the TIN overlaps itself or is not manifold).
    std::unordered_map<std::uint64_t, std::uint32_t> he;
    he.reserve(h.tin_.size() * 4);
    for (std::uint32_t i = 0; i < h.tin_.size(); ++i)
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = h.tin_[i][k], b = h.tin_[i][(k + 1) % 3];
        if (!he.emplace(edge_key(a, b), i).second)
          throw HybridError(src + ": TIN edge (" + std::to_string(a) + "," + std::to_string(b) +
                            ") is used twice in the same direction (overlapping or non-manifold TIN)");
      }
    std::unordered_map<std::uint32_t, std::uint32_t> next;  // boundary half-edge a -> b
    for (const auto& [key, tri] : he) {
      const std::uint32_t a = std::uint32_t(key >> 32), b = std::uint32_t(key);
      if (he.count(edge_key(b, a))) continue;
      if (!next.emplace(a, b).second)
        throw HybridError(src + ": the TIN boundary touches itself at vertex " + std::to_string(a) +
                          " (not a set of simple rings)");
    }
    // Rings, each started at its smallest vertex id for determinism.
    std::vector<std::uint32_t> starts;
    for (const auto& [a, b] : next) starts.push_back(a);
    std::sort(starts.begin(), starts.end());
    std::unordered_map<std::uint32_t, bool> done;
    std::vector<std::vector<std::uint32_t>> rings;
    for (std::uint32_t s : starts) {
      if (done.count(s)) continue;
      std::vector<std::uint32_t> ring;
      std::uint32_t v = s;
      do {
        done[v] = true;
        ring.push_back(v);
        auto it = next.find(v);
        if (it == next.end())
          throw HybridError(src + ": the TIN boundary is not closed at vertex " + std::to_string(v));
        v = it->second;
      } while (v != s && ring.size() <= next.size());
      rings.push_back(std::move(ring));
    }
    // Intersection vertices with the finest-level grid lines; split the triangle of each edge.
    // triangle -> (edge start, new vertices on that edge in order)
    std::unordered_map<std::uint32_t, std::vector<std::pair<std::uint32_t, std::uint32_t>>> extra;
    for (auto& ring : rings) {
      std::vector<std::uint32_t> out;
      for (std::size_t i = 0; i < ring.size(); ++i) {
        const std::uint32_t a = ring[i], b = ring[(i + 1) % ring.size()];
        out.push_back(a);
        const LPoint A = P(a), B = P(b);
        std::vector<std::pair<double, LPoint>> cuts;
        auto add_lines = [&](bool vertical) {
          const std::int64_t a0 = vertical ? A.x : A.y, b0 = vertical ? B.x : B.y;
          if (a0 == b0) return;
          const std::int64_t lo = std::min(a0, b0), hi = std::max(a0, b0);
          for (std::int64_t c = (lo / ks + 1) * ks; c < hi; c += ks) {
            const double t = double(c - a0) / double(b0 - a0);
            LPoint p = vertical ? LPoint{c, std::llround(double(A.y) + t * double(B.y - A.y))}
                                : LPoint{std::llround(double(A.x) + t * double(B.x - A.x)), c};
            cuts.push_back({t, p});
          }
        };
        add_lines(true);
        add_lines(false);
        std::sort(cuts.begin(), cuts.end(), [](const auto& u, const auto& v) { return u.first < v.first; });
        const std::uint32_t tri = he.at(edge_key(a, b));
        LPoint last = A;
        for (const auto& [t, p] : cuts) {
          if (p == last || p == B) continue;
          last = p;
          const double z = h.vertices_[a].z + t * (h.vertices_[b].z - h.vertices_[a].z);
          h.vertices_.push_back({p.x, p.y, z});
          const std::uint32_t id = std::uint32_t(h.vertices_.size() - 1);
          out.push_back(id);
          extra[tri].push_back({a, id});
        }
      }
      ring = std::move(out);
    }
    for (auto& [tri, ids] : extra) split_triangle(tri, ids);
    // Rotate every ring to start at a section end of the coarsest level.
    const std::int64_t cs = ks << (L - 1);
    for (auto& ring : rings) {
      const std::size_t n = ring.size();
      std::size_t start = n;
      for (std::size_t i = 0; i < n && start == n; ++i) {
        const std::int64_t c0 = edge_cell(P(ring[(i + n - 1) % n]), P(ring[i]), cs);
        const std::int64_t c1 = edge_cell(P(ring[i]), P(ring[(i + 1) % n]), cs);
        if (c0 < 0 || c1 < 0 || c0 != c1) start = i;
      }
      if (start == n)
        throw HybridError(src + ": a TIN boundary ring lies inside one coarsest grid cell (" +
                          std::to_string(h.step_ << (L - 1)) +
                          " samples); use fewer levels or a smaller grid step");
      std::rotate(ring.begin(), ring.begin() + std::ptrdiff_t(start), ring.end());
    }
    h.ring_begin_.push_back(0);
    for (const auto& ring : rings) {
      h.tb_.insert(h.tb_.end(), ring.begin(), ring.end());
      h.ring_begin_.push_back(std::uint32_t(h.tb_.size()));
    }
    h.conn_.assign(h.tb_.size(), 1);
  }

  void split_triangle(std::uint32_t tri, const std::vector<std::pair<std::uint32_t, std::uint32_t>>& ids) {
    const auto t = h.tin_[tri];
    std::vector<std::uint32_t> poly;
    for (int k = 0; k < 3; ++k) {
      poly.push_back(t[k]);
      for (const auto& [a, id] : ids)
        if (a == t[k]) poly.push_back(id);  // new vertices of edge t[k] -> t[k+1], in order
    }
    std::vector<LPoint> pts(h.vertices_.size());
    for (std::uint32_t v : poly) pts[v] = P(v);
    std::vector<std::array<std::uint32_t, 3>> out;
    if (!detail::ear_clip(pts, poly, out))
      throw HybridError(src + ": TIN triangle " + std::to_string(tri) +
                        " is too thin to be split where its boundary edge crosses a grid line");
    h.tin_[tri] = out[0];
    for (std::size_t i = 1; i < out.size(); ++i) h.tin_.push_back(out[i]);
  }

  /// Cell (row * huge + col packed) of an edge at cell size cs, or -1 if it lies on a grid line.
  static std::int64_t edge_cell(const LPoint& a, const LPoint& b, std::int64_t cs) {
    const std::int64_t mx = a.x + b.x, my = a.y + b.y;
    if (mx % (2 * cs) == 0 || my % (2 * cs) == 0) return -1;
    return (my / (2 * cs)) * (std::int64_t(1) << 31) + mx / (2 * cs);
  }

  // --- Step 2: per level, sections, cycles, classification, convexification. -----------------
  struct Section {
    std::uint32_t A = 0, L = 0;  // TB start, vertex count (wrapping within the ring)
    std::int64_t tau_a = 0, tau_b = 0;
    std::uint8_t C = 0, I = 0;
    int next = -1;
  };
  struct Cycle {
    std::vector<std::uint32_t> seq;   // TB indices
    std::vector<int> sections;        // indices into the cell's sections, cycle order
    std::vector<LPoint> corners;      // the uncovered corners after the last section, positive order
    std::vector<std::uint32_t> hull;  // direct hull chain (TB indices)
    std::vector<std::size_t> gaps;    // positions of section exits followed by a border gap
  };
  struct CellWork {
    std::uint32_t cell = 0;
    std::vector<Section> sections;
    std::vector<Cycle> cycles;
  };
  // Finer-level membership: TB index -> (group id, last TB index of the group) for non-last members.
  std::vector<std::int64_t> prev_group_last_;  // -1 = not a non-last member
  std::vector<std::int64_t> cur_group_last_;
  // Direct hulls for verification: (level, cell, cycle) -> chain.
  std::map<std::tuple<int, std::uint32_t, int>, std::vector<std::uint32_t>> hulls_;

  std::uint32_t section_tb(const Section& s, std::uint32_t k) const {
    std::uint32_t t = s.A;
    for (std::uint32_t i = 0; i < k; ++i) t = next_tb(t);
    return t;
  }

  static std::int64_t tau(const LPoint& p, std::int64_t x0, std::int64_t y0, std::int64_t cs) {
    const std::int64_t x1 = x0 + cs, y1 = y0 + cs;
    if (p.y == y0) return p.x - x0;
    if (p.x == x1) return cs + (p.y - y0);
    if (p.y == y1) return 2 * cs + (x1 - p.x);
    return 3 * cs + (y1 - p.y);
  }

  void process_level(int l) {
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

  void close_section(std::map<std::uint32_t, CellWork>& cells, const Section& s, std::int64_t packed,
                     int cx) {
    const std::uint32_t cell = std::uint32_t((packed >> 31) * cx + (packed & ((std::int64_t(1) << 31) - 1)));
    CellWork& w = cells[cell];
    w.cell = cell;
    w.sections.push_back(s);
  }

  /// At the common point v of exit(si) and entry(sj): is the border direction of decreasing tau
  /// inside the TIN wedge at v (between sj's first edge and si's last edge, TIN on the left)?
  bool border_behind_covered(const Section& si, const Section& sj, std::int64_t x0, std::int64_t y0,
                             std::int64_t cs) {
    const LPoint v = TP(sj.A), prev = TP(section_tb(si, si.L - 2)), next = TP(next_tb(sj.A));
    const std::int64_t t = tau(v, x0, y0, cs);
    const std::int64_t side = ((t - 1 + 4 * cs) % (4 * cs)) / cs;  // edge holding tau - epsilon
    static const LPoint dir[4] = {{-1, 0}, {0, -1}, {1, 0}, {0, 1}};
    const LPoint w{v.x + dir[side].x, v.y + dir[side].y};
    const bool l1 = orient(v, next, w) > 0, l2 = orient(prev, v, w) > 0;
    return orient(prev, v, next) > 0 ? (l1 && l2) : (l1 || l2);
  }

  void build_cycles(int l, CellWork& w, std::int64_t cs, int cx) {
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
        throw HybridError(src + ": " + cell_name(l, w.cell, cx) +
                          ": TIN boundary sections do not form cycles");
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

  /// Hull chain of a cycle: convex hull of the cycle's vertices and the corners not in its arc,
  /// walked CCW from the first to the last vertex of the sequence (collinear points kept).
  std::vector<std::size_t> hull_chain(int l, std::uint32_t cell, int cx, const Cycle& cyc, std::int64_t x0,
                                      std::int64_t y0, std::int64_t cs) {
    struct Pt {
      LPoint p;
      long pos;  // sequence position, or -1 for a corner
    };
    std::vector<Pt> pts;
    for (std::size_t i = 0; i < cyc.seq.size(); ++i) pts.push_back({TP(cyc.seq[i]), long(i)});
    const LPoint corner[4] = {{x0, y0}, {x0 + cs, y0}, {x0 + cs, y0 + cs}, {x0, y0 + cs}};
    for (const LPoint& c : corner) {
      const bool in_arc = std::find(cyc.corners.begin(), cyc.corners.end(), c) != cyc.corners.end();
      const bool is_vertex = std::any_of(pts.begin(), pts.end(), [&](const Pt& q) { return q.p == c; });
      if (!in_arc && !is_vertex) pts.push_back({c, -1});
    }
    // Andrew's monotone chain, strict.
    std::vector<Pt> s = pts;
    std::sort(s.begin(), s.end(),
              [](const Pt& a, const Pt& b) { return a.p.x != b.p.x ? a.p.x < b.p.x : a.p.y < b.p.y; });
    std::vector<LPoint> hull;
    for (int pass = 0; pass < 2; ++pass) {
      const std::size_t base = hull.size();
      for (const Pt& q : s) {
        while (hull.size() >= base + 2 && orient(hull[hull.size() - 2], hull.back(), q.p) <= 0)
          hull.pop_back();
        hull.push_back(q.p);
      }
      hull.pop_back();
      std::reverse(s.begin(), s.end());
    }
    // Boundary walk with collinear points: for each hull edge, every point on it in order.
    std::vector<Pt> ring;
    for (std::size_t k = 0; k < hull.size(); ++k) {
      const LPoint a = hull[k], b = hull[(k + 1) % hull.size()];
      std::vector<std::pair<double, Pt>> on;
      for (const Pt& q : pts)
        if (detail::on_segment(a, b, q.p) && !(q.p == b))
          on.push_back({std::hypot(double(q.p.x - a.x), double(q.p.y - a.y)), q});
      std::sort(on.begin(), on.end(), [](const auto& u, const auto& v) {
        return u.first != v.first ? u.first < v.first : u.second.pos < v.second.pos;
      });
      for (const auto& [d, q] : on) ring.push_back(q);
    }
    const long last = long(cyc.seq.size() - 1);
    std::size_t start = ring.size();
    for (std::size_t k = 0; k < ring.size(); ++k)
      if (ring[k].pos == 0) start = k;
    auto fail = [&](const std::string& why) {
      return HybridError(src + ": " + cell_name(l, cell, cx) + ": " + why);
    };
    if (start == ring.size()) throw fail("the first vertex of a section is not on the convex hull");
    std::vector<std::size_t> chain;
    for (std::size_t k = 0; k < ring.size(); ++k) {
      const Pt& q = ring[(start + k) % ring.size()];
      if (q.pos < 0) throw fail("the convex hull chain passes a cell corner (unsupported configuration)");
      if (!chain.empty() && std::size_t(q.pos) <= chain.back()) continue;  // duplicate position
      chain.push_back(std::size_t(q.pos));
      if (q.pos == last) break;
    }
    if (chain.back() != std::size_t(last))
      throw fail("the convex hull chain does not reach the section's end");
    return chain;
  }

  void convexify(int l, std::uint32_t cell, int cx, Cycle& cyc) {
    const std::int64_t cs = ks << l;
    const std::int64_t x0 = std::int64_t(cell % std::uint32_t(cx)) * cs,
                       y0 = std::int64_t(cell / std::uint32_t(cx)) * cs;
    const std::vector<std::size_t> chain = hull_chain(l, cell, cx, cyc, x0, y0, cs);
    for (std::size_t p : chain) cyc.hull.push_back(cyc.seq[p]);
    std::unordered_map<std::uint32_t, std::size_t> pos;
    for (std::size_t i = 0; i < cyc.seq.size(); ++i) pos.emplace(cyc.seq[i], i);
    const std::uint32_t n = std::uint32_t(h.tb_.size());
    for (std::size_t k = 0; k + 1 < chain.size(); ++k) {
      const std::size_t p = chain[k], q = chain[k + 1];
      if (q == p + 1) continue;
      // Reduced polygon: finer cavities collapsed to their lids.
      std::vector<std::size_t> R{p};
      std::size_t r = p;
      while (r < q) {
        const std::uint32_t t = cyc.seq[r];
        std::size_t nx = r + 1;
        if (h.conn_[t] > 1 && !std::binary_search(cyc.gaps.begin(), cyc.gaps.end(), r)) {
          auto it = pos.find((t + h.conn_[t]) % n);
          if (it == pos.end() || it->second <= r || it->second > q)
            throw HybridError(
                src + ": " + cell_name(l, cell, cx) +
                ": a finer level's cavity crosses this level's convex hull (unsupported configuration)");
          nx = it->second;
        }
        r = nx;
        R.push_back(r);
      }
      if (R.size() == 2) continue;  // already filled at a finer level
      triangulate_pocket(l, cell, cx, cyc, R);
    }
  }

  // Triangulation of one reduced pocket polygon in the fan-with-nested-cavities form that one
  // connectivity index per vertex encodes, preferring triangulations that every finer level still
  // decodes exactly (see the note on constraints R1/R2 below). Memoised search, O(N^4) worst case.
  struct Pocket {
    std::vector<LPoint> pt;
    std::vector<std::int64_t> last;  // reduced index of the finer group's last vertex; -1 free; N+1 beyond
    std::vector<char> fixed;         // section exits: may not open a cavity here
    std::vector<std::vector<char>> diag;
    bool constrained = true;
    std::unordered_map<std::uint64_t, int> memo;  // -> chosen s' + 1, or 0 = impossible
  };

  static std::uint64_t key(std::size_t a, std::size_t s, std::size_t j, bool need) {
    return (std::uint64_t(a) << 40) | (std::uint64_t(s) << 20) | (std::uint64_t(j) << 1) | (need ? 1 : 0);
  }

  // R1: a new cavity of k must end beyond the finer group that k belongs to (else the finer level
  // would decode it as its own). R2: then k's finer successor must open such a cavity too, unless
  // it is the group's last vertex (else the finer level would fan k too far).
  bool cave(Pocket& pk, std::size_t k, std::size_t j) {
    if (!pk.diag[k][j] || pk.fixed[k]) return false;
    bool need = false;
    if (pk.constrained && pk.last[k] >= 0) {
      if (std::int64_t(j) <= pk.last[k]) return false;
      need = std::int64_t(k + 1) != pk.last[k];
    }
    return fan(pk, k, k + 1, j, need);
  }

  bool fan(Pocket& pk, std::size_t a, std::size_t s, std::size_t j, bool need) {
    if (s == j) return !need;
    const std::uint64_t kk = key(a, s, j, need);
    if (auto it = pk.memo.find(kk); it != pk.memo.end()) return it->second > 0;
    pk.memo[kk] = 0;
    for (std::size_t s2 = s + 1; s2 <= j; ++s2) {
      if (need && s2 == s + 1) continue;
      if (orient(pk.pt[a], pk.pt[s], pk.pt[s2]) == 0) continue;
      if (s2 != j && !pk.diag[a][s2]) continue;
      if (s2 > s + 1 && !cave(pk, s, s2)) continue;
      if (!fan(pk, a, s2, j, false)) continue;
      pk.memo[kk] = int(s2) + 1;
      return true;
    }
    return false;
  }

  void emit(Pocket& pk, const std::vector<std::uint32_t>& tbs, std::size_t a, std::size_t s, std::size_t j,
            bool need, int l, std::uint32_t cell) {
    while (s != j) {
      const std::size_t s2 = std::size_t(pk.memo.at(key(a, s, j, need)) - 1);
      std::array<std::uint32_t, 3> tri{tbs[a], tbs[s2], tbs[s]};
      if (orient(pk.pt[a], pk.pt[s2], pk.pt[s]) < 0) std::swap(tri[1], tri[2]);
      h.direct_.push_back({l, cell, tri});
      if (s2 > s + 1) {
        h.conn_[tbs[s]] = dist(tbs[s], tbs[s2]);
        bool need2 = false;
        if (pk.constrained && pk.last[s] >= 0) need2 = std::int64_t(s + 1) != pk.last[s];
        emit(pk, tbs, s, s + 1, s2, need2, l, cell);
      }
      s = s2;
      need = false;
    }
  }

  void triangulate_pocket(int l, std::uint32_t cell, int cx, const Cycle& cyc,
                          const std::vector<std::size_t>& R) {
    const std::size_t N = R.size() - 1;
    if (N > 400)
      throw HybridError(src + ": " + cell_name(l, cell, cx) + ": a cavity of " + std::to_string(N + 1) +
                        " hull vertices is too large (limit 401)");
    Pocket pk;
    std::vector<std::uint32_t> tbs;
    for (std::size_t r : R) {
      tbs.push_back(cyc.seq[r]);
      pk.pt.push_back(TP(cyc.seq[r]));
    }
    pk.fixed.assign(N + 1, 0);
    for (std::size_t k = 0; k <= N; ++k)
      pk.fixed[k] = std::binary_search(cyc.gaps.begin(), cyc.gaps.end(), R[k]);
    if (pk.fixed[0])
      throw HybridError(
          src + ": " + cell_name(l, cell, cx) +
          ": a cavity starts at a section's exit point (unsupported configuration); use fewer levels");
    // Finer-level groups.
    pk.last.assign(N + 1, -1);
    for (std::size_t k = 0; k <= N; ++k) {
      const std::int64_t g = prev_group_last_.empty() ? -1 : prev_group_last_[tbs[k]];
      if (g < 0) continue;
      pk.last[k] = std::int64_t(N + 1);
      for (std::size_t m = k + 1; m <= N; ++m)
        if (tbs[m] == std::uint32_t(g)) {
          pk.last[k] = std::int64_t(m);
          break;
        }
    }
    // Valid diagonals of the polygon R_0..R_N closed by the lid.
    pk.diag.assign(N + 1, std::vector<char>(N + 1, 0));
    // CCW order of the pocket: R_0, R_N, R_{N-1}, ..., R_1.
    auto ccw_next = [&](std::size_t k) { return k == 0 ? N : k - 1; };
    auto ccw_prev = [&](std::size_t k) { return k == N ? 0 : k + 1; };
    auto in_cone = [&](std::size_t a, std::size_t b) {
      const LPoint& A = pk.pt[a];
      const LPoint& B = pk.pt[b];
      const LPoint& A0 = pk.pt[ccw_prev(a)];
      const LPoint& A1 = pk.pt[ccw_next(a)];
      if (orient(A, A1, A0) >= 0) return orient(A, B, A0) > 0 && orient(B, A, A1) > 0;
      return !(orient(A, B, A1) >= 0 && orient(B, A, A0) >= 0);
    };
    for (std::size_t a = 0; a <= N; ++a)
      for (std::size_t b = a + 2; b <= N; ++b) {
        if (a == 0 && b == N) {
          pk.diag[a][b] = 1;
          continue;
        }
        bool ok = in_cone(a, b) && in_cone(b, a);
        for (std::size_t e = 0; e <= N && ok; ++e) {
          const std::size_t f = (e == N) ? 0 : e + 1;  // edge e -> f (the lid for e == N)
          if (e == a || e == b || f == a || f == b) {
            // Adjacent edge: only a collinear overlap is a problem.
            const std::size_t other = (e == a || e == b) ? f : e;
            if (other != a && other != b && detail::on_segment(pk.pt[a], pk.pt[b], pk.pt[other])) ok = false;
            continue;
          }
          if (detail::segments_meet(pk.pt[a], pk.pt[b], pk.pt[e], pk.pt[f])) ok = false;
        }
        pk.diag[a][b] = ok ? 1 : 0;
      }
    bool need0 = false, ok = true;
    if (pk.last[0] >= 0) {
      ok = std::int64_t(N) > pk.last[0];
      need0 = std::int64_t(1) != pk.last[0];
    }
    if (!(ok && fan(pk, 0, 1, N, need0))) {
      pk.constrained = false;
      pk.memo.clear();
      need0 = false;
      if (!fan(pk, 0, 1, N, false))
        throw HybridError(src + ": " + cell_name(l, cell, cx) +
                          ": a cavity of the convexification cannot be triangulated");
    }
    h.conn_[tbs[0]] = dist(tbs[0], tbs[N]);
    emit(pk, tbs, 0, 1, N, need0, l, cell);
  }

  // --- Step 3: sub-cell trees and verification. ----------------------------------------------
  void build_trees() {
    for (int l = 0; l < L; ++l) {
      LevelEncoding& enc = h.levels_[std::size_t(l)];
      enc.tree.clear();
      enc.tree_offset.assign(1, 0);
      for (const PcCell& pc : enc.vc) {
        if (l > 0) {
          std::vector<std::pair<int, std::uint32_t>> queue{{l, pc.cell}};
          for (std::size_t qi = 0; qi < queue.size(); ++qi) {
            const auto [ql, qc] = queue[qi];
            const LevelEncoding& up = h.levels_[std::size_t(ql)];
            const LevelEncoding& dn = h.levels_[std::size_t(ql - 1)];
            const std::uint32_t i = qc % std::uint32_t(up.cells_x), j = qc / std::uint32_t(up.cells_x);
            for (std::uint32_t q = 0; q < 4; ++q) {
              const std::uint32_t ci = 2 * i + (q & 1), cj = 2 * j + (q >> 1);
              const std::uint32_t child = cj * std::uint32_t(dn.cells_x) + ci;
              const CellClass cc = dn.gc[child];
              enc.tree.push_back(std::uint8_t(cc));
              if (cc == CellClass::PC && ql - 1 > 0) queue.push_back({ql - 1, child});
            }
          }
        }
        enc.tree_offset.push_back(std::uint32_t(enc.tree.size()));
      }
    }
  }

  void verify() {
    for (int l = 0; l < L; ++l) {
      const LevelEncoding& enc = h.levels_[std::size_t(l)];
      for (const PcCell& pc : enc.vc) {
        auto dec = h.decoded_fill(l, pc.cell), dir = h.direct_fill(l, pc.cell);
        auto canon = [](std::vector<std::array<std::uint32_t, 3>> v) {
          for (auto& t : v) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
          std::sort(v.begin(), v.end());
          return v;
        };
        if (canon(dec) != canon(dir))
          throw HybridError(src + ": " + cell_name(l, pc.cell, enc.cells_x) +
                            ": the one-index connectivity cannot encode this level's convexification "
                            "(decoded " +
                            std::to_string(dec.size()) + " triangles, direct " + std::to_string(dir.size()) +
                            "); use fewer levels");
        const CellTessellation t = Extractor::tessellate(h, l, pc);
        double tri_area2 = 0, u_area2 = 0;
        auto pt = [&](std::uint32_t tb) { return TP(tb); };
        for (const auto& f : t.fill) tri_area2 += detail::area2({pt(f[0]), pt(f[1]), pt(f[2])});
        const std::int64_t cs = ks << l;
        const std::int64_t x0 = std::int64_t(pc.cell % std::uint32_t(enc.cells_x)) * cs;
        const std::int64_t y0 = std::int64_t(pc.cell / std::uint32_t(enc.cells_x)) * cs;
        for (const auto& c : t.corner_tris) {
          std::vector<LPoint> tri;
          for (const CellRef& r : c)
            tri.push_back(r.corner
                              ? LPoint{x0 + ((r.id == 1 || r.id == 2) ? cs : 0), y0 + (r.id >= 2 ? cs : 0)}
                              : pt(r.id));
          const double a = detail::area2(tri);
          if (!(a > 0))
            throw HybridError(src + ": " + cell_name(l, pc.cell, enc.cells_x) +
                              ": a corner triangle is flipped or degenerate");
          tri_area2 += a;
        }
        for (double a : t.uncovered_area2) u_area2 += a;
        if (std::abs(tri_area2 - u_area2) > 1e-9 * std::max(1.0, u_area2))
          throw HybridError(src + ": " + cell_name(l, pc.cell, enc.cells_x) +
                            ": convexification and corner triangles do not cover the uncovered area exactly "
                            "(unsupported configuration)");
        for (std::size_t k = 0; k < t.hulls.size(); ++k) {
          auto it = hulls_.find({l, pc.cell, int(k)});
          if (it == hulls_.end() || it->second != t.hulls[k])
            throw HybridError(src + ": " + cell_name(l, pc.cell, enc.cells_x) +
                              ": the decoded convex hull differs from the direct one; use fewer levels");
        }
      }
    }
  }
};

// ---------------------------------------------------------------------------------------------

std::vector<std::array<std::uint32_t, 3>> HybridTerrain::direct_fill(int level, std::uint32_t cell) const {
  const LevelEncoding& enc = levels_.at(std::size_t(level));
  std::vector<std::array<std::uint32_t, 3>> out;
  for (const FillRecord& f : direct_) {
    if (f.level > level) continue;
    const int shift = level - f.level;
    const std::uint32_t fx = f.cell % std::uint32_t(levels_[std::size_t(f.level)].cells_x);
    const std::uint32_t fy = f.cell / std::uint32_t(levels_[std::size_t(f.level)].cells_x);
    if ((fy >> shift) * std::uint32_t(enc.cells_x) + (fx >> shift) == cell) out.push_back(f.tri);
  }
  return out;
}

HybridTerrain HybridTerrain::build(const pm::Heightfield& grid, const TinMesh& tin, const HybridOptions& o) {
  return build(
      grid.width(), grid.height(),
      [&](int col, int row) {
        return grid.valid(col, row) ? grid.at(col, row) : std::numeric_limits<double>::quiet_NaN();
      },
      grid.source, tin, o);
}

HybridTerrain HybridTerrain::build(int width, int height, const std::function<double(int, int)>& node_z,
                                   const std::string& source, const TinMesh& tin, const HybridOptions& o) {
  assert(o.grid_step >= 1 && o.levels >= 1 && o.levels <= 16);
  HybridTerrain h;
  Builder b(h);
  b.src = tin.source.empty() ? std::string("TIN") : tin.source;
  b.L = o.levels;
  h.step_ = o.grid_step;
  const int coarse = o.grid_step << (o.levels - 1);
  const int ncx = (width - 1) / coarse, ncy = (height - 1) / coarse;
  if (ncx < 1 || ncy < 1)
    throw HybridError(source + ": a " + std::to_string(width) + "x" + std::to_string(height) +
                      " grid holds no coarsest cell of " + std::to_string(coarse) + " samples (grid step " +
                      std::to_string(o.grid_step) + ", " + std::to_string(o.levels) + " levels)");
  h.domain_w_ = ncx * coarse;
  h.domain_h_ = ncy * coarse;
  const int nx = h.domain_w_ / o.grid_step + 1, ny = h.domain_h_ / o.grid_step + 1;
  h.grid_z_.resize(std::size_t(nx) * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const double z = node_z(i * o.grid_step, j * o.grid_step);
      if (std::isnan(z))
        throw HybridError(source + ": grid node (" + std::to_string(i * o.grid_step) + "," +
                          std::to_string(j * o.grid_step) + ") is a void");
      h.grid_z_[std::size_t(j) * nx + i] = z;
    }
  b.ks = std::int64_t(o.grid_step) * kScale;
  b.load_tin(tin);
  h.levels_.resize(std::size_t(o.levels));
  for (int l = 0; l < o.levels; ++l) b.process_level(l);
  b.build_trees();
  b.verify();
  return h;
}

}  // namespace terralod::blocks::hybrid
