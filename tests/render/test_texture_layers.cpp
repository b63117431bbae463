// Tests of the CPU reference of texture-layer combination: each operation on tiny images with
// answers derived by hand, masks, the lens, key-frame sequences, decal mode.
#include <gtest/gtest.h>

#include "terralod/render/texture_layers.hpp"

namespace {

using namespace terralod::render;
using Px = std::array<std::uint8_t, 4>;

// All layers are 2 x 1 images over the world rectangle [0,2] x [0,1]; the output grid is the
// same, so output pixel x samples texel x of every layer.
const GeoRect kGeo{0, 0, 2, 1};

RgbaImage two(Px a, Px b) {
  RgbaImage img(2, 1);
  img.set(0, 0, a);
  img.set(1, 0, b);
  return img;
}
LayerSource src(const RgbaImage& img) { return LayerSource{{img}, kGeo}; }
LayerStyle style(LayerOp op, float weight = 1.0f) {
  LayerStyle s;
  s.op = op;
  s.weight = weight;
  return s;
}
LayerStackOptions black() {
  LayerStackOptions o;
  o.base_color = {0, 0, 0};
  o.lighting = false;
  return o;
}
Px out(const std::vector<LayerStyle>& st, const std::vector<LayerSource>& s, int x,
       const LayerStackOptions& o = black(), const RgbaImage* lens_img = nullptr, const Lens& lens = {}) {
  return combine_layers(st, s, lens_img, lens, kGeo, 2, 1, o).get(x, 0);
}

TEST(TextureLayers, AddSubtractMultiplyWithClampingAfterEachLayer) {
  // Black base; + 100; + 100 -> 200; - 50 -> 150; * black at weight 0.5 -> 150 * 0.5 = 75.
  const RgbaImage g100 = two({100, 100, 100, 255}, {100, 100, 100, 255});
  const RgbaImage g50 = two({50, 50, 50, 255}, {50, 50, 50, 255});
  const RgbaImage g0 = two({0, 0, 0, 255}, {0, 0, 0, 255});
  std::vector<LayerStyle> st = {style(LayerOp::Add), style(LayerOp::Add), style(LayerOp::Subtract),
                                style(LayerOp::Multiply, 0.5f)};
  std::vector<LayerSource> s = {src(g100), src(g100), src(g50), src(g0)};
  EXPECT_EQ(out(st, s, 0), (Px{75, 75, 75, 255}));
  // Clamping per layer: 200 + 100 = 300 -> 255, then - 100 -> 155 (not 200).
  st = {style(LayerOp::Add), style(LayerOp::Add), style(LayerOp::Add), style(LayerOp::Subtract)};
  s = {src(g100), src(g100), src(g100), src(g100)};
  EXPECT_EQ(out(st, s, 1), (Px{155, 155, 155, 255}));
  // Subtracting below zero clamps at 0: 0 - 50 -> 0, + 100 -> 100.
  st = {style(LayerOp::Subtract), style(LayerOp::Add)};
  s = {src(g50), src(g100)};
  EXPECT_EQ(out(st, s, 0), (Px{100, 100, 100, 255}));
}

TEST(TextureLayers, BlendByWeightAndByAlpha) {
  // Base 0; layer 1 opaque white -> 255; layer 2 black at weight 0.2 -> 255 * 0.8 = 204.
  const RgbaImage white = two({255, 255, 255, 255}, {255, 255, 255, 255});
  const RgbaImage black_half = two({0, 0, 0, 255}, {0, 0, 0, 0});  // pixel 1 transparent
  std::vector<LayerStyle> st = {style(LayerOp::Blend), style(LayerOp::Blend, 0.2f)};
  std::vector<LayerSource> s = {src(white), src(black_half)};
  EXPECT_EQ(out(st, s, 0), (Px{204, 204, 204, 255}));
  EXPECT_EQ(out(st, s, 1), (Px{255, 255, 255, 255}));  // alpha 0: no effect
  // Channels separately: red over green at weight 0.6: (0.6*255, 0.4*255, 0) = (153, 102, 0).
  st = {style(LayerOp::Blend), style(LayerOp::Blend, 0.6f)};
  s = {src(two({0, 255, 0, 255}, {0, 255, 0, 255})), src(two({255, 0, 0, 255}, {255, 0, 0, 255}))};
  EXPECT_EQ(out(st, s, 0), (Px{153, 102, 0, 255}));
  // A disabled layer does nothing.
  st[1].enabled = false;
  EXPECT_EQ(out(st, s, 0), (Px{0, 255, 0, 255}));
}

TEST(TextureLayers, MaskingByAnAlphaLayer) {
  // Layer 0: mask only, alpha 0 at pixel 0 and 255 at pixel 1. Layer 1: opaque white masked
  // by layer 0 -> pixel 0 stays black, pixel 1 white; inverted -> the opposite.
  const RgbaImage mask = two({9, 9, 9, 0}, {9, 9, 9, 255});
  const RgbaImage white = two({255, 255, 255, 255}, {255, 255, 255, 255});
  LayerStyle m = style(LayerOp::Blend);
  m.mask_only = true;
  LayerStyle w = style(LayerOp::Blend);
  w.mask = MaskSource::Layer;
  w.mask_layer = 0;
  std::vector<LayerStyle> st = {m, w};
  std::vector<LayerSource> s = {src(mask), src(white)};
  EXPECT_EQ(out(st, s, 0), (Px{0, 0, 0, 255}));
  EXPECT_EQ(out(st, s, 1), (Px{255, 255, 255, 255}));
  st[1].invert_mask = true;
  EXPECT_EQ(out(st, s, 0), (Px{255, 255, 255, 255}));
  EXPECT_EQ(out(st, s, 1), (Px{0, 0, 0, 255}));
  // The mask layer's colour never shows (mask_only), even disabled it still masks.
  st[0].enabled = false;
  st[1].invert_mask = false;
  EXPECT_EQ(out(st, s, 0), (Px{0, 0, 0, 255}));
  EXPECT_EQ(out(st, s, 1), (Px{255, 255, 255, 255}));
}

TEST(TextureLayers, TheLensMasksWhereItIsAndMovesWithItsRectangle) {
  // Lens: a 2 x 2 opaque texture over [1,2] x [0,1] (output pixel 1 only), then moved to
  // [0,1] x [0,1]. Layer: opaque red through the lens, over grey base 0.5 (128).
  const RgbaImage lens_img = two({255, 255, 255, 255}, {255, 255, 255, 255});
  LayerStyle r = style(LayerOp::Blend);
  r.mask = MaskSource::Lens;
  std::vector<LayerStyle> st = {r};
  std::vector<LayerSource> s = {src(two({255, 0, 0, 255}, {255, 0, 0, 255}))};
  LayerStackOptions o = black();
  o.base_color = {0.5f, 0.5f, 0.5f};
  Lens lens{true, GeoRect{1, 0, 2, 1}};
  EXPECT_EQ(out(st, s, 0, o, &lens_img, lens), (Px{128, 128, 128, 255}));
  EXPECT_EQ(out(st, s, 1, o, &lens_img, lens), (Px{255, 0, 0, 255}));
  lens.rect = GeoRect{0, 0, 1, 1};
  EXPECT_EQ(out(st, s, 0, o, &lens_img, lens), (Px{255, 0, 0, 255}));
  EXPECT_EQ(out(st, s, 1, o, &lens_img, lens), (Px{128, 128, 128, 255}));
  lens.enabled = false;  // off: the lens mask is 0 everywhere
  EXPECT_EQ(out(st, s, 0, o, &lens_img, lens), (Px{128, 128, 128, 255}));
  // The lens texture: opaque centre, transparent corners.
  const RgbaImage l = make_lens_texture(32);
  EXPECT_EQ(l.get(16, 16)[3], 255);
  EXPECT_EQ(l.get(0, 0)[3], 0);
}

TEST(TextureLayers, SequencesInterpolateConsecutiveKeyFrames) {
  // Key frames grey 0, 100, 200 (opaque), blended over black at weight 1.
  auto grey = [](std::uint8_t g) { return two({g, g, g, 255}, {g, g, g, 255}); };
  LayerSource seq{{grey(0), grey(100), grey(200)}, kGeo};
  LayerStyle st = style(LayerOp::Blend);
  const std::vector<LayerSource> s = {seq};
  auto at = [&](float t) {
    st.time = t;
    return out({st}, s, 0)[0];
  };
  EXPECT_EQ(at(0.0f), 0);
  EXPECT_EQ(at(0.25f), 25);  // 0.75 * 0 + 0.25 * 100
  EXPECT_EQ(at(1.0f), 100);
  EXPECT_EQ(at(1.5f), 150);  // halfway between 100 and 200
  EXPECT_EQ(at(2.0f), 200);  // the last key frame
  const SequencePosition p = sequence_position(3, 1.5f);
  EXPECT_EQ(p.i, 1);
  EXPECT_EQ(p.j, 2);
  EXPECT_FLOAT_EQ(p.f, 0.5f);
}

TEST(TextureLayers, TopographicLayerMeansDecalMode) {
  // Lighting factor 0.5: applied without a topographic layer, not with one.
  std::vector<LayerStyle> st = {style(LayerOp::Blend)};
  const std::array<float, 4> texel{0.8f, 0.8f, 0.8f, 1.0f};
  LayerStackOptions o;
  EXPECT_FLOAT_EQ(combine_texels(st, std::span(&texel, 1), 0.0f, 0.5f, o)[0], 0.4f);
  st[0].topographic = true;
  EXPECT_TRUE(decal_mode(st));
  EXPECT_FLOAT_EQ(combine_texels(st, std::span(&texel, 1), 0.0f, 0.5f, o)[0], 0.8f);
  st[0].enabled = false;  // switched off: lighting again, on the base colour 0.5
  EXPECT_FALSE(decal_mode(st));
  EXPECT_FLOAT_EQ(combine_texels(st, std::span(&texel, 1), 0.0f, 0.5f, o)[0], 0.25f);
}

}  // namespace
