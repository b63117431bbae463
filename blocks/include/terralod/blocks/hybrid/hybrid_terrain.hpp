// Hybrid terrain: a multiresolution reference grid joined without cracks to TIN microstructures
// by incremental local convexification and corner tessellation (Boo, Amor, Doellner 2007).
//
// Usage:
//   namespace hy = terralod::blocks::hybrid;
//   pm::Heightfield dem = terralod::blocks::read_dem("N44W072.hgt");
//   hy::TinMesh tin = hy::tin_from_world(pm::read_ply("valley.ply"), dem.transform);
//   hy::HybridTerrain h = hy::HybridTerrain::build(dem, tin, {.grid_step = 4, .levels = 3});
//   hy::HybridMesh m = h.extract(/*level=*/1, hy::Scheme::Triangles);   // (col,row,z), CCW
//   pm::write_mesh(hy::to_world(m, dem.transform), "hybrid.ply");
//   std::vector<std::uint8_t> blob = h.encode();                        // into hybrid.db
//   hy::HybridTerrain back = hy::HybridTerrain::decode(blob, "hybrid.db");
//
// Model (all coordinates in (col,row) samples of the reference DEM; CCW = orient2d > 0 there):
//   - Grid level l (0 = finest) has square cells of grid_step * 2^l samples; its nodes carry the
//     DEM heights. The domain is the largest [0, W] x [0, H] whole number of coarsest cells.
//   - The TIN (one or more, merged) must be a plan-view manifold triangulation inside the domain.
//     Its positions are snapped to 1/65536 of a sample (exact integer predicates). Its boundary rings
//     (outer rings and holes, TIN on the left) form the TIN Boundary (TB) array. Every point where
//     a ring meets a finest-level cell border becomes a TB vertex (the paper's intersection
//     vertices): height interpolated along the TIN edge, the adjacent TIN triangle split.
//   - Per level, every cell is NC (TIN-free interior), CC (interior covered) or PC; the Grid
//     Classification list codes them 0 / 10 / 11 in row order.
//   - Inside a PC cell the TIN boundary forms sections (maximal runs of ring edges inside the
//     open cell, also ended where the ring touches the cell border). Sections that bound the same
//     uncovered region are chained into a cycle (the paper's appendix: several sections per
//     cell), walking the border from each exit with the uncovered side on the right. The convex
//     hull of the cell minus that region is computed; the cavities between hull and sections are
//     filled with triangles that keep every finer level's triangles (incremental
//     convexification, finest to coarsest). A section's exit that is followed by a border gap in
//     its cycle never opens a cavity in that cell (its index belongs to the neighbour cell where
//     it is an entry). Among the triangulations of a cavity the builder searches for one whose
//     one-index encoding every finer level still decodes exactly.
//   - Every TB vertex stores one connectivity index (farthest vertex it is joined to, as a TB
//     offset); the Vertex Classification list stores per PC cell and section (A, L)(C, I) plus a
//     cycle-end flag. decode_cavities (Fig. 7) rebuilds any level's triangles from it; build()
//     checks, for every level and cell, that the decode equals the direct convexification, and
//     that convexification + corner triangles cover exactly the uncovered area.
//   - Scheme::Triangles: NC cells as two triangles, PC cells as convexification + corner
//     triangles. Scheme::SubCells (paper section 5): PC cells are split recursively by the sub-cell
//     tree (codes 0/10/11 per child, breadth first) down to the finest level; NC sub-cells are
//     grid cells with the DEM's own node heights (the paper interpolates the parent's corners;
//     T-junction removal keeps the result watertight either way), unit PC sub-cells get the
//     finest level's convexification and corner tessellation.
//   - Any mix of levels over the coarsest cells (extract_mixed) is watertight: every triangle edge
//     that runs along a grid line is split at every output vertex lying on it (T-junction removal),
//     and a position shared by grid and TIN uses the TIN vertex's height.
//
// Unsupported configurations throw HybridError naming the level and cell: a boundary ring inside
// one coarsest cell (use fewer levels), an uncovered region of one cell bounded by several
// sections and reaching two separate groups of corners (the paper's Fig. 16 case), a cavity
// starting at a section's exit, and cavities that one connectivity index per vertex cannot
// encode at every level. build() never returns a model it has not decoded and checked.
//
// Memory: the model holds the DEM's grid nodes (8 bytes each), the TIN (32 bytes per vertex, 12 per
// triangle), 8 bytes per TB vertex and 1 byte per cell of every level; build() temporarily needs
// O(TB vertices * levels). Extraction output: ~2 triangles per NC cell plus the TIN.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/blocks/hybrid/convexification.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/mesh_io.hpp"

namespace terralod::blocks::hybrid {

/// Bad input data or an unsupported configuration; what() names the source and the problem.
class HybridError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct HybridOptions {
  int grid_step = 4;  ///< K: samples between finest-level grid nodes, >= 1
  int levels = 3;     ///< grid levels, >= 1 (level l: cells of grid_step * 2^l samples)
};

/// A TIN in (col,row) sample coordinates of the reference grid plus heights in metres.
struct TinMesh {
  std::vector<std::array<double, 3>> points;            ///< (col, row, z)
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< any winding; made CCW by build()
  std::string source;                                   ///< for error messages
};

/// Maps a world-frame mesh (x, y metres, z) into (col,row) of `transform` (must be invertible).
TinMesh tin_from_world(const pm::TriangleMeshData& world, const pm::GridTransform& transform,
                       const std::string& source = {});
/// Concatenates several TINs (they must not overlap; build() checks the union).
TinMesh merge_tins(const std::vector<TinMesh>& tins);

enum class CellClass : std::uint8_t { NC = 0, CC = 2, PC = 3 };  ///< GC codes 0, 10, 11
enum class Scheme : std::uint8_t { Triangles, SubCells };

/// One section of a PC cell: (A, L) the TB run, (C, I) the corners after it, and whether it
/// closes its cycle (the corners then belong to the cycle's hull chain).
struct SectionCode {
  std::uint32_t A = 0, L = 0;
  std::uint8_t C = 0, I = 0;
  bool closes = true;
  bool operator==(const SectionCode&) const = default;
};
struct PcCell {
  std::uint32_t cell = 0;  ///< row * cells_x + col at this level
  std::vector<SectionCode> sections;
  bool operator==(const PcCell&) const = default;
};
struct LevelEncoding {
  int cells_x = 0, cells_y = 0, cell_size = 0;  ///< cell_size in samples
  std::vector<CellClass> gc;                    ///< row order
  std::vector<PcCell> vc;                       ///< the PC cells, row order
  std::vector<std::uint8_t> tree;               ///< sub-cell tree codes of all PC cells, concatenated
  std::vector<std::uint32_t> tree_offset;       ///< per vc entry + 1: its codes in `tree`
  bool operator==(const LevelEncoding&) const = default;
};

/// An extracted hybrid mesh in (col,row,z); triangles CCW in (col,row).
struct HybridMesh {
  std::vector<std::array<double, 3>> points;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::size_t grid_triangles = 0, tin_triangles = 0, convexification_triangles = 0, corner_triangles = 0,
              split_edges = 0;  ///< triangles split by T-junction removal
};

/// World-frame copy (x, y from `transform`, z); winding flipped when determinant() < 0 so that
/// faces stay CCW seen from above.
pm::TriangleMeshData to_world(const HybridMesh& mesh, const pm::GridTransform& transform);

/// The paper's Table 2 for one level, plus the sub-cell tree cost.
struct LevelReport {
  int level = 0, cells = 0, nc = 0, cc = 0, pc = 0;
  double pc_percent = 0;
  std::uint32_t max_connectivity = 0;  ///< largest cavity (TB offset) decoded at this level
  std::uint32_t l_max = 0;             ///< longest section (vertices)
  int bits_per_section = 0;            ///< bits(A) + bits(L_max) + 2 (C) + 2 (I)
  std::uint64_t gc_bits = 0, vc_bits = 0;
  double tree_bits_per_pc = 0;  ///< sub-cell tree bits per PC cell (mean)
  std::uint64_t tree_bits_max = 0;
  std::size_t sections = 0;
};
struct StorageReport {
  std::size_t tb_vertices = 0, rings = 0, tin_vertices = 0, tin_triangles = 0;
  std::uint32_t max_connectivity = 0;
  int connectivity_bits = 0, address_bits = 0;
  std::vector<LevelReport> levels;
};

class HybridTerrain {
 public:
  /// Builds the model (see the header comment). Throws HybridError on bad data.
  static HybridTerrain build(const pm::Heightfield& grid, const TinMesh& tin,
                             const HybridOptions& options = {});
  /// The same from the grid nodes alone (all build() reads of the DEM): a `width` x `height`
  /// sample grid whose node (col, row), both multiples of grid_step, has height node_z(col, row)
  /// (NaN = a void). `source` names the grid in errors. The tree builder's hybrid node strategy
  /// uses it over a window of a larger DEM without copying the window.
  static HybridTerrain build(int width, int height, const std::function<double(int, int)>& node_z,
                             const std::string& source, const TinMesh& tin,
                             const HybridOptions& options = {});

  int levels() const { return int(levels_.size()); }
  int grid_step() const { return step_; }
  int domain_width() const { return domain_w_; }   ///< samples
  int domain_height() const { return domain_h_; }  ///< samples
  const LevelEncoding& level(int l) const { return levels_.at(std::size_t(l)); }
  const std::vector<std::uint32_t>& tb() const { return tb_; }              ///< TB index -> vertex id
  const std::vector<std::uint32_t>& connectivity() const { return conn_; }  ///< per TB index
  const std::vector<std::uint32_t>& ring_begin() const { return ring_begin_; }
  /// Position (col,row) of a TB vertex.
  PlanPoint tb_point(std::uint32_t tb_index) const;

  /// The whole grid at one level (0 <= level < levels()).
  HybridMesh extract(int level, Scheme scheme = Scheme::Triangles) const;
  /// One level per coarsest cell (row order, size = coarsest cells, values in [0, levels())).
  HybridMesh extract_mixed(std::span<const int> coarse_levels, Scheme scheme = Scheme::Triangles) const;

  /// Convexification triangles of one PC cell decoded from the stored encoding (TB indices, CCW).
  std::vector<std::array<std::uint32_t, 3>> decoded_fill(int level, std::uint32_t cell) const;
  /// The same triangles as computed directly by build() (before encoding), CCW.
  std::vector<std::array<std::uint32_t, 3>> direct_fill(int level, std::uint32_t cell) const;

  StorageReport storage_report() const;

  /// Self-contained blob (format documented in hybrid_terrain.cpp), version + CRC-32.
  std::vector<std::uint8_t> encode() const;
  /// Throws HybridError naming `what` on a truncated, corrupt or foreign blob.
  static HybridTerrain decode(std::span<const std::uint8_t> blob, const std::string& what);

  struct Vertex {
    std::int64_t x = 0, y = 0;  ///< lattice: 1/65536 sample
    double z = 0;
  };

 private:
  friend struct Builder;
  friend struct Extractor;
  int step_ = 1, domain_w_ = 0, domain_h_ = 0;
  std::vector<double> grid_z_;    ///< finest-level nodes, row-major, (domain_w/step + 1) per row
  std::vector<Vertex> vertices_;  ///< TIN vertices incl. intersection vertices
  std::vector<std::array<std::uint32_t, 3>> tin_;  ///< CCW, boundary triangles split
  std::vector<std::uint32_t> tb_, conn_, ring_begin_;
  std::vector<LevelEncoding> levels_;
  // Build-time only (not serialised): direct fill triangles with the level they were made at.
  struct FillRecord {
    int level;
    std::uint32_t cell;  ///< at `level`
    std::array<std::uint32_t, 3> tri;
  };
  std::vector<FillRecord> direct_;
};

}  // namespace terralod::blocks::hybrid
