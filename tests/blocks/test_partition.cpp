// Tests for blocks/partition.hpp: the block layout, block heightfields (samples and world frame),
// and per-block PMs (corners fixed, border vertices on the border, exact base-mesh error).
#include <gtest/gtest.h>

#include <stdexcept>

#include "mesh_checker.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace tb = terralod::blocks;
namespace pm = terralod::pm;

TEST(Partition, BlockSizes) {
  for (int n : {3, 5, 9, 17, 33, 65, 129, 257, 513, 1025}) EXPECT_TRUE(tb::is_valid_block_size(n)) << n;
  for (int n : {-1, 0, 1, 2, 4, 6, 7, 10, 256, 258}) EXPECT_FALSE(tb::is_valid_block_size(n)) << n;
  EXPECT_THROW(tb::partition(100, 100, 256), std::invalid_argument);
  EXPECT_THROW(tb::partition(1, 1, 257), std::invalid_argument);
  EXPECT_THROW(tb::partition(1, 100, 257), std::invalid_argument);
}

// 1201 samples with 257-sample blocks: 1200 cells = 4 x 256 + 176, so 5 blocks per side, the
// last one [1024, 1200] (177 samples).
TEST(Partition, SrtmTileLayout) {
  const tb::BlockLayout l = tb::partition(1201, 1201, 257);
  EXPECT_EQ(l.blocks_x, 5);
  EXPECT_EQ(l.blocks_y, 5);
  EXPECT_EQ(l.count(), 25u);
  EXPECT_EQ(l.rect({0, 0}), (tb::SampleRect{0, 0, 256, 256}));
  EXPECT_EQ(l.rect({1, 2}), (tb::SampleRect{256, 512, 512, 768}));
  EXPECT_EQ(l.rect({4, 4}), (tb::SampleRect{1024, 1024, 1200, 1200}));
  EXPECT_EQ(l.rect(0, 0, 4, 4), (tb::SampleRect{0, 0, 1200, 1200}));
  // Exactly divisible: 1025 = 4 x 256 + 1 -> 4 blocks, none partial.
  const tb::BlockLayout e = tb::partition(1025, 513, 257);
  EXPECT_EQ(e.blocks_x, 4);
  EXPECT_EQ(e.blocks_y, 2);
  EXPECT_EQ(e.rect({3, 1}), (tb::SampleRect{768, 256, 1024, 512}));
  // A 2 x 2 grid is one block of one cell.
  const tb::BlockLayout t = tb::partition(2, 2, 257);
  EXPECT_EQ(t.count(), 1u);
  EXPECT_EQ(t.rect({0, 0}), (tb::SampleRect{0, 0, 1, 1}));
}

// Neighbours share their border samples and the blocks cover every cell exactly once.
TEST(Partition, BlocksTileTheGrid) {
  for (auto [w, h, n] :
       {std::array{1201, 1201, 257}, std::array{100, 37, 9}, std::array{17, 33, 17}, std::array{18, 5, 5}}) {
    const tb::BlockLayout l = tb::partition(w, h, n);
    std::vector<int> cover(std::size_t(w - 1) * (h - 1), 0);
    for (tb::BlockKey k : l.keys()) {
      const tb::SampleRect r = l.rect(k);
      EXPECT_GE(r.width(), 2);
      EXPECT_GE(r.height(), 2);
      EXPECT_LE(r.width(), n);
      EXPECT_LE(r.height(), n);
      if (k.col + 1 < l.blocks_x) {
        EXPECT_EQ(l.rect({k.col + 1, k.row}).col0, r.col1);
      }
      if (k.row + 1 < l.blocks_y) {
        EXPECT_EQ(l.rect({k.col, k.row + 1}).row0, r.row1);
      }
      for (int j = r.row0; j < r.row1; ++j)
        for (int i = r.col0; i < r.col1; ++i) ++cover[std::size_t(j) * (w - 1) + i];
    }
    for (int c : cover) ASSERT_EQ(c, 1) << w << " x " << h << " / " << n;
  }
}

TEST(Partition, BlockHeightfieldKeepsSamplesAndWorldFrame) {
  pm::TerrainOptions o;
  o.width = 40;
  o.height = 30;
  pm::Heightfield hf = pm::generate_terrain(o);
  hf.transform = pm::GridTransform{1000.0, 30.0, 2.0, 5000.0, -1.5, -30.0};  // sheared, to test affinity
  const tb::SampleRect r{16, 8, 32, 24};
  const pm::Heightfield b = tb::block_heightfield(hf, r);
  ASSERT_EQ(b.width(), 17);
  ASSERT_EQ(b.height(), 17);
  for (int j = 0; j < 17; ++j)
    for (int i = 0; i < 17; ++i) {
      ASSERT_EQ(b.at(i, j), hf.at(16 + i, 8 + j));
      const auto [x, y] = b.transform.to_world(i, j);
      const auto [X, Y] = hf.transform.to_world(16 + i, 8 + j);
      EXPECT_NEAR(x, X, 1e-9);
      EXPECT_NEAR(y, Y, 1e-9);
    }
}

// The block PM keeps its corners through every collapse, keeps border vertices on the border,
// and base_mesh_error equals an independent brute-force measurement of the base mesh.
TEST(Partition, BlockPmCornersBordersAndBaseError) {
  pm::TerrainOptions o;
  o.width = o.height = 49;
  o.seed = 7;
  const pm::Heightfield hf = pm::generate_terrain(o);
  const tb::BlockLayout l = tb::partition(49, 49, 17);
  for (tb::BlockKey k : l.keys()) {
    const pm::ProgressiveMesh p = tb::build_block_pm(hf, l.rect(k));
    const pm::Heightfield& b = p.heightfield();
    const int W = b.width(), H = b.height();
    const pm::TriangleMesh base = p.extract_after(p.vsplit_count());
    std::vector<bool> present(b.size(), false);
    for (std::uint32_t v : base.vertices) present[v] = true;
    for (std::uint32_t c : {0u, std::uint32_t(W - 1), std::uint32_t((H - 1) * W), std::uint32_t(H * W - 1)})
      EXPECT_TRUE(present[c]) << "corner " << c << " collapsed";
    // Border: the base mesh's boundary edges lie on the block border (a watertight cover of the
    // block's rectangle, checked independently).
    const terralod::test::MeshCheck c = terralod::test::check_mesh(b, base);
    EXPECT_TRUE(c.topology_ok()) << c.describe();
    double brute = 0.0;
    for (const auto& t : base.triangles)
      brute = std::max(brute, terralod::test::triangle_error(b, base.vertices[t[0]], base.vertices[t[1]],
                                                             base.vertices[t[2]])
                                  .max());
    EXPECT_NEAR(tb::base_mesh_error(p), brute, 1e-9 * (1.0 + brute));
    EXPECT_LE(tb::base_mesh_error(p), p.max_error() + 1e-9);
  }
}

}  // namespace
