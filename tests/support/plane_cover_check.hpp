// Independent check that a triangle mesh in the plane covers the rectangle [0,W] x [0,H]
// exactly once and is watertight (header-only; for any mesh of (x, y, z) points).
//
// Usage:
//   const std::string why = terralod::test::check_plane_cover(mesh.points, mesh.triangles, W, H);
//   EXPECT_EQ(why, "");
//
// Checks: no two vertices share a position; every triangle is CCW (positive area); every
// directed edge is used once (no overlap); an edge without its twin lies on the rectangle's
// border (else a crack or a T-junction); the triangles' areas sum to W * H. Returns "" or what
// is wrong.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace terralod::test {

inline double plane_orient(const std::array<double, 3>& a, const std::array<double, 3>& b,
                           const std::array<double, 3>& c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

inline std::string check_plane_cover(const std::vector<std::array<double, 3>>& points,
                                     const std::vector<std::array<std::uint32_t, 3>>& triangles, double W,
                                     double H) {
  std::set<std::pair<double, double>> at;
  for (const auto& p : points)
    if (!at.insert({p[0], p[1]}).second)
      return "two vertices at (" + std::to_string(p[0]) + "," + std::to_string(p[1]) + ")";
  double area = 0;
  std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
  for (const auto& t : triangles) {
    const double o = plane_orient(points[t[0]], points[t[1]], points[t[2]]);
    if (!(o > 0)) return "flipped or degenerate triangle";
    area += o / 2;
    for (int k = 0; k < 3; ++k)
      if (!edges.insert({t[std::size_t(k)], t[std::size_t((k + 1) % 3)]}).second)
        return "directed edge used twice (overlap)";
  }
  for (const auto& [a, b] : edges) {
    if (edges.count({b, a})) continue;
    const auto& p = points[a];
    const auto& q = points[b];
    const bool border = (p[0] == 0 && q[0] == 0) || (p[0] == W && q[0] == W) || (p[1] == 0 && q[1] == 0) ||
                        (p[1] == H && q[1] == H);
    if (!border)
      return "open edge (" + std::to_string(p[0]) + "," + std::to_string(p[1]) + ")-(" +
             std::to_string(q[0]) + "," + std::to_string(q[1]) + ") inside the domain (crack or T-junction)";
  }
  if (std::abs(area - W * H) > 1e-9 * W * H)
    return "area " + std::to_string(area) + " != " + std::to_string(W * H);
  return "";
}

}  // namespace terralod::test
