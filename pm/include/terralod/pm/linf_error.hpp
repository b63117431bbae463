// Exact L-infinity (maximum vertical) error of a grid-aligned triangle against a heightfield.
//
// Implements the measure of Eq. 1 of the view-dependent PM paper (seeds/view-dependent-pm-
// dynamic-loading.txt, section 2): E = max over the triangle's domain of |phi_simplified(p) -
// phi_full(p)|. Both surfaces are piecewise linear, so the difference is linear on every cell
// of their overlay and its maximum lies at an overlay vertex: an original sample inside the
// closed triangle, a triangle corner (a sample itself), or a crossing of a triangle edge with
// an edge of the full-resolution triangulation. ErrorMetric::Continuous measures all three
// (the true L-infinity distance of the two surfaces); ErrorMetric::Samples only the samples
// (what delatin and martini report, and what DESIGN.md's contract requires at minimum).
//
// The full-resolution surface is the grid triangulated along the diagonal from (i,j) to
// (i+1,j+1) in every cell.
//
// Usage:
//   terralod::pm::LInfError err(heightfield, terralod::pm::ErrorMetric::Continuous);
//   double e = err.triangle({0, 0}, {8, 0}, {8, 8});   // metres
//
// Exactness: corners are integer grid points, so barycentric weights are exact integers; the
// error is evaluated as |sum(w_i z_i) - W z| / W. For heights that are integers (SRTM) every
// term is an exact double, so the result is exact; for other heights the rounding error is
// below 1e-12 of the height range.
// Windows: an LInfError may measure over a window of a larger grid (GridWindow: the heightfield
// holds the grid's samples from `origin` on). It then measures the terms of the maximum that lie
// in the window: the samples of the triangle inside it and the crossings of its edges with grid
// edges inside it, each computed with exactly the formula, and rounding, of the whole-grid
// measure. The maximum over windows that cover the grid, overlapping by one sample row and
// column so that every grid edge lies in one of them, is therefore the whole-grid error bit for
// bit (blocks' surface scan streams a DEM this way).
//
// Memory: none beyond a reference to the heightfield.
#pragma once

#include <array>
#include <cstdint>

#include "terralod/pm/grid_triangle.hpp"  // GridPoint, orient2d
#include "terralod/pm/heightfield.hpp"

namespace terralod::pm {

enum class ErrorMetric : std::uint8_t {
  Samples = 0,     ///< max over the original samples inside the triangle
  Continuous = 1,  ///< true L-infinity distance of the two piecewise-linear surfaces
};

/// Where an LInfError's heightfield lies in the grid, and whether its holes count.
struct GridWindow {
  GridPoint origin{0, 0};   ///< the grid sample that is the heightfield's sample (0, 0)
  bool skip_holes = false;  ///< hole samples, and grid edges with a hole endpoint, take no part
};

class LInfError {
 public:
  /// The heightfield must outlive this object. Points passed to the methods are grid points
  /// (whole-grid indices); by default the heightfield is the whole grid and holes count as
  /// samples (their stored heights).
  LInfError(const Heightfield& hf, ErrorMetric metric, GridWindow window = {})
      : hf_(&hf), metric_(metric), window_(window) {}

  ErrorMetric metric() const { return metric_; }

  /// Error of the triangle (a,b,c) with heights taken from the samples at its corners.
  /// Degenerate triangles (zero area) are measured along their extent as segments.
  /// When the error exceeds `cutoff`, evaluation may stop early and return any value > cutoff.
  double triangle(GridPoint a, GridPoint b, GridPoint c, double cutoff = kNoCutoff) const;

  /// Maximum vertical distance along the segment a-b between its linear interpolation and
  /// the full-resolution surface, at every crossing with a grid edge and every sample on it.
  double segment(GridPoint a, GridPoint b, double cutoff = kNoCutoff) const;

  /// Error at the original samples inside the closed triangle only (both metrics need it).
  double samples_in_triangle(GridPoint a, GridPoint b, GridPoint c, double cutoff = kNoCutoff) const;

  /// The same three measures with the corners' heights given (z[k] for the k-th corner, which
  /// may lie outside a window), over the terms that lie in the heightfield (header comment).
  /// With z read from the corner samples and the whole grid, they equal the functions above.
  double triangle(GridPoint a, GridPoint b, GridPoint c, const std::array<double, 3>& z,
                  double cutoff = kNoCutoff) const;
  double segment(GridPoint a, GridPoint b, double za, double zb, double cutoff = kNoCutoff) const;
  double samples_in_triangle(GridPoint a, GridPoint b, GridPoint c, const std::array<double, 3>& z,
                             double cutoff = kNoCutoff) const;

  /// Height of the full-resolution surface at a point given in the heightfield's index space.
  double surface_height(double col, double row) const;

  static constexpr double kNoCutoff = 1e300;

 private:
  double at(GridPoint p) const { return hf_->at(p.x - window_.origin.x, p.y - window_.origin.y); }

  const Heightfield* hf_;
  ErrorMetric metric_;
  GridWindow window_;
};

}  // namespace terralod::pm
