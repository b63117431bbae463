// Static geomorph M^G(alpha) between two selectively refined meshes M^A and M^B of one PM:
// their plan-view overlay, with heights blended from M^A's surface to M^B's. The product uses it
// in `terralod view --morph-to` (apps/cmd_view.cpp): a transition between two viewpoints, drawn
// as one image per alpha.
//
// Usage:
//   terralod::pm::SelectiveRefinement a(dag), b(dag);
//   a.update(view_a);  b.update(view_b);
//   terralod::pm::Geomorph g = terralod::pm::make_geomorph(a, b);
//   terralod::pm::RenderMesh m = g.at(/*alpha=*/0.25);   // 0: is M^A's surface, 1: M^B's
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 3, last paragraph: for any two
// selectively refined meshes M^A and M^B, a mesh M^G(alpha) whose vertices vary with alpha,
// M^G(0) looking identical to M^A and M^G(1) to M^B.
//
// Construction. M^A and M^B are triangulations of the same domain (collapse_dag.hpp). Their
// overlay cuts every triangle of M^A by every triangle of M^B that overlaps it; each piece is a
// convex polygon inside one triangle of each, triangulated without new points. Its vertices
// are vertices of M^A or M^B (samples) and crossings of an edge of M^A with an edge of M^B.
// Every vertex keeps its plan position; its height goes from z_A (M^A's surface there) to z_B
// (M^B's surface there): z(alpha) = (1 - alpha) z_A + alpha z_B. On each piece both surfaces
// are linear, so M^G(alpha) is exactly the pointwise blend (1 - alpha) M^A + alpha M^B:
//   - M^G(0) is M^A's surface and M^G(1) is M^B's, at every point (vertices of M^A keep their
//     sample heights bit for bit; a crossing's height is rounded once, to the nearest double
//     of its exact rational value);
//   - no triangle flips or moves in plan view at any alpha (plan positions are fixed; pieces
//     are found with exact integer predicates, crossings rounded to the nearest double);
//   - the surface changes at every point by (z_B - z_A) d(alpha): a geomorph over time never
//     changes faster than |M^B - M^A| / duration.
// Why not the classic PM geomorph (vertices of the common refinement F(S_A n S_B) sliding from
// their ancestors in M^A to those in M^B): measured on a 129 x 129 terrain over 100 random
// pose pairs, 4% of its triangles fold over in plan view at some alpha. Why not heights only
// on F(S_A n S_B): its triangles do not lie inside M^A's, so M^G(0) would differ from M^A
// between vertices.
//
// Contract: both selections must use the same CollapseDag (std::invalid_argument otherwise);
// grids up to 8193 samples per side (exact predicates in 128-bit integers; std::invalid_argument
// beyond); alpha in [0, 1] (std::invalid_argument otherwise). Memory: 40 bytes per vertex and 12
// per triangle of the overlay (typically 1.5-3 times the larger mesh), plus a bucket grid of
// M^B's triangles while building. Time: O(overlay size + bucket entries).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "terralod/pm/selective_refinement.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::pm {

struct Geomorph {
  static constexpr std::uint32_t kNoSample = 0xffffffffu;
  /// Sample of each vertex, or kNoSample for a crossing of an M^A edge with an M^B edge.
  std::vector<std::uint32_t> samples;
  std::vector<std::array<double, 2>> plan;              ///< (col, row) in index space
  std::vector<double> z_from, z_to;                     ///< heights on M^A and on M^B, metres
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< CCW in (col, row)
  GridTransform transform;                              ///< the heightfield's

  /// M^G(alpha): world positions (transform of plan, (1 - alpha) z_from + alpha z_to).
  RenderMesh at(double alpha) const;
};

/// The geomorph from a's current selection to b's (their logical meshes; running runtime
/// morphs are ignored).
Geomorph make_geomorph(const SelectiveRefinement& a, const SelectiveRefinement& b);

}  // namespace terralod::pm
