// The builder of the hybrid grid + TIN model (private: HybridTerrain::build runs it), its state
// and its steps, one file each (Boo, Amor, Doellner, "Unified hybrid terrain representation
// based on local convexifications", sections 2-5 and the appendix):
//   1. hybrid_build_rings.cpp: the TIN, its boundary rings and their intersection vertices with
//      the finest grid lines (load_tin);
//   2. hybrid_build_cells.cpp: per level, the rings' sections in each cell, their cycles and the
//      cell classification (GC and VC lists; process_level);
//      hybrid_build_convexification.cpp: the local convexification of each cycle, encoded as
//      one connectivity index per TIN-boundary vertex (convexify);
//   3. hybrid_terrain.cpp: the sub-cell trees and the check that the encoding decodes to what
//      was built (build_trees, verify).
// Positions are lattice points (detail::LPoint, kScale units per sample); a TB index is a
// position in HybridTerrain::tb_, the TIN-boundary vertices ring after ring.
#pragma once

#include <algorithm>
#include <cstdint>
#include <map>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "hybrid_geometry.hpp"
#include "terralod/blocks/hybrid/hybrid_terrain.hpp"

namespace terralod::blocks::hybrid {

/// "level <l> cell (<col>,<row>)", for errors.
std::string cell_name(int level, std::uint32_t cell, int cells_x);

struct Builder {
  HybridTerrain& h;
  std::string src;
  int L = 1;
  std::int64_t ks = 0;  // finest cell size in lattice units

  explicit Builder(HybridTerrain& out) : h(out) {}

  detail::LPoint P(std::uint32_t vertex) const { return {h.vertices_[vertex].x, h.vertices_[vertex].y}; }
  detail::LPoint TP(std::uint32_t t) const { return P(h.tb_[t]); }
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

  /// Cell (row * huge + col packed) of an edge at cell size cs, or -1 if it lies on a grid line.
  static std::int64_t edge_cell(const detail::LPoint& a, const detail::LPoint& b, std::int64_t cs) {
    const std::int64_t mx = a.x + b.x, my = a.y + b.y;
    if (mx % (2 * cs) == 0 || my % (2 * cs) == 0) return -1;
    return (my / (2 * cs)) * (std::int64_t(1) << 31) + mx / (2 * cs);
  }

  // --- Step 1: the TIN, its rings and the intersection vertices (hybrid_build_rings.cpp). -----
  void load_tin(const TinMesh& tin);
  void split_triangle(std::uint32_t tri, const std::vector<std::pair<std::uint32_t, std::uint32_t>>& ids);

  // --- Step 2: per level, sections, cycles, classification (hybrid_build_cells.cpp) and
  // convexification (hybrid_build_convexification.cpp). ---------------------------------------
  struct Section {
    std::uint32_t A = 0, L = 0;  // TB start, vertex count (wrapping within the ring)
    std::int64_t tau_a = 0, tau_b = 0;
    std::uint8_t C = 0, I = 0;
    int next = -1;
  };
  struct Cycle {
    std::vector<std::uint32_t> seq;       // TB indices
    std::vector<int> sections;            // indices into the cell's sections, cycle order
    std::vector<detail::LPoint> corners;  // the uncovered corners after the last section, positive order
    std::vector<std::uint32_t> hull;      // direct hull chain (TB indices)
    std::vector<std::size_t> gaps;        // positions of section exits followed by a border gap
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

  static std::int64_t tau(const detail::LPoint& p, std::int64_t x0, std::int64_t y0, std::int64_t cs) {
    const std::int64_t x1 = x0 + cs, y1 = y0 + cs;
    if (p.y == y0) return p.x - x0;
    if (p.x == x1) return cs + (p.y - y0);
    if (p.y == y1) return 2 * cs + (x1 - p.x);
    return 3 * cs + (y1 - p.y);
  }

  void process_level(int l);
  void close_section(std::map<std::uint32_t, CellWork>& cells, const Section& s, std::int64_t packed, int cx);
  bool border_behind_covered(const Section& si, const Section& sj, std::int64_t x0, std::int64_t y0,
                             std::int64_t cs);
  void build_cycles(int l, CellWork& w, std::int64_t cs, int cx);

  std::vector<std::size_t> hull_chain(int l, std::uint32_t cell, int cx, const Cycle& cyc, std::int64_t x0,
                                      std::int64_t y0, std::int64_t cs);
  void convexify(int l, std::uint32_t cell, int cx, Cycle& cyc);
  struct Pocket;  // one reduced pocket polygon being triangulated
  bool cave(Pocket& pk, std::size_t k, std::size_t j);
  bool fan(Pocket& pk, std::size_t a, std::size_t s, std::size_t j, bool need);
  void emit(Pocket& pk, const std::vector<std::uint32_t>& tbs, std::size_t a, std::size_t s, std::size_t j,
            bool need, int l, std::uint32_t cell);
  void triangulate_pocket(int l, std::uint32_t cell, int cx, const Cycle& cyc,
                          const std::vector<std::size_t>& R);

  // --- Step 3: sub-cell trees and verification (hybrid_terrain.cpp). ---------------------------
  void build_trees();
  void verify();
};

}  // namespace terralod::blocks::hybrid
