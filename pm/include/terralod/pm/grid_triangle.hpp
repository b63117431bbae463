// Exact rasterisation of a triangle whose corners are grid points: its edge functions, the span
// of samples inside the closed triangle on each row, and the plane through its corners' heights.
// LInfError::samples_in_triangle and the TIN builders' error scans (blocks) both rasterise with
// it, so that their numbers agree bit for bit.
//
// Usage:
//   terralod::pm::GridPoint a{0, 0}, b{8, 8}, c{8, 0};
//   const auto t = terralod::pm::GridTriangle::ccw(a, b, c);   // swaps b and c: (a, b, c) is CCW now
//   const double Z[3] = {za, zb, zc};                           // heights at a, b, c
//   const double sx = t.plane_x(Z);
//   t.for_each_span([&](int y, std::int64_t xl, std::int64_t xr) {   // samples (xl .. xr, y) are inside
//     const double sy = t.plane_y(Z, y);   // the plane at (x, y) is (sx * x + sy) / t.area2
//   });
//
// Exactness: the edge functions are integers (corners below 2^31). A span's bound -Cy/A is a
// quotient of integers below 2^31, so its double is correctly rounded and, being at least 1/|A|
// away from any integer it is not equal to, floor/ceil of the double equal floor/ceil of the
// exact quotient. Memory: none.
#pragma once

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <type_traits>
#include <utility>

namespace terralod::pm {

/// A sample of the grid by its (column, row) index.
struct GridPoint {
  int x = 0;  ///< column
  int y = 0;  ///< row
  bool operator==(const GridPoint&) const = default;
};

/// Twice the signed area of (a,b,c) in (col,row) index space; > 0 for the mesh's orientation.
/// floor(a / b) for b > 0 (C++'s / truncates toward zero): where a step of a rational slope
/// lands on the grid.
inline std::int64_t floor_div(std::int64_t a, std::int64_t b) {
  assert(b > 0);
  const std::int64_t q = a / b;
  return (a % b != 0 && a < 0) ? q - 1 : q;
}

inline std::int64_t orient2d(GridPoint a, GridPoint b, GridPoint c) {
  return std::int64_t(b.x - a.x) * (c.y - a.y) - std::int64_t(b.y - a.y) * (c.x - a.x);
}

struct GridTriangle {
  /// Edge k, opposite corner k: E_k(x, y) = A[k] x + B[k] y + C[k], >= 0 inside the triangle;
  /// E_k / area2 is corner k's barycentric weight.
  std::int64_t A[3], B[3], C[3];
  std::int64_t area2;              ///< twice the triangle's area; 0 for a degenerate triangle
  int x_min, x_max, y_min, y_max;  ///< the corners' bounding box

  /// The triangle (a, b, c) made counter-clockwise: b and c are swapped (in the caller's
  /// variables) when it is clockwise.
  static GridTriangle ccw(GridPoint& a, GridPoint& b, GridPoint& c) {
    GridTriangle t;
    t.area2 = orient2d(a, b, c);
    if (t.area2 < 0) std::swap(b, c), t.area2 = -t.area2;
    const GridPoint P[3] = {a, b, c};
    for (int k = 0; k < 3; ++k) {
      const GridPoint s = P[(k + 1) % 3], e = P[(k + 2) % 3];
      t.A[k] = -(std::int64_t(e.y) - s.y);
      t.B[k] = std::int64_t(e.x) - s.x;
      t.C[k] = -(t.A[k] * s.x + t.B[k] * s.y);
    }
    t.x_min = std::min({a.x, b.x, c.x}), t.x_max = std::max({a.x, b.x, c.x});
    t.y_min = std::min({a.y, b.y, c.y}), t.y_max = std::max({a.y, b.y, c.y});
    return t;
  }

  /// Narrows [xl, xr] to the samples of row y inside the closed triangle; empty when xl > xr.
  void row_span(int y, std::int64_t& xl, std::int64_t& xr) const {
    for (int k = 0; k < 3; ++k) {
      const std::int64_t Cy = B[k] * y + C[k];  // A x + Cy >= 0 inside
      if (A[k] > 0)
        xl = std::max(xl, std::int64_t(std::ceil(double(-Cy) / double(A[k]))));
      else if (A[k] < 0)
        xr = std::min(xr, std::int64_t(std::floor(double(Cy) / double(-A[k]))));
      else if (Cy < 0)
        xr = xl - 1;
    }
  }

  /// Calls f(y, xl, xr) for every row y (increasing) whose span xl .. xr of samples inside the
  /// closed triangle is not empty: row_span's spans, with each edge's bound floor((B y + C) /
  /// |A|) stepped exactly from row to row (quotient and remainder) instead of divided anew.
  /// When f returns bool, false stops the scan.
  template <class F>
  void for_each_span(F&& f) const {
    for_each_span(x_min, y_min, x_max, y_max, std::forward<F>(f));
  }

  /// for_each_span clipped to the samples of columns col0 .. col1 and rows row0 .. row1 (a
  /// window of the grid): the same spans, cut to the window. The bounds are exact quotients
  /// whichever row the stepping starts from, so a window's spans are the whole scan's, clipped.
  template <class F>
  void for_each_span(int col0, int row0, int col1, int row1, F&& f) const {
    const int y0 = std::max(y_min, row0), y1 = std::min(y_max, row1);
    const std::int64_t x0 = std::max(x_min, col0), x1 = std::min(x_max, col1);
    if (y0 > y1 || x0 > x1) return;
    std::int64_t q[3] = {}, r[3] = {}, d[3] = {}, qs[3] = {}, rs[3] = {};
    for (int k = 0; k < 3; ++k) {
      d[k] = A[k] < 0 ? -A[k] : A[k];
      if (d[k] == 0) continue;
      const std::int64_t m = B[k] * y0 + C[k];
      q[k] = floor_div(m, d[k]), r[k] = m - q[k] * d[k];
      qs[k] = floor_div(B[k], d[k]), rs[k] = B[k] - qs[k] * d[k];
    }
    for (int y = y0; y <= y1; ++y) {
      std::int64_t xl = x0, xr = x1;
      for (int k = 0; k < 3; ++k) {
        if (A[k] > 0)  // A x + M >= 0: x >= ceil(-M / A) = -floor(M / A)
          xl = std::max(xl, -q[k]);
        else if (A[k] < 0)  // x <= floor(M / -A)
          xr = std::min(xr, q[k]);
        else if (B[k] * y + C[k] < 0)
          xr = xl - 1;
        q[k] += qs[k], r[k] += rs[k];
        if (r[k] >= d[k] && d[k] > 0) r[k] -= d[k], ++q[k];
      }
      if (xl > xr) continue;
      if constexpr (std::is_same_v<decltype(f(y, xl, xr)), bool>) {
        if (!f(y, xl, xr)) return;
      } else {
        f(y, xl, xr);
      }
    }
  }

  /// The plane through the heights Z[k] at corner k, times area2, is plane_x(Z) * x +
  /// plane_y(Z, y) at (x, y), computed in this order (which every user shares).
  double plane_x(const double Z[3]) const {
    return double(A[0]) * Z[0] + double(A[1]) * Z[1] + double(A[2]) * Z[2];
  }
  double plane_y(const double Z[3], int y) const {
    return double(B[0] * y + C[0]) * Z[0] + double(B[1] * y + C[1]) * Z[1] + double(B[2] * y + C[2]) * Z[2];
  }
};

}  // namespace terralod::pm
