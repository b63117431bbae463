// Tests of thematic textures: class tables, colour ramps and bands exact on small rasters, DEM
// attributes (slope, aspect) on analytic planes, reductions, LOD-dependent design rules and
// the pyramid levels they draw.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/thematic_texture.hpp"

namespace tr = terralod::render;
namespace tp = terralod::pm;

namespace {
const float kNaN = std::numeric_limits<float>::quiet_NaN();
const tr::Rgba kForest{34, 139, 34, 255}, kWater{65, 105, 225, 255}, kTown{200, 60, 60, 255};

tr::FloatRaster raster(int w, int h, std::initializer_list<float> v) {
  tr::FloatRaster r(w, h);
  r.v.assign(v);
  return r;
}
}  // namespace

TEST(ThematicTexture, ClassTableMapsEveryPixelExactly) {
  // 3 x 2 land use:   1 2 3        forest water town
  //                   2 9 NaN      water  ?     nodata
  const tr::FloatRaster cls = raster(3, 2, {1, 2, 3, 2, 9, kNaN});
  tr::ClassTable t({{1, kForest}, {2, kWater}, {3, kTown}}, /*unknown=*/{255, 0, 255, 255});
  const tr::RgbaImage img = tr::apply_mapper(cls, t);
  ASSERT_EQ(img.width, 3);
  ASSERT_EQ(img.height, 2);
  EXPECT_EQ(img.get(0, 0), kForest);
  EXPECT_EQ(img.get(1, 0), kWater);
  EXPECT_EQ(img.get(2, 0), kTown);
  EXPECT_EQ(img.get(0, 1), kWater);
  EXPECT_EQ(img.get(1, 1), (tr::Rgba{255, 0, 255, 255}));
  EXPECT_EQ(img.get(2, 1), (tr::Rgba{0, 0, 0, 0}));
  EXPECT_THROW(t.map(1.5f), std::invalid_argument);  // not a class id
}

TEST(ThematicTexture, LinearRampAndBands) {
  // Ramp 0 -> (0,0,0,255), 100 -> (200,100,50,255), 200 -> (200,200,250,255).
  tr::ColorRamp ramp({{0.0f, {0, 0, 0, 255}}, {100.0f, {200, 100, 50, 255}}, {200.0f, {200, 200, 250, 255}}});
  EXPECT_EQ(ramp.map(-5.0f), (tr::Rgba{0, 0, 0, 255}));     // below: first colour
  EXPECT_EQ(ramp.map(25.0f), (tr::Rgba{50, 25, 13, 255}));  // 12.5 rounds to 13
  EXPECT_EQ(ramp.map(100.0f), (tr::Rgba{200, 100, 50, 255}));
  EXPECT_EQ(ramp.map(150.0f), (tr::Rgba{200, 150, 150, 255}));
  EXPECT_EQ(ramp.map(1e9f), (tr::Rgba{200, 200, 250, 255}));  // above: last colour
  EXPECT_EQ(ramp.map(kNaN), (tr::Rgba{0, 0, 0, 0}));
  // Elevation bands [0, 500) green, [500, 1000) brown, >= 1000 white; below 0 nodata.
  tr::ColorRamp bands(
      {{0.0f, {0, 160, 0, 255}}, {500.0f, {140, 90, 40, 255}}, {1000.0f, {255, 255, 255, 255}}},
      tr::ColorRamp::Mode::Step);
  const tr::RgbaImage img = tr::apply_mapper(raster(5, 1, {-1, 0, 499.9f, 500, 1500}), bands);
  EXPECT_EQ(img.get(0, 0), (tr::Rgba{0, 0, 0, 0}));
  EXPECT_EQ(img.get(1, 0), (tr::Rgba{0, 160, 0, 255}));
  EXPECT_EQ(img.get(2, 0), (tr::Rgba{0, 160, 0, 255}));
  EXPECT_EQ(img.get(3, 0), (tr::Rgba{140, 90, 40, 255}));
  EXPECT_EQ(img.get(4, 0), (tr::Rgba{255, 255, 255, 255}));
  EXPECT_THROW(tr::ColorRamp({{1.0f, {}}, {1.0f, {}}}), std::invalid_argument);
  EXPECT_THROW(tr::ColorRamp({}), std::invalid_argument);
}

TEST(ThematicTexture, SlopeAndAspectOfPlanes) {
  // z = -x * tan(30 deg) on a 30 m grid: slope 30 degrees, facing east (aspect 90).
  // z = +y: slope 45, facing south (aspect 180). Flat: slope 0, aspect NaN.
  const double t30 = std::tan(std::numbers::pi / 6);
  struct Case {
    double a, b, slope, aspect;
  };
  for (const Case& k :
       {Case{-t30, 0, 30, 90}, Case{0, 1, 45, 180},
        Case{1, 1, std::atan(std::sqrt(2.0)) * 180 / std::numbers::pi, 225}, Case{0, 0, 0, -1}}) {
    tp::Heightfield hf(6, 5);
    hf.transform = tp::GridTransform::north_up(0, 0, 30, 30);
    for (int r = 0; r < 5; ++r)
      for (int c = 0; c < 6; ++c) {
        const auto [x, y] = hf.transform.to_world(c, r);
        hf.at(c, r) = 100 + k.a * x + k.b * y;
      }
    const tr::FloatRaster s = tr::terrain_attribute(hf, tr::TerrainAttribute::SlopeDegrees);
    const tr::FloatRaster a = tr::terrain_attribute(hf, tr::TerrainAttribute::AspectDegrees);
    const tr::FloatRaster e = tr::terrain_attribute(hf, tr::TerrainAttribute::Elevation);
    EXPECT_NEAR(s.at(2, 2), k.slope, 1e-4);
    if (k.aspect < 0)
      EXPECT_TRUE(std::isnan(a.at(2, 2)));
    else
      EXPECT_NEAR(a.at(2, 2), k.aspect, 1e-4);
    EXPECT_FLOAT_EQ(e.at(3, 1), float(hf.at(3, 1)));
  }
}

TEST(ThematicTexture, ReductionsOfBlocks) {
  // 4 x 4 classes, step 2:    1 1 | 2 3        majority: 1 | 2 (2,3,2,3: tie -> smallest)
  //                           1 2 | 3 2
  //                           ----+----
  //                           5 5 | N N        majority: 5 | NaN (all NaN)
  //                           4 5 | N N
  const tr::FloatRaster cls = raster(4, 4, {1, 1, 2, 3, 1, 2, 3, 2, 5, 5, kNaN, kNaN, 4, 5, kNaN, kNaN});
  const tr::TexelRegion reg{0, 0, -1, -1, /*step=*/2};
  const tr::FloatRaster maj = tr::reduce_raster(cls, reg, tr::Reduction::Majority);
  ASSERT_EQ(maj.width, 2);
  EXPECT_EQ(maj.at(0, 0), 1.0f);
  EXPECT_EQ(maj.at(1, 0), 2.0f);
  EXPECT_EQ(maj.at(0, 1), 5.0f);
  EXPECT_TRUE(std::isnan(maj.at(1, 1)));
  const tr::FloatRaster mean = tr::reduce_raster(cls, reg, tr::Reduction::Mean);
  EXPECT_FLOAT_EQ(mean.at(0, 0), 1.25f);
  EXPECT_FLOAT_EQ(mean.at(0, 1), 4.75f);
  const tr::FloatRaster near = tr::reduce_raster(cls, reg, tr::Reduction::Nearest);
  EXPECT_EQ(near.at(1, 0), 2.0f);
  EXPECT_EQ(near.at(0, 1), 5.0f);
  // A region clipped at the edge: cols 1..3 with step 2 -> texels at cols 1 and 3 (block of 1).
  const tr::FloatRaster clip = tr::reduce_raster(cls, {1, 0, 3, 2, 2}, tr::Reduction::Mean);
  ASSERT_EQ(clip.width, 2);
  EXPECT_FLOAT_EQ(clip.at(0, 0), 2.0f);  // cols 1,2 rows 0,1: (1 + 2 + 2 + 3) / 4
  EXPECT_FLOAT_EQ(clip.at(1, 0), 2.5f);  // col 3 rows 0,1: (3 + 2) / 2
}

TEST(ThematicTexture, LodDesignRuleChangesTheLookWithTexelSize) {
  // Forest (1) with a one-sample clearing (2) in a 4 x 4 raster of 10 m samples:
  //   1 1 1 1
  //   1 2 1 1      near (texel 10 m): exact classes, the clearing is visible
  //   1 1 1 1      far  (texel 40 m, step 4): majority -> all forest, drawn by the far ramp
  //   1 1 1 1
  tr::FloatRaster cls(4, 4, 1.0f);
  cls.at(1, 1) = 2.0f;
  auto near =
      std::make_shared<tr::ClassTable>(std::map<int, tr::Rgba>{{1, kForest}, {2, {240, 230, 140, 255}}});
  auto far = std::make_shared<tr::ColorRamp>(
      std::vector<tr::ColorRamp::Stop>{{1.0f, {0, 100, 0, 255}}, {2.0f, {250, 250, 200, 255}}});
  tr::LodDesignRule rule(tr::Reduction::Majority);
  rule.add(/*max_texel_size_m=*/20.0, near);
  rule.add(/*max_texel_size_m=*/1e9, far);
  EXPECT_EQ(&rule.mapper_for(10.0), near.get());
  EXPECT_EQ(&rule.mapper_for(20.0), near.get());
  EXPECT_EQ(&rule.mapper_for(40.0), far.get());
  const tr::RgbaImage fine = rule.render(cls, {}, /*sample_size_m=*/10.0);
  ASSERT_EQ(fine.width, 4);
  EXPECT_EQ(fine.get(1, 1), (tr::Rgba{240, 230, 140, 255}));
  EXPECT_EQ(fine.get(0, 0), kForest);
  const tr::RgbaImage coarse = rule.render(cls, {0, 0, -1, -1, /*step=*/4}, 10.0);
  ASSERT_EQ(coarse.width, 1);
  EXPECT_EQ(coarse.get(0, 0), (tr::Rgba{0, 100, 0, 255}));
  // Step 2 (texel 20 m) still uses the near table, on the majority of each 2 x 2 block.
  const tr::RgbaImage mid = rule.render(cls, {0, 0, -1, -1, 2}, 10.0);
  ASSERT_EQ(mid.width, 2);
  EXPECT_EQ(mid.get(0, 0), kForest);  // 1 1 / 1 2 -> 1
}

namespace {
// A rule that records the regions it is asked for and draws each as (step, col0 + cols, rows, 255).
struct RecordingRule final : tr::DesignRule {
  mutable std::vector<tr::TexelRegion> regions;
  int extra_width = 0;  // > 0: draws a wrong size
  tr::RgbaImage render(const tr::FloatRaster& values, const tr::TexelRegion& region, double) const override {
    regions.push_back(region);
    tr::RgbaImage img(region.out_width(values.width) + extra_width, region.out_height(values.height));
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x)
        img.set(x, y, {std::uint8_t(region.step), std::uint8_t(region.cols), std::uint8_t(region.rows), 255});
    return img;
  }
};
}  // namespace

TEST(ThematicTexture, PyramidLevelsHaveThePyramidSizesAndBlocksOfTwoToTheK) {
  // 13 x 6 values, max texture size 2: pyramid_levels 13x6, 6x3, 3x1, 1x1. Level k asks for
  // step 2^k over min(W, w_k 2^k) x min(H, h_k 2^k) samples:
  //   k=0: 13 x 6 step 1;  k=1: 12 x 6 step 2 (column 12 left out);  k=2: 12 x 4 step 4;
  //   k=3: 8 x 6 step 8 (h_3 = 1 is max(1, 6/8 = 0): the one row covers all 6).
  const tr::FloatRaster values(13, 6, 1.0f);
  RecordingRule rec;
  const std::vector<tr::RgbaImage> lv = tr::render_pyramid_levels(rec, values, /*sample_size_m=*/10.0, 2);
  ASSERT_EQ(lv.size(), 4u);
  const std::vector<tr::LevelSize> want = tr::pyramid_levels(13, 6, 2);
  const int cols[] = {13, 12, 12, 8}, rows[] = {6, 6, 4, 6};
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_EQ((tr::LevelSize{lv[k].width, lv[k].height}), want[k]) << "level " << k;
    const tr::TexelRegion& r = rec.regions[k];
    EXPECT_EQ(r.col0, 0);
    EXPECT_EQ(r.row0, 0);
    EXPECT_EQ(r.step, 1 << k) << "level " << k;
    EXPECT_EQ(r.cols, cols[k]) << "level " << k;
    EXPECT_EQ(r.rows, rows[k]) << "level " << k;
  }
  // A rule that draws the wrong size is refused, naming the level.
  RecordingRule wrong;
  wrong.extra_width = 1;
  try {
    tr::render_pyramid_levels(wrong, values, 10.0, 2);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("level 0 as 14 x 6"), std::string::npos) << e.what();
  }
}

TEST(ThematicTexture, PyramidLevelsPickTheLookByTexelSize) {
  // v(c, r) = c + 100 r on 13 x 6 samples of 10 m; near ramp 0 -> 1000 black to red, far ramp
  // black to green; near up to 25 m: levels 0 (10 m) and 1 (20 m) near, 2 (40 m) far. Mean:
  //   level 0 texel (12, 5) = 512             -> red   512/1000*250 = 128
  //   level 1 texel (1, 0)  = mean of cols 2..3, rows 0..1 = 2.5 + 50 = 52.5 -> red 13.125 = 13
  //   level 2 texel (0, 0)  = mean of cols 0..3, rows 0..3 = 1.5 + 150 = 151.5 -> green 37.875 = 38
  tr::FloatRaster v(13, 6);
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 13; ++c) v.at(c, r) = float(c + 100 * r);
  tr::LodDesignRule rule(tr::Reduction::Mean);
  rule.add(25.0, std::make_shared<tr::ColorRamp>(
                     std::vector<tr::ColorRamp::Stop>{{0.0f, {0, 0, 0, 255}}, {1000.0f, {250, 0, 0, 255}}}));
  rule.add(1e30, std::make_shared<tr::ColorRamp>(
                     std::vector<tr::ColorRamp::Stop>{{0.0f, {0, 0, 0, 255}}, {1000.0f, {0, 250, 0, 255}}}));
  const std::vector<tr::RgbaImage> lv = tr::render_pyramid_levels(rule, v, 10.0, 2);
  ASSERT_EQ(lv.size(), 4u);
  EXPECT_EQ(lv[0].get(12, 5), (tr::Rgba{128, 0, 0, 255}));
  EXPECT_EQ(lv[1].get(1, 0), (tr::Rgba{13, 0, 0, 255}));
  EXPECT_EQ(lv[2].get(0, 0), (tr::Rgba{0, 38, 0, 255}));
}
