// Greedy-insertion TINs and non-regular grids of heightfield samples with an exact L-infinity
// error: the TIN and non-regular-grid strategies of the approximation tree (seeds/approximation-
// tree.txt, section 3.2) and the TIN microstructures of the hybrid terrain.
//
// Usage:
//   namespace tb = terralod::blocks;
//   tb::TinSurface tin = tb::build_greedy_tin(hf, tb::SampleRect{0, 0, 256, 256}, {/*max_error=*/1.0});
//   // tin.points[i] = (col,row); heights are hf.at(col,row); tin.error <= 1.0 unless max_points hit.
//   tb::TinSurface area = tb::build_greedy_tin(hf, {{10, 10}, {90, 12}, {50, 80}}, {/*max_error=*/2.0});
//   tb::NonRegularGrid g = tb::build_nonregular_grid(hf, tb::SampleRect{0, 0, 64, 64}, {.max_error = 0,
//   .max_points = 81});
//
// Contract (all three builders):
//   - hf: the full-resolution terrain; read only, not retained. Its sizes must be < 2^24.
//   - Points are samples of hf (integer (col,row)); a point's height is hf.at(col,row). Hole
//     samples (hf.valid false) are never inserted and never measured; corners of a rect domain
//     and polygon vertices are used even if they are holes (their height is then hf.at, 0 by
//     the Heightfield contract), so callers should keep holes off those.
//   - Triangles index `points`, are CCW in (col,row) (pm::orient2d > 0), never degenerate, and
//     cover the domain exactly once in plan view.
//   - `error` is the exact L-infinity distance of the surface to the full-resolution surface
//     over the domain in the chosen metric, the same number pm::LInfError gives (max over the
//     triangles of LInfError::triangle): ErrorMetric::Samples = max over the valid samples in
//     the domain; ErrorMetric::Continuous = also at every crossing of a triangle edge with an
//     edge of the full-resolution triangulation (for heightfields with holes, crossings of grid
//     edges that touch a hole are skipped).
//   - max_error >= 0 metres; insertion stops as soon as error <= max_error (for a polygon: the
//     error apart from TinSurface::boundary_error) or one more point
//     would exceed max_points. max_points must be >= the initial points (4 for a rect; the
//     polygon's vertex count for a polygon), asserted.
//   - Ties (several samples of equal error) are broken deterministically: results depend only on
//     the inputs.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "terralod/blocks/sample_rect.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/linf_error.hpp"

namespace terralod::blocks {

struct TinOptions {
  double max_error = 0.0;                                ///< metres, >= 0
  std::size_t max_points = SIZE_MAX;                     ///< at most this many points
  pm::ErrorMetric metric = pm::ErrorMetric::Continuous;  ///< what `error` measures
  /// Called now and then with an estimate of the fraction done in [0, 1] (from the error reached
  /// on a log scale, or the points used), and with 1 at the end; may be empty.
  std::function<void(double)> progress = {};
};

struct TinSurface {
  std::vector<std::array<int, 2>> points;               ///< (col,row) samples of the heightfield
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< CCW in (col,row)
  double error = 0.0;                                   ///< exact L-inf error over the domain, metres
  /// The part of `error` reached where boundary edges cross grid edges (ErrorMetric::Continuous;
  /// 0 otherwise). Insertion can only lower it with samples on the boundary, so it may stay above
  /// max_error for a polygon with slanted edges (a rect's boundary never exceeds its samples').
  double boundary_error = 0.0;
};

/// Greedy insertion (Garland & Heckbert 1995, "Fast polygonal approximation of terrains and
/// height fields", algorithm III): starts from the domain's 4 corners (2 triangles), then inserts
/// the sample of largest error until error <= max_error or max_points are used. The
/// triangulation is Delaunay in (col,row) (exact integer predicates; cocircular ties are kept,
/// not flipped). The domain must be at least 2 x 2 samples and inside hf (asserted).
TinSurface build_greedy_tin(const pm::Heightfield& hf, SampleRect domain, const TinOptions& options = {});

/// Same, restricted to a simple polygon given in (col,row) (either orientation): its vertices are
/// rounded to the nearest samples (consecutive duplicates dropped), its edges become the TIN's
/// boundary and are never flipped (constrained Delaunay), and the samples inside or on the
/// rounded polygon are candidates. The result's first points are the rounded vertices, in CCW
/// order (orient2d > 0; the input's order reversed when it was clockwise). Under
/// ErrorMetric::Continuous the crossings of boundary edges with grid edges count in `error` too
/// (see TinSurface::boundary_error): insertion stops when the rest is <= max_error, so `error`
/// may stay above it (ErrorMetric::Samples has no such floor). Throws std::invalid_argument when the rounded
/// polygon has fewer than 3 vertices, zero area, a vertex outside hf, or crosses itself.
TinSurface build_greedy_tin(const pm::Heightfield& hf, const std::vector<std::array<double, 2>>& polygon,
                            const TinOptions& options = {});

struct NonRegularGridOptions {
  double max_error = 0.0;                                ///< metres, >= 0
  std::size_t max_points = SIZE_MAX;                     ///< rows * cols never exceeds it (>= 4)
  pm::ErrorMetric metric = pm::ErrorMetric::Continuous;  ///< what `error` measures
};

struct NonRegularGrid {
  std::vector<int> cols, rows;  ///< sorted, distinct, include the domain's first and last
  double error = 0.0;           ///< exact L-inf error of `surface`, metres (same as surface.error)
  /// The rows x cols intersections, row-major (points[j * cols.size() + i] = (cols[i], rows[j])),
  /// every cell split along the diagonal from (cols[i], rows[j]) to (cols[i+1], rows[j+1]) (the
  /// same diagonal as the full-resolution surface), 2 CCW triangles per cell.
  TinSurface surface;
};

/// Non-regular grid (approximation-tree paper, section 3.2): starts with the domain's boundary
/// rows and columns, then repeatedly adds the row and the column through the point of largest
/// error (a sample, or for a crossing the nearer endpoint of the crossed grid edge), until
/// error <= max_error or rows * cols would exceed max_points. The domain must be at least 2 x 2.
NonRegularGrid build_nonregular_grid(const pm::Heightfield& hf, SampleRect domain,
                                     const NonRegularGridOptions& options = {});

}  // namespace terralod::blocks
