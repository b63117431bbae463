// Tests of the block grid, block summaries and the active region (centre block, n from the
// eye height by b = a cot(theta), the (2(n+p)+1)^2 set).
#include <gtest/gtest.h>

#include <cmath>

#include "block_fixture.hpp"
#include "terralod/blocks/active_region.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;

TEST(BlockGrid, LayoutOfTheSrtmTile) {
  // 1201 samples, blocks of 257: 1200 / 256 = 4.69 -> 5 blocks per side, the last one
  // covering samples 1024..1200 (177 samples).
  const tb::BlockGrid g(1201, 1201, 257, pm::GridTransform::north_up(0, 0, 30, 30));
  EXPECT_EQ(g.cols(), 5);
  EXPECT_EQ(g.rows(), 5);
  EXPECT_EQ(g.domain({4, 4}), (tb::SampleRect{1024, 1024, 1200, 1200}));
  EXPECT_EQ(g.domain({1, 0}), (tb::SampleRect{256, 0, 512, 256}));
  EXPECT_DOUBLE_EQ(g.block_extent_m(), 256 * 30.0);
  // Exactly divisible: 513 samples, blocks of 257 -> 2 x 2.
  EXPECT_EQ(tb::BlockGrid(513, 257, 257, pm::GridTransform::identity()).cols(), 2);
  EXPECT_EQ(tb::BlockGrid(513, 257, 257, pm::GridTransform::identity()).rows(), 1);
  EXPECT_THROW(tb::BlockGrid(1, 5, 257, pm::GridTransform::identity()), std::invalid_argument);
  EXPECT_THROW(tb::BlockGrid(5, 5, 2, pm::GridTransform::identity()), std::invalid_argument);
}

TEST(BlockGrid, WorldToBlockAndBack) {
  // North-up: x = 1000 + 30 col, y = 5000 - 30 row; blocks of 33 samples span 960 m.
  const tb::BlockGrid g(257, 257, 33, pm::GridTransform::north_up(1000, 5000, 30, 30));
  const auto [c, r] = g.to_grid(1000 + 30 * 40.5, 5000 - 30 * 70.25);
  EXPECT_NEAR(c, 40.5, 1e-12);
  EXPECT_NEAR(r, 70.25, 1e-12);
  EXPECT_EQ(g.block_at(1000 + 30 * 40.5, 5000 - 30 * 70.25), (tb::BlockKey{1, 2}));  // 40.5/32, 70.25/32
  EXPECT_EQ(g.block_at(-1e9, 1e9), (tb::BlockKey{0, 0}));                            // clamped
  EXPECT_EQ(g.block_at(1e9, -1e9), (tb::BlockKey{7, 7}));
  const pm::Vec3 w = g.world(32, 64, 7.0);
  EXPECT_EQ(w.x, 1000 + 30 * 32.0);
  EXPECT_EQ(w.y, 5000 - 30 * 64.0);
}

TEST(BlockSummary, TinyBlockByHand) {
  // 3 x 3 block, heights        0 0 0
  //                             0 4 0      the two-triangle mesh on the corners is flat at 0;
  //                             0 0 2      ... except corner (2,2) = 2.
  // TM lower triangle (0,0),(2,0),(2,2): at the centre (1,1), on the diagonal, height 1; the
  // sample is 4 -> error 3. Upper triangle: (1,2) has TM height 1 (halfway (0,2)-(2,2)... on
  // the edge from (0,2) to (2,2): 1), sample 0 -> 1. Largest: 3.
  pm::Heightfield hf(3, 3);
  hf.at(1, 1) = 4;
  hf.at(2, 2) = 2;
  const pm::ProgressiveMesh p = pm::ProgressiveMesh::build(hf);
  const tb::BlockSummary s = tb::summarize_block(p, {0, 0});
  EXPECT_EQ(s.z00, 0);
  EXPECT_EQ(s.z11, 2);
  EXPECT_EQ(s.zmin, 0);
  EXPECT_EQ(s.zmax, 4);
  EXPECT_DOUBLE_EQ(s.tm_error, 3.0);
  const tb::BlockGrid g(3, 3, 3, pm::GridTransform::identity());
  EXPECT_DOUBLE_EQ(tb::tm_height(g, {0, 0}, s, 1, 1), 1.0);
  EXPECT_DOUBLE_EQ(tb::tm_height(g, {0, 0}, s, 1, 2), 1.0);
  EXPECT_DOUBLE_EQ(tb::tm_height(g, {0, 0}, s, 2, 0), 0.0);
}

TEST(BlockSummary, TmHeightOnBothTriangles) {
  // Corners z00 = 0, z10 = 10, z01 = 20, z11 = 30 (a plane: z = 10 u + 20 v): both triangles
  // agree with the plane.
  const tb::BlockGrid g(5, 5, 5, pm::GridTransform::identity());
  tb::BlockSummary s;
  s.z00 = 0, s.z10 = 10, s.z01 = 20, s.z11 = 30;
  EXPECT_DOUBLE_EQ(tb::tm_height(g, {0, 0}, s, 2, 2), 15.0);
  EXPECT_DOUBLE_EQ(tb::tm_height(g, {0, 0}, s, 3, 1), 10 * 0.75 + 20 * 0.25);
  EXPECT_DOUBLE_EQ(tb::tm_height(g, {0, 0}, s, 1, 3), 10 * 0.25 + 20 * 0.75);
}

TEST(BlockSummary, BlobRoundTripAndCorruption) {
  const terralod::test::BlockedTerrain t = terralod::test::make_blocked_terrain(65, 49, 17, /*seed=*/3);
  ASSERT_EQ(t.grid.cols(), 4);
  ASSERT_EQ(t.grid.rows(), 3);
  std::vector<std::uint8_t> blob = tb::encode_block_summaries(t.grid, t.summaries);
  // Version 2: 16-byte header, per block 40 bytes + 12 per point + 7 per triangle (3 u8
  // indices with <= 256 points, an f32 error), 4-byte CRC.
  std::size_t expect = 16 + 4;
  for (const tb::BlockSummary& s : t.summaries) expect += 40 + 12 * s.points.size() + 7 * s.triangles.size();
  EXPECT_EQ(blob.size(), expect);
  EXPECT_EQ(tb::decode_block_summaries(t.grid, blob, "t.db"), t.summaries);
  for (const tb::BlockSummary& s : t.summaries) {
    EXPECT_LE(s.zmin, std::min({s.z00, s.z10, s.z01, s.z11}));
    EXPECT_GE(s.tm_error, 0);
    EXPECT_LE(s.standin_error, s.tm_error);  // the default TIN starts from the two triangles
  }
  blob[40] ^= 1;
  try {
    tb::decode_block_summaries(t.grid, blob, "t.db");
    FAIL() << "corruption not detected";
  } catch (const tb::DatabaseError& e) {
    EXPECT_EQ(std::string(e.what()), "t.db: block_summaries: checksum mismatch");
  }
  const tb::BlockGrid other(65, 65, 17, t.grid.transform());
  EXPECT_THROW(tb::decode_block_summaries(other, tb::encode_block_summaries(t.grid, t.summaries), "t.db"),
               tb::DatabaseError);
}

// An all-void block's record is its 40-byte header alone, so a terrain that is mostly void (a
// coastline tile, a mosaic with missing tiles) has a blob of about 40 bytes a block: it decodes.
// The decoder's size check once assumed 95 bytes a record and refused such a blob as too small.
TEST(BlockSummary, MostlyEmptyBlocksDecode) {
  tb::StandinOptions two;
  two.kind = tb::StandinKind::TwoTriangles;
  const terralod::test::BlockedTerrain t =
      terralod::test::make_blocked_terrain(65, 49, 17, /*seed=*/3, 30.0, 1200.0, {two});
  std::vector<tb::BlockSummary> s(t.summaries.size());
  for (tb::BlockSummary& b : s) b.empty = true;
  s[5] = t.summaries[5];
  const std::vector<std::uint8_t> blob = tb::encode_block_summaries(t.grid, s);
  ASSERT_EQ(s[5].points.size(), 4u);
  EXPECT_EQ(blob.size(), 16 + 4 + 11 * tb::kBlockSummaryRecordHeader + (40 + 12 * 4 + 7 * 2));
  EXPECT_LT(blob.size(), 20 + 95 * s.size());  // below the old check's floor
  EXPECT_EQ(tb::decode_block_summaries(t.grid, blob, "t.db"), s);
  // Still refused when it cannot hold a header a block.
  const std::vector<std::uint8_t> cut(blob.begin(), blob.begin() + 20 + 40 * 11);
  try {
    tb::decode_block_summaries(t.grid, cut, "t.db");
    FAIL() << "a blob too small for its grid was accepted";
  } catch (const tb::DatabaseError& e) {
    EXPECT_NE(std::string(e.what()).find("too small for 12 block records"), std::string::npos) << e.what();
  }
}

TEST(ActiveRegion, InnerRadiusFollowsTheHeightRule) {
  // b = a cot(theta); n = ceil(b / L), clamped to [n_min, n_max].
  tb::ActiveRegionOptions o;
  o.theta_deg = 45;  // cot = 1: b = a
  o.n_min = 1;
  o.n_max = 5;
  EXPECT_EQ(tb::inner_radius(0, 1000, o), 1);
  EXPECT_EQ(tb::inner_radius(999, 1000, o), 1);
  EXPECT_EQ(tb::inner_radius(1500, 1000, o), 2);
  EXPECT_EQ(tb::inner_radius(4000, 1000, o), 4);
  EXPECT_EQ(tb::inner_radius(1e12, 1000, o), 5);
  o.theta_deg = 20;                              // cot 20 = 2.7475
  EXPECT_EQ(tb::inner_radius(300, 960, o), 1);   // b = 824 m
  EXPECT_EQ(tb::inner_radius(400, 960, o), 2);   // b = 1099 m
  EXPECT_EQ(tb::inner_radius(1000, 960, o), 3);  // b = 2747 m
}

TEST(ActiveRegion, ExactSetAroundTheCentreBlock) {
  // Flat terrain at height 0, 12 x 12 blocks of 33 samples (960 m at 30 m spacing).
  const tb::BlockGrid g(12 * 32 + 1, 12 * 32 + 1, 33, pm::GridTransform::north_up(0, 0, 30, 30));
  const std::vector<tb::BlockSummary> flat(g.block_count());
  tb::ActiveRegionOptions o;  // theta 20, p 1
  for (double z : {300.0, 400.0, 1000.0}) {
    // Eye over block (5, 6): x = 30 * (5 * 32 + 10), y = -30 * (6 * 32 + 20).
    const pm::Vec3 eye{30.0 * (5 * 32 + 10), -30.0 * (6 * 32 + 20), z};
    const tb::ActiveRegion r = tb::active_region(g, flat, eye, o);
    const int n = z == 300.0 ? 1 : z == 400.0 ? 2 : 3;
    EXPECT_EQ(r.centre, (tb::BlockKey{5, 6}));
    EXPECT_EQ(r.n, n) << "z " << z;
    EXPECT_DOUBLE_EQ(r.height_m, z);
    const int side = 2 * (n + o.p) + 1;
    EXPECT_EQ(r.inner.size() + r.outer.size(), std::size_t(side * side));
    EXPECT_EQ(r.inner.size(), std::size_t((2 * n + 1) * (2 * n + 1)));
    for (int c = 0; c < g.cols(); ++c)
      for (int w = 0; w < g.rows(); ++w) {
        const int d = std::max(std::abs(c - 5), std::abs(w - 6));
        EXPECT_EQ(r.is_active({c, w}), d <= n + o.p);
        EXPECT_EQ(r.is_inner({c, w}), d <= n);
      }
  }
  // At the corner of the grid the set is clipped: (n + p + 1)^2 blocks.
  const tb::ActiveRegion r = tb::active_region(g, flat, {10, -10, 300}, o);
  EXPECT_EQ(r.centre, (tb::BlockKey{0, 0}));
  EXPECT_EQ(r.inner.size() + r.outer.size(), 9u);
  EXPECT_EQ(r.inner.size(), 4u);
}

TEST(ActiveRegion, HeightIsMeasuredAboveTheTwoTriangleGround) {
  // One block of 33 samples whose corners are all at 500 m: an eye at 800 m is 300 m up.
  const tb::BlockGrid g(33, 33, 33, pm::GridTransform::north_up(0, 0, 30, 30));
  std::vector<tb::BlockSummary> s(1);
  s[0].z00 = s[0].z10 = s[0].z01 = s[0].z11 = 500;
  const tb::ActiveRegion r = tb::active_region(g, s, {100, -100, 800}, {});
  EXPECT_DOUBLE_EQ(r.height_m, 300);
  EXPECT_NEAR(r.visible_m, 300 / std::tan(20 * M_PI / 180), 1e-9);
  EXPECT_EQ(r.inner.size(), 1u);
  EXPECT_TRUE(r.outer.empty());
}
