// Tests of the hybrid scheme's run-time primitives against the paper's worked examples: the
// cavity decoder (Fig. 7, Table 1, the TB array of Fig. 5 and its per-cell reading of Fig. 4)
// and the corner tessellation of section 2.1 (Fig. 3).
#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "terralod/blocks/hybrid/convexification.hpp"

namespace hy = terralod::blocks::hybrid;

namespace {

// Connectivities of the TB array of the paper's Fig. 5 (coarsest level):
// TB = {0(1), 1(14), 2(1), 3(10), 4(9), 5(6), 6(1), 7(2), 8(1), 9(1), 10(1), 11(1), 12(1),
//       13(2), 14(1), 15(1), 16(1)}, embedded in a longer ring so that no cavity wraps.
std::vector<std::uint32_t> fig5_connectivity() {
  std::vector<std::uint32_t> c(64, 1);
  c[1] = 14;
  c[3] = 10;
  c[4] = 9;
  c[5] = 6;
  c[7] = 2;
  c[13] = 2;
  return c;
}

std::vector<std::uint32_t> range(std::uint32_t a, std::uint32_t b) {
  std::vector<std::uint32_t> v;
  for (std::uint32_t i = a; i <= b; ++i) v.push_back(i);
  return v;
}

std::set<std::uint32_t> neighbours_after(const std::vector<hy::FanTriangle>& tris, std::uint32_t apex) {
  std::set<std::uint32_t> s;
  for (const auto& t : tris)
    if (t.apex == apex) s.insert(t.previous), s.insert(t.current);
  return s;
}

}  // namespace

TEST(HybridDecoder, Table1StepByStep) {
  // Up-left cell of Fig. 4: VC (4, 9), TB = {4(9), 5(6), 6(1), 7(2), 8(1), 9(1), 10(1), 11(1), 12(1)}.
  const auto conn = fig5_connectivity();
  const auto d = hy::decode_cavities(range(4, 12), conn, /*trace=*/true);
  // Table 1, column "Triangle", in order.
  const std::vector<hy::FanTriangle> expected = {{5, 6, 7},   {7, 8, 9},  {5, 7, 9},  {5, 9, 10},
                                                 {5, 10, 11}, {4, 5, 11}, {4, 11, 12}};
  EXPECT_EQ(d.triangles, expected);
  // Table 1, column "S list" after each vertex is read (rows of one vertex merged).
  std::vector<std::pair<std::uint32_t, std::vector<std::uint32_t>>> after;
  for (const auto& s : d.steps) {
    if (!after.empty() && after.back().first == s.vertex)
      after.back().second = s.s_list;
    else
      after.push_back({s.vertex, s.s_list});
  }
  const std::vector<std::pair<std::uint32_t, std::vector<std::uint32_t>>> table = {
      {4, {4}},    {5, {4, 5}},  {6, {4, 5}}, {7, {4, 5, 7}}, {8, {4, 5, 7}},
      {9, {4, 5}}, {10, {4, 5}}, {11, {4}},   {12, {4}}};
  EXPECT_EQ(after, table);
  // Vertex 4's cavity ends at 13, outside the cell: (4, 12, 13) is not generated; the local
  // convex hull of the cell is {4, 12} (Fig. 4b).
  EXPECT_EQ(d.hull, (std::vector<std::uint32_t>{4, 12}));
}

TEST(HybridDecoder, Fig5CoarsestLevelConnections) {
  const auto conn = fig5_connectivity();
  const auto d = hy::decode_cavities(range(0, 16), conn);
  // "vertex 4 is connected to ... {5, 11, 12, 13}"; "vertex 5 ... {6, 7, 9, 10, 11}".
  EXPECT_EQ(neighbours_after(d.triangles, 4), (std::set<std::uint32_t>{5, 11, 12, 13}));
  EXPECT_EQ(neighbours_after(d.triangles, 5), (std::set<std::uint32_t>{6, 7, 9, 10, 11}));
  // "vertex 1 is connected with that at distance 14 i.e., vertex 15".
  EXPECT_EQ(*neighbours_after(d.triangles, 1).rbegin(), 15u);
  // New local convex hull {0, 1, 15, 16} (Fig. 5).
  EXPECT_EQ(d.hull, (std::vector<std::uint32_t>{0, 1, 15, 16}));
  // Every vertex strictly between 1 and 15 is inside the cavity: the cavity polygon 1..15 has
  // 15 vertices, hence 13 triangles.
  EXPECT_EQ(d.triangles.size(), 13u);
}

TEST(HybridDecoder, Fig4FinerCellsFromTheSameArray) {
  const auto conn = fig5_connectivity();
  // Up-right cell: VC (0, 5); only triangle (1, 2, 3); hull {0, 1, 3, 4}.
  auto ur = hy::decode_cavities(range(0, 4), conn);
  EXPECT_EQ(ur.triangles, (std::vector<hy::FanTriangle>{{1, 2, 3}}));
  EXPECT_EQ(ur.hull, (std::vector<std::uint32_t>{0, 1, 3, 4}));
  // Down-left cell: VC (12, 5); cavity 13..15; hull {12, 13, 15, 16}.
  auto dl = hy::decode_cavities(range(12, 16), conn);
  EXPECT_EQ(dl.triangles, (std::vector<hy::FanTriangle>{{13, 14, 15}}));
  EXPECT_EQ(dl.hull, (std::vector<std::uint32_t>{12, 13, 15, 16}));
}

TEST(HybridDecoder, Fig6SingleCavity) {
  // TB = {20(5), 21(1), 22(1), 23(1), 24(1), 25(-)}: triangles {20,21,22}, {20,22,23},
  // {20,23,24}, {20,24,25}.
  std::vector<std::uint32_t> conn(40, 1);
  conn[20] = 5;
  auto d = hy::decode_cavities(range(20, 25), conn);
  EXPECT_EQ(d.triangles,
            (std::vector<hy::FanTriangle>{{20, 21, 22}, {20, 22, 23}, {20, 23, 24}, {20, 24, 25}}));
  EXPECT_EQ(d.hull, (std::vector<std::uint32_t>{20, 25}));
}

TEST(HybridDecoder, EmptyAndTrivialSequences) {
  std::vector<std::uint32_t> conn(8, 1);
  EXPECT_TRUE(hy::decode_cavities({}, conn).triangles.empty());
  auto d = hy::decode_cavities(range(2, 5), conn);
  EXPECT_TRUE(d.triangles.empty());
  EXPECT_EQ(d.hull, range(2, 5));
}

TEST(HybridCornerTessellation, Fig3CornerShift) {
  //  Cell [0,10]^2 in (col,row); the TIN covers the bottom-right part. Hull chain v1..v5 runs
  //  from the bottom border to the right border, TIN on its left (positive orientation):
  //
  //   c0 (0,0) ------------------ c1 (10,0)
  //    |                      v5 (10,3)
  //    |              v4 (8,5)
  //    |        v3 (6,6.5)
  //    |    v2 (4,8)
  //   c3 (0,10) ---- v1 (3,10) ------ c2 (10,10)  [covered]
  //
  //  Uncovered corners in positive order from the one next to v1: c3, c0, c1.
  std::vector<hy::PlanPoint> hull = {{3, 10}, {4, 8}, {6, 6.5}, {8, 5}, {10, 3}};
  std::vector<hy::PlanPoint> corners = {{0, 10}, {0, 0}, {10, 0}};
  auto tris = hy::corner_tessellation(hull, corners);
  // 5 hull vertices + 3 corners bound a polygon of 8 vertices: 6 triangles.
  ASSERT_EQ(tris.size(), 6u);
  double area = 0;
  for (const auto& t : tris) {
    auto p = [&](std::uint32_t i) { return i < 5 ? hull[i] : corners[i - 5]; };
    const auto a = p(t[0]), b = p(t[1]), c = p(t[2]);
    const double o = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    EXPECT_GT(o, 0);
    area += o / 2;
  }
  // Uncovered area = square - area under the chain (shoelace of the covered polygon).
  std::vector<hy::PlanPoint> covered = {{3, 10}, {10, 10}, {10, 3}, {8, 5}, {6, 6.5}, {4, 8}};
  double cov = 0;
  for (std::size_t i = 0; i < covered.size(); ++i) {
    const auto& a = covered[i];
    const auto& b = covered[(i + 1) % covered.size()];
    cov += a[0] * b[1] - b[0] * a[1];
  }
  EXPECT_DOUBLE_EQ(area, 100.0 - std::abs(cov) / 2);
  // c3 (index 5) is joined to v1 and v2 first, then the shift to c0.
  EXPECT_EQ(tris[0], (std::array<std::uint32_t, 3>{5, 1, 0}));
}

TEST(HybridCornerTessellation, NoCornerNoTriangle) {
  std::vector<hy::PlanPoint> hull = {{0, 5}, {10, 5}};
  EXPECT_TRUE(hy::corner_tessellation(hull, {}).empty());
  std::vector<hy::PlanPoint> bent = {{0, 5}, {5, 4}, {10, 5}};
  EXPECT_THROW(hy::corner_tessellation(bent, {}), std::runtime_error);
}
