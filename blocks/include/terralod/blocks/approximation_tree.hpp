// The approximation tree A(s,d): a hierarchy of rectangular terrain patches, each approximated by
// at most s points with an exact error, at most d children per node, mixed node strategies (grid,
// TIN, non-regular grid, PM block), its versioned checksummed serialization, and the per-frame
// selection of patches by frustum culling and visual geometric error.
//
// Usage:
//   namespace tb = terralod::blocks;
//   tb::ApproximationTree tree = tb::decode_tree(*db.read_blob("tree"), db.path() + ": tree");
//   terralod::pm::View view(camera);
//   tb::SelectionResult sel = tb::select_nodes(tree, view, {/*alpha_px=*/2.0});
//   for (std::size_t i = 0; i < sel.selected.size(); ++i) {
//     const tb::TreeNode& n = tree.node(sel.selected[i]);
//     if (n.strategy == tb::Strategy::PmBlock)   // refine the block's PM at sel.visual[i].tolerance_px
//       ...;
//     else                                      // draw n.surface (within n.error metres)
//       ...;
//   }
//
// Paper: seeds/approximation-tree.txt, section 3.1 (definition: domains D_N, |P_N| <= s, at most
// d children partitioning D_N, epsilon_T(N) = max over D_N of |h_T - h_T_N|), section 4
// (rendering: cull by the bounding box, alpha_N = projected length in pixels of a vertical
// segment of length epsilon(N) centred at the point of B_N nearest the camera, descend while
// alpha exceeds the threshold), section 6 (one interface, several strategies).
//
// Contract:
//   - Node ids are dense 0..size()-1, the root is 0, and every child id is larger than its
//     parent's (nodes are stored breadth first). Domains are SampleRects of the whole terrain
//     grid; the children's domains partition the parent's domain as closed cell rectangles:
//     their union is the parent's rectangle and their interiors are disjoint (they share border
//     samples, like blocks do).
//   - TreeNode::error is the exact L-infinity distance (pm::LInfError, the tree's metric)
//     between the node's surface and the full-resolution surface over its domain, metres. For
//     a PM block leaf it is the exact error of the block PM's base mesh (the coarsest surface
//     the block can show; the runtime refinement only lowers it).
//   - TreeNode::bbox (world metres) contains the node's surface and the full-resolution
//     terrain over its domain: x, y from the GridTransform of the domain corners, z the sample
//     height range of the domain (a piecewise-linear surface on samples stays within it).
//   - NodeSurface points are samples: (col, row) of the whole grid and z = the sample's
//     height, bit for bit; triangles are CCW in (col, row) and cover the domain exactly once.
//     Hybrid nodes (hybrid/hybrid_tree.hpp) are the exception: their points may be TIN vertices
//     off the samples, and their TIN triangles belong to the node holding their centroid, so
//     only the union of a whole selection covers the plan exactly once.
//   - Memory: about 200 bytes per node plus 40 bytes per surface point and 12 per triangle.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/sample_rect.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/linf_error.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::blocks {

/// How a node approximates its domain (seeds/approximation-tree.txt, section 3.2).
enum class Strategy : std::uint8_t { Grid = 0, Tin = 1, NonRegularGrid = 2, PmBlock = 3, Hybrid = 4 };
inline constexpr int kStrategyCount = 5;

/// "grid", "tin", "nonregular", "pm_block", "hybrid".
const char* strategy_name(Strategy s);

/// The node's approximating surface (empty for PmBlock: its surface is the block's PM).
struct NodeSurface {
  std::vector<std::array<double, 3>> points;            ///< (col, row, z): whole-grid sample + height, metres
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< indices into points, CCW in (col, row)
  /// Grid and NonRegularGrid only: the sorted columns and rows of the node's grid; points are
  /// then row-major (points[j * cols.size() + i] = (cols[i], rows[j])) and every cell is split
  /// along (cols[i], rows[j])-(cols[i+1], rows[j+1]) like the full-resolution surface.
  std::vector<int> cols, rows;
};

/// Fills surface.triangles for a Grid/NonRegularGrid surface from its cols and rows (two CCW
/// triangles per cell, split along the cell's (cols[i],rows[j])-(cols[i+1],rows[j+1]) diagonal).
void triangulate_grid(NodeSurface& surface);

struct TreeNode {
  std::int64_t id = 0, parent = -1;    ///< root: parent = -1
  std::vector<std::int64_t> children;  ///< at most d
  int level = 0;                       ///< root = 0
  SampleRect domain;                   ///< whole-grid samples
  Strategy strategy = Strategy::Grid;
  double error = 0;               ///< exact epsilon(N), metres (see the contract)
  pm::Box bbox;                   ///< world metres
  std::optional<BlockKey> block;  ///< PmBlock leaves: the block in the database
  NodeSurface surface;
  /// Texture hook (issue "texture layers"): edge length in metres of one texel of the node's
  /// texture patch; 0 = no texture, gamma is then not evaluated.
  double texel_m = 0.0;

  bool leaf() const { return children.empty(); }
};

/// Bad tree bytes. what() = "<name>: <problem>".
class TreeFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class ApproximationTree {
 public:
  /// Build parameters recorded with the tree.
  struct Parameters {
    std::size_t max_points = 25;  ///< s: no node has more surface points
    int max_children = 4;         ///< d: no node has more children
    int patch = 4;                ///< P: grid nodes have (P+1)^2 points (at most)
    pm::ErrorMetric metric = pm::ErrorMetric::Continuous;
    pm::GridTransform transform;  ///< of the whole grid
    int grid_width = 0, grid_height = 0;
    bool operator==(const Parameters&) const = default;
  };

  ApproximationTree() = default;
  /// Takes the nodes as built; asserts ids are dense and parents precede children.
  ApproximationTree(Parameters parameters, std::vector<TreeNode> nodes);

  const TreeNode& root() const { return nodes_.at(0); }
  const TreeNode& node(std::int64_t id) const { return nodes_.at(std::size_t(id)); }
  std::size_t size() const { return nodes_.size(); }
  const std::vector<TreeNode>& nodes() const { return nodes_; }
  const Parameters& parameters() const { return params_; }
  /// Nodes per Strategy (index = the enum's value).
  std::array<std::size_t, kStrategyCount> count_by_strategy() const;
  int depth() const;  ///< largest level + 1 (0 for an empty tree)
  /// Heap bytes the decoded tree holds (its nodes' arrays' capacities).
  std::size_t memory_bytes() const;

 private:
  Parameters params_;
  std::vector<TreeNode> nodes_;
};

/// Serializes a tree (format documented byte by byte in approximation_tree.cpp; version
/// kTreeFormatVersion; CRC-32 trailer). Deterministic. Lossless: decode_tree(encode_tree(t))
/// has the same nodes, bit for bit.
inline constexpr std::uint32_t kTreeFormatVersion = 1;
std::vector<std::uint8_t> encode_tree(const ApproximationTree& tree);
/// Parses encode_tree's bytes; TreeFormatError "<name>: <problem>" for any bad input (safe on
/// hostile bytes: every count is checked against the bytes left).
ApproximationTree decode_tree(std::span<const std::uint8_t> bytes, const std::string& name_for_errors);
/// Bytes of one node's record in encode_tree's format (its share of the tree's size).
std::size_t encoded_node_bytes(const TreeNode& node);

// ---------------------------------------------------------------------------------------------
// Selection (paper section 4)

struct SelectionOptions {
  double alpha_px = 1.0;  ///< geometric threshold, pixels (> 0)
  /// Texture threshold, pixels^2 of one texel (gamma); infinity = ignored. Evaluated only for
  /// nodes with texel_m > 0.
  double gamma_px = std::numeric_limits<double>::infinity();
  bool cull = true;  ///< hierarchical frustum culling by the node boxes
};

/// Visual errors of one selected node.
struct NodeVisual {
  double alpha_px = 0;  ///< the paper's alpha(N) (at the nearest point of the box)
  double bound_px = 0;  ///< conservative bound over the whole box (View::vertical_error_px)
  double gamma_px = 0;  ///< texel area in pixels at the box's smallest depth (0 without texture)
  /// PmBlock leaves: the tolerance, pixels, to hand to the block's selective refinement (the
  /// remaining budget, SelectionOptions::alpha_px); 0 for nodes drawn with their own surface.
  double tolerance_px = 0;
};

struct SelectionResult {
  std::vector<std::int64_t> selected;     ///< node ids, in depth-first order
  std::vector<NodeVisual> visual;         ///< parallel to selected
  std::size_t visited = 0;                ///< nodes whose box was tested
  std::size_t culled = 0;                 ///< visited nodes outside the frustum (subtree skipped)
  std::size_t points = 0, triangles = 0;  ///< of the selected non-PM surfaces
  std::size_t pm_blocks = 0;              ///< selected PmBlock leaves
  /// The guaranteed screen-space error of the selection, pixels: max over selected nodes of
  /// bound_px (own surface) or min(bound_px, tolerance_px) (PM blocks: the refinement at
  /// tolerance_px never goes coarser than the base mesh, whose bound is bound_px).
  double bound_px = 0;
  double alpha_max_px = 0;  ///< max over selected nodes of the paper's alpha
  double ms = 0;            ///< wall time of select_nodes
};

/// The paper's alpha(N): the vertical segment of length error_m centred at the point of `box`
/// nearest the eye, projected, its length in pixels. The segment is first clipped to the near
/// plane; infinity when the eye is inside the box or nothing of the segment is in front of the
/// near plane (the node must then be refined). Not an upper bound over the box: see
/// select_nodes.
double paper_alpha_px(const pm::View& view, const pm::Box& box, double error_m);

/// Traverses the tree from the root: a node whose box is outside the frustum is counted as
/// culled and skipped with its subtree; otherwise it is selected when it is a leaf or when its
/// conservative bound meets alpha_px (and gamma meets gamma_px), else its children are visited.
SelectionResult select_nodes(const ApproximationTree& tree, const pm::View& view,
                             const SelectionOptions& options = {});

}  // namespace terralod::blocks
