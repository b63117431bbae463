// Heights on a triangle given by three (col, row, z) points in whole-grid sample coordinates
// (private to the terrain runtime): its bounding box test, the barycentric coordinates of a
// point, and the height there of the plane through the corners.
//
// Contract: barycentric() divides by det, twice the signed plan area of the triangle; with
// det == 0 the coordinates are not finite (callers that may meet a degenerate triangle test
// det first). Everything is inline and allocates nothing.
#pragma once

#include <algorithm>
#include <array>

namespace terralod::blocks::detail {

using Tri3 = std::array<std::array<double, 3>, 3>;

/// (c, r) = l0 t[0] + l1 t[1] + l2 t[2] in plan, with l0 + l1 + l2 = 1.
struct Barycentric {
  double det, l0, l1, l2;
};

inline Barycentric barycentric(const Tri3& t, double c, double r) {
  const auto &a = t[0], &b = t[1], &e = t[2];
  const double det = (b[0] - a[0]) * (e[1] - a[1]) - (b[1] - a[1]) * (e[0] - a[0]);
  const double l1 = ((c - a[0]) * (e[1] - a[1]) - (r - a[1]) * (e[0] - a[0])) / det;
  const double l2 = ((b[0] - a[0]) * (r - a[1]) - (b[1] - a[1]) * (c - a[0])) / det;
  return {det, 1 - l1 - l2, l1, l2};
}

/// The height of t's plane at the point whose barycentric coordinates are w.
inline double plane_height(const Tri3& t, const Barycentric& w) {
  return w.l0 * t[0][2] + w.l1 * t[1][2] + w.l2 * t[2][2];
}

/// The height of t's plane at (c, r).
inline double plane_height(const Tri3& t, double c, double r) {
  return plane_height(t, barycentric(t, c, r));
}

/// True when (c, r) lies outside the plan bounding box of t.
inline bool outside_box(const Tri3& t, double c, double r) {
  return c < std::min({t[0][0], t[1][0], t[2][0]}) || c > std::max({t[0][0], t[1][0], t[2][0]}) ||
         r < std::min({t[0][1], t[1][1], t[2][1]}) || r > std::max({t[0][1], t[1][1], t[2][1]});
}

}  // namespace terralod::blocks::detail
