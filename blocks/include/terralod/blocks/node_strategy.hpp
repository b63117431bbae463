// How a node of the approximation tree approximates the terrain over its domain: one interface
// (NodeStrategy) and the strategies of the paper behind it. Used by the tree builder
// (tree_builder.hpp) and by the blocks' stand-ins (active_region.hpp).
//
// Node strategies (seeds/approximation-tree.txt, section 3.2), each a NodeStrategy:
//   Grid            (P+1) x (P+1) evenly spaced columns and rows of the source grid (fewer when
//                   the domain has fewer samples), quadtree children: d = 4, s = (P+1)^2.
//   Tin             greedy insertion of the sample of largest error (build_greedy_tin) until
//                   error 0 or s points; binary k-d children splitting the longer side at a
//                   sample: d = 2.
//   NonRegularGrid  row and column through the point of largest error (build_nonregular_grid),
//                   at most s points; binary k-d children: d = 2.
//   Hybrid          the grid's (P+1) x (P+1) points plus, in the 2 x 2 cells around the interior
//                   grid node where the grid is worst, a greedy TIN microstructure of at most s
//                   points joined to the grid by local convexification (hybrid/hybrid_terrain.hpp,
//                   seeds/hybrid-grid-tin-convexification.txt); every point a sample; quadtree
//                   children: d = 4. Details in src/hybrid/hybrid_strategy.cpp.
//   PmBlock         a leaf whose surface is a block's PM in the database (refined at run time).
#pragma once

#include <cstddef>
#include <memory>

#include "terralod/blocks/approximation_tree.hpp"
#include "terralod/blocks/sample_rect.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/linf_error.hpp"

namespace terralod::blocks {

/// One approximation strategy: how a node's surface is chosen over a domain.
class NodeStrategy {
 public:
  virtual ~NodeStrategy() = default;
  virtual Strategy kind() const = 0;
  /// Largest number of children a node of this strategy gets (d).
  virtual int max_children() const = 0;
  /// Largest number of surface points (s).
  virtual std::size_t max_points() const = 0;
  /// The surface over `domain` (at least 2 x 2 samples): points are samples of hf.
  virtual NodeSurface approximate(const pm::Heightfield& hf, SampleRect domain) const = 0;
};

/// The strategies of the paper; patch = P (>= 1), max_points = s (>= 4).
std::unique_ptr<NodeStrategy> make_grid_strategy(int patch);
std::unique_ptr<NodeStrategy> make_tin_strategy(std::size_t max_points, pm::ErrorMetric metric);
std::unique_ptr<NodeStrategy> make_nonregular_strategy(std::size_t max_points, pm::ErrorMetric metric);
/// Grid of patch P plus a TIN microstructure of at most tin_points (>= 4) points (see above).
std::unique_ptr<NodeStrategy> make_hybrid_strategy(int patch, std::size_t tin_points, pm::ErrorMetric metric);

/// Exact error of a surface against hf: max over its triangles of pm::LInfError::triangle,
/// measured over hf's valid samples only when hf has holes (what is not there has no error).
double surface_error(const pm::Heightfield& hf, const NodeSurface& surface, pm::ErrorMetric metric);

}  // namespace terralod::blocks
