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
// Memory: none beyond a reference to the heightfield.
#pragma once

#include <cstdint>

#include "terralod/pm/grid_triangle.hpp"  // GridPoint, orient2d
#include "terralod/pm/heightfield.hpp"

namespace terralod::pm {

enum class ErrorMetric : std::uint8_t {
  Samples = 0,     ///< max over the original samples inside the triangle
  Continuous = 1,  ///< true L-infinity distance of the two piecewise-linear surfaces
};

class LInfError {
 public:
  /// The heightfield must outlive this object.
  LInfError(const Heightfield& hf, ErrorMetric metric) : hf_(&hf), metric_(metric) {}

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

  /// Height of the full-resolution surface at a point given in index space.
  double surface_height(double col, double row) const;

  static constexpr double kNoCutoff = 1e300;

 private:
  const Heightfield* hf_;
  ErrorMetric metric_;
};

}  // namespace terralod::pm
