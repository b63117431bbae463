// Symbol textures (render/symbol_texture.hpp): the level view distance, the anti-aliased disc with
// its outline drawn at a texel position, "over" stacking, clipping, and which objects a level
// draws by distance and by screen-size rules; answers computed by hand in the comments.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "terralod/render/symbol_texture.hpp"

namespace {

namespace tb = terralod::blocks;
using namespace terralod::render;
using Rgba = std::array<std::uint8_t, 4>;  // RgbaImage::get

TEST(SymbolTexture, LevelDistanceIsTheTexelSeenAsGammaPixels) {
  // 30 m texels at focal 623.5 px project to 1 px (gamma 1) at 30 x 623.5 = 18705 m.
  EXPECT_DOUBLE_EQ(symbol_level_distance_m(30.0), 18705.0);
  EXPECT_DOUBLE_EQ(symbol_level_distance_m(60.0), 2 * 18705.0);
}

TEST(SymbolTexture, DiscWithOutlineAtTheTexelPosition) {
  // Diameter 7 centred on texel (10, 10)'s centre: radius 3.5, coverage clamp(4 - r, 0, 1);
  // along row 10 texels at offsets 0..3 are wholly covered, offset 4 not at all. The fill
  // (radius 2.5, coverage clamp(3 - r)) covers offsets 0..2; offset 3 is pure outline (x 0.25).
  RgbaImage img(21, 21);
  draw_symbol(img, 10.5, 10.5, SymbolStyle{{200, 40, 0, 255}, 7});
  for (int x = 0; x < 21; ++x) EXPECT_EQ(img.get(x, 10)[3], std::abs(x - 10) <= 3 ? 255 : 0) << x;
  for (int y = 0; y < 21; ++y) EXPECT_EQ(img.get(10, y)[3], std::abs(y - 10) <= 3 ? 255 : 0) << y;
  EXPECT_EQ(img.get(10, 10), (Rgba{200, 40, 0, 255}));
  EXPECT_EQ(img.get(8, 10), (Rgba{200, 40, 0, 255}));
  EXPECT_EQ(img.get(7, 10), (Rgba{50, 10, 0, 255}));
  EXPECT_EQ(img.get(13, 10), (Rgba{50, 10, 0, 255}));
  // Total coverage ~ the disc's area, pi 3.5^2 = 38.48 texels; nothing beyond radius + 1.
  double sum = 0;
  for (int y = 0; y < 21; ++y)
    for (int x = 0; x < 21; ++x) {
      sum += img.get(x, y)[3] / 255.0;
      if (std::hypot(x - 10, y - 10) > 4.5) {
        EXPECT_EQ(img.get(x, y)[3], 0) << x << "," << y;
      }
    }
  EXPECT_NEAR(sum, M_PI * 3.5 * 3.5, 0.02 * M_PI * 3.5 * 3.5);
}

TEST(SymbolTexture, BandsOfRowsAreTheLevelsRowsTexelForTexel) {
  // 300 overlapping half-transparent symbols (stacking order matters), some past the edges: any
  // band of rows drawn alone equals those rows of the whole level.
  std::vector<SymbolPosition> at;
  std::uint64_t h = 12345;
  const auto next = [&h] {  // a small LCG: positions with fractions
    h = h * 6364136223846793005ull + 1442695040888963407ull;
    return double(h >> 11) / double(1ull << 53);
  };
  for (int i = 0; i < 300; ++i) at.push_back({next() * 160 - 5, next() * 107 - 5});
  for (const SymbolStyle& style : {SymbolStyle{{0, 120, 255, 140}, 7}, SymbolStyle{{200, 40, 0, 90}, 2}}) {
    const RgbaImage whole = render_symbol_rows(at, 150, 0, 97, style);
    for (int rows : {1, 13, 16, 64})
      for (int row0 = 0; row0 < 97; row0 += rows) {
        const int n = std::min(rows, 97 - row0);
        const RgbaImage band = render_symbol_rows(at, 150, row0, n, style);
        ASSERT_EQ(band.height, n);
        for (int y = 0; y < n; ++y)
          for (int x = 0; x < 150; ++x)
            ASSERT_EQ(band.get(x, y), whole.get(x, row0 + y)) << x << "," << row0 + y;
      }
  }
}

TEST(SymbolTexture, SmallSymbolsStackingAndClipping) {
  // Diameter 1: one texel, all outline (the colour x 0.25).
  RgbaImage one(11, 11);
  draw_symbol(one, 5.5, 5.5, SymbolStyle{{200, 40, 0, 255}, 1});
  for (int y = 0; y < 11; ++y)
    for (int x = 0; x < 11; ++x)
      EXPECT_EQ(one.get(x, y), x == 5 && y == 5 ? (Rgba{50, 10, 0, 255}) : (Rgba{0, 0, 0, 0}))
          << x << "," << y;
  // Half-transparent colour twice: alpha 128, then 0.502 + 0.502 (1 - 0.502) = 0.752 -> 192.
  RgbaImage two(11, 11);
  const SymbolStyle half{{0, 0, 255, 128}, 5};
  draw_symbol(two, 5.5, 5.5, half);
  EXPECT_EQ(two.get(5, 5), (Rgba{0, 0, 255, 128}));
  draw_symbol(two, 5.5, 5.5, half);
  EXPECT_EQ(two.get(5, 5), (Rgba{0, 0, 255, 192}));
  // At the corner: clipped, the corner texel covered.
  RgbaImage corner(4, 4);
  draw_symbol(corner, 0.0, 0.0, SymbolStyle{});
  EXPECT_EQ(corner.get(0, 0)[3], 255);
}

TEST(SymbolTexture, LevelsDrawTheObjectsTheirDistanceOrScreenSizeMakesSymbols) {
  // Distance rules: symbol up to 10 km. Georef 100 x 100 m, 10 x 10 texels: 10 m texels are seen
  // at 6235 m (drawn), 20 m texels at 12470 m (not).
  const tb::ObjectRules by_distance = tb::parse_object_rules(
      R"({"ranges": [{"max_distance_m": 10000, "draw": "symbol"}, {"draw": "none"}]})", "distance.json");
  // Anchor (35, 75): u = 35 / 100 x 10 = 3.5, v = (100 - 75) / 100 x 10 = 2.5: texel (3, 2).
  const std::vector<SymbolObject> objs{{{35.0, 75.0}, 20.0, &by_distance}};
  const GeoRect georef{0, 0, 100, 100};
  std::size_t drawn = 99;
  const RgbaImage near =
      render_symbol_level(objs, georef, {10, 10}, 10.0, SymbolStyle{{9, 9, 9, 255}, 3}, &drawn);
  EXPECT_EQ(drawn, 1u);
  EXPECT_EQ(near.get(3, 2), (Rgba{9, 9, 9, 255}));  // radius 1.5: the fill (0.5) covers the centre
  EXPECT_EQ(near.get(5, 2)[3], 0);
  const RgbaImage far = render_symbol_level(objs, georef, {10, 10}, 20.0, SymbolStyle{}, &drawn);
  EXPECT_EQ(drawn, 0u);
  EXPECT_EQ(far, RgbaImage(10, 10));
  // Screen-size rules: an extent of 100 m at d = t x f covers 100 x f / (t x f) = 100 / t px:
  // t = 4 -> 25 px (icon), t = 10 -> 10 px (symbol), t = 100 -> 1 px (none).
  const tb::ObjectRules by_size = tb::parse_object_rules(
      R"({"ranges": [{"min_screen_px": 20, "draw": "icon"}, {"min_screen_px": 2, "draw": "symbol"},
                     {"draw": "none"}]})",
      "size.json");
  const std::vector<SymbolObject> sized{{{50.0, 50.0}, 100.0, &by_size}};
  for (const auto& [texel_m, expected] : {std::pair{4.0, 0u}, {10.0, 1u}, {100.0, 0u}}) {
    render_symbol_level(sized, georef, {10, 10}, texel_m, SymbolStyle{}, &drawn);
    EXPECT_EQ(drawn, expected) << texel_m;
  }
}

}  // namespace
