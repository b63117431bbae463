// Tests of texture trees: sub-image choice for hand-computed domains and limits, pruning at
// the finest level, gamma against hand-computed projections, selection and ancestor reuse.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "terralod/blocks/approximation_tree.hpp"
#include "terralod/render/texture_tree.hpp"

namespace {

using namespace terralod::render;
namespace pm = terralod::pm;

// The image: 1024 x 512 texels over the world rectangle [0,1024] x [0,512] (1 m texels at
// level 0), max texture size 256 -> levels 1024x512 (1 m), 512x256 (2 m), 256x128 (4 m).
const GeoRect kGeo{0, 0, 1024, 512};
std::vector<LevelSize> levels() { return pyramid_levels(1024, 512, 256); }

pm::Box box(double x0, double y0, double x1, double y1, double z0 = 0, double z1 = 0) {
  return pm::Box{{x0, y0, z0}, {x1, y1, z1}};
}

// The tree drawn (world rectangles, y up):
//   0 root [0,1024]x[0,512]
//   ├─ 1 [0,512]x[256,512]      (north-west quarter)
//   │   └─ 3 [0,256]x[384,512]
//   │       └─ 4 [0,128]x[448,512]
//   └─ 2 [512,1024]x[0,256]     (south-east quarter)
std::vector<PatchDomain> chain() {
  std::vector<PatchDomain> d(5);
  for (int i = 0; i < 5; ++i) d[i].id = i;
  d[0].parent = -1, d[0].children = {1, 2}, d[0].bbox = box(0, 0, 1024, 512);
  d[1].parent = 0, d[1].children = {3}, d[1].bbox = box(0, 256, 512, 512);
  d[2].parent = 0, d[2].bbox = box(512, 0, 1024, 256);
  d[3].parent = 1, d[3].children = {4}, d[3].bbox = box(0, 384, 256, 512);
  d[4].parent = 3, d[4].bbox = box(0, 448, 128, 512);
  return d;
}

TEST(TextureTree, SubImageIsTheFinestLevelThatFits) {
  const TextureConstraints c{256, false};
  // Root: 1024x512 and 512x256 are too wide; level 2 whole: (0,0) 256x128.
  EXPECT_EQ(choose_subimage(levels(), kGeo, {0, 0, 1024, 512}, c), (PixelRect{2, 0, 0, 256, 128}));
  // North-west quarter: level 0 is 512x256 (too wide); level 1, 2 m texels: x 0..256,
  // y from (512-512)/2 = 0 to (512-256)/2 = 128 -> (0,0) 256x128.
  EXPECT_EQ(choose_subimage(levels(), kGeo, {0, 256, 512, 512}, c), (PixelRect{1, 0, 0, 256, 128}));
  // South-east quarter at level 1: x 256..512, y 128..256.
  EXPECT_EQ(choose_subimage(levels(), kGeo, {512, 0, 1024, 256}, c), (PixelRect{1, 256, 128, 256, 128}));
  // A domain not on texel edges takes whole covering texels: x 10.5..20.2 -> texels 10..20
  // (11), y 100.25..101 -> rows 511-101 = 411 .. ceil(512-100.25 = 411.75) = 412 (1).
  EXPECT_EQ(choose_subimage(levels(), kGeo, {10.5, 100.25, 20.2, 101}, c), (PixelRect{0, 10, 411, 11, 1}));
}

TEST(TextureTree, PowerOfTwoSubImagesGrowAndStayInside) {
  const TextureConstraints c{256, true};
  // x 100..300 = 200 texels -> 256 fits, but y 0..512 -> 512 does not: level 1 (2 m):
  // x 50..150 = 100 -> 128, y 0..256 = 256 -> 256.
  EXPECT_EQ(choose_subimage(levels(), kGeo, {100, 0, 300, 512}, c), (PixelRect{1, 50, 0, 128, 256}));
  // Near the east edge: x 900..1024 = 124 -> 128, shifted left to 896 to stay in 1024;
  // y (512-64)=448..512 = 64 -> 64.
  EXPECT_EQ(choose_subimage(levels(), kGeo, {900, 0, 1024, 64}, c), (PixelRect{0, 896, 448, 128, 64}));
  // The covered world rectangle of that patch: x 896..1024, y 0..64.
  EXPECT_EQ(pixel_rect_georef(levels(), kGeo, PixelRect{0, 896, 448, 128, 64}), (GeoRect{896, 0, 1024, 64}));
  // A 1 m wide texture with 3 texels: 3 -> 4 > the image, so the patch pads beyond it.
  const std::vector<LevelSize> tiny = pyramid_levels(3, 1, 256);
  EXPECT_EQ(choose_subimage(tiny, GeoRect{0, 0, 3, 1}, GeoRect{0, 0, 3, 1}, c), (PixelRect{0, 0, 0, 4, 1}));
}

TEST(TextureTree, PatchesMirrorTheTreeAndPruneBelowTheFinestLevel) {
  const TextureTree t(chain(), levels(), kGeo, TextureConstraints{256, false});
  EXPECT_EQ(t.patch(0).rect, (PixelRect{2, 0, 0, 256, 128}));
  EXPECT_DOUBLE_EQ(t.patch(0).texel_w, 4.0);
  EXPECT_EQ(t.patch(1).rect, (PixelRect{1, 0, 0, 256, 128}));
  EXPECT_EQ(t.patch(2).rect, (PixelRect{1, 256, 128, 256, 128}));
  // Node 3 [0,256]x[384,512] fits at level 0: (0,0) 256x128; its subtree (node 4) is pruned.
  EXPECT_EQ(t.patch(3).rect, (PixelRect{0, 0, 0, 256, 128}));
  EXPECT_EQ(t.patch(3).georef, (GeoRect{0, 384, 256, 512}));
  EXPECT_FALSE(t.has_patch(4));
  EXPECT_EQ(t.owner(4), 3);
  EXPECT_EQ(t.patch_count(), 4u);
  EXPECT_EQ(t.parent_patch(4), 1);  // owner 3's parent patch
  EXPECT_EQ(t.parent_patch(3), 1);
  EXPECT_EQ(t.parent_patch(0), -1);
  EXPECT_DOUBLE_EQ(t.texel_m(0), 4.0);  // level 2
  EXPECT_DOUBLE_EQ(t.texel_m(1), 2.0);
  EXPECT_DOUBLE_EQ(t.texel_m(4), 1.0);  // pruned: its owner's level 0
  // Every patch covers its node's world domain.
  for (std::int64_t n = 0; n < 5; ++n) {
    const GeoRect g = t.patch(t.owner(n)).georef;
    const pm::Box& b = t.domain(n).bbox;
    EXPECT_TRUE(g.minx <= b.lo.x && g.miny <= b.lo.y && g.maxx >= b.hi.x && g.maxy >= b.hi.y) << "node " << n;
  }
}

TEST(TextureTree, DomainsComeStraightFromApproximationTreeNodes) {
  // A root with one child, as blocks::ApproximationTree stores them.
  std::vector<terralod::blocks::TreeNode> nodes(2);
  nodes[0].children = {1};
  nodes[0].domain = {0, 0, 64, 32};
  nodes[0].bbox = box(0, 0, 1024, 512);
  nodes[0].error = 3.5;
  nodes[1].id = 1, nodes[1].parent = 0;
  nodes[1].domain = {0, 0, 32, 32};
  nodes[1].bbox = box(0, 0, 512, 512);
  const std::vector<PatchDomain> d = patch_domains(nodes);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].children, (std::vector<std::int64_t>{1}));
  EXPECT_EQ(d[1].parent, 0);
  EXPECT_EQ(d[0].domain, nodes[0].domain);
  EXPECT_DOUBLE_EQ(d[0].error, 3.5);
  const TextureTree t(d, levels(), kGeo, TextureConstraints{256, false});
  EXPECT_EQ(t.patch(1).rect, (PixelRect{1, 0, 0, 256, 256}));  // 512 x 512 m at 2 m texels
}

TEST(TextureTree, RejectsNodeListsThatAreNotTrees) {
  std::vector<PatchDomain> d = chain();
  d[4].parent = 2;  // 3 lists 4 as a child, but 4 names 2
  EXPECT_THROW(TextureTree(d, levels(), kGeo), std::invalid_argument);
}

// Camera straight down from 100 m over (x, y), 90 degree field of view, 200 x 200 pixels:
// K = 200 / (2 tan 45) = 100 pixels per unit tangent; at depth d a horizontal length L spans
// K L / d pixels exactly (the ground is parallel to the image plane).
pm::View down(double x, double y, double z = 100) {
  pm::Camera cam;
  cam.x = x, cam.y = y, cam.z = z;
  cam.pitch_deg = -90;
  cam.fovy_deg = 90;
  cam.width_px = cam.height_px = 200;
  return pm::View(cam);
}

TEST(TextureTree, GammaIsTheProjectedTexelAreaAtTheNearestPoint) {
  // Box [-50,50]^2 x [0,10]: nearest point (0,0,10), depth 90. A 2 x 3 m texel spans
  // (100*2/90) x (100*3/90) = 60000/8100 = 7.4074 pixels^2.
  EXPECT_NEAR(visual_texture_error_px(down(0, 0), box(-50, -50, 50, 50, 0, 10), 2, 3), 60000.0 / 8100.0,
              1e-9);
  // Camera beside the box: nearest point (50, 0, 10), still depth 90 (same area, the
  // rectangle only moves off-centre in a plane parallel to the image).
  EXPECT_NEAR(visual_texture_error_px(down(80, 0), box(-50, -50, 50, 50, 0, 10), 2, 3), 60000.0 / 8100.0,
              1e-9);
  // Level camera at z = 10 looking north; box [-5,5] x [100,200] x [0,0]: nearest point
  // (0,100,0), 10 m below the eye. A 2 x 2 texel's corners at depths 99 and 101 project to
  // x = +-K/depth, y = K*10/depth below the centre: a trapezoid with parallel sides 200/101
  // and 200/99 pixels, 1000 (1/99 - 1/101) pixels apart.
  pm::Camera cam;
  cam.z = 10, cam.fovy_deg = 90, cam.width_px = cam.height_px = 200;
  const pm::View level(cam);
  const double want = (200.0 / 101 + 200.0 / 99) / 2 * 1000 * (1.0 / 99 - 1.0 / 101);
  EXPECT_NEAR(visual_texture_error_px(level, box(-5, 100, 5, 200), 2, 2), want, 1e-9);
  // Behind the eye: infinite.
  EXPECT_TRUE(std::isinf(visual_texture_error_px(level, box(-5, -200, 5, -100), 2, 2)));
}

TEST(TextureTree, SelectionAndAncestorReuse) {
  // Camera 100 m above (64, 480) looking down; every box has top z = 0 -> depth 100, and a
  // square texel of side s has gamma = (100 s / 100)^2 = s^2: root (4 m) 16, node 1 (2 m) 4,
  // nodes 3 and 4 (1 m) 1.
  const TextureTree t(chain(), levels(), kGeo, TextureConstraints{256, false});
  const pm::View v = down(64, 480);
  EXPECT_NEAR(visual_texture_error_px(v, t.domain(0).bbox, 4, 4), 16.0, 1e-9);
  PatchSelectionOptions o;
  o.gamma_px = 4;
  o.cull = false;
  // Root gamma 16 > 4: descend; node 1 gamma 4 <= 4: selected; node 2 (level 1, 2 m texel,
  // nearest point (512, 256, 0): depth 100 too) also 4: selected.
  EXPECT_EQ(select_patches(t, v, o).selected, (std::vector<std::int64_t>{1, 2}));
  o.gamma_px = 1;  // node 1 descends to 3 (gamma 1, finest level: no further descent for gamma)
  EXPECT_EQ(select_patches(t, v, o).selected, (std::vector<std::int64_t>{3, 2}));
  // Alpha: node 3 with error 1 m: vertical_error_px > 0.5 px forces node 4.
  std::vector<PatchDomain> d = chain();
  d[3].error = 1;
  const TextureTree t2(d, levels(), kGeo, TextureConstraints{256, false});
  o.alpha_px = 0.5;
  EXPECT_EQ(select_patches(t2, v, o).selected, (std::vector<std::int64_t>{4, 2}));

  // Reuse: node 4 (textured by 3 at 1 m) at threshold 4 takes node 1's patch (2 m, gamma 4),
  // the ancestor closest to the root within the threshold; at 16 the root's; at 0.5 none
  // qualifies and it keeps its finest, owner 3.
  const std::int64_t sel[] = {4, 3};
  auto g4 = choose_textures(t, v, sel, 4);
  ASSERT_EQ(g4.size(), 1u);  // both share node 1's texture
  EXPECT_EQ(g4[0].texture_node, 1);
  EXPECT_EQ(g4[0].nodes, (std::vector<std::int64_t>{4, 3}));
  EXPECT_EQ(choose_textures(t, v, sel, 16)[0].texture_node, 0);
  auto g05 = choose_textures(t, v, sel, 0.5);
  ASSERT_EQ(g05.size(), 1u);
  EXPECT_EQ(g05[0].texture_node, 3);
  // Two groups when textures differ: node 2 at threshold 4 uses its own patch (root's 16 > 4).
  const std::int64_t sel2[] = {4, 2, 3};
  auto g = choose_textures(t, v, sel2, 4);
  ASSERT_EQ(g.size(), 2u);
  EXPECT_EQ(g[0].texture_node, 1);
  EXPECT_EQ(g[0].nodes, (std::vector<std::int64_t>{4, 3}));
  EXPECT_EQ(g[1].texture_node, 2);
}

}  // namespace
