// Private to terrain_session.cpp: joins the selected meshes of neighbouring blocks into one
// watertight drawn mesh by re-triangulating their unmatched border triangles (paper Fig. 6),
// after merging close unmatched border vertices to their midpoint (paper section 4.3, "reset
// to their midpoint"), or by hanging skirts; computes the error the merge and the stitch add.
// See terrain_session.hpp, steps 5-6 and "The bound", and "Sliver merging" below.
// Memory: the output mesh plus one hash entry per vertex, the sorted border lists and, per
// patch that has a merge candidate, a vertex-to-triangle table (4 bytes per vertex and per
// triangle corner).
//
// Sliver merging (merge_tolerance_samples > 0, SeamMode::Stitch only). On every border
// shared by two patches, walk the union of both sides' border vertices in order; two
// consecutive ones that belong to one side each (both unmatched) and are fewer than
// merge_tolerance_samples samples apart become one vertex. The targets tried, in order:
// their midpoint sample (rounded down; only when they are >= 2 apart), the vertex of the
// finer side (more vertices on that border; ties: the first patch), the other one. A side
// whose vertex is not at the target moves it there along the border, and may do so only when
//   (i)   every triangle around it stays CCW and non-degenerate in (col,row),
//   (ii)  it is not a corner of its block and its patch has heights (SeamPatch::heights;
//         stand-ins have none and are never moved: the other side merges toward them),
//   (iii) every moved triangle t, measured exactly against the block's samples
//         (pm::LInfError, ErrorMetric::Continuous: e_t), has View::vertical_error_px(box_t,
//         e_t) <= the block's own bound_px, box_t its corners widened by e_t vertically
//         (0 when the box is culled). So a merge never raises the frame's bound.
// Both sides then hold the same sample there (bit-identical, one displayed height: the
// existing vertex's, or for a new midpoint sample its rest height plus the mean morph offset
// of the two moved vertices), so the stitch leaves it alone. The bound argument of
// terrain_session.hpp holds with S the merged surface: every moved triangle is within its
// measured e_t (inside box_t), every other triangle within the block's bound, and the stitch
// adds its delta on top of that, with delta computed against the merged border polyline.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/terrain_session.hpp"
#include "terralod/pm/heightfield.hpp"

namespace terralod::blocks::detail {

/// One block's mesh as drawn this frame.
struct SeamPatch {
  BlockKey key;
  std::vector<std::uint64_t> samples;  ///< terrain sample of each vertex (row * grid_width + col)
  std::vector<double> rest_z;          ///< true heights
  std::vector<double> display_z;       ///< displayed heights (geomorphs)
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< local indices, CCW in (col,row)
  double bound_px = 0;                                  ///< the block's own guaranteed bound
  /// The block's own samples (block-local grid: sample (col,row) of the terrain is
  /// (col - domain.col0, row - domain.row0) here), not owned; null for patches whose
  /// vertices may not move (stand-ins): the sliver merge never moves their vertices.
  const pm::Heightfield* heights = nullptr;
};

struct SeamResult {
  double bound_px = 0;              ///< max over patches and stitched triangles (see terrain_session.hpp)
  double max_delta_m = 0;           ///< largest |z(p) - S(p)| of an inserted vertex
  std::size_t seam_triangles = 0;   ///< original triangles that were re-triangulated
  std::size_t merged_pairs = 0;     ///< unmatched border vertex pairs merged into one vertex
  std::size_t refused_pairs = 0;    ///< candidate pairs left unmerged (conditions (i)-(iii))
  std::size_t moved_triangles = 0;  ///< triangles whose corners the merge moved
  double max_merge_error_m = 0;     ///< largest e_t of a moved triangle
};

/// Assembles `patches` (sorted by key, each block at most once) into `out`, merging border
/// vertices closer than `merge_tolerance_samples` (>= 0; 0 = no merging) in Stitch mode.
SeamResult assemble(const BlockGrid& grid, const std::vector<SeamPatch>& patches, const pm::View& view,
                    SeamMode mode, double skirt_depth_m, const std::vector<BlockSummary>& summaries,
                    DrawnMesh& out, double merge_tolerance_samples = 0);

}  // namespace terralod::blocks::detail
