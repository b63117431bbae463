// The boundary rule of L-infinity collapses, shared by ProgressiveMesh::build and ModLInfT
// (linf_decimater_module.hpp) so that both keep a grid mesh's outline the same way.
//
// Usage:
//   // u is a boundary vertex with exactly two boundary neighbours, a and b:
//   if (terralod::pm::boundary_straight_at(a, u, b)) { /* u may move into a or into b */ }
//
// The rule (every collapse u -> w of either builder obeys it): a vertex on the mesh's boundary
// (the grid's border, or the edge of a hole: voids kept as holes, the footprint of a warped DEM)
// moves only into one of its two boundary neighbours, along the boundary edge to it, and only
// where the boundary runs straight through it: u lies strictly between its neighbours on one
// line. The new boundary edge then covers the two it replaces, so the outline — the grid's
// border and every hole — keeps its shape exactly. Grid corners never move (the boundary turns
// there), a border vertex stays on its border line, and a vertex where two stretches of
// boundary meet (more than two boundary neighbours: a hole touching the border or another hole
// at one vertex) never moves. Before, a hole's edge never moved at all: a warped DEM's block
// kept every sample of a straight edge of its footprint at its coarsest level (257 vertices
// where 2 do). Points are (column, row) of the grid.
// Memory: none.
#pragma once

#include <cstdint>

#include "terralod/pm/grid_triangle.hpp"  // GridPoint, orient2d

namespace terralod::pm {

/// Whether p lies strictly between a and b on one line (the boundary is straight through p).
inline bool boundary_straight_at(GridPoint a, GridPoint p, GridPoint b) {
  const std::int64_t dot = std::int64_t(a.x - p.x) * (b.x - p.x) + std::int64_t(a.y - p.y) * (b.y - p.y);
  return orient2d(a, p, b) == 0 && dot < 0;
}

}  // namespace terralod::pm
