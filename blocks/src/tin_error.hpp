// Private helpers of the TIN and non-regular-grid builders: the exact error of one triangle with
// the sample (or grid-edge endpoint) where it is largest, so that the builders know what to insert.
//
// The numbers are those of pm::LInfError (same formulas, same rounding): scan_triangle equals
// LInfError::samples_in_triangle restricted to valid samples, and edge_error equals
// LInfError::segment on heightfields without holes (it is used for those); worst_crossing
// locates the crossing that segment's maximum comes from. Memory: none.
#pragma once

#include <cstdint>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/linf_error.hpp"

namespace terralod::blocks::detail {

/// Largest |plane - sample| over the valid samples of the closed triangle (a,b,c) (either
/// orientation, non-degenerate), and the first sample (row-major) where it is reached with a
/// strictly positive value; (-1,-1) when every valid sample is on the plane. Samples equal to a
/// corner are skipped as candidates (their error, rounding noise at most, still counts).
struct SampleScan {
  double error = 0.0;
  pm::GridPoint worst{-1, -1};
};
SampleScan scan_triangle(const pm::Heightfield& hf, pm::GridPoint a, pm::GridPoint b, pm::GridPoint c);

/// The worst crossing of the segment p-q with an edge of the full-resolution triangulation
/// (vertical, horizontal and diagonal grid edges; samples on the segment included), skipping grid
/// edges with a hole endpoint. `s0`,`s1` are the endpoints of the crossed grid edge, `s0` the one
/// nearer to the crossing (s1 == s0 for a sample on the segment); (-1,-1) when no crossing counts.
struct Crossing {
  double error = 0.0;
  pm::GridPoint s0{-1, -1}, s1{-1, -1};
};
Crossing worst_crossing(const pm::Heightfield& hf, pm::GridPoint p, pm::GridPoint q);

/// Sets mask[(y - y0) * width + (x - x0)] = 1 for every sample (x,y) of the closed triangle
/// (a,b,c) (non-degenerate, either orientation; the mask must cover its bounding box).
void mark_triangle(pm::GridPoint a, pm::GridPoint b, pm::GridPoint c, int x0, int y0, int width,
                   std::vector<std::uint8_t>& mask);

/// The crossing error of p-q: LInfError::segment when hf has no holes, else worst_crossing.
double edge_error(const pm::LInfError& linf, const pm::Heightfield& hf, pm::GridPoint p, pm::GridPoint q);

/// The exact error of the triangle (a,b,c) over hf's valid samples, in `linf`'s metric (built
/// with `metric` over hf): LInfError::triangle when hf has no holes; otherwise the valid samples
/// of the closed triangle and, for the continuous metric, the crossings of its edges with grid
/// edges between valid samples (scan_triangle's and worst_crossing's values: LInfError with
/// GridWindow::skip_holes). Holes, wherever they are, take no part. A degenerate triangle is
/// measured as its segments, as LInfError::triangle does.
double triangle_error(const pm::LInfError& linf, const pm::Heightfield& hf, pm::ErrorMetric metric,
                      pm::GridPoint a, pm::GridPoint b, pm::GridPoint c);

}  // namespace terralod::blocks::detail
