// Height queries on a Heightfield at arbitrary world points: the inverse of its GridTransform
// and the bilinear surface through the samples, for terrain following, cameras and scripted
// flights (one implementation instead of one per tool).
//
// Usage:
//   terralod::pm::Heightfield hf = ...;                              // metric world frame
//   auto [col, row] = terralod::pm::world_to_grid(hf.transform, x, y);  // fractional indices
//   double z = terralod::pm::bilinear_height(hf, x, y);              // metres; clamped to the grid
//
// Contract:
//   - world_to_grid(t, x, y): (col, row) with t.to_world(col, row) == (x, y) up to rounding;
//     t must be invertible (determinant != 0, assert). Points outside the grid give indices
//     outside [0, width-1] x [0, height-1].
//   - bilinear_height(hf, x, y): hf has at least one sample (assert). The point is clamped to
//     the grid (a point beyond the border gets the border's height), then the height is the
//     bilinear blend of the 2 x 2 samples around it (1 x N and N x 1 grids: linear; 1 x 1: the
//     sample). Holes (hf.valid() false) take no part: the weights of the valid corners are
//     renormalised; NaN when all four corners are holes. Exact at the samples.
//   - Cost: O(1), no allocation.
#pragma once

#include <utility>

#include "terralod/pm/heightfield.hpp"

namespace terralod::pm {

/// Fractional grid (col, row) of world (x, y): the inverse of the affine transform.
std::pair<double, double> world_to_grid(const GridTransform& transform, double x, double y);

/// Bilinear height of the samples under world (x, y), clamped to the grid (see the contract).
double bilinear_height(const Heightfield& hf, double x, double y);

}  // namespace terralod::pm
