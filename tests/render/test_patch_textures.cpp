// Tests of per-patch textures (patch_textures.hpp): the patch each drawn node binds follows
// gamma; drawn through LayeredRenderer (headless OSMesa) the picture is exactly the chosen
// pyramid level, so every patch is placed where it belongs; the parent's patch is bound while
// a patch loads; the texture memory stays within the budget by raising gamma; the triangle
// order is a permutation grouped by texture.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include "gl_fixture.hpp"
#include "square_camera.hpp"
#include "terralod/pm/view.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/layered_renderer.hpp"
#include "terralod/render/patch_textures.hpp"

namespace {

namespace pm = terralod::pm;
using namespace terralod::render;

// A root 0 over [0,64]^2 with four children 1..4 (quadrants SW, SE, NE, NW) and a 64 x 64
// image over the same square, max texture size 32: levels 64 (1 m texels) and 32 (2 m); the
// root's patch is the whole of level 1, each child's its quadrant of level 0.
std::vector<PatchDomain> quad_domains() {
  std::vector<PatchDomain> d(5);
  d[0].id = 0;
  d[0].children = {1, 2, 3, 4};
  d[0].bbox = pm::Box{{0, 0, 0}, {64, 64, 0}};
  const double x0[4] = {0, 32, 32, 0}, y0[4] = {0, 0, 32, 32};
  for (int i = 1; i <= 4; ++i) {
    d[i].id = i;
    d[i].parent = 0;
    d[i].bbox = pm::Box{{x0[i - 1], y0[i - 1], 0}, {x0[i - 1] + 32, y0[i - 1] + 32, 0}};
  }
  return d;
}

std::shared_ptr<const TextureTree> quad_tree() {
  return std::make_shared<const TextureTree>(quad_domains(), pyramid_levels(64, 64, 32),
                                             GeoRect{0, 0, 64, 64}, TextureConstraints{32, false});
}

// The pyramid: level 0 a pattern of distinct opaque colours, level 1 its even texels.
RgbaImage level_image(int level) {
  const int n = 64 >> level, step = 1 << level;
  RgbaImage img(n, n);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      img.set(x, y,
              {std::uint8_t((x * step * 7 + y * step * 3) % 251), std::uint8_t((x * step * 5 + 11) % 253),
               std::uint8_t((y * step * 13 + 7) % 255), 255});
  return img;
}

RgbaImage crop(const RgbaImage& img, const PixelRect& r) {
  RgbaImage out(r.width, r.height);
  for (int y = 0; y < r.height; ++y)
    for (int x = 0; x < r.width; ++x) {
      const std::uint8_t* p = img.pixel(r.x0 + x, r.y0 + y);
      out.set(x, y, {p[0], p[1], p[2], p[3]});
    }
  return out;
}

// A loader of the tree's patches; loads of `gated` nodes wait until the gate opens.
struct Loader {
  std::shared_ptr<const TextureTree> tree = quad_tree();
  std::mutex m;
  std::condition_variable cv;
  bool open = true;
  std::set<std::int64_t> gated;
  std::atomic<int> loads{0};
  TextureLoader fn() {
    return [this](const TextureKey& k) {
      {
        std::unique_lock l(m);
        cv.wait(l, [&] { return open || !gated.count(k.node); });
      }
      ++loads;
      const PixelRect& r = tree->patch(k.node).rect;
      return crop(level_image(r.level), r);
    };
  }
  void release() {
    {
      std::lock_guard l(m);
      open = true;
    }
    cv.notify_all();
  }
};

// Opens the loader's gate when destroyed: declared after the PatchTextures, it runs first, so
// a failing test still lets the workers finish before they are joined.
struct OpenAtExit {
  Loader& loader;
  ~OpenAtExit() { loader.release(); }
};

// The flat square as four quadrants of two triangles each (3 x 3 vertices, 1 m = 1 unit).
DrawMesh quad_mesh(std::vector<std::int64_t>& triangle_node) {
  DrawMesh d;
  d.origin = {32.0, 32.0, 0.0};
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) d.xyz.insert(d.xyz.end(), {float(32 * i - 32), float(32 * j - 32), 0.0f});
  for (int v = 0; v < 9; ++v) d.normals.insert(d.normals.end(), {0.0f, 0.0f, 1.0f});
  const int cells[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};  // nodes 1..4
  triangle_node.clear();
  for (int q = 0; q < 4; ++q) {
    const std::uint32_t a = std::uint32_t(cells[q][1] * 3 + cells[q][0]);
    d.indices.insert(d.indices.end(), {a, a + 1, a + 4, a, a + 4, a + 3});
    triangle_node.insert(triangle_node.end(), 2, q + 1);
  }
  return d;
}

// The tests below look at the square straight down (square_camera.hpp), one pixel per metre, so a
// level-0 texel covers 1 pixel^2 and a level-1 texel 4 (gamma at the nearest point of a box is at
// least that).

// Every triangle exactly once, the groups' ranges tiling the order.
void expect_grouped(const PatchTextureFrame& f, std::size_t triangles) {
  std::vector<std::uint32_t> sorted = f.triangle_order;
  std::sort(sorted.begin(), sorted.end());
  ASSERT_EQ(sorted.size(), triangles);
  for (std::size_t t = 0; t < triangles; ++t) EXPECT_EQ(sorted[t], t);
  std::size_t next = 0;
  for (const PatchTextureGroup& g : f.groups) {
    EXPECT_EQ(g.first_triangle, next);
    EXPECT_GT(g.triangle_count, 0u);
    next += g.triangle_count;
  }
  EXPECT_EQ(next, triangles);
}

TEST(PatchTextures, GammaChoosesTheCoarsestPatchWhoseTexelFitsAndGroupsTheTriangles) {
  Loader loader;
  std::vector<std::int64_t> nodes;
  quad_mesh(nodes);
  const pm::View view(terralod::test::square_down_camera());
  for (const auto& [gamma, want_root] : {std::pair{100.0, true}, std::pair{1.5, false}}) {
    PatchTextures pt({loader.tree}, loader.fn(), {gamma, std::size_t(1) << 20, 1});
    pt.frame(view, nodes, {true});
    pt.cache().wait_idle(10000);
    const PatchTextureFrame& f = pt.frame(view, nodes, {true});
    expect_grouped(f, nodes.size());
    EXPECT_EQ(f.stats.nodes, 4u);
    EXPECT_EQ(f.stats.from_parent, 0u);
    EXPECT_EQ(f.stats.gamma_px, gamma);
    if (want_root) {
      ASSERT_EQ(f.groups.size(), 1u);
      EXPECT_EQ(f.groups[0].used[0].node, 0);
      EXPECT_EQ(f.stats.wanted, 1u);
    } else {
      ASSERT_EQ(f.groups.size(), 4u);
      for (const PatchTextureGroup& g : f.groups) {
        ASSERT_EQ(g.triangle_count, 2u);
        for (std::size_t k = 0; k < 2; ++k)
          EXPECT_EQ(nodes[f.triangle_order[g.first_triangle + k]], g.used[0].node);
        ASSERT_TRUE(g.pixels[0]);
        EXPECT_EQ(g.pixels[0]->width, 32);
      }
      EXPECT_EQ(f.stats.wanted, 4u);
    }
  }
}

TEST(PatchTextures, TheParentIsBoundWhileAPatchLoads) {
  Loader loader;
  std::vector<std::int64_t> nodes;
  quad_mesh(nodes);
  const pm::View view(terralod::test::square_down_camera());
  PatchTextures pt({loader.tree}, loader.fn(), {1.5, std::size_t(1) << 20, 1});
  const OpenAtExit open_at_exit{loader};
  // Nothing resident yet: the wanted patches and their ancestors are requested, nothing bound.
  loader.open = false;
  loader.gated = {1, 2, 3, 4};
  pt.set_gamma(100.0);  // wants the root only
  const PatchTextureFrame& f0 = pt.frame(view, nodes, {true});
  EXPECT_EQ(f0.stats.from_parent, 1u);
  ASSERT_EQ(f0.groups.size(), 1u);
  EXPECT_EQ(f0.groups[0].used[0].node, -1);
  pt.cache().wait_idle(10000);
  // The children's loads wait at the gate: every node binds the root meanwhile.
  pt.set_gamma(1.5);
  const PatchTextureFrame& f1 = pt.frame(view, nodes, {true});
  ASSERT_EQ(f1.groups.size(), 1u);
  EXPECT_EQ(f1.groups[0].used[0].node, 0);
  EXPECT_EQ(f1.stats.wanted, 4u);
  EXPECT_EQ(f1.stats.from_parent, 4u);
  expect_grouped(f1, nodes.size());
  loader.release();
  pt.cache().wait_idle(10000);
  const PatchTextureFrame& f2 = pt.frame(view, nodes, {true});
  EXPECT_EQ(f2.stats.from_parent, 0u);
  EXPECT_EQ(f2.groups.size(), 4u);
}

TEST(PatchTextures, TheBudgetRaisesGammaAndHoldsTheResidentBytes) {
  Loader loader;
  std::vector<std::int64_t> nodes;
  quad_mesh(nodes);
  const pm::View view(terralod::test::square_down_camera());
  const std::size_t patch = 32 * 32 * 4;
  PatchTextures pt({loader.tree}, loader.fn(), {1.5, 2 * patch, 1});
  EXPECT_EQ(pt.max_patch_bytes(0), patch);
  for (int k = 0; k < 5; ++k) {
    const PatchTextureFrame& f = pt.frame(view, nodes, {true});
    EXPECT_EQ(f.stats.wanted, 1u) << "four children do not fit two patches: the root does";
    EXPECT_GE(f.stats.gamma_px, 4.0);
    pt.cache().wait_idle(10000);
    EXPECT_LE(pt.cache().stats().resident_bytes, 2 * patch);
  }
  // The eye inside the boxes (on the ground, looking along it): every texel's gamma is
  // unbounded, so doubling gamma cannot help; the children give way to the root.
  pm::Camera low = terralod::test::square_down_camera();
  low.x = 16, low.y = 16, low.z = 0, low.pitch_deg = 0;
  const PatchTextureFrame& f = pt.frame(pm::View(low), nodes, {true});
  EXPECT_EQ(f.stats.wanted, 1u);
  for (const PatchTextureGroup& g : f.groups) EXPECT_LE(g.used[0].node, 0);
  PatchTextures unbounded({loader.tree}, loader.fn(), {1.5, std::size_t(1) << 20, 1});
  EXPECT_GT(unbounded.frame(pm::View(low), nodes, {true}).stats.wanted, 2u)
      << "without budget pressure: children";
  // A budget of all five patches: gamma stays as asked.
  PatchTextures roomy({loader.tree}, loader.fn(), {1.5, 5 * patch, 1});
  EXPECT_EQ(roomy.frame(view, nodes, {true}).stats.gamma_px, 1.5);
}

TEST(PatchTextures, DisabledLayersAndForeignNodesBindNothing) {
  Loader loader;
  std::vector<std::int64_t> nodes;
  quad_mesh(nodes);
  nodes[3] = -1;
  nodes[5] = 99;  // not in the tree
  const pm::View view(terralod::test::square_down_camera());
  PatchTextures pt({loader.tree, loader.tree}, loader.fn(), {1.5, std::size_t(1) << 20, 1});
  pt.frame(view, nodes, {true, false});
  pt.cache().wait_idle(10000);
  const PatchTextureFrame& f = pt.frame(view, nodes, {true, false});
  expect_grouped(f, nodes.size());
  for (const PatchTextureGroup& g : f.groups) {
    EXPECT_EQ(g.used[1].node, -1) << "layer 1 is off";
    EXPECT_FALSE(g.pixels[1]);
  }
  for (std::size_t k = 0; k < f.triangle_order.size(); ++k) {
    const std::int64_t n = nodes[f.triangle_order[k]];
    const auto g = std::find_if(f.groups.begin(), f.groups.end(), [&](const PatchTextureGroup& g) {
      return k >= g.first_triangle && k < g.first_triangle + g.triangle_count;
    });
    ASSERT_NE(g, f.groups.end());
    if (n < 0 || n > 4)
      EXPECT_EQ(g->used[0].node, -1) << "triangle of a foreign node";
    else
      EXPECT_EQ(g->used[0].node, n);
  }
  EXPECT_THROW(pt.frame(view, nodes, {true}), std::invalid_argument);
  EXPECT_THROW(PatchTextures({}, loader.fn()), std::invalid_argument);
  EXPECT_THROW(PatchTextures({loader.tree}, loader.fn(), {0.0, 1, 1}), std::invalid_argument);
}

struct Gl : terralod::test::OffscreenGl<64, 64> {};

// Drawn through the layered renderer (nearest texels, no lighting), the picture is exactly the
// chosen level: each child's patch at its quadrant (gamma 1.5), or the root's (gamma 100).
TEST_F(Gl, EveryPatchIsDrawnWhereItBelongs) {
  Loader loader;
  std::vector<std::int64_t> nodes;
  const DrawMesh mesh = quad_mesh(nodes);
  const pm::Camera cam = terralod::test::square_down_camera();
  const pm::View view(cam);
  for (const auto& [gamma, level] : {std::pair{1.5, 0}, std::pair{100.0, 1}}) {
    PatchTextures pt({loader.tree}, loader.fn(), {gamma, std::size_t(1) << 20, 1});
    pt.frame(view, nodes, {true});
    pt.cache().wait_idle(10000);
    const PatchTextureFrame& f = pt.frame(view, nodes, {true});
    DrawMesh sorted;
    order_triangles(mesh, f.triangle_order, sorted);
    LayeredRendererOptions o;
    o.linear_filter = false;
    o.stack.lighting = false;
    LayeredRenderer r(*ctx, o);
    const MeshId id = r.upload(sorted);
    std::vector<LayeredItem> items;
    for (const PatchTextureGroup& g : f.groups)
      items.push_back(LayeredItem{
          id,
          {LayerBinding(r.texture_for(g.used[0], *g.pixels[0]), pt.tree(0).patch(g.used[0].node).georef)},
          g.first_triangle,
          g.triangle_count});
    const std::vector<LayerStyle> styles(1);
    const LayeredFrameStats s = r.draw(cam, styles, Lens{}, items);
    EXPECT_EQ(s.triangles, 8u);
    EXPECT_EQ(s.meshes, level == 0 ? 4u : 1u);
    const Image img = r.read_color();
    const RgbaImage want = level_image(level);
    int worst = 0;
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x)
        for (int c = 0; c < 3; ++c)
          worst =
              std::max(worst, std::abs(int(img.pixel(x, y)[c]) - int(want.pixel(x >> level, y >> level)[c])));
    EXPECT_LE(worst, 1) << "gamma " << gamma;
  }
}

}  // namespace
