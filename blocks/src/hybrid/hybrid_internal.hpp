// Private interface between the hybrid model's builder, extractor and serialiser: the
// tessellation of one PC cell from the stored encoding (decoder of Fig. 7 + corner tessellation).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "hybrid_geometry.hpp"
#include "terralod/blocks/hybrid/hybrid_terrain.hpp"

namespace terralod::blocks::hybrid {

/// A vertex of a cell's tessellation: a TB index, or a cell corner 0..3 (paper numbering).
struct CellRef {
  bool corner = false;
  std::uint32_t id = 0;
};

struct CellTessellation {
  std::vector<std::array<std::uint32_t, 3>> fill;     ///< TB indices, CCW
  std::vector<std::array<CellRef, 3>> corner_tris;    ///< CCW
  std::vector<std::vector<std::uint32_t>> hulls;      ///< per cycle, TB indices
  std::vector<double> uncovered_area2;                ///< per cycle, twice the uncovered area (lattice units)
  std::vector<std::vector<std::uint32_t>> sequences;  ///< per cycle, TB indices
  std::uint32_t max_connectivity = 0;                 ///< largest cavity closed inside the cell
};

struct Extractor {
  /// Decodes one PC cell of `level`. Throws HybridError if the encoding is inconsistent.
  static CellTessellation tessellate(const HybridTerrain& h, int level, const PcCell& pc);
  static detail::LPoint tb_lpoint(const HybridTerrain& h, std::uint32_t t) {
    const auto& v = h.vertices_[h.tb_[t]];
    return {v.x, v.y};
  }
  static std::uint32_t next_tb(const HybridTerrain& h, std::uint32_t t);
  /// With remove_t_junctions = false the triangles are left as emitted: cell triangles first,
  /// then the TIN's triangles (the last tin(h).size(), in order); points begin with the TIN
  /// vertices (vertices(h), in order).
  static HybridMesh extract(const HybridTerrain& h, const std::vector<int>& coarse_levels, Scheme scheme,
                            bool remove_t_junctions = true);
  static const std::vector<HybridTerrain::Vertex>& vertices(const HybridTerrain& h) { return h.vertices_; }
  static const std::vector<std::array<std::uint32_t, 3>>& tin(const HybridTerrain& h) { return h.tin_; }
};

/// T-junction removal: splits every triangle of `tris` (indices into `lp`) whose edge runs along
/// a grid line (x or y a multiple of `line_step` lattice units) at every point of `lp` strictly
/// inside that edge (ear clipping); returns the number of triangles split. HybridError if a
/// split polygon cannot be triangulated.
std::size_t split_t_junctions(const std::vector<detail::LPoint>& lp,
                              std::vector<std::array<std::uint32_t, 3>>& tris, std::int64_t line_step);

}  // namespace terralod::blocks::hybrid
