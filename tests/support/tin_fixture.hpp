// Test support for the hybrid grid + TIN tests (header-only, for tests that link
// terralod::blocks): the bumpy grid they lay TINs on, the plane that gives TIN vertices their
// heights, TINs shaped as a block of squares or as a fan, and the realistic example: a valley of
// the SRTM tile N44W072 with the polygon committed in examples/hybrid/.
//
// Usage:
//   const pm::Heightfield hf = terralod::test::bumpy_grid(33, 33);
//   const auto tin = terralod::test::grid_tin(4, 4, 8, 8, 2);   // squares over [4,20] x [4,20]
//   const auto fan = terralod::test::fan_tin({{10, 8}, {13, 10}, {10, 12}, {7, 10}}, {10, 10});
//   std::ifstream csv(std::string(TERRALOD_EXAMPLES_DIR) + "/hybrid/valley_N44W072.csv");
//   const terralod::test::Valley v = terralod::test::valley_of(n44w072, csv);
//   const auto tin = terralod::test::valley_tin(v);
//
// Contract: coordinates are (col, row) of the grid; every TIN vertex (c, r) has the height
// tin_height(c, r) = 50 + 0.3 c - 0.2 r (the tests tell TIN heights from grid heights by it).
// fan_tin's polygon must be star-shaped around `centre` and have the TIN
// on its left (positive orientation in (col, row)); a polygon that is not fails the test.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <istream>
#include <string>
#include <vector>

#include "terralod/blocks/greedy_tin.hpp"
#include "terralod/blocks/hybrid/hybrid_terrain.hpp"
#include "terralod/pm/heightfield.hpp"

namespace terralod::test {

/// w x h samples of the plane 10 + 0.5 c + 0.25 r plus a bump pattern ((7 c + 3 r) mod 5).
inline pm::Heightfield bumpy_grid(int w, int h) {
  pm::Heightfield hf(w, h);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) hf.at(c, r) = 10.0 + 0.5 * c + 0.25 * r + ((c * 7 + r * 3) % 5);
  hf.source = "generated grid";
  return hf;
}

inline double tin_height(double c, double r) { return 50.0 + 0.3 * c - 0.2 * r; }

/// A cols x rows block of step-sized squares from (c0, r0), each cut into two triangles.
inline blocks::hybrid::TinMesh grid_tin(double c0, double r0, int cols, int rows, double step) {
  blocks::hybrid::TinMesh t;
  t.source = "grid TIN";
  for (int j = 0; j <= rows; ++j)
    for (int i = 0; i <= cols; ++i) {
      const double c = c0 + i * step, r = r0 + j * step;
      t.points.push_back({c, r, tin_height(c, r)});
    }
  auto id = [&](int i, int j) { return std::uint32_t(j * (cols + 1) + i); };
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < cols; ++i) {
      t.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      t.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  return t;
}

/// A fan of triangles from `centre` to each edge of `poly`.
inline blocks::hybrid::TinMesh fan_tin(const std::vector<std::array<double, 2>>& poly,
                                       std::array<double, 2> centre) {
  blocks::hybrid::TinMesh t;
  t.source = "test TIN";
  t.points.push_back({centre[0], centre[1], tin_height(centre[0], centre[1])});
  for (const auto& p : poly) t.points.push_back({p[0], p[1], tin_height(p[0], p[1])});
  const std::uint32_t n = std::uint32_t(poly.size());
  for (std::uint32_t i = 0; i < n; ++i) {
    t.triangles.push_back({0, 1 + i, 1 + (i + 1) % n});
    const auto& a = t.points[0];
    const auto& b = t.points[1 + i];
    const auto& c = t.points[1 + (i + 1) % n];
    EXPECT_GT((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]), 0) << "fixture not star-shaped";
  }
  return t;
}

/// The valley example: cols 384..592, rows 336..704 of N44W072 and the valley polygon there.
struct Valley {
  pm::Heightfield crop;                        ///< 209 x 369 samples, identity transform
  std::vector<std::array<double, 2>> polygon;  ///< (col, row) of the crop
};

/// `full`: the 1201 x 1201 tile N44W072; `csv`: the polygon, one "x,y" line per vertex in the
/// tile's world metres (empty lines, '#' comments and the "x,y" header skipped).
inline Valley valley_of(const pm::Heightfield& full, std::istream& csv) {
  const int c0 = 384, r0 = 336, w = 209, hgt = 369;
  Valley v{pm::Heightfield(w, hgt), {}};
  for (int r = 0; r < hgt; ++r)
    for (int c = 0; c < w; ++c) v.crop.at(c, r) = full.at(c0 + c, r0 + r);
  v.crop.source = "N44W072 crop";
  for (std::string line; std::getline(csv, line);) {
    if (line.empty() || line[0] == '#' || line[0] == 'x') continue;
    const double x = std::stod(line.substr(0, line.find(','))),
                 y = std::stod(line.substr(line.find(',') + 1));
    v.polygon.push_back(
        {(x - full.transform.x0) / full.transform.xc - c0, (y - full.transform.y0) / full.transform.yr - r0});
  }
  return v;
}

/// The greedy TIN (max error 5 m) of the crop's samples inside the polygon, with the DEM's heights.
inline blocks::hybrid::TinMesh valley_tin(const Valley& v) {
  const blocks::TinSurface surf = blocks::build_greedy_tin(v.crop, v.polygon, {.max_error = 5.0});
  blocks::hybrid::TinMesh tin;
  tin.source = "valley TIN";
  for (const auto& p : surf.points) tin.points.push_back({double(p[0]), double(p[1]), v.crop.at(p[0], p[1])});
  tin.triangles = surf.triangles;
  return tin;
}

}  // namespace terralod::test
