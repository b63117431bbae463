// Tests for the per-frame selection of approximation-tree nodes (approximation_tree.hpp,
// select_nodes and paper_alpha_px): hand-computed alpha values, why alpha is not an upper
// bound, and the traversal invariants over random cameras on generated terrains.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "printed_seed.hpp"
#include "terralod/blocks/approximation_tree.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace tb = terralod::blocks;
namespace pm = terralod::pm;

// All hand-computed cases use a 1280 x 720 image with fovy = 90 degrees, so K = 720 / (2 tan 45)
// = 360 pixels per unit of tangent, and the eye at the origin.
pm::Camera camera(double yaw, double pitch) {
  pm::Camera c;
  c.x = c.y = c.z = 0.0;
  c.yaw_deg = yaw;
  c.pitch_deg = pitch;
  c.fovy_deg = 90.0;
  c.width_px = 1280;
  c.height_px = 720;
  return c;
}

// Level camera looking north (+y). Box x in [-10,10], y in [100,200], z in [-5,5], error 2 m:
//
//        z                      the nearest point is p = (0, 100, 0), depth 100; the segment
//        |   [box]              (0,100,-1)-(0,100,1) is parallel to the image plane and
//   eye -+---|-----> y          projects to 2 * 360 / 100 = 7.2 pixels.
TEST(PaperAlpha, LevelCameraStraightAhead) {
  const pm::View v(camera(0, 0));
  const pm::Box b{{-10, 100, -5}, {10, 200, 5}};
  EXPECT_NEAR(tb::paper_alpha_px(v, b, 2.0), 7.2, 1e-9);
  // Level camera: the conservative bound is the same number (vertical factor 1, depth 100).
  EXPECT_NEAR(v.vertical_error_px(b, 2.0), 7.2, 1e-9);
}

// Same camera; box x in [30,40], y in [100,200], z in [10,20], error 4 m: p = (30, 100, 10),
// depth 100, the segment (30,100,8)-(30,100,12) projects to rows 360 - 360*8/100 = 331.2 and
// 360 - 360*12/100 = 316.8: 14.4 pixels.
TEST(PaperAlpha, LevelCameraOffAxis) {
  const pm::View v(camera(0, 0));
  EXPECT_NEAR(tb::paper_alpha_px(v, pm::Box{{30, 100, 10}, {40, 200, 20}}, 4.0), 14.4, 1e-9);
}

// Looking straight down (pitch -90: forward = -z, right = +x, up = +y). Box x in [30,40],
// y in [-5,5], z in [-110,-100], error 2 m: p = (30, 0, -100); the segment ends at depths 99
// and 101, both 30 m right of the axis, so they land at columns 640 + 360*30/99 and
// 640 + 360*30/101: alpha = 10800 (1/99 - 1/101) = 21600 / 9999 = 2.16022 pixels.
TEST(PaperAlpha, LookingStraightDown) {
  const pm::View v(camera(0, -90));
  EXPECT_NEAR(tb::paper_alpha_px(v, pm::Box{{30, -5, -110}, {40, 5, -100}}, 2.0), 21600.0 / 9999.0, 1e-9);
}

TEST(PaperAlpha, EyeInsideTheBoxAndZeroError) {
  const pm::View v(camera(0, 0));
  EXPECT_TRUE(std::isinf(tb::paper_alpha_px(v, pm::Box{{-1, -1, -1}, {1, 1, 1}}, 1.0)));
  EXPECT_EQ(tb::paper_alpha_px(v, pm::Box{{-10, 100, -5}, {10, 200, 5}}, 0.0), 0.0);
}

// The paper's alpha is not an upper bound over the box: looking straight down at a box right
// below the eye, p is on the optical axis and its vertical segment projects to a point, while
// the same segment at a corner of the box projects to a streak of positive length. The
// conservative bound covers it.
TEST(PaperAlpha, AlphaIsNotAnUpperBound) {
  const pm::View v(camera(0, -90));
  const pm::Box b{{-50, -50, -110}, {50, 50, -100}};
  const double alpha = tb::paper_alpha_px(v, b, 2.0);
  EXPECT_NEAR(alpha, 0.0, 1e-9);
  double ax, ay, cx, cy;
  ASSERT_TRUE(v.project({50, 50, -101}, ax, ay));
  ASSERT_TRUE(v.project({50, 50, -99}, cx, cy));
  const double corner = std::hypot(cx - ax, cy - ay);
  EXPECT_GT(corner, 1.0);
  EXPECT_GE(v.vertical_error_px(b, 2.0), corner);
}

// ---------------------------------------------------------------------------------------------
// Traversal invariants

struct Fixture {
  pm::Heightfield hf;
  tb::ApproximationTree tree;
};

Fixture make_tree(bool pm_leaves) {
  pm::TerrainOptions o;
  o.width = o.height = 129;
  o.spacing = 30.0;
  o.seed = 9;
  Fixture f;
  f.hf = pm::generate_terrain(o);
  const tb::BlockLayout l = tb::partition(129, 129, 33);
  tb::TreeBuildOptions opt;
  opt.pm_leaves = pm_leaves;
  std::vector<double> errors(l.count(), 25.0);
  f.tree = tb::build_tree(f.hf, l, opt, errors);
  return f;
}

void check_selection(const tb::ApproximationTree& tree, const pm::View& view,
                     const tb::SelectionOptions& opt) {
  const tb::SelectionResult r = tb::select_nodes(tree, view, opt);
  ASSERT_EQ(r.selected.size(), r.visual.size());
  // descend(n): n is visited, inside the frustum, not a leaf, and its bound exceeds the threshold.
  std::vector<char> descends(tree.size(), 0), reached(tree.size(), 0);
  std::size_t visited = 0, culled = 0;
  std::int64_t area = 0;
  const std::int64_t root_area =
      std::int64_t(tree.root().domain.width() - 1) * (tree.root().domain.height() - 1);
  std::vector<char> selected(tree.size(), 0);
  for (std::size_t i = 0; i < r.selected.size(); ++i) {
    ASSERT_FALSE(selected[std::size_t(r.selected[i])]) << "selected twice";
    selected[std::size_t(r.selected[i])] = 1;
  }
  for (const tb::TreeNode& n : tree.nodes()) {
    const bool reach = n.parent < 0 || descends[std::size_t(n.parent)];
    reached[std::size_t(n.id)] = reach;
    if (!reach) {
      EXPECT_FALSE(selected[std::size_t(n.id)]) << "node " << n.id << " selected below a stopping node";
      continue;
    }
    ++visited;
    const bool out = view.outside(n.bbox);
    const double bound = view.vertical_error_px(n.bbox, n.error);
    if (out) {
      ++culled;
      area += std::int64_t(n.domain.width() - 1) * (n.domain.height() - 1);
      EXPECT_FALSE(selected[std::size_t(n.id)]) << "culled node " << n.id << " selected";
      continue;
    }
    const bool stop = n.leaf() || bound <= opt.alpha_px;
    EXPECT_EQ(bool(selected[std::size_t(n.id)]), stop) << "node " << n.id;
    if (stop) area += std::int64_t(n.domain.width() - 1) * (n.domain.height() - 1);
    descends[std::size_t(n.id)] = !stop;
  }
  EXPECT_EQ(r.visited, visited);
  EXPECT_EQ(r.culled, culled);
  EXPECT_EQ(area, root_area) << "selected + culled nodes do not cover the terrain once";
  double bound = 0.0;
  for (std::size_t i = 0; i < r.selected.size(); ++i) {
    const tb::TreeNode& n = tree.node(r.selected[i]);
    const tb::NodeVisual& v = r.visual[i];
    EXPECT_EQ(v.bound_px, view.vertical_error_px(n.bbox, n.error));
    EXPECT_EQ(v.alpha_px, tb::paper_alpha_px(view, n.bbox, n.error));
    if (n.strategy == tb::Strategy::PmBlock) {
      EXPECT_EQ(v.tolerance_px, opt.alpha_px);
      bound = std::max(bound, std::min(v.bound_px, v.tolerance_px));
    } else {
      bound = std::max(bound, v.bound_px);
      if (!n.leaf()) {
        EXPECT_LE(v.bound_px, opt.alpha_px);
      }
    }
  }
  EXPECT_EQ(r.bound_px, bound);
}

class Selection : public ::testing::TestWithParam<bool> {};

TEST_P(Selection, InvariantsOverRandomCameras) {
  const Fixture f = make_tree(GetParam());
  std::mt19937 rng = terralod::test::printed_seed_rng(2024);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double extent = 128 * 30.0;
  std::size_t total_culled = 0, total_selected = 0;
  for (int trial = 0; trial < 60; ++trial) {
    pm::Camera c;
    c.x = -0.3 * extent + 1.6 * extent * u01(rng);
    c.y = -0.3 * extent + 1.6 * extent * u01(rng);
    c.z = 200.0 + 3000.0 * u01(rng);
    c.yaw_deg = 360.0 * u01(rng);
    c.pitch_deg = -80.0 + 75.0 * u01(rng);
    c.far_m = 2000.0 + 20000.0 * u01(rng);
    const pm::View view(c);
    for (double alpha : {1.0, 2.0, 4.0, 16.0}) {
      tb::SelectionOptions opt;
      opt.alpha_px = alpha;
      SCOPED_TRACE("trial " + std::to_string(trial) + " alpha " + std::to_string(alpha));
      check_selection(f.tree, view, opt);
      const tb::SelectionResult r = tb::select_nodes(f.tree, view, opt);
      total_culled += r.culled;
      total_selected += r.selected.size();
    }
  }
  EXPECT_GT(total_culled, 0u);  // the cameras do exercise culling
  EXPECT_GT(total_selected, 0u);
}

INSTANTIATE_TEST_SUITE_P(Trees, Selection, ::testing::Values(false, true), [](const auto& info) {
  return info.param ? std::string("PmLeaves") : std::string("GridOnly");
});

TEST(Selection, NoCullingSelectsACoverOfTheWholeTerrain) {
  const Fixture f = make_tree(false);
  pm::Camera c;
  c.x = -5000;
  c.y = -5000;
  c.z = 100;
  c.yaw_deg = 225;  // looking away from the terrain
  const pm::View view(c);
  tb::SelectionOptions opt;
  opt.cull = false;
  const tb::SelectionResult r = tb::select_nodes(f.tree, view, opt);
  EXPECT_EQ(r.culled, 0u);
  std::int64_t area = 0;
  for (std::int64_t id : r.selected)
    area += std::int64_t(f.tree.node(id).domain.width() - 1) * (f.tree.node(id).domain.height() - 1);
  EXPECT_EQ(area, 128 * 128);
  opt.cull = true;
  const tb::SelectionResult culled = tb::select_nodes(f.tree, view, opt);
  EXPECT_EQ(culled.visited, 1u);  // the root is outside: nothing below it is visited
  EXPECT_EQ(culled.culled, 1u);
  EXPECT_TRUE(culled.selected.empty());
}

// The texture hook: a node whose texel is magnified beyond gamma is refined even when its
// geometric error is small enough.
TEST(Selection, GammaHookRefinesTexturedNodes) {
  Fixture f = make_tree(false);
  std::vector<tb::TreeNode> nodes = f.tree.nodes();
  for (tb::TreeNode& n : nodes) n.texel_m = 1000.0;  // huge texels
  const tb::ApproximationTree textured(f.tree.parameters(), nodes);
  pm::Camera c;
  c.x = 64 * 30.0;
  c.y = -3000;
  c.z = 5000;
  c.pitch_deg = -45;
  const pm::View view(c);
  tb::SelectionOptions opt;
  opt.alpha_px = 1e9;  // geometry alone would select the root
  EXPECT_EQ(tb::select_nodes(textured, view, opt).selected, std::vector<std::int64_t>{0});
  opt.gamma_px = 4.0;
  const tb::SelectionResult r = tb::select_nodes(textured, view, opt);
  EXPECT_GT(r.selected.size(), 1u);
  for (std::size_t i = 0; i < r.selected.size(); ++i)
    if (!textured.node(r.selected[i]).leaf()) {
      EXPECT_LE(r.visual[i].gamma_px, 4.0);
    }
}

}  // namespace
