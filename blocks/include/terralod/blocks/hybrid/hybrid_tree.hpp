// The hybrid grid + TIN terrain as a node strategy of the approximation tree: grid alone far
// away, the hybrid levels (TIN microstructure, convexification, corner triangles) near the
// camera, and the crack-free union of any selection.
//
// Usage:
//   namespace hy = terralod::blocks::hybrid;
//   hy::HybridTerrain h = hy::HybridTerrain::build(dem, tin, {.grid_step = 4, .levels = 3});
//   hy::HybridTree t = hy::HybridTree::build(h, dem);                  // exact node errors
//   db.put_blob("hybrid_tree", terralod::blocks::encode_tree(t.tree()));
//   // ... later, from the database:
//   hy::HybridTree back = hy::HybridTree::attach(h, terralod::blocks::decode_tree(blob, "hybrid.db:
//   hybrid_tree"),
//                                                "hybrid.db");
//   hy::HybridSelection s = back.select(terralod::pm::View(camera), {/*alpha_px=*/2.0});
//   draw(hy::to_world(s.mesh, dem.transform));                         // watertight, CCW
//
// The tree (seeds/approximation-tree.txt section 3 with the node strategy of seeds/
// hybrid-grid-tin-convexification.txt; the coarsest hybrid cells have cs = grid_step *
// 2^(levels-1) samples, cells_x x cells_y of them):
//   - Grid nodes (Strategy::Grid, "grid alone"): a quadtree of groups of G x G coarsest cells
//     (G a power of two, the root's G the smallest covering all cells; groups clipped to the
//     domain, empty ones left out). A group's surface is the grid of spacing cs * G / min(G, P)
//     samples (P = HybridTreeOptions::patch) plus the domain's last row and column, DEM heights
//     (a TIN vertex's height where one sits on a grid node). It ignores the TIN.
//   - A group of one coarsest cell has one child: the Hybrid node of that cell at the coarsest
//     level levels-1, whose only child is the same cell at level levels-2, ..., down to level 0
//     (children refine one level; d = 4 above, 1 in the hybrid chains).
//   - A Hybrid node's surface: the cell's grid triangles of its level, convexification and
//     corner triangles (HybridTerrain::extract's, before T-junction removal), plus the TIN
//     triangles whose centroid lies in the cell (they may reach into neighbouring cells).
//   - Every node's error is exact (max over its triangles of the L-infinity distance to the
//     DEM's full-resolution surface, evaluated at every overlay vertex: corners, samples inside,
//     crossings with the grid's vertical, horizontal and diagonal edges); bbox = the domain's
//     samples and the surface's points.
// Crack-free assembly (select / assemble): the selection is one node per coarsest cell or group.
// TIN triangles tie cells together: coarsest cells whose closed squares meet a TIN triangle's
// bounding rectangle form clusters (union-find). When any cell of a cluster is drawn hybrid,
// every Grid node covering a cell of that cluster is replaced by its children until those
// cells are hybrid (counted in `forced`; it only ever refines), and a cell of that cluster that
// the selection left out (culled) is added at the coarsest hybrid level, so that no TIN triangle
// reaching into a drawn cell is missing (counted in `added`). The union of the drawn surfaces
// is then exactly the triangles of HybridTerrain::extract_mixed for the hybrid cells, plus grid
// cells elsewhere; every edge along a grid line is split at the union's vertices on it
// (extract_mixed's T-junction removal), so the result covers the domain once and is watertight.
//
// Memory: the tree holds every level's hybrid mesh once (about 40 bytes per point, 12 per
// triangle, ~levels x the finest grid's triangles in total) plus the grid quadtree (<= (P+1)^2
// points per node); build() temporarily holds one extracted level. assemble(): the output mesh
// plus a hash of its vertices.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "terralod/blocks/approximation_tree.hpp"
#include "terralod/blocks/hybrid/hybrid_terrain.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::blocks::hybrid {

struct HybridTreeOptions {
  int patch = 2;  ///< P: a grid-only group node has at most P x P grid cells, >= 1
};

/// What one frame draws.
struct HybridSelection {
  SelectionResult selection;        ///< select_nodes' result (before the cluster closure)
  std::vector<std::int64_t> nodes;  ///< the drawn nodes (after the closure)
  std::vector<int>
      cell_level;  ///< per coarsest cell, row order: grid level drawn, -1 = grid alone, -2 = not drawn
  std::size_t forced = 0;  ///< Grid nodes refined by the closure
  std::size_t added = 0;   ///< cells of drawn TIN clusters absent from `selected` (culled), added
  std::size_t hybrid_nodes = 0, grid_nodes = 0;  ///< among `nodes`
  std::size_t tin_triangles = 0;                 ///< TIN triangles drawn (before T-junction splits)
  std::size_t height_conflicts = 0;  ///< plan positions where drawn nodes disagree on z (0 by construction)
  double error_m = 0;                ///< max exact error of the drawn nodes, metres
  /// select() only: max over the drawn nodes of View::vertical_error_px(bbox, error): the bound
  /// of their own surfaces (the T-junction splits along shared borders, which insert a
  /// neighbour's vertices, are not re-measured).
  double bound_px = 0;
  HybridMesh mesh;  ///< the union, (col,row,z), CCW; split_edges = T-junction splits
};

class HybridTree {
 public:
  /// Builds the tree of `h`; `dem` is the full-resolution DEM h was built from (errors are
  /// measured against it). Asserts patch >= 1.
  static HybridTree build(const HybridTerrain& h, const pm::Heightfield& dem,
                          const HybridTreeOptions& options = {});
  /// Joins a stored tree (decode_tree of build()'s tree) to its terrain; HybridError naming
  /// `what` when the tree's shape does not fit h (other levels, cells or strategies).
  static HybridTree attach(const HybridTerrain& h, ApproximationTree tree, const std::string& what);

  const ApproximationTree& tree() const { return tree_; }
  /// Grid level of a Hybrid node (0 = finest), -1 for a Grid node.
  int grid_level(std::int64_t node) const { return node_level_.at(std::size_t(node)); }
  int cells_x() const { return cells_x_; }  ///< coarsest cells per row
  int cells_y() const { return cells_y_; }
  int cell_size() const { return cell_size_; }  ///< samples per coarsest cell side
  /// Cluster of a coarsest cell (row order); -1 when no TIN triangle comes near it.
  int cluster(std::size_t cell) const { return cluster_.at(cell); }

  /// Closure + union of a set of nodes that covers the domain once (as select_nodes returns
  /// without culling). Asserts every id is valid.
  HybridSelection assemble(std::span<const std::int64_t> selected) const;
  /// select_nodes(tree(), view, options), then assemble().
  HybridSelection select(const pm::View& view, const SelectionOptions& options = {}) const;

 private:
  void index(const HybridTerrain& h, const std::string& what);
  ApproximationTree tree_;
  int levels_ = 0, cells_x_ = 0, cells_y_ = 0, cell_size_ = 0;
  std::int64_t line_step_ = 0;          ///< finest grid step, lattice units
  std::vector<int> node_level_;         ///< per node
  std::vector<int> cluster_;            ///< per coarsest cell
  std::vector<std::int64_t> top_node_;  ///< per coarsest cell: its Hybrid node at the coarsest level
  std::vector<std::size_t> tin_owned_;  ///< per coarsest cell: TIN triangles with their centroid in it
};

/// Exact L-infinity distance between the plane of the triangle (a, b, c) ((col, row, z), any
/// winding, non-degenerate) and the full-resolution surface of `dem` over the triangle: max at
/// the corners, the valid samples inside, and the crossings of its edges with the grid's
/// vertical, horizontal and diagonal edges. Points must lie inside the grid.
double triangle_error(const pm::Heightfield& dem, const std::array<double, 3>& a,
                      const std::array<double, 3>& b, const std::array<double, 3>& c);

}  // namespace terralod::blocks::hybrid
