// Vertex hierarchy of a progressive mesh with saturated errors and world-space bounding spheres.
//
// Usage:
//   terralod::pm::ProgressiveMesh pm = terralod::pm::ProgressiveMesh::build(hf);
//   terralod::pm::VertexHierarchy vh(pm);
//   for (std::uint32_t r = 0; r < vh.root_count(); ++r) {         // roots = base-mesh vertices
//     const terralod::pm::HierarchyNode& n = vh.node(r);
//     if (n.is_leaf()) continue;
//     const auto& wchild = vh.node(n.first_child);                  // same sample as n
//     const auto& uchild = vh.node(n.first_child + 1);              // the sample vsplit restores
//   }
//
// Model (Hoppe 1997; seeds/view-dependent-pm-dynamic-loading.txt, section 3, Figs. 2 and 4):
// the base-mesh vertices are the roots; vsplit k, the inverse of collapse c = collapses[n-1-k]
// (u -> w), splits the node that currently represents sample c.w into two children: the
// w-child (sample c.w, same position as its parent) and the u-child (sample c.u). A vertex
// front through this forest is a selectively refined mesh; the leaves are the full-resolution
// vertices.
//
// Contract:
//   - Node numbering: nodes [0, root_count()) are the roots in increasing sample order; vsplit
//     k creates nodes root_count() + 2k (w-child) and root_count() + 2k + 1 (u-child). So
//     node_count() = base_vertex_count + 2 * vsplit_count, every child's index is larger than
//     its parent's, and a node's children are first_child and first_child + 1.
//   - error: saturated L-infinity error in metres, max(split_error(i), children's error);
//     leaves 0. A parent's error is never below a child's, so "error <= tolerance" is monotone.
//     The vsplit that splits a node and its own collapse error are derived (vsplit_of,
//     split_error) rather than stored, to keep nodes at 32 bytes.
//   - radius: metres in the world frame (x, y from hf.transform.to_world(col, row), z = the
//     height). A leaf's sphere, centred at its sample, holds every neighbour of the sample in
//     the full-resolution mesh (edges of ProgressiveMesh::full_face); a parent's sphere holds
//     its children's spheres (Fig. 4): r = max(r_wchild, |p - p_uchild| + r_uchild). Hence a
//     node's sphere holds every full-resolution vertex below it and their 1-rings.
//   - Build: O(samples + collapses): one pass over the grid cells, one forward and one backward
//     pass over the vsplits; about 0.2 s for a 1201 x 1201 tile (1.44M vertices).
//   - Memory: 32 bytes per node plus 8 bytes per vsplit (split errors), i.e. about 72 bytes per
//     full-resolution vertex, plus 4 bytes per sample for leaf_of(). The hierarchy copies what
//     it needs; the ProgressiveMesh need not outlive it.
#pragma once

#include <cstdint>
#include <vector>

#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::pm {

/// One vertex of the hierarchy (32 bytes; two per cache line).
struct HierarchyNode {
  static constexpr std::uint32_t kNone = 0xffffffffu;

  std::uint32_t sample = 0;           ///< sample index (row * width + col): the node's position
  std::uint32_t parent = kNone;       ///< kNone for roots
  std::uint32_t first_child = kNone;  ///< w-child; the u-child is first_child + 1; kNone for leaves
  std::uint32_t depth = 0;            ///< 0 for roots
  double error = 0.0;   ///< saturated error: max(split error, children's error), metres; 0 for leaves
  double radius = 0.0;  ///< bounding-sphere radius in world metres

  bool is_leaf() const { return first_child == kNone; }
  bool is_root() const { return parent == kNone; }
};

class VertexHierarchy {
 public:
  VertexHierarchy() = default;
  explicit VertexHierarchy(const ProgressiveMesh& pm);

  std::size_t node_count() const { return nodes_.size(); }
  std::size_t root_count() const { return root_count_; }
  std::size_t vsplit_count() const { return split_errors_.size(); }
  const HierarchyNode& node(std::uint32_t i) const { return nodes_[i]; }
  const std::vector<HierarchyNode>& nodes() const { return nodes_; }

  /// Index k of the vsplit that splits node i; HierarchyNode::kNone for leaves.
  std::uint32_t vsplit_of(std::uint32_t i) const {
    return nodes_[i].is_leaf() ? HierarchyNode::kNone
                               : std::uint32_t((nodes_[i].first_child - root_count_) / 2);
  }
  /// Error of the collapse that vsplit_of(i) undoes (collapses[n-1-k].error), metres; 0 for leaves.
  double split_error(std::uint32_t i) const {
    return nodes_[i].is_leaf() ? 0.0 : split_errors_[vsplit_of(i)];
  }
  /// Error of the collapse that vsplit k undoes, metres.
  double vsplit_error(std::size_t k) const { return split_errors_[k]; }
  /// Node split by vsplit k (k < vsplit_count()).
  std::uint32_t split_node(std::size_t k) const { return nodes_[root_count_ + 2 * k].parent; }
  /// Leaf node of a sample (a full-resolution vertex); HierarchyNode::kNone for samples that
  /// are not mesh vertices (holes).
  std::uint32_t leaf_of(std::uint32_t sample) const { return leaf_of_[sample]; }
  /// Root above a node (walks up: O(depth)).
  std::uint32_t root_of(std::uint32_t node) const;

 private:
  std::vector<HierarchyNode> nodes_;
  std::vector<double> split_errors_;  // by vsplit index
  std::vector<std::uint32_t> leaf_of_;
  std::size_t root_count_ = 0;
};

}  // namespace terralod::pm
