// Tests of the OSMesa shading generator: the analytic formulas on planes, the shadow of a step,
// tiling, regions and holes, and agreement with the CPU generator on a generated terrain and on
// the real N44W072 tile (skipped when the data file is absent).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/gpu_shading.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/topographic_texture.hpp"

namespace tr = terralod::render;
namespace tp = terralod::pm;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

std::unique_ptr<tr::GlContext>& context() {
  static std::unique_ptr<tr::GlContext> ctx = tr::create_offscreen_context({/*width=*/16, /*height=*/16});
  return ctx;
}

struct Diff {
  double max_abs = 0;     // in shading units
  int max_grey = 0;       // largest |grey_cpu - grey_gpu|
  std::size_t over2 = 0;  // texels whose grey levels differ by more than 2
  std::size_t n = 0;
};

Diff compare(const tr::FloatRaster& a, const tr::FloatRaster& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  Diff d;
  for (std::size_t i = 0; i < a.v.size() && i < b.v.size(); ++i) {
    ++d.n;
    if (std::isnan(a.v[i]) || std::isnan(b.v[i])) {
      EXPECT_EQ(std::isnan(a.v[i]), std::isnan(b.v[i])) << "hole mismatch at " << i;
      continue;
    }
    d.max_abs = std::max(d.max_abs, double(std::abs(a.v[i] - b.v[i])));
    const int g = std::abs(int(tr::grey_level(a.v[i])) - int(tr::grey_level(b.v[i])));
    d.max_grey = std::max(d.max_grey, g);
    d.over2 += g > 2;
  }
  return d;
}

tp::Heightfield plane(int w, int h, const tp::GridTransform& t, double a, double b) {
  tp::Heightfield hf(w, h);
  hf.transform = t;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const auto [x, y] = t.to_world(c, r);
      hf.at(c, r) = 800.0 + a * x + b * y;
    }
  return hf;
}

}  // namespace

TEST(GpuShading, PlanesMatchTheCpuFormula) {
  // The CPU generator is checked against the formulas on planes (test_topographic_texture);
  // here the GPU must agree with it to float rounding on the same planes, every method.
  tr::GpuShadingReport rep;
  for (auto [a, b] : std::vector<std::pair<double, double>>{{0, 0}, {0.3, -0.2}, {-1.1, 0.6}})
    for (auto m : {tr::ShadingMethod::Lambert, tr::ShadingMethod::Phong, tr::ShadingMethod::Multidirectional,
                   tr::ShadingMethod::RelativeHeight})
      for (double az : {30.0, 225.0}) {
        const tp::Heightfield hf = plane(11, 9, tp::GridTransform::north_up(0, 0, 30, 20), a, b);
        tr::ShadingOptions o;
        o.method = m, o.azimuth_deg = az, o.altitude_deg = 35, o.ambient = 0.1, o.relative_radius = 2;
        const tr::FloatRaster cpu = tr::shade_terrain(hf, o);
        const tr::FloatRaster gpu = tr::shade_terrain_gpu(hf, o, {}, {}, context().get(), &rep);
        const Diff d = compare(cpu, gpu);
        EXPECT_LE(d.max_abs, 2e-5) << tr::shading_method_name(m) << " a=" << a << " b=" << b << " az=" << az;
      }
  EXPECT_EQ(rep.tiles, 1);
  std::printf("renderer: %s\n", rep.renderer.c_str());
  // Hand value: z = -x, light from the east at 45 degrees -> n.l = 1 (see the CPU test).
  const tp::Heightfield east = plane(5, 5, tp::GridTransform::north_up(0, 0, 30, 30), -1.0, 0.0);
  tr::ShadingOptions o;
  o.azimuth_deg = 90;
  EXPECT_NEAR(tr::shade_terrain_gpu(east, o, {}, {}, context().get()).at(2, 2), 1.0, 1e-6);
}

TEST(GpuShading, StepShadowMatchesHOverTanH) {
  // Plateau H = 100 m west of column 9, ground from column 10, dx = 10 m, light from the west
  // at tan h = 0.5: ground texels j with (j - 9) * 10 < 200 are shadowed, columns 10..28.
  tp::Heightfield hf(80, 4);
  hf.transform = tp::GridTransform::north_up(0, 30, 10, 10);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 80; ++c) hf.at(c, r) = c <= 9 ? 100.0 : 0.0;
  tr::ShadingOptions o;
  o.azimuth_deg = 270, o.altitude_deg = std::atan(0.5) / kDeg, o.shadows = true, o.ambient = 0.25;
  const tr::FloatRaster s = tr::shade_terrain_gpu(hf, o, {}, {}, context().get());
  for (int c = 10; c < 80; ++c)
    EXPECT_EQ(s.at(c, 1) == 0.25f, c <= 28) << "column " << c << " value " << s.at(c, 1);
}

TEST(GpuShading, TilesRegionsAndHolesAgreeWithTheCpu) {
  tp::TerrainOptions to;
  to.width = 301, to.height = 257, to.seed = 11, to.relief = 1500;
  std::printf("generated terrain seed %llu\n", static_cast<unsigned long long>(to.seed));
  tp::Heightfield hf = tp::generate_terrain(to);
  std::vector<std::uint8_t> mask(hf.size(), 1);
  for (int r = 100; r < 110; ++r)
    for (int c = 40; c < 47; ++c) mask[std::size_t(r) * 301 + c] = 0;
  hf.set_mask(mask);
  for (auto m : {tr::ShadingMethod::Lambert, tr::ShadingMethod::Phong, tr::ShadingMethod::Multidirectional,
                 tr::ShadingMethod::RelativeHeight}) {
    tr::ShadingOptions o;
    o.method = m, o.shadows = m != tr::ShadingMethod::RelativeHeight, o.altitude_deg = 25,
    o.azimuth_deg = 300;
    const tr::FloatRaster cpu = tr::shade_terrain(hf, o);
    tr::GpuShadingReport rep;
    const tr::FloatRaster whole = tr::shade_terrain_gpu(hf, o, {}, {}, context().get(), &rep);
    EXPECT_EQ(rep.tiles, 1);
    tr::GpuShadingOptions g;
    g.max_tile = 64;  // 5 x 5 tiles of at most 64 x 64
    const tr::FloatRaster tiled = tr::shade_terrain_gpu(hf, o, {}, g, context().get(), &rep);
    EXPECT_EQ(rep.tiles, 25);
    ASSERT_EQ(tiled.v.size(), whole.v.size());
    EXPECT_EQ(std::memcmp(tiled.v.data(), whole.v.data(), whole.v.size() * sizeof(float)), 0)
        << "tiling must not change a texel";  // bitwise: holes are NaN
    const Diff d = compare(cpu, whole);
    std::printf("%s: CPU vs GPU max |diff| %.3g, max %d grey levels, %zu of %zu texels > 2 levels\n",
                tr::shading_method_name(m), d.max_abs, d.max_grey, d.over2, d.n);
    EXPECT_LE(double(d.over2), 0.001 * double(d.n)) << tr::shading_method_name(m);
    EXPECT_TRUE(std::isnan(whole.at(42, 105)));
    // A region with a step (coarser level): the same texels as the CPU's region.
    const tr::TexelRegion reg{/*col0=*/17, /*row0=*/9, /*cols=*/250, /*rows=*/200, /*step=*/4};
    const Diff dr =
        compare(tr::shade_terrain(hf, o, reg), tr::shade_terrain_gpu(hf, o, reg, g, context().get()));
    EXPECT_LE(double(dr.over2), 0.001 * double(dr.n));
    EXPECT_EQ(dr.n, std::size_t(63 * 50));
  }
}

TEST(GpuShading, MisuseIsRejected) {
  tp::Heightfield hf(8, 8);
  tr::ShadingOptions o;
  o.altitude_deg = 95;
  EXPECT_THROW(tr::shade_terrain_gpu(hf, o, {}, {}, context().get()), std::invalid_argument);
  o = {};
  tr::GpuShadingOptions g;
  g.max_tile = -1;
  EXPECT_THROW(tr::shade_terrain_gpu(hf, o, {}, g, context().get()), std::invalid_argument);
  // A private context is made when none is given.
  EXPECT_EQ(tr::shade_terrain_gpu(hf, o).width, 8);
}

// The full 1201 x 1201 tile (named RealTileFull: excluded from the sanitizer runs).
TEST(GpuShading, N44W072RealTileFullAgreesWithTheCpu) {
  const std::filesystem::path path = std::filesystem::path(TERRALOD_DATA_DIR) / "N44W072.hgt";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " not found";
  const tp::Heightfield hf = terralod::blocks::read_dem(path.string());
  // Multidirectional with shadows marches four rays per texel: checked on the generated terrain.
  for (bool shadows : {false, true})
    for (auto m : {tr::ShadingMethod::Lambert, tr::ShadingMethod::Multidirectional}) {
      if (shadows && m == tr::ShadingMethod::Multidirectional) continue;
      tr::ShadingOptions o;
      o.method = m, o.shadows = shadows, o.altitude_deg = 30;
      const auto t0 = std::chrono::steady_clock::now();
      const tr::FloatRaster cpu = tr::shade_terrain(hf, o);
      const auto t1 = std::chrono::steady_clock::now();
      tr::GpuShadingReport rep;
      const tr::FloatRaster gpu = tr::shade_terrain_gpu(hf, o, {}, {}, context().get(), &rep);
      const auto t2 = std::chrono::steady_clock::now();
      const Diff d = compare(cpu, gpu);
      std::printf(
          "N44W072 %s shadows=%d: CPU %.0f ms, GPU %.0f ms (%d tile(s)); max |diff| %.3g, max %d grey "
          "levels, %zu of %zu texels > 2 levels\n",
          tr::shading_method_name(m), int(shadows),
          std::chrono::duration<double, std::milli>(t1 - t0).count(),
          std::chrono::duration<double, std::milli>(t2 - t1).count(), rep.tiles, d.max_abs, d.max_grey,
          d.over2, d.n);
      EXPECT_LE(double(d.over2), 0.001 * double(d.n));
      if (!shadows) {
        EXPECT_LE(d.max_grey, 1);
      }
    }
}
