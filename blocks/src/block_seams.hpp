// Private to terrain_session.cpp: joins the selected meshes of neighbouring blocks into one
// watertight drawn mesh by re-triangulating their unmatched border triangles (paper Fig. 6),
// or by hanging skirts; computes the error the stitch adds. See terrain_session.hpp, steps
// 5-6 and "The bound", for the algorithm and its argument.
// Memory: the output mesh plus one hash entry per vertex and the sorted border lists.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/terrain_session.hpp"

namespace terralod::blocks::detail {

/// One block's mesh as drawn this frame.
struct SeamPatch {
  BlockKey key;
  std::vector<std::uint64_t> samples;  ///< terrain sample of each vertex (row * grid_width + col)
  std::vector<double> rest_z;          ///< true heights
  std::vector<double> display_z;       ///< displayed heights (geomorphs)
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< local indices, CCW in (col,row)
  double bound_px = 0;                 ///< the block's own guaranteed bound
};

struct SeamResult {
  double bound_px = 0;        ///< max over patches and stitched triangles (see terrain_session.hpp)
  double max_delta_m = 0;     ///< largest |z(p) - S(p)| of an inserted vertex
  std::size_t seam_triangles = 0;  ///< original triangles that were re-triangulated
};

/// Assembles `patches` (sorted by key, each block at most once) into `out`.
SeamResult assemble(const BlockGrid& grid, const std::vector<SeamPatch>& patches, const pm::View& view, SeamMode mode,
                    double skirt_depth_m, const std::vector<BlockSummary>& summaries, DrawnMesh& out);

}  // namespace terralod::blocks::detail
