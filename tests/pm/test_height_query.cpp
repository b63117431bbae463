// Tests of pm/height_query.hpp: the inverse grid transform and the bilinear height, on a tiny
// hand-computed fixture, with holes, degenerate grids and a rotated transform.
#include <gtest/gtest.h>

#include <cmath>

#include "terralod/pm/height_query.hpp"

namespace {

namespace pm = terralod::pm;

// 3 x 2 samples, north-up, 30 m spacing, first sample centre at (0, 90):
//
//   y = 90   (row 0):   0 -- 10 -- 20        x = 0, 30, 60
//   y = 60   (row 1):  30 -- 40 -- 80
pm::Heightfield fixture() {
  pm::Heightfield hf(3, 2);
  const double z[6] = {0, 10, 20, 30, 40, 80};
  for (int i = 0; i < 6; ++i) hf[std::size_t(i)] = z[i];
  hf.transform = pm::GridTransform::north_up(0, 90, 30, 30);
  return hf;
}

TEST(HeightQuery, WorldToGridInvertsTheTransform) {
  const pm::Heightfield hf = fixture();
  const auto [c, r] = pm::world_to_grid(hf.transform, 45, 75);
  EXPECT_DOUBLE_EQ(c, 1.5);
  EXPECT_DOUBLE_EQ(r, 0.5);
  // A rotated, sheared transform: to_world then world_to_grid returns the indices.
  const pm::GridTransform t{1000, 20, -7, 5000, 9, -25};
  for (const auto& [gc, gr] : {std::pair{0.0, 0.0}, {3.25, -1.5}, {100.0, 42.75}}) {
    const auto [x, y] = t.to_world(gc, gr);
    const auto [bc, br] = pm::world_to_grid(t, x, y);
    EXPECT_NEAR(bc, gc, 1e-9);
    EXPECT_NEAR(br, gr, 1e-9);
  }
}

TEST(HeightQuery, BilinearIsExactAtSamplesAndBlendsInside) {
  const pm::Heightfield hf = fixture();
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) {
      const auto [x, y] = hf.transform.to_world(c, r);
      EXPECT_EQ(pm::bilinear_height(hf, x, y), hf.at(c, r)) << c << "," << r;
    }
  EXPECT_DOUBLE_EQ(pm::bilinear_height(hf, 15, 75), 20.0);    // (0 + 10 + 30 + 40) / 4
  EXPECT_DOUBLE_EQ(pm::bilinear_height(hf, 45, 75), 37.5);    // (10 + 20 + 40 + 80) / 4
  EXPECT_DOUBLE_EQ(pm::bilinear_height(hf, 7.5, 90), 2.5);    // a quarter along 0 -- 10
  EXPECT_DOUBLE_EQ(pm::bilinear_height(hf, 60, 82.5), 35.0);  // a quarter down 20 -- 80
}

TEST(HeightQuery, PointsOutsideAreClampedToTheBorder) {
  const pm::Heightfield hf = fixture();
  EXPECT_DOUBLE_EQ(pm::bilinear_height(hf, -100, 90), 0.0);
  EXPECT_DOUBLE_EQ(pm::bilinear_height(hf, 200, -500), 80.0);
  EXPECT_DOUBLE_EQ(pm::bilinear_height(hf, 15, 1000), 5.0);  // north of row 0: between 0 and 10
}

TEST(HeightQuery, HolesTakeNoPart) {
  pm::Heightfield hf = fixture();
  std::vector<std::uint8_t> mask(6, 1);
  mask[4] = 0;  // (1,1), height 40, is a hole
  hf.set_mask(mask);
  // Cell (0,0): corners 0, 10, 30 valid with weight 1/4 each: 40/4 / (3/4).
  EXPECT_NEAR(pm::bilinear_height(hf, 15, 75), 40.0 / 3.0, 1e-12);
  EXPECT_EQ(pm::bilinear_height(hf, 0, 60), 30.0);           // a valid sample next to the hole
  EXPECT_TRUE(std::isnan(pm::bilinear_height(hf, 30, 60)));  // on the hole itself
}

TEST(HeightQuery, DegenerateGrids) {
  pm::Heightfield one(1, 1);
  one.at(0, 0) = 7;
  EXPECT_EQ(pm::bilinear_height(one, 123, -4), 7.0);
  pm::Heightfield row(3, 1);  // 0, 10, 30 along x, spacing 1
  row.at(1, 0) = 10, row.at(2, 0) = 30;
  EXPECT_DOUBLE_EQ(pm::bilinear_height(row, 1.5, 0.0), 20.0);
  EXPECT_DOUBLE_EQ(pm::bilinear_height(row, 1.5, 9.0), 20.0);  // off the line: clamped onto it
}

}  // namespace
