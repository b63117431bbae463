// Tests for the approximation tree A(s,d) (blocks/approximation_tree.hpp, tree_builder.hpp):
// exact node errors against a brute-force recomputation, children partitioning the parent's
// domain, the s and d limits, bounding boxes, strategy choice, and the "tree" blob format.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <set>
#include <utility>

#include "mesh_checker.hpp"
#include "printed_seed.hpp"
#include "terralod/blocks/approximation_tree.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace tb = terralod::blocks;
namespace pm = terralod::pm;

pm::Heightfield terrain(int w, int h, std::uint64_t seed = 3) {
  pm::TerrainOptions o;
  o.width = w;
  o.height = h;
  o.seed = seed;
  o.quantize_to_metres = true;
  return pm::generate_terrain(o);
}

/// Brute-force epsilon(N): the independent checker's error of every surface triangle.
double brute_error(const pm::Heightfield& hf, const tb::NodeSurface& s) {
  double worst = 0.0;
  auto idx = [&](std::uint32_t v) {
    return std::uint32_t(s.points[v][1]) * std::uint32_t(hf.width()) + std::uint32_t(s.points[v][0]);
  };
  for (const auto& t : s.triangles)
    worst = std::max(worst, terralod::test::triangle_error(hf, idx(t[0]), idx(t[1]), idx(t[2])).max());
  return worst;
}

/// Every invariant of the tree contract, for every node.
void check_tree(const pm::Heightfield& hf, const tb::ApproximationTree& tree, const tb::TreeBuildOptions& opt,
                bool pm_leaves) {
  ASSERT_GT(tree.size(), 0u);
  EXPECT_EQ(tree.root().domain, (tb::SampleRect{0, 0, hf.width() - 1, hf.height() - 1}));
  EXPECT_EQ(tree.root().parent, -1);
  for (const tb::TreeNode& n : tree.nodes()) {
    SCOPED_TRACE("node " + std::to_string(n.id) + " " + tb::strategy_name(n.strategy));
    // s and d.
    const std::size_t s = n.strategy == tb::Strategy::Grid ? std::size_t(opt.patch + 1) * (opt.patch + 1)
                          : n.strategy == tb::Strategy::Hybrid
                              ? tb::make_hybrid_strategy(opt.patch, opt.max_points, opt.metric)->max_points()
                              : opt.max_points;
    EXPECT_LE(n.surface.points.size(), s);
    const bool quad = n.strategy == tb::Strategy::Grid || n.strategy == tb::Strategy::Hybrid;
    EXPECT_LE(n.children.size(), quad ? 4u : 2u);
    EXPECT_LE(n.surface.points.size(), tree.parameters().max_points);
    EXPECT_LE(int(n.children.size()), tree.parameters().max_children);
    // Exact error.
    if (n.strategy == tb::Strategy::PmBlock) {
      EXPECT_TRUE(pm_leaves);
      EXPECT_TRUE(n.leaf());
      EXPECT_TRUE(n.block.has_value());
      EXPECT_TRUE(n.surface.points.empty());
    } else {
      const double brute = brute_error(hf, n.surface);
      EXPECT_NEAR(n.error, brute, 1e-9 * (1.0 + brute));
      // The surface covers the domain exactly once: its triangle areas sum to the domain's.
      std::int64_t area2 = 0;
      for (const auto& t : n.surface.triangles) {
        const auto g = [&](std::uint32_t v) {
          return pm::GridPoint{int(n.surface.points[v][0]), int(n.surface.points[v][1])};
        };
        const std::int64_t o = pm::orient2d(g(t[0]), g(t[1]), g(t[2]));
        EXPECT_GT(o, 0);
        area2 += o;
      }
      EXPECT_EQ(area2, 2 * std::int64_t(n.domain.width() - 1) * (n.domain.height() - 1));
      // Every point is a corner of a triangle (a point under the surface would be drawn on an edge).
      std::vector<bool> used(n.surface.points.size(), false);
      for (const auto& t : n.surface.triangles)
        for (std::uint32_t v : t) used[v] = true;
      EXPECT_EQ(std::count(used.begin(), used.end(), false), 0);
      // ... and without a T-junction: every edge inside the domain has its twin.
      std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
      for (const auto& t : n.surface.triangles)
        for (int k = 0; k < 3; ++k) edges.insert({t[std::size_t(k)], t[std::size_t((k + 1) % 3)]});
      for (const auto& [a, b] : edges) {
        if (edges.count({b, a})) continue;
        const auto& p = n.surface.points[a];
        const auto& q = n.surface.points[b];
        const bool on_border = (p[0] == q[0] && (p[0] == n.domain.col0 || p[0] == n.domain.col1)) ||
                               (p[1] == q[1] && (p[1] == n.domain.row0 || p[1] == n.domain.row1));
        EXPECT_TRUE(on_border) << "edge (" << p[0] << "," << p[1] << ")-(" << q[0] << "," << q[1]
                               << ") has no twin inside the domain";
      }
      for (const auto& p : n.surface.points) {
        EXPECT_TRUE(n.domain.contains(int(p[0]), int(p[1])));
        EXPECT_EQ(p[2], hf.at(int(p[0]), int(p[1])));
      }
    }
    // The box holds every sample of the domain.
    for (int r = n.domain.row0; r <= n.domain.row1; ++r)
      for (int c = n.domain.col0; c <= n.domain.col1; ++c) {
        const auto [x, y] = hf.transform.to_world(c, r);
        const double z = hf.at(c, r);
        ASSERT_TRUE(x >= n.bbox.lo.x - 1e-9 && x <= n.bbox.hi.x + 1e-9 && y >= n.bbox.lo.y - 1e-9 &&
                    y <= n.bbox.hi.y + 1e-9 && z >= n.bbox.lo.z && z <= n.bbox.hi.z);
      }
    // Children partition the domain: inside it, cell areas sum to it, pairwise interiors disjoint.
    if (!n.leaf()) {
      std::int64_t area = 0;
      for (std::size_t i = 0; i < n.children.size(); ++i) {
        const tb::TreeNode& c = tree.node(n.children[i]);
        EXPECT_EQ(c.parent, n.id);
        EXPECT_EQ(c.level, n.level + 1);
        EXPECT_GT(c.id, n.id);
        EXPECT_TRUE(n.domain.contains(c.domain.col0, c.domain.row0) &&
                    n.domain.contains(c.domain.col1, c.domain.row1));
        EXPECT_GE(c.domain.width(), 2);
        EXPECT_GE(c.domain.height(), 2);
        area += std::int64_t(c.domain.width() - 1) * (c.domain.height() - 1);
        for (std::size_t j = 0; j < i; ++j) {
          const tb::SampleRect& a = c.domain;
          const tb::SampleRect& b = tree.node(n.children[j]).domain;
          const bool disjoint = a.col1 <= b.col0 || b.col1 <= a.col0 || a.row1 <= b.row0 || b.row1 <= a.row0;
          EXPECT_TRUE(disjoint) << "children " << c.id << " and " << n.children[j] << " overlap";
        }
      }
      EXPECT_EQ(area, std::int64_t(n.domain.width() - 1) * (n.domain.height() - 1));
    }
  }
}

// A 5 x 3 terrain drawn by hand; the grid node with P = 2 takes columns 0, 2, 4 and rows 0, 1, 2:
//
//   row 0:  0  0  8  0  0        the only sample off the coarse grid with an error is (1,1)
//   row 1:  0  4  0  0  0        ... and (3,1)? no: col 3 is not on the grid, height 0 there
//   row 2:  0  0  0  0  0        and the coarse surface is 0 except the peak (2,0) = 8.
//
// Coarse grid points: (0,0)=0 (2,0)=8 (4,0)=0 / (0,1)=0 (2,1)=0 (4,1)=0 / rows 2 all 0.
// The coarse cell (0,0)-(2,1) is split along (0,0)-(2,1); at sample (1,0) the coarse surface is
// 4 (midpoint of 0 and 8 on the top edge), the terrain 0: error 4; at (1,1) the coarse surface
// is 0 ((0,1)-(2,1) bottom edge), the terrain 4: error 4; (3,0) likewise 4. So epsilon = 4.
TEST(ApproximationTree, HandDrawnGridNodeError) {
  pm::Heightfield hf(5, 3);
  hf.at(2, 0) = 8;
  hf.at(1, 1) = 4;
  const auto grid = tb::make_grid_strategy(2);
  const tb::NodeSurface s = grid->approximate(hf, {0, 0, 4, 2});
  EXPECT_EQ(s.cols, (std::vector<int>{0, 2, 4}));
  EXPECT_EQ(s.rows, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(s.points.size(), 9u);
  EXPECT_EQ(s.triangles.size(), 8u);
  EXPECT_DOUBLE_EQ(tb::surface_error(hf, s, pm::ErrorMetric::Samples), 4.0);
  EXPECT_DOUBLE_EQ(tb::surface_error(hf, s, pm::ErrorMetric::Continuous), 4.0);
  EXPECT_DOUBLE_EQ(brute_error(hf, s), 4.0);
}

TEST(ApproximationTree, GridAbovePmBlocks) {
  const pm::Heightfield hf = terrain(81, 57);
  const tb::BlockLayout l = tb::partition(81, 57, 17);  // 5 x 4 blocks, partial last row
  std::vector<double> errors(l.count());
  for (std::size_t i = 0; i < errors.size(); ++i) errors[i] = double(i);  // any values: they are stored
  tb::TreeBuildOptions opt;
  const tb::ApproximationTree tree = tb::build_tree(hf, l, opt, errors);
  check_tree(hf, tree, opt, /*pm_leaves=*/true);
  const auto counts = tree.count_by_strategy();
  EXPECT_EQ(counts[std::size_t(tb::Strategy::PmBlock)], l.count());  // one leaf per block
  for (const tb::TreeNode& n : tree.nodes())
    if (n.strategy == tb::Strategy::PmBlock) {
      EXPECT_EQ(n.domain, l.rect(*n.block));
      EXPECT_EQ(n.error, errors[std::size_t(n.block->col) * l.blocks_y + n.block->row]);
    } else {
      EXPECT_EQ(n.strategy, tb::Strategy::Grid);
      EXPECT_FALSE(n.leaf());
    }
}

struct Case {
  const char* name;
  std::vector<tb::StrategyChoice> levels;
  double leaf_error;
};

class PureTrees : public ::testing::TestWithParam<Case> {};

TEST_P(PureTrees, InvariantsHold) {
  const Case& c = GetParam();
  const pm::Heightfield hf = terrain(49, 41, 11);
  tb::TreeBuildOptions opt;
  opt.levels = c.levels;
  opt.pm_leaves = false;
  opt.leaf_error = c.leaf_error;
  opt.max_points = 16;
  opt.patch = 3;
  opt.threads = 2;
  const tb::ApproximationTree tree = tb::build_tree(hf, tb::partition(49, 41, 17), opt);
  check_tree(hf, tree, opt, /*pm_leaves=*/false);
  // Leaves meet leaf_error unless they are single cells (which are exact: error 0).
  for (const tb::TreeNode& n : tree.nodes())
    if (n.leaf()) {
      EXPECT_LE(n.error, c.leaf_error);
    }
  // Round trip of the blob, bit for bit.
  const std::vector<std::uint8_t> bytes = tb::encode_tree(tree);
  const tb::ApproximationTree back = tb::decode_tree(bytes, "mem");
  ASSERT_EQ(back.size(), tree.size());
  EXPECT_EQ(back.parameters(), tree.parameters());
  std::size_t sum = 0;
  for (std::size_t i = 0; i < tree.size(); ++i) {
    const tb::TreeNode &a = tree.nodes()[i], &b = back.nodes()[i];
    EXPECT_EQ(a.parent, b.parent);
    EXPECT_EQ(a.children, b.children);
    EXPECT_EQ(a.domain, b.domain);
    EXPECT_EQ(a.strategy, b.strategy);
    EXPECT_EQ(a.error, b.error);
    EXPECT_EQ(a.surface.points, b.surface.points);
    EXPECT_EQ(a.surface.triangles, b.surface.triangles);
    EXPECT_EQ(a.bbox.lo.z, b.bbox.lo.z);
    EXPECT_EQ(a.bbox.hi.x, b.bbox.hi.x);
    sum += tb::encoded_node_bytes(a);
  }
  EXPECT_EQ(tb::encode_tree(back), bytes);
  EXPECT_LT(sum, bytes.size());
}

INSTANTIATE_TEST_SUITE_P(Strategies, PureTrees,
                         ::testing::Values(Case{"grid", {tb::StrategyChoice::Grid}, 0.0},
                                           Case{"tin", {tb::StrategyChoice::Tin}, 2.0},
                                           Case{"nonregular", {tb::StrategyChoice::NonRegularGrid}, 2.0},
                                           Case{"hybrid", {tb::StrategyChoice::Hybrid}, 3.0},
                                           Case{"auto", {tb::StrategyChoice::Auto}, 5.0},
                                           Case{"mixed",
                                                {tb::StrategyChoice::Grid, tb::StrategyChoice::Tin,
                                                 tb::StrategyChoice::NonRegularGrid},
                                                3.0}),
                         [](const auto& info) { return std::string(info.param.name); });

// Auto keeps, per node, the candidate with the smallest error x bytes.
TEST(ApproximationTree, AutoPicksSmallestErrorTimesBytes) {
  const pm::Heightfield hf = terrain(33, 33, 5);
  tb::TreeBuildOptions opt;
  opt.levels = {tb::StrategyChoice::Auto};
  opt.pm_leaves = false;
  opt.leaf_error = 1e9;  // the root only
  const tb::ApproximationTree tree = tb::build_tree(hf, tb::partition(33, 33, 33), opt);
  ASSERT_EQ(tree.size(), 1u);
  double best = 1e300;
  for (const auto& s : {tb::make_grid_strategy(opt.patch), tb::make_tin_strategy(opt.max_points, opt.metric),
                        tb::make_nonregular_strategy(opt.max_points, opt.metric),
                        tb::make_hybrid_strategy(opt.patch, opt.max_points, opt.metric)}) {
    tb::TreeNode n = tree.root();
    n.strategy = s->kind();
    n.surface = s->approximate(hf, n.domain);
    n.error = tb::surface_error(hf, n.surface, opt.metric);
    best = std::min(best, n.error * double(tb::encoded_node_bytes(n)));
  }
  EXPECT_EQ(tree.root().error * double(tb::encoded_node_bytes(tree.root())), best);
}

// The hybrid strategy puts its TIN microstructure in the 2 x 2 cells where the grid is worst
// (here around a narrow peak), joins it to the grid by convexification, keeps every point on a
// sample at the sample's height, and lowers the node's error below the grid's.
TEST(ApproximationTree, HybridStrategyRefinesWhereTheGridIsWorst) {
  pm::Heightfield hf(65, 65);
  for (int r = 0; r < 65; ++r)
    for (int c = 0; c < 65; ++c) {
      const double d2 = (c - 41.0) * (c - 41.0) + (r - 23.0) * (r - 23.0);
      hf.at(c, r) = std::round(0.3 * c + 0.2 * r + 400.0 * std::exp(-d2 / 40.0));
    }
  const tb::SampleRect d{0, 0, 64, 64};
  const auto grid = tb::make_grid_strategy(4);
  const auto hybrid = tb::make_hybrid_strategy(4, 25, pm::ErrorMetric::Continuous);
  const tb::NodeSurface g = grid->approximate(hf, d);
  const tb::NodeSurface h = hybrid->approximate(hf, d);
  const double eg = tb::surface_error(hf, g, pm::ErrorMetric::Continuous);
  const double eh = tb::surface_error(hf, h, pm::ErrorMetric::Continuous);
  std::printf("grid: %zu points, error %.2f m; hybrid: %zu points, %zu triangles, error %.2f m\n",
              g.points.size(), eg, h.points.size(), h.triangles.size(), eh);
  EXPECT_LT(eh, 0.5 * eg);
  EXPECT_GT(h.points.size(), g.points.size());
  EXPECT_LE(h.points.size(), hybrid->max_points());
  EXPECT_TRUE(h.cols.empty() && h.rows.empty());
  // The microstructure sits in the 2 x 2 cells around grid node (48, 16) (the worst block); the
  // grid's points come first, less the block's centre node, which the TIN covers.
  for (std::size_t v = g.points.size() - 1; v < h.points.size(); ++v) {
    EXPECT_GT(h.points[v][0], 32);
    EXPECT_LT(h.points[v][0], 64);
    EXPECT_GT(h.points[v][1], 0);
    EXPECT_LT(h.points[v][1], 32);
  }
  tb::TreeBuildOptions opt;
  opt.levels = {tb::StrategyChoice::Hybrid};
  opt.pm_leaves = false;
  opt.leaf_error = 1e9;  // the root only
  const tb::ApproximationTree tree = tb::build_tree(hf, tb::partition(65, 65, 65), opt);
  check_tree(hf, tree, opt, /*pm_leaves=*/false);
  EXPECT_EQ(tree.root().strategy, tb::Strategy::Hybrid);
  EXPECT_EQ(tree.root().surface.points, h.points);
  const tb::ApproximationTree back = tb::decode_tree(tb::encode_tree(tree), "mem");
  EXPECT_EQ(back.root().surface.points, h.points);
  EXPECT_EQ(back.root().surface.triangles, h.triangles);
  // Rectangular cells (16 x 8 samples): the block's hybrid grid has step 8, so the cells beside
  // the block take its extra border nodes into fans; check_tree finds any T-junction.
  pm::Heightfield flat(65, 33);
  for (int r = 0; r < 33; ++r)
    for (int c = 0; c < 65; ++c) flat.at(c, r) = hf.at(c, r + 7);
  const tb::ApproximationTree rect = tb::build_tree(flat, tb::partition(65, 33, 65), opt);
  check_tree(flat, rect, opt, /*pm_leaves=*/false);
  const tb::NodeSurface g2 = grid->approximate(flat, rect.root().domain);
  std::printf("65 x 33: grid error %.2f m, hybrid %.2f m with %zu points\n",
              tb::surface_error(flat, g2, pm::ErrorMetric::Continuous), rect.root().error,
              rect.root().surface.points.size());
  EXPECT_GT(rect.root().surface.points.size(),
            g2.points.size() + 5);  // the microstructure and the block's nodes
  EXPECT_LT(rect.root().error, tb::surface_error(flat, g2, pm::ErrorMetric::Continuous));
}

// Hybrid levels above PM blocks (the runtime's configuration): every hybrid node keeps the
// contract, including those whose block touches the node's border.
TEST(ApproximationTree, HybridAbovePmBlocks) {
  const pm::Heightfield hf = terrain(385, 385, /*seed=*/16);  // 30 m spacing, 1200 m relief
  const tb::BlockLayout l = tb::partition(385, 385, 65);
  tb::TreeBuildOptions opt;
  opt.levels = {tb::StrategyChoice::Hybrid};
  const tb::ApproximationTree tree = tb::build_tree(hf, l, opt, std::vector<double>(l.count(), 1.0));
  check_tree(hf, tree, opt, /*pm_leaves=*/true);
  std::size_t with_tin = 0;
  for (const tb::TreeNode& n : tree.nodes())
    if (n.strategy == tb::Strategy::Hybrid && n.surface.points.size() > 25) ++with_tin;
  EXPECT_GT(with_tin, 0u);
}

TEST(TreeFormat, CorruptionTruncationAndVersion) {
  const pm::Heightfield hf = terrain(33, 33);
  tb::TreeBuildOptions opt;
  opt.pm_leaves = false;
  opt.leaf_error = 20.0;
  const std::vector<std::uint8_t> bytes = tb::encode_tree(tb::build_tree(hf, tb::partition(33, 33, 33), opt));
  std::mt19937 rng = terralod::test::printed_seed_rng(12345);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<std::uint8_t> b = bytes;
    b[rng() % b.size()] ^= std::uint8_t(1u << (rng() % 8));
    try {
      tb::decode_tree(b, "terrain.db: tree");
      ADD_FAILURE() << "a flipped bit was not detected";
    } catch (const tb::TreeFormatError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("terrain.db: tree: ", 0), 0u) << e.what();
    }
  }
  for (std::size_t n : {std::size_t(0), std::size_t(5), std::size_t(16), bytes.size() / 2, bytes.size() - 1})
    EXPECT_THROW(tb::decode_tree(std::span(bytes).first(n), "t"), tb::TreeFormatError) << n;
}

}  // namespace
