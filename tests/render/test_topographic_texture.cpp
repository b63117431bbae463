// Tests of the CPU topographic texture generator (GL-free): shading formulas on analytic planes,
// Horn edge replication, shadow lengths of a vertical step, relative-height shading, regions,
// threads, holes, and agreement with `gdaldem hillshade` when gdal-bin is installed.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/topographic_texture.hpp"

namespace tr = terralod::render;
namespace tp = terralod::pm;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Plane z = z0 + a*x + b*y sampled on a w x h grid with transform t.
tp::Heightfield plane(int w, int h, const tp::GridTransform& t, double a, double b, double z0 = 500.0) {
  tp::Heightfield hf(w, h);
  hf.transform = t;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const auto [x, y] = t.to_world(c, r);
      hf.at(c, r) = z0 + a * x + b * y;
    }
  return hf;
}

// The header's formulas evaluated from the analytic gradient (gx, gy) = (a, b).
double expected(const tr::ShadingOptions& o, double gx, double gy) {
  const double len = std::sqrt(1 + gx * gx + gy * gy);
  const tr::Vec3d n{-gx / len, -gy / len, 1 / len};
  auto dot = [&](const tr::Vec3d& l) { return n.x * l.x + n.y * l.y + n.z * l.z; };
  if (o.method == tr::ShadingMethod::Multidirectional) {
    double sw = 0, sd = 0;
    for (double az : o.multidirectional_azimuths) {
      const double gd = gx * std::sin(az * kDeg) + gy * std::cos(az * kDeg);
      const double g2 = gx * gx + gy * gy;
      const double w = g2 > 0 ? gd * gd / g2 : 1.0;
      sw += w, sd += w * std::max(0.0, dot(tr::light_direction(az, o.altitude_deg)));
    }
    return o.ambient + (1 - o.ambient) * sd / sw;
  }
  const tr::Vec3d l = tr::light_direction(o.azimuth_deg, o.altitude_deg);
  const double nl = dot(l);
  if (o.method == tr::ShadingMethod::Lambert) return o.ambient + (1 - o.ambient) * std::max(0.0, nl);
  const double rv = 2 * nl * n.z - l.z;
  const double s = (nl > 0 && rv > 0) ? std::pow(rv, o.phong_shininess) : 0.0;
  return std::min(1.0, o.phong_ka + o.phong_kd * std::max(0.0, nl) + o.phong_ks * s);
}

}  // namespace

TEST(TopographicTexture, LightDirectionFollowsTheConvention) {
  // Azimuth clockwise from north: 0 = north (+y), 90 = east (+x); altitude 90 = zenith.
  const tr::Vec3d n = tr::light_direction(0, 45), e = tr::light_direction(90, 30),
                  z = tr::light_direction(123, 90);
  EXPECT_NEAR(n.x, 0, 1e-15);
  EXPECT_NEAR(n.y, std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(n.z, std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(e.x, std::sqrt(3.0) / 2, 1e-15);
  EXPECT_NEAR(e.y, 0, 1e-15);
  EXPECT_NEAR(e.z, 0.5, 1e-15);
  EXPECT_NEAR(z.z, 1, 1e-15);
}

TEST(TopographicTexture, HandComputedPlaneValues) {
  // z = -x (a plane facing east at 45 degrees), 30 m grid:  n = (1, 0, 1) / sqrt(2).
  //   light from the east at 45 deg: l = (cos45, 0, sin45)  -> n.l = 1
  //   light from the north at 45 deg: l = (0, cos45, sin45) -> n.l = 1/2
  //   light from the west at 30 deg: l = (-cos30, 0, sin30) -> n.l = (0.5 - 0.866) / sqrt2 < 0 -> 0
  const tp::Heightfield hf = plane(5, 5, tp::GridTransform::north_up(0, 120, 30, 30), -1.0, 0.0);
  tr::ShadingOptions o;
  o.azimuth_deg = 90;
  EXPECT_NEAR(tr::shade_terrain(hf, o).at(2, 2), 1.0, 1e-6);
  o.azimuth_deg = 0;
  EXPECT_NEAR(tr::shade_terrain(hf, o).at(2, 2), 0.5, 1e-6);
  o.azimuth_deg = 270, o.altitude_deg = 30;
  EXPECT_EQ(tr::shade_terrain(hf, o).at(2, 2), 0.0f);
  // Horn edge replication: at column 0 the window's west column is column 0 itself, so the
  // difference spans one sample over 8 weights of two-sample spacing: half the slope.
  // gx = -0.5 -> n = (0.5, 0, 1) / sqrt(1.25); light from the east at 45 deg:
  //   n.l = (0.5 + 1) * sqrt(0.5) / sqrt(1.25) = 0.948683...
  o.azimuth_deg = 90, o.altitude_deg = 45;
  EXPECT_NEAR(tr::shade_terrain(hf, o).at(0, 2), 1.5 * std::sqrt(0.5) / std::sqrt(1.25), 1e-6);
  const tr::Vec3d n = tr::horn_normal(hf, 2, 2);
  EXPECT_NEAR(n.x, std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(n.y, 0, 1e-12);
}

TEST(TopographicTexture, PlanesMatchTheFormulaForEveryMethod) {
  // Non-square spacing and a rotated grid exercise the J^-T mapping of Horn's gradient.
  const double th = 20 * kDeg;
  const std::vector<tp::GridTransform> frames = {
      tp::GridTransform::north_up(1000, 5000, 30, 20),
      tp::GridTransform{0, 25 * std::cos(th), 25 * std::sin(th), 0, 25 * std::sin(th), -25 * std::cos(th)}};
  const std::vector<std::pair<double, double>> grads = {
      {0, 0}, {0.3, 0}, {0, -0.7}, {0.4, 0.25}, {-1.2, 0.9}};
  const std::vector<tr::ShadingMethod> methods = {tr::ShadingMethod::Lambert, tr::ShadingMethod::Phong,
                                                  tr::ShadingMethod::Multidirectional};
  for (const auto& t : frames)
    for (auto [a, b] : grads) {
      const tp::Heightfield hf = plane(9, 7, t, a, b);
      for (auto m : methods)
        for (double az : {0.0, 75.0, 200.0, 315.0})
          for (double alt : {15.0, 45.0, 80.0}) {
            tr::ShadingOptions o;
            o.method = m, o.azimuth_deg = az, o.altitude_deg = alt, o.ambient = 0.1;
            const tr::FloatRaster s = tr::shade_terrain(hf, o);
            o.shadows = true;  // a plane never shadows itself where it is lit
            const tr::FloatRaster sh = tr::shade_terrain(hf, o);
            const double want = expected(o, a, b);
            for (int r = 1; r < 6; ++r)
              for (int c = 1; c < 8; ++c) {
                ASSERT_NEAR(s.at(c, r), want, 2e-6) << tr::shading_method_name(m) << " a=" << a << " b=" << b
                                                    << " az=" << az << " alt=" << alt;
                // Lit texels are unchanged by shadows; texels facing away are dark either way.
                ASSERT_NEAR(sh.at(c, r), want, 2e-6) << "shadows on";
              }
          }
    }
}

TEST(TopographicTexture, StepCastsShadowOfLengthHOverTanH) {
  // Plateau of height H west of column 9, flat ground from column 10 (dx = 10 m), lit from
  // the west at altitude h:
  //   z:  H H ... H | 0 0 0 0 ...      col 9 = last plateau sample, col 10 = first ground
  // A ground texel at column j is shadowed iff (j - 9) * dx < H / tan h (the ray toward the
  // light passes the plateau's edge at column 9 below H). The shadow measured from the edge
  // is therefore H / tan h to within one texel.
  const double dx = 10.0;
  for (double H : {100.0, 37.0})
    for (double alt : {26.565051177, 40.0, 12.0}) {
      tp::Heightfield hf(120, 5);
      hf.transform = tp::GridTransform::north_up(0, 40, dx, dx);
      for (int r = 0; r < 5; ++r)
        for (int c = 0; c < 120; ++c) hf.at(c, r) = c <= 9 ? H : 0.0;
      tr::ShadingOptions o;
      o.azimuth_deg = 270, o.altitude_deg = alt, o.shadows = true, o.ambient = 0.25;
      const tr::FloatRaster s = tr::shade_terrain(hf, o);
      const double len = H / std::tan(alt * kDeg);
      int shadowed = 0;
      for (int c = 10; c < 120; ++c)
        if (s.at(c, 2) == 0.25f) ++shadowed;  // ambient only
      // Shadowed texels are contiguous from the edge.
      for (int c = 10; c < 10 + shadowed; ++c) EXPECT_EQ(s.at(c, 2), 0.25f) << c;
      // The shadow runs from the edge (column 9) to halfway between the last shadowed texel
      // and the first lit one: (shadowed + 0.5) * dx.
      EXPECT_LE(std::abs((shadowed + 0.5) * dx - len), dx)
          << "H=" << H << " alt=" << alt << " shadowed=" << shadowed;
      // Beyond the shadow and off the Horn window of the cliff, flat ground: sin(h).
      EXPECT_NEAR(s.at(11 + shadowed, 2), 0.25 + 0.75 * std::sin(alt * kDeg), 1e-6);
    }
  // The same step along the rows, lit from the north: the shadow falls southwards.
  tp::Heightfield hf(5, 80);
  hf.transform = tp::GridTransform::north_up(0, 800, dx, dx);
  for (int r = 0; r < 80; ++r)
    for (int c = 0; c < 5; ++c) hf.at(c, r) = r <= 9 ? 50.0 : 0.0;
  tr::ShadingOptions o;
  o.azimuth_deg = 0, o.altitude_deg = 30, o.shadows = true;
  const tr::FloatRaster s = tr::shade_terrain(hf, o);
  int shadowed = 0;
  for (int r = 10; r < 80; ++r) shadowed += s.at(2, r) == 0.0f;
  EXPECT_LE(std::abs((shadowed + 0.5) * dx - 50.0 / std::tan(30 * kDeg)), dx) << shadowed;
}

TEST(TopographicTexture, RelativeHeightOfARamp) {
  // z = 10 * col on a 9 x 3 grid. Window radius 2 (Chebyshev):
  //   col 0: window cols 0..2 -> (0 - 0) / 20 = 0      col 1: cols 0..3 -> 10 / 30 = 1/3
  //   col 4: cols 2..6 -> 20 / 40 = 1/2                col 8: cols 6..8 -> 20 / 20 = 1
  tp::Heightfield hf(9, 3);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 9; ++c) hf.at(c, r) = 10.0 * c;
  tr::ShadingOptions o;
  o.method = tr::ShadingMethod::RelativeHeight, o.relative_radius = 2;
  const tr::FloatRaster s = tr::shade_terrain(hf, o);
  EXPECT_FLOAT_EQ(s.at(0, 1), 0.0f);
  EXPECT_FLOAT_EQ(s.at(1, 1), 1.0f / 3.0f);
  EXPECT_FLOAT_EQ(s.at(4, 0), 0.5f);
  EXPECT_FLOAT_EQ(s.at(8, 2), 1.0f);
  // Global range: col / 8.
  o.relative_radius = 0;
  const tr::FloatRaster g = tr::shade_terrain(hf, o);
  for (int c = 0; c < 9; ++c) EXPECT_FLOAT_EQ(g.at(c, 1), c / 8.0f);
  // Flat ground: 0.5 everywhere.
  tp::Heightfield flat(4, 4);
  for (float v : tr::shade_terrain(flat, o).v) EXPECT_EQ(v, 0.5f);
  // A peak in the middle of a 7 x 7 grid: the local maximum is 1, ground around it 0.
  tp::Heightfield peak(7, 7);
  peak.at(3, 3) = 80.0;
  o.relative_radius = 1;
  const tr::FloatRaster p = tr::shade_terrain(peak, o);
  EXPECT_EQ(p.at(3, 3), 1.0f);
  EXPECT_EQ(p.at(2, 2), 0.0f);
  EXPECT_EQ(p.at(0, 0), 0.5f);  // window without the peak is flat
}

TEST(TopographicTexture, ParallelRowsRegionsAndHoles) {
  tp::TerrainOptions to;
  to.width = 97, to.height = 83, to.seed = 7;
  std::printf("generated terrain seed %llu\n", static_cast<unsigned long long>(to.seed));
  const tp::Heightfield hf = tp::generate_terrain(to);
  for (auto m :
       {tr::ShadingMethod::Lambert, tr::ShadingMethod::Multidirectional, tr::ShadingMethod::RelativeHeight}) {
    tr::ShadingOptions o;
    o.method = m, o.shadows = m != tr::ShadingMethod::RelativeHeight, o.altitude_deg = 20, o.threads = 1;
    const tr::FloatRaster one = tr::shade_terrain(hf, o);
    o.threads = 3;
    EXPECT_EQ(tr::shade_terrain(hf, o), one) << "threads must not change the result";
    // A sub-region with step 3 is exactly the corresponding texels of the full texture.
    const tr::TexelRegion reg{/*col0=*/5, /*row0=*/11, /*cols=*/40, /*rows=*/31, /*step=*/3};
    const tr::FloatRaster sub = tr::shade_terrain(hf, o, reg);
    ASSERT_EQ(sub.width, 14);
    ASSERT_EQ(sub.height, 11);
    for (int j = 0; j < sub.height; ++j)
      for (int i = 0; i < sub.width; ++i) ASSERT_EQ(sub.at(i, j), one.at(5 + 3 * i, 11 + 3 * j));
    if (m == tr::ShadingMethod::Lambert) {
      int dark = 0;
      for (float v : one.v) dark += v == 0.0f;
      EXPECT_GT(dark, 0) << "altitude 20 on rugged terrain casts some shadow";
    }
  }
  // Holes are NaN and transparent.
  tp::Heightfield holes = hf;
  std::vector<std::uint8_t> mask(holes.size(), 1);
  mask[10 * 97 + 10] = 0;
  holes.set_mask(mask);
  tr::ShadingOptions o;
  o.shadows = true;
  const tr::FloatRaster s = tr::shade_terrain(holes, o);
  EXPECT_TRUE(std::isnan(s.at(10, 10)));
  const tr::RgbaImage img = tr::grey_to_rgba(s);
  EXPECT_EQ(img.get(10, 10), (std::array<std::uint8_t, 4>{0, 0, 0, 0}));
  EXPECT_EQ(img.get(11, 10)[3], 255);
  EXPECT_EQ(img.get(11, 10)[0], tr::grey_level(s.at(11, 10)));
}

TEST(TopographicTexture, MisuseIsRejectedWithAMessage) {
  tp::Heightfield hf(8, 8);
  tr::ShadingOptions o;
  o.altitude_deg = 0;
  EXPECT_THROW(tr::shade_terrain(hf, o), std::invalid_argument);
  o = {};
  EXPECT_THROW(tr::shade_terrain(hf, o, {0, 0, -1, -1, 0}), std::invalid_argument);
  EXPECT_THROW(tr::shade_terrain(hf, o, {4, 4, 5, 1, 1}), std::invalid_argument);
  EXPECT_THROW(tr::shade_terrain(hf, o, {8, 0, -1, -1, 1}), std::invalid_argument);
  o.method = tr::ShadingMethod::RelativeHeight, o.shadows = true;
  try {
    tr::shade_terrain(hf, o);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("shadows"), std::string::npos) << e.what();
  }
  EXPECT_EQ(tr::parse_shading_method("multidirectional"), tr::ShadingMethod::Multidirectional);
  EXPECT_EQ(tr::parse_shading_method("relative"), tr::ShadingMethod::RelativeHeight);
  EXPECT_THROW(tr::parse_shading_method("gouraud"), std::invalid_argument);
}

// gdaldem writes 1 + 254 * shade (0 = nodata); with ambient 0 and shadows off our Lambert and
// multidirectional values must reproduce it within one grey level.
TEST(TopographicTexture, MatchesGdaldemHillshade) {
  if (std::system("command -v gdaldem > /dev/null 2>&1") != 0 ||
      std::system("gdal_translate --version > /dev/null 2>&1") != 0)
    GTEST_SKIP() << "gdaldem not installed (apt package gdal-bin)";
  tp::TerrainOptions to;
  to.width = 64, to.height = 48, to.seed = 3, to.spacing = 30, to.relief = 900;
  std::printf("generated terrain seed %llu\n", static_cast<unsigned long long>(to.seed));
  tp::Heightfield hf = tp::generate_terrain(to);
  const double cell = 30.0, xll = 500000.0, yll = 4000000.0;
  // AAIGrid corners: sample (c, r) centre = (xll + (c + 0.5) cell, yll + (H - r - 0.5) cell).
  hf.transform = tp::GridTransform::north_up(xll + 0.5 * cell, yll + (48 - 0.5) * cell, cell, cell);
  const std::filesystem::path dir = std::filesystem::path(TERRALOD_TEST_TMP) / "gdaldem_e1";
  std::filesystem::create_directories(dir);
  {
    std::ofstream f(dir / "dem.asc");
    f << "ncols 64\nnrows 48\nxllcorner " << xll << "\nyllcorner " << yll << "\ncellsize " << cell << "\n";
    char buf[64];
    for (int r = 0; r < 48; ++r) {
      for (int c = 0; c < 64; ++c) {
        std::snprintf(buf, sizeof buf, "%.9g ", hf.at(c, r));
        f << buf;
        hf.at(c, r) = std::strtod(buf, nullptr);  // shade exactly what gdal reads
      }
      f << "\n";
    }
  }
  const std::string d = dir.string();
  ASSERT_EQ(
      std::system(("gdal_translate -q -of GTiff -ot Float64 " + d + "/dem.asc " + d + "/dem.tif").c_str()),
      0);
  struct Case {
    const char* args;
    tr::ShadingMethod method;
    double az, alt;
  };
  for (const Case& k : {Case{"-az 315 -alt 45", tr::ShadingMethod::Lambert, 315, 45},
                        Case{"-az 100 -alt 25", tr::ShadingMethod::Lambert, 100, 25},
                        Case{"-multidirectional -alt 45", tr::ShadingMethod::Multidirectional, 315, 45}}) {
    const std::string out = d + "/hs.tif";
    std::filesystem::remove(out);
    ASSERT_EQ(
        std::system(("gdaldem hillshade -q " + std::string(k.args) + " " + d + "/dem.tif " + out).c_str()),
        0);
    const tr::Image g = tr::read_image(out);
    ASSERT_EQ(g.width, 64);
    ASSERT_EQ(g.height, 48);
    tr::ShadingOptions o;
    o.method = k.method, o.azimuth_deg = k.az, o.altitude_deg = k.alt;
    const tr::FloatRaster s = tr::shade_terrain(hf, o);
    double worst = 0;
    for (int r = 1; r < 47; ++r)  // gdaldem leaves the border as nodata without -compute_edges
      for (int c = 1; c < 63; ++c) {
        const double want = g.pixel(c, r)[0];
        worst = std::max(worst, std::abs(1.0 + 254.0 * s.at(c, r) - want));
      }
    EXPECT_LE(worst, 1.0) << k.args;
    std::printf("gdaldem hillshade %s: max |1 + 254 s - gdal| = %.3f grey levels\n", k.args, worst);
  }
}
