// Tests for blocks/seam_stitch.hpp: hand-drawn stitches, T-junctions between patches of
// different sizes, and on generated terrains: watertight unions, bit-identical shared vertices,
// and the 2e bound of a stitched patch of error e.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <random>

#include "mesh_checker.hpp"
#include "printed_seed.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/blocks/seam_stitch.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace tb = terralod::blocks;
namespace pm = terralod::pm;

/// The union of the patches as one mesh over hf (vertices merged by sample).
pm::TriangleMesh merge(const pm::Heightfield& hf, const std::vector<tb::StitchPatch>& patches) {
  pm::TriangleMesh m;
  std::map<std::uint32_t, std::uint32_t> index;
  for (const tb::StitchPatch& p : patches) {
    std::vector<std::uint32_t> local;
    for (const pm::GridPoint& g : p.vertices) {
      const std::uint32_t s = std::uint32_t(g.y * hf.width() + g.x);
      auto [it, fresh] = index.try_emplace(s, std::uint32_t(m.vertices.size()));
      if (fresh) m.vertices.push_back(s);
      local.push_back(it->second);
    }
    for (const auto& t : p.triangles) m.triangles.push_back({local[t[0]], local[t[1]], local[t[2]]});
  }
  return m;
}

// Two 4 x 4-cell patches side by side; the right one has a vertex at (4,2) on the shared
// border, the left one does not:
//
//   (0,0)-----(4,0)-----(8,0)        left:  (0,0)(4,0)(4,4) and (0,0)(4,4)(0,4)
//     |  \      | \       |          right: (4,0)(8,0)(8,4), (4,0)(8,4)(4,2), (4,2)(8,4)(4,4)
//     |    \   (4,2)  \   |
//     |      \  |    \    |          stitching splits the left triangle (0,0)(4,0)(4,4) into
//   (0,4)-----(4,4)-----(8,4)        (4,0)(4,2)(0,0) and (4,2)(4,4)(0,0).
TEST(SeamStitch, HandDrawnTJunction) {
  std::vector<tb::StitchPatch> p(2);
  p[0].domain = {0, 0, 4, 4};
  p[0].vertices = {{0, 0}, {4, 0}, {4, 4}, {0, 4}};
  p[0].triangles = {{0, 1, 2}, {0, 2, 3}};
  p[1].domain = {4, 0, 8, 4};
  p[1].vertices = {{4, 0}, {8, 0}, {8, 4}, {4, 4}, {4, 2}};
  p[1].triangles = {{0, 1, 2}, {0, 2, 4}, {4, 2, 3}};
  const tb::StitchResult r = tb::stitch_seams(p);
  EXPECT_EQ(r.inserted_vertices, 1u);
  EXPECT_EQ(r.split_triangles, 1u);
  ASSERT_EQ(p[0].vertices.size(), 5u);
  EXPECT_EQ(p[0].vertices[4], (pm::GridPoint{4, 2}));
  ASSERT_EQ(p[0].triangles.size(), 3u);
  EXPECT_EQ(r.new_triangles[0], (std::vector<std::uint32_t>{0, 2}));
  EXPECT_TRUE(r.new_triangles[1].empty());
  EXPECT_EQ(p[1].triangles.size(), 3u);  // unchanged
  // The two pieces, in either order.
  const std::array<std::uint32_t, 3> a{1, 4, 0}, b{4, 2, 0};
  EXPECT_TRUE((p[0].triangles[0] == a && p[0].triangles[2] == b) ||
              (p[0].triangles[0] == b && p[0].triangles[2] == a));
  pm::Heightfield hf(9, 5);
  const terralod::test::MeshCheck c = terralod::test::check_mesh(hf, merge(hf, p));
  EXPECT_TRUE(c.topology_ok()) << c.describe();
}

// A corner triangle with two border edges that both receive vertices; and a large patch next
// to two small ones (their shared corner (4,2) lands inside the large patch's edge).
TEST(SeamStitch, CornerTriangleAndPatchesOfDifferentSizes) {
  std::vector<tb::StitchPatch> p(4);
  // Large patch [0,4]x[0,4], triangulated with the diagonal (4,0)-(0,4): the corner triangle
  // (4,0)(4,4)(0,4) has two border edges (right and bottom).
  p[0].domain = {0, 0, 4, 4};
  p[0].vertices = {{0, 0}, {4, 0}, {4, 4}, {0, 4}};
  p[0].triangles = {{0, 1, 3}, {1, 2, 3}};
  // Two small patches on its right: [4,6]x[0,2] split... as two triangles each, and [4,6]x[2,4].
  p[1].domain = {4, 0, 6, 2};
  p[1].vertices = {{4, 0}, {6, 0}, {6, 2}, {4, 2}};
  p[1].triangles = {{0, 1, 2}, {0, 2, 3}};
  p[2].domain = {4, 2, 6, 4};
  p[2].vertices = {{4, 2}, {6, 2}, {6, 4}, {4, 4}};
  p[2].triangles = {{0, 1, 2}, {0, 2, 3}};
  // Below it: [0,4]x[4,6] with an extra vertex (2,4) on the shared border.
  p[3].domain = {0, 4, 4, 6};
  p[3].vertices = {{0, 4}, {4, 4}, {4, 6}, {0, 6}, {2, 4}};
  p[3].triangles = {{0, 4, 3}, {4, 1, 2}, {4, 2, 3}};
  // The lower-right corner [4,6]x[4,6] to close the square.
  p.push_back({});
  p[4].domain = {4, 4, 6, 6};
  p[4].vertices = {{4, 4}, {6, 4}, {6, 6}, {4, 6}};
  p[4].triangles = {{0, 1, 2}, {0, 2, 3}};
  const tb::StitchResult r = tb::stitch_seams(p);
  EXPECT_EQ(p[0].vertices.size(), 6u);   // (4,2) and (2,4)
  EXPECT_EQ(p[0].triangles.size(), 4u);  // the corner triangle became three
  EXPECT_EQ(r.split_triangles, 1u);
  pm::Heightfield hf(7, 7);
  const terralod::test::MeshCheck c = terralod::test::check_mesh(hf, merge(hf, p));
  EXPECT_TRUE(c.topology_ok()) << c.describe();
}

// Blocks of a generated terrain extracted at different errors: after stitching the union is
// watertight, every split triangle is within 2 e of its block's error e (the fan-split bound
// of seam_stitch.hpp) and the unsplit ones within e.
TEST(SeamStitch, BlocksAtDifferentErrorsStayWithinTwiceTheirError) {
  const pm::Heightfield hf =
      pm::generate_terrain({.width = 97, .height = 81, .seed = 21, .quantize_to_metres = true});
  const tb::BlockLayout l = tb::partition(97, 81, 17);
  std::vector<pm::ProgressiveMesh> pms;
  for (tb::BlockKey k : l.keys()) pms.push_back(tb::build_block_pm(hf, l.rect(k)));
  std::mt19937 rng = terralod::test::printed_seed_rng(77);
  std::size_t splits = 0;
  for (int trial = 0; trial < 6; ++trial) {
    std::vector<double> e(pms.size());
    std::vector<tb::StitchPatch> patches(pms.size());
    for (std::size_t b = 0; b < pms.size(); ++b) {
      e[b] = std::uniform_real_distribution<double>(0.0, 40.0)(rng);
      const pm::TriangleMesh m = pms[b].extract(e[b]);
      const tb::SampleRect r = l.rect(l.keys()[b]);
      patches[b].domain = r;
      for (std::uint32_t s : m.vertices)
        patches[b].vertices.push_back({r.col0 + int(s % r.width()), r.row0 + int(s / r.width())});
      patches[b].triangles = m.triangles;
    }
    const tb::StitchResult res = tb::stitch_seams(patches);
    splits += res.split_triangles;
    const pm::TriangleMesh merged = merge(hf, patches);
    const terralod::test::MeshCheck c = terralod::test::check_mesh(hf, merged);
    ASSERT_TRUE(c.topology_ok()) << c.describe();
    for (std::size_t b = 0; b < patches.size(); ++b) {
      std::vector<char> is_new(patches[b].triangles.size(), 0);
      for (std::uint32_t t : res.new_triangles[b]) is_new[t] = 1;
      for (std::size_t t = 0; t < patches[b].triangles.size(); ++t) {
        const auto& tri = patches[b].triangles[t];
        auto s = [&](std::uint32_t v) {
          return std::uint32_t(patches[b].vertices[v].y * hf.width() + patches[b].vertices[v].x);
        };
        const double err = terralod::test::triangle_error(hf, s(tri[0]), s(tri[1]), s(tri[2])).max();
        EXPECT_LE(err, (is_new[t] ? 2.0 : 1.0) * e[b] + 1e-9) << "block " << b << " triangle " << t;
      }
    }
  }
  EXPECT_GT(splits, 0u);  // the trials do exercise splitting
}

}  // namespace
