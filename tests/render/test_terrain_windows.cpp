// Textures computed window by window (terrain_windows.hpp) are the whole grid's, bit for bit:
// every shading method, with shadows reaching far across windows, relative height over a radius
// and over the whole grid, coarse steps, holes; and the windows stay the size asked for.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <memory>

#include "run_command.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/terrain_windows.hpp"
#include "terralod/render/thematic_texture.hpp"
#include "terralod/render/topographic_texture.hpp"

namespace tr = terralod::render;
namespace tb = terralod::blocks;
namespace pm = terralod::pm;

namespace {

// A rough 203 x 171 terrain on a 30 x 20 m grid with a hole, and windows of it with a
// counter of what they read.
struct Windows {
  pm::Heightfield hf;
  std::size_t reads = 0, most = 0;  // windows read, the largest in samples
  int widest = 0;

  Windows() {
    pm::TerrainOptions to;
    to.width = 203, to.height = 171, to.seed = 9, to.relief = 900;
    hf = pm::generate_terrain(to);
    hf.transform = pm::GridTransform::north_up(1000.0, 9000.0, 30.0, 20.0);
    std::vector<std::uint8_t> mask(hf.size(), 1);
    for (int r = 60; r < 75; ++r)
      for (int c = 100; c < 130; ++c) mask[std::size_t(r) * hf.width() + c] = 0;
    hf.set_mask(std::move(mask));
  }

  tr::TerrainWindows windows(std::size_t window_samples) {
    tr::TerrainWindows t;
    t.width = hf.width(), t.height = hf.height();
    t.transform = hf.transform;
    t.lo = std::numeric_limits<double>::infinity(), t.hi = -t.lo;
    for (std::size_t i = 0; i < hf.size(); ++i)
      if (hf.valid(i)) t.lo = std::min(t.lo, hf[i]), t.hi = std::max(t.hi, hf[i]);
    t.window_samples = window_samples;
    t.read = [this](int c0, int r0, int cols, int rows) {
      ++reads;
      most = std::max(most, std::size_t(cols) * std::size_t(rows));
      widest = std::max({widest, cols, rows});
      return tb::block_heightfield(hf, {c0, r0, c0 + cols - 1, r0 + rows - 1});
    };
    return t;
  }
};

// Same values, NaN included, bit for bit.
void expect_identical(const tr::FloatRaster& a, const tr::FloatRaster& b) {
  ASSERT_EQ(a.width, b.width);
  ASSERT_EQ(a.height, b.height);
  std::size_t differ = 0, first = 0;
  for (std::size_t i = 0; i < a.v.size(); ++i)
    if (std::memcmp(&a.v[i], &b.v[i], sizeof(float)) != 0 && differ++ == 0) first = i;
  EXPECT_EQ(differ, 0u) << "first at texel " << first % a.width << "," << first / a.width << ": "
                        << a.v[first] << " against " << b.v[first];
}

}  // namespace

TEST(TerrainWindows, ShadingWindowByWindowIsTheWholeGridsBitForBit) {
  Windows w;
  struct Case {
    const char* name;
    tr::ShadingOptions o;
    tr::TexelRegion region;
  };
  std::vector<Case> cases;
  tr::ShadingOptions o;
  cases.push_back({"lambert", o, {}});
  o.shadows = true;
  o.altitude_deg = 50;  // rays climb 900 m over 750 m: 25 columns and 38 rows beyond a tile
  cases.push_back({"lambert, sun from the north-west", o, {}});
  o.altitude_deg = 8;  // over 6 km: windows reach the grid's north and west edges
  cases.push_back({"lambert, low sun from the north-west", o, {}});
  o.azimuth_deg = 100, o.altitude_deg = 30, o.method = tr::ShadingMethod::Phong;
  o.vertical_exaggeration = 0.4;
  cases.push_back({"phong, sun from the east, flattened", o, {}});
  o.azimuth_deg = 100, o.altitude_deg = 15, o.method = tr::ShadingMethod::Phong;
  o.vertical_exaggeration = 2.5;
  cases.push_back({"phong, sun from the east, exaggerated", o, {7, 5, 150, 120, 3}});
  o = {};
  o.shadows = true, o.altitude_deg = 12, o.method = tr::ShadingMethod::Multidirectional;
  cases.push_back({"multidirectional, four suns", o, {}});
  o.altitude_deg = 40, o.vertical_exaggeration = 0.5;
  cases.push_back({"multidirectional, four higher suns", o, {1, 2, 180, 160, 1}});
  o.azimuth_deg = 180, o.method = tr::ShadingMethod::Lambert, o.shadow_bias = 0;
  cases.push_back({"lambert, sun due south, no bias", o, {0, 0, -1, -1, 2}});
  o = {};
  o.method = tr::ShadingMethod::RelativeHeight;
  cases.push_back({"relative height, radius 16", o, {}});
  o.relative_radius = 0;
  cases.push_back({"relative height over the whole grid", o, {3, 4, -1, -1, 1}});
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const tr::FloatRaster whole = tr::shade_terrain(w.hf, c.o, c.region);
    const tr::FloatRaster windowed = tr::shade_terrain(w.windows(32 * 32), c.o, c.region);
    expect_identical(windowed, whole);
  }
  EXPECT_GT(w.reads, 50u);
}

TEST(TerrainWindows, AttributesWindowByWindowAreTheWholeGridsBitForBit) {
  Windows w;
  for (tr::TerrainAttribute a : {tr::TerrainAttribute::SlopeDegrees, tr::TerrainAttribute::AspectDegrees,
                                 tr::TerrainAttribute::Elevation})
    for (const tr::TexelRegion& r : {tr::TexelRegion{}, tr::TexelRegion{5, 9, 101, 77, 4}}) {
      SCOPED_TRACE(int(a));
      expect_identical(tr::terrain_attribute(w.windows(40 * 40), a, r), tr::terrain_attribute(w.hf, a, r));
    }
}

TEST(TerrainWindows, MarginsReachAsFarAsARayClimbsToTheHighestSample) {
  tr::TerrainWindows t;
  t.width = t.height = 1000;
  t.transform = pm::GridTransform::north_up(0, 0, 30.0, 30.0);
  t.lo = 100, t.hi = 400;  // 300 m of relief
  tr::ShadingOptions o;
  EXPECT_EQ(tr::shading_margins(t, o).right, 1);              // no shadows: Horn's neighbours
  o.shadows = true, o.azimuth_deg = 90, o.altitude_deg = 45;  // east: 300 m = 10 columns, and one
  tr::WindowMargins m = tr::shading_margins(t, o);
  EXPECT_GE(m.right, 11);  // 10 + 1, or 11 + 1 where 300 / tan(45 deg) rounds above 300
  EXPECT_LE(m.right, 12);
  EXPECT_EQ(m.left, 1);
  EXPECT_LE(m.top, 2);
  EXPECT_LE(m.bottom, 2);
  o.azimuth_deg = 0;  // north is up the rows: toward row 0
  o.vertical_exaggeration = 2;
  m = tr::shading_margins(t, o);
  EXPECT_GE(m.top, 21);
  EXPECT_LE(m.top, 22);
  EXPECT_LE(m.bottom, 2);
  o.method = tr::ShadingMethod::RelativeHeight, o.shadows = false, o.relative_radius = 7;
  m = tr::shading_margins(t, o);
  EXPECT_EQ(m.left, 7);
  EXPECT_EQ(m.bottom, 7);
  o.method = tr::ShadingMethod::Lambert, o.shadows = true, o.altitude_deg = 0;
  EXPECT_THROW(tr::shading_margins(t, o), std::invalid_argument);
}

TEST(TerrainWindows, WindowsStayTheSizeAskedFor) {
  Windows w;
  tr::TerrainWindows t = w.windows(48 * 48);
  tr::terrain_attribute(t, tr::TerrainAttribute::SlopeDegrees);
  // Tiles of 64 samples a side (the least) with Horn's margin of one.
  EXPECT_LE(w.most, std::size_t(66 * 66));
  EXPECT_GT(w.reads, 6u);
  // A GPU's limit on a side is kept even where the budget would allow wider windows.
  w.most = 0, w.widest = 0;
  t.window_samples = std::size_t(1) << 24;
  t.max_side = 50;
  tr::ShadingOptions o;
  expect_identical(tr::shade_terrain(t, o), tr::shade_terrain(w.hf, o));
  EXPECT_LE(w.widest, 50);
  EXPECT_THROW(tr::shade_terrain(t, o, {0, 0, 204, -1, 1}), std::invalid_argument);
}

TEST(TerrainWindows, RuleLevelsWindowByWindowAreTheWholeGridsFile) {
  Windows w;
  const terralod::test::TempDir dir("rule-windows");
  for (tr::Reduction g : {tr::Reduction::Mean, tr::Reduction::Nearest}) {
    SCOPED_TRACE(int(g));
    tr::LodDesignRule rule(g);
    rule.add(70.0, std::make_shared<tr::ColorRamp>(std::vector<tr::ColorRamp::Stop>{
                       {0.0f, {255, 255, 255, 255}}, {45.0f, {160, 0, 0, 255}}}));
    rule.add(1e30, std::make_shared<tr::ColorRamp>(
                       std::vector<tr::ColorRamp::Stop>{{0.0f, {0, 0, 255, 255}}, {30.0f, {0, 255, 0, 255}}},
                       tr::ColorRamp::Mode::Step));
    tr::PyramidOptions po;
    po.max_texture_size = 20;  // 203 x 171 down to 12 x 10: five levels, blocks of up to 16 samples
    po.tile_size = 16;
    const std::string whole = (dir.path() / "whole.tx").string(),
                      windowed = (dir.path() / "windowed.tx").string();
    tr::ImagePyramid::write_levels(
        tr::render_pyramid_levels(rule, tr::terrain_attribute(w.hf, tr::TerrainAttribute::SlopeDegrees), 25.0,
                                  po.max_texture_size),
        whole, po);
    tr::write_rule_pyramid(w.windows(24 * 24), tr::TerrainAttribute::SlopeDegrees, rule, 25.0, windowed, po);
    const tr::ImagePyramid a(whole, po), b(windowed, po);
    ASSERT_EQ(a.levels(), 5);
    ASSERT_EQ(b.level_sizes(), a.level_sizes());
    for (int k = 0; k < a.levels(); ++k) {
      const tr::PixelRect r{k, 0, 0, a.level(k).width, a.level(k).height};
      EXPECT_TRUE(a.read(r) == b.read(r)) << "level " << k;
    }
  }
}
