// Partitioning of a terrain grid into square blocks of 2^k + 1 samples that share their border
// samples, and the per-block progressive meshes built from them.
//
// Usage:
//   namespace tb = terralod::blocks;
//   tb::BlockLayout layout = tb::partition(/*width=*/1201, /*height=*/1201, /*block_size=*/257);
//   // layout.blocks_x == 5: columns [0,256] [256,512] [512,768] [768,1024] [1024,1200]
//   for (tb::BlockKey k : layout.keys()) {
//     terralod::pm::Heightfield sub = tb::block_heightfield(hf, layout.rect(k));   // own transform
//     terralod::pm::ProgressiveMesh pm = tb::build_block_pm(hf, layout.rect(k));   // one thread
//   }
//
// Contract (seeds/view-dependent-pm-dynamic-loading.txt, section 4.1: the terrain is cut into
// blocks, each block's PM keeps its four corners fixed):
//   - block_size must be 2^k + 1 with k >= 1 (3, 5, 9, ..., 257, ...); width, height >= 2.
//     Otherwise std::invalid_argument naming the bad value.
//   - Block (c, r) covers columns [c (N-1), min((c+1)(N-1), W-1)] and the same for rows, with
//     N = block_size: neighbours share their border column/row of samples; the last column
//     (row) of blocks is partial when (W - 1) is not a multiple of (N - 1). Every block has at
//     least 2 x 2 samples. blocks_x = ceil((W - 1) / (N - 1)).
//   - block_heightfield copies the samples (and the void mask) of the rect; its transform maps
//     the block's local (col, row) to the same world point as the whole grid's transform maps
//     the global (col0 + col, row0 + row), so block vertices decode directly to world positions.
//   - build_block_pm: pm::ProgressiveMesh::build of that sub-heightfield on one thread (blocks
//     run in parallel instead); the PM builder fixes the four corners and keeps border vertices
//     on their own border line, so the blocks meet along straight shared borders.
// Memory: block_heightfield allocates 8 bytes per block sample (+1 with a void mask).
#pragma once

#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/sample_rect.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::blocks {

struct BlockLayout {
  int grid_width = 0, grid_height = 0;  ///< samples of the whole terrain
  int block_size = 0;                   ///< samples per block side, 2^k + 1
  int blocks_x = 0, blocks_y = 0;       ///< blocks per row / column

  /// Samples covered by block `k` (0 <= k.col < blocks_x, 0 <= k.row < blocks_y; asserted).
  SampleRect rect(BlockKey k) const;
  /// Samples covered by the blocks [c0, c1] x [r0, r1] (inclusive block indices).
  SampleRect rect(int c0, int r0, int c1, int r1) const;
  /// All blocks, sorted by (col, row) like BlockDatabase::blocks().
  std::vector<BlockKey> keys() const;
  std::size_t count() const { return std::size_t(blocks_x) * std::size_t(blocks_y); }
  bool contains(BlockKey k) const { return k.col >= 0 && k.row >= 0 && k.col < blocks_x && k.row < blocks_y; }
};

/// True for 3, 5, 9, 17, ... (2^k + 1, k >= 1).
bool is_valid_block_size(int block_size);

/// The block grid of a width x height terrain (see the contract above).
BlockLayout partition(int width, int height, int block_size);

/// A copy of the samples of `rect` with its own GridTransform (see the contract above).
pm::Heightfield block_heightfield(const pm::Heightfield& hf, SampleRect rect);

/// The block's PM, built on one thread with `metric`.
pm::ProgressiveMesh build_block_pm(const pm::Heightfield& hf, SampleRect rect,
                                   pm::ErrorMetric metric = pm::ErrorMetric::Continuous);
/// The same from the block's own samples (block_heightfield(hf, rect), or DemSource::read(rect)).
pm::ProgressiveMesh build_block_pm(const pm::Heightfield& block, pm::ErrorMetric metric);

/// Exact L-infinity error (pm::LInfError, the PM's metric) of the PM's base mesh (its coarsest
/// extraction): the error of a PM block when it is drawn with no refinement at all.
double base_mesh_error(const pm::ProgressiveMesh& pm);

}  // namespace terralod::blocks
