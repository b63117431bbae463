// Seam stitching: makes independently triangulated rectangular patches (PM blocks extracted at
// different errors, tree nodes of any strategy) meet watertight by inserting, into each patch's
// border triangles, the border vertices its neighbours have and it lacks.
//
// Usage:
//   namespace tb = terralod::blocks;
//   std::vector<tb::StitchPatch> patches = ...;   // domains tile the plane, vertices are samples
//   tb::StitchResult r = tb::stitch_seams(patches);
//   // every patch now has, on every shared border, exactly the union of both sides' vertices;
//   // r.new_triangles[i] lists patch i's triangles that came from splits: measure those.
//
// Method. A border triangle (a, b, c) whose edge a-b lies on its patch's domain border, with
// neighbour vertices p_1..p_k strictly inside a-b, is replaced by the fan (a,p_1,c), (p_1,p_2,c),
// ..., (p_k,b,c); a triangle with two border edges is split along both. The inserted vertices
// are the neighbours' own (col,row) samples, so both sides end up with the same polyline and
// bit-identical vertices (heights are the samples' heights).
//
// Error (write it down, it is why extraction re-extracts): let S be the patch's surface and
// d_i = z(p_i) - S(p_i) the error of S at an inserted sample, |d_i| <= e when S is within e.
// The fan surface is S' = S + sum_i phi_i d_i, phi_i the piecewise-linear hat function of p_i
// on the fan (phi_i >= 0, sum_i phi_i <= 1). So |S' - z| <= |S - z| + max |d_i| <= 2e: a
// stitched patch of error e is within 2e, not e. A caller that must stay within E measures the
// new triangles exactly and, where one exceeds E, redoes that patch at e = E/2, which the bound
// above guarantees to be enough (database_extract.hpp does this).
//
// Contract: domains are SampleRects of one grid whose interiors do not overlap; each patch's
// triangles are CCW in (col,row), non-degenerate, and cover its domain; vertices on a patch's
// border lie on its domain rectangle. Patches are modified in place: new vertices are appended,
// split triangles are replaced (the first piece takes the old slot, the rest are appended).
// Cost: O(V log V + T log V) for V border vertices and T triangles; memory: the border vertex
// sets (8 bytes per border vertex) and a vertex map per patch.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "terralod/blocks/sample_rect.hpp"
#include "terralod/pm/linf_error.hpp"

namespace terralod::blocks {

struct StitchPatch {
  SampleRect domain;                                    ///< whole-grid samples
  std::vector<pm::GridPoint> vertices;                  ///< whole-grid (col,row) samples
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< into vertices, CCW in (col,row)
};

struct StitchResult {
  std::size_t inserted_vertices = 0;  ///< vertices added to patches (counted per patch)
  std::size_t split_triangles = 0;    ///< original triangles that were split
  /// Per patch: indices (into its triangles) of the triangles created by splits.
  std::vector<std::vector<std::uint32_t>> new_triangles;
  /// Parallel to new_triangles: the index of the original triangle each one was split from,
  /// and that triangle's corners before the stitch (indices into the patch's vertices).
  std::vector<std::vector<std::uint32_t>> new_triangle_sources;
  std::vector<std::vector<std::array<std::uint32_t, 3>>> new_triangle_source_corners;
};

/// Stitches all seams between the patches (see above).
StitchResult stitch_seams(std::vector<StitchPatch>& patches);

}  // namespace terralod::blocks
