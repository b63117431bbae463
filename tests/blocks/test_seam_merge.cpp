// Tests of the sliver merge at block seams (blocks/src/block_seams.hpp, paper section 4.3:
// unmatched boundary vertices closer than a tolerance are reset to their midpoint): hand-drawn
// merges 1 and 2 samples apart, merges refused (a flip, a block corner, the error bound),
// stand-ins merged toward; on generated terrain and N44W072, sessions with merging on and off:
// watertight, measured screen error within the reported bound, and the worst seam triangle.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <functional>
#include <thread>

#include "block_seams.hpp"  // private to blocks/: the test target adds blocks/src
#include "screen_error_checker.hpp"
#include "session_fixture.hpp"
#include "terralod/blocks/terrain_session.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace td = terralod::blocks::detail;
using terralod::test::BlockedTerrain;
using terralod::test::MemoryStore;
using terralod::test::settle;
using Tri = std::array<std::uint32_t, 3>;

namespace {

// A terrain of cols x rows blocks of `block` samples, world = (col, row), heights z(col,row),
// and the patches handed to detail::assemble.
struct Fixture {
  pm::Heightfield hf;
  tb::BlockGrid grid;
  std::deque<pm::Heightfield> crops;  // block-local heights (stable addresses)
  std::vector<tb::BlockSummary> summaries;
  std::vector<td::SeamPatch> patches;
  pm::Camera camera;

  Fixture(int cols, int rows, int block, const std::function<double(int, int)>& z)
      : hf(cols * (block - 1) + 1, rows * (block - 1) + 1),
        grid(hf.width(), hf.height(), block, pm::GridTransform::identity()),
        summaries(grid.block_count()) {
    for (int r = 0; r < hf.height(); ++r)
      for (int c = 0; c < hf.width(); ++c) hf.at(c, r) = z(c, r);
    camera.x = hf.width() / 2.0;  // high above the middle, looking straight down
    camera.y = hf.height() / 2.0;
    camera.z = 300;
    camera.pitch_deg = -90;
    camera.far_m = 1e4;
  }

  // A patch of block k from whole-grid vertices and CCW triangles; movable = has heights.
  void add(tb::BlockKey k, const std::vector<pm::GridPoint>& vs, const std::vector<Tri>& ts,
           bool movable = true, double bound_px = 1e9) {
    const tb::SampleRect d = grid.domain(k);
    td::SeamPatch p;
    p.key = k;
    for (const pm::GridPoint& g : vs) {
      p.samples.push_back(std::uint64_t(g.y) * std::uint64_t(hf.width()) + std::uint64_t(g.x));
      p.rest_z.push_back(hf.at(g.x, g.y));
    }
    p.display_z = p.rest_z;
    p.triangles = ts;
    p.bound_px = bound_px;
    if (movable) {
      pm::Heightfield& c = crops.emplace_back(d.width(), d.height());
      for (int r = 0; r < d.height(); ++r)
        for (int col = 0; col < d.width(); ++col) c.at(col, r) = hf.at(d.col0 + col, d.row0 + r);
      p.heights = &c;
    }
    patches.push_back(std::move(p));
    std::sort(patches.begin(), patches.end(),
              [](const td::SeamPatch& a, const td::SeamPatch& b) { return a.key < b.key; });
  }

  td::SeamResult assemble(double tolerance, tb::DrawnMesh& out) const {
    return td::assemble(grid, patches, pm::View(camera), tb::SeamMode::Stitch, 0.0, summaries, out,
                        tolerance);
  }
  tb::SampleRect region() const { return {0, 0, hf.width() - 1, hf.height() - 1}; }

  // Sets every patch's bound_px the way a block reports one: View::vertical_error_px of its
  // box (heights widened by e) and e, its exact L-infinity error.
  void set_patch_bounds() {
    const pm::LInfError err(hf, pm::ErrorMetric::Continuous);
    for (td::SeamPatch& p : patches) {
      const tb::SampleRect d = grid.domain(p.key);
      double e = 0, lo = 1e300, hi = -1e300;
      for (const Tri& t : p.triangles) {
        pm::GridPoint c[3];
        for (int k = 0; k < 3; ++k)
          c[k] = {int(p.samples[t[k]] % std::uint64_t(hf.width())),
                  int(p.samples[t[k]] / std::uint64_t(hf.width()))};
        e = std::max(e, err.triangle(c[0], c[1], c[2]));
      }
      for (int r = d.row0; r <= d.row1; ++r)
        for (int c = d.col0; c <= d.col1; ++c) lo = std::min(lo, hf.at(c, r)), hi = std::max(hi, hf.at(c, r));
      const pm::Box box{{double(d.col0), double(d.row0), lo - e}, {double(d.col1), double(d.row1), hi + e}};
      p.bound_px = pm::View(camera).vertical_error_px(box, e);
    }
  }
};

bool has_sample(const tb::DrawnMesh& m, const pm::Heightfield& hf, int col, int row) {
  const std::uint64_t s = std::uint64_t(row) * std::uint64_t(hf.width()) + std::uint64_t(col);
  return std::find(m.samples.begin(), m.samples.end(), s) != m.samples.end();
}

pm::TriangleMesh as_triangle_mesh(const tb::DrawnMesh& m) {
  pm::TriangleMesh t;
  for (std::uint64_t s : m.samples) t.vertices.push_back(std::uint32_t(s));
  t.triangles = m.triangles;
  return t;
}

// The worst plan-view aspect (shortest height / longest edge = 2 area / longest edge^2, world
// metres; 0.866 for an equilateral triangle) of the triangles with an edge on a block border
// inside `region` (the seams), and how many are slivers (aspect < 0.05).
struct SeamShape {
  double worst_aspect = 1;
  std::size_t triangles = 0, slivers = 0;
};
SeamShape seam_shape(const tb::DrawnMesh& m, const tb::BlockGrid& grid, tb::SampleRect region,
                     const std::function<bool(tb::BlockKey)>& of_block = {}) {
  SeamShape s;
  const std::uint64_t W = std::uint64_t(grid.grid_width());
  const int step = grid.block_size() - 1;
  auto seam_line = [&](int v, int lo, int hi) { return v % step == 0 && v > lo && v < hi; };
  for (std::size_t ti = 0; ti < m.triangles.size(); ++ti) {
    const auto& t = m.triangles[ti];
    if (of_block && !of_block(m.triangle_block[ti])) continue;
    bool seam = false;
    for (int e = 0; e < 3; ++e) {
      const std::uint64_t a = m.samples[t[e]], b = m.samples[t[(e + 1) % 3]];
      const int ca = int(a % W), ra = int(a / W), cb = int(b % W), rb = int(b / W);
      seam = seam || (ca == cb && seam_line(ca, region.col0, region.col1)) ||
             (ra == rb && seam_line(ra, region.row0, region.row1));
    }
    if (!seam) continue;
    const pm::Vec3 &p = m.positions[t[0]], &q = m.positions[t[1]], &r = m.positions[t[2]];
    const double area2 = std::abs((q.x - p.x) * (r.y - p.y) - (q.y - p.y) * (r.x - p.x));
    const double l2 = std::max({(q.x - p.x) * (q.x - p.x) + (q.y - p.y) * (q.y - p.y),
                                (r.x - q.x) * (r.x - q.x) + (r.y - q.y) * (r.y - q.y),
                                (p.x - r.x) * (p.x - r.x) + (p.y - r.y) * (p.y - r.y)});
    const double aspect = area2 / l2;
    s.worst_aspect = std::min(s.worst_aspect, aspect);
    ++s.triangles;
    if (aspect < 0.05) ++s.slivers;
  }
  return s;
}

double plane(int c, int r) { return 2.0 * c + 3.0 * r; }

// Two 8 x 8-cell blocks, A = (0,0) over cols 0..8 and B = (1,0) over cols 8..16, sharing col 8.
// A has its own border vertex at (8,a), B at (8,b):
//
//   (0,0)------(8,0)------(16,0)       A: (0,0)(8,0)(8,a), (0,0)(8,a)(8,8), (0,0)(8,8)(0,8)
//     | \___     |  \___     |         B: a fan from (8,b): (8,0)(16,0)(8,b), (8,b)(16,0)(16,8),
//     |     \_ (8,a)    \_   |            (8,b)(16,8)(8,8)
//     |       \_ |     _(8,b)
//   (0,8)------(8,8)------(16,8)
void two_blocks(Fixture& f, int a, int b, bool b_movable = true, double bound_px = 1e9) {
  f.add({0, 0}, {{0, 0}, {8, 0}, {8, 8}, {0, 8}, {8, a}}, {{0, 1, 4}, {0, 4, 2}, {0, 2, 3}}, true, bound_px);
  f.add({1, 0}, {{8, 0}, {16, 0}, {16, 8}, {8, 8}, {8, b}}, {{0, 1, 4}, {4, 1, 2}, {4, 2, 3}}, b_movable,
        bound_px);
}

}  // namespace

TEST(SeamMerge, TwoSamplesApartMeetAtTheMidpoint) {
  // a = 3, b = 5: without merging each side gets the other's vertex (2 split triangles, one
  // of them the needle (0,0)(8,3)(8,5)); with tolerance 3 both move to (8,4), nothing splits.
  Fixture f(2, 1, 9, plane);
  two_blocks(f, 3, 5);
  tb::DrawnMesh off, on;
  const td::SeamResult r0 = f.assemble(0, off);
  EXPECT_EQ(r0.merged_pairs, 0u);
  EXPECT_EQ(r0.seam_triangles, 2u);
  EXPECT_TRUE(has_sample(off, f.hf, 8, 3) && has_sample(off, f.hf, 8, 5));
  const td::SeamResult r1 = f.assemble(3, on);
  EXPECT_EQ(r1.merged_pairs, 1u);
  EXPECT_EQ(r1.refused_pairs, 0u);
  EXPECT_EQ(r1.seam_triangles, 0u);
  EXPECT_EQ(r1.moved_triangles, 5u);     // A: 2 around (8,3), B: 3 around (8,5)
  EXPECT_EQ(r1.max_merge_error_m, 0.0);  // a plane is exact on any triangulation
  EXPECT_TRUE(has_sample(on, f.hf, 8, 4));
  EXPECT_FALSE(has_sample(on, f.hf, 8, 3) || has_sample(on, f.hf, 8, 5));
  EXPECT_EQ(on.triangles.size(), 6u);
  for (const tb::DrawnMesh* m : {&off, &on}) {
    const auto w = terralod::test::check_watertight(*m, f.grid, f.region());
    EXPECT_TRUE(w.ok()) << w.describe();
  }
  // The needle: 2 * area / longest^2 of (0,0)(8,3)(8,5) = 16 / 89; merged, the worst seam
  // triangle is (0,0)(8,4)(8,8): 32 / 128.
  const SeamShape s0 = seam_shape(off, f.grid, f.region()), s1 = seam_shape(on, f.grid, f.region());
  EXPECT_DOUBLE_EQ(s0.worst_aspect, 16.0 / 89.0);
  EXPECT_DOUBLE_EQ(s1.worst_aspect, 32.0 / 128.0);
  // Tolerance 2 does not reach 2 samples apart.
  tb::DrawnMesh m2;
  EXPECT_EQ(f.assemble(2, m2).merged_pairs, 0u);
}

TEST(SeamMerge, OneSampleApartKeepsTheFinerSidesVertex) {
  // a = 3, b = 4, and B also has (8,6): B is the finer side on col 8 (4 vertices against 3),
  // so A's (8,3) moves onto B's (8,4); then A gets B's (8,6) inserted by the stitch.
  //   B: (8,0)(16,0)(8,4), (8,4)(16,0)(16,8), (8,4)(16,8)(8,6), (8,6)(16,8)(8,8)
  Fixture f(2, 1, 9, plane);
  f.add({0, 0}, {{0, 0}, {8, 0}, {8, 8}, {0, 8}, {8, 3}}, {{0, 1, 4}, {0, 4, 2}, {0, 2, 3}});
  f.add({1, 0}, {{8, 0}, {16, 0}, {16, 8}, {8, 8}, {8, 4}, {8, 6}},
        {{0, 1, 4}, {4, 1, 2}, {4, 2, 5}, {5, 2, 3}});
  tb::DrawnMesh m;
  const td::SeamResult r = f.assemble(2, m);
  EXPECT_EQ(r.merged_pairs, 1u);
  EXPECT_EQ(r.moved_triangles, 2u);
  EXPECT_EQ(r.seam_triangles, 1u);  // A's (0,0)(8,4)(8,8) split at (8,6)
  EXPECT_FALSE(has_sample(m, f.hf, 8, 3));
  EXPECT_TRUE(has_sample(m, f.hf, 8, 4) && has_sample(m, f.hf, 8, 6));
  const auto w = terralod::test::check_watertight(m, f.grid, f.region());
  EXPECT_TRUE(w.ok()) << w.describe();
  // With equal counts (no (8,6)) the first block's vertex stays: B's (8,4) moves to (8,3).
  Fixture g(2, 1, 9, plane);
  two_blocks(g, 3, 4);
  tb::DrawnMesh n;
  EXPECT_EQ(g.assemble(2, n).merged_pairs, 1u);
  EXPECT_TRUE(has_sample(n, g.hf, 8, 3));
  EXPECT_FALSE(has_sample(n, g.hf, 8, 4));
}

TEST(SeamMerge, RefusedWhenEveryTargetWouldFlipATriangle) {
  // A: (8,3) with an inner vertex Q = (7,3); moving (8,3) to (8,4) or (8,5) flips
  // (0,0)(8,3)(7,3) (orientation 3 -> -4, -11), since the line (0,0)-(7,3) crosses col 8 at 3.43.
  // B: (8,5) with R = (9,5); moving (8,5) to (8,4) or (8,3) flips (8,5)(9,5)(16,8) (3 -> -4,
  // -11), since the line (9,5)-(16,8) crosses col 8 at 4.57.
  //
  //   A: (0,0)(8,0)(8,3), (0,0)(8,3)(7,3), (7,3)(8,3)(8,8), (7,3)(8,8)(0,8), (0,0)(7,3)(0,8)
  //   B: (8,5)(9,5)(16,8), (8,5)(16,8)(8,8), (8,0)(16,0)(9,5), (9,5)(16,0)(16,8), (8,0)(9,5)(8,5)
  Fixture f(2, 1, 9, plane);
  f.add({0, 0}, {{0, 0}, {8, 0}, {8, 8}, {0, 8}, {8, 3}, {7, 3}},
        {{0, 1, 4}, {0, 4, 5}, {5, 4, 2}, {5, 2, 3}, {0, 5, 3}});
  f.add({1, 0}, {{8, 0}, {16, 0}, {16, 8}, {8, 8}, {8, 5}, {9, 5}},
        {{4, 5, 2}, {4, 2, 3}, {0, 1, 5}, {5, 1, 2}, {0, 5, 4}});
  tb::DrawnMesh m;
  const td::SeamResult r = f.assemble(3, m);
  EXPECT_EQ(r.merged_pairs, 0u);
  EXPECT_EQ(r.refused_pairs, 1u);
  EXPECT_EQ(r.seam_triangles, 2u);  // the stitch joins them as without merging
  EXPECT_TRUE(has_sample(m, f.hf, 8, 3) && has_sample(m, f.hf, 8, 5));
  const auto w = terralod::test::check_watertight(m, f.grid, f.region());
  EXPECT_TRUE(w.ok()) << w.describe();
}

TEST(SeamMerge, StandInsNeverMoveTheOtherSideMergesTowardThem) {
  // B has no heights (a stand-in): neither the midpoint (8,4) nor A's (8,3) can be reached
  // without moving B's vertex, so A's (8,3) moves to B's (8,5).
  Fixture f(2, 1, 9, plane);
  two_blocks(f, 3, 5, /*b_movable=*/false);
  tb::DrawnMesh m;
  const td::SeamResult r = f.assemble(3, m);
  EXPECT_EQ(r.merged_pairs, 1u);
  EXPECT_EQ(r.moved_triangles, 2u);
  EXPECT_TRUE(has_sample(m, f.hf, 8, 5));
  EXPECT_FALSE(has_sample(m, f.hf, 8, 3) || has_sample(m, f.hf, 8, 4));
  EXPECT_EQ(r.seam_triangles, 0u);
}

TEST(SeamMerge, CornersNeverMoveAndNothingMergesIntoThem) {
  // 2 x 2 blocks sharing the corner (8,8). Block (0,0) has (8,7) on its east side, 1 sample
  // from the corner, and (7,8) on its last row; (1,0) has (8,6); (0,1) has (6,8); (1,1) only
  // its corners. On col 8: 6 (B) and 7 (A) merge (1 apart, equal counts: A's (8,7) stays);
  // on row 8: 6 (C) and 7 (A) merge to A's (7,8). The corner (8,8) is matched on both
  // borders: never a merge candidate, never moved. Every block corner is still drawn.
  //
  //   (0,0)---------(8,0)---------(16,0)   (0,0): (0,0)(8,0)(8,7), (0,0)(8,7)(7,8),
  //     |            (8,6)           |            (7,8)(8,7)(8,8), (0,0)(7,8)(0,8)
  //     |            (8,7)           |     (1,0): (8,0)(16,0)(8,6), (8,6)(16,0)(16,8),
  //   (0,8)--(6,8)(7,8)(8,8)-------(16,8)         (8,6)(16,8)(8,8)
  //     |                            |     (0,1): (0,8)(6,8)(0,16), (6,8)(8,8)(8,16),
  //   (0,16)--------(8,16)--------(16,16)         (6,8)(8,16)(0,16)
  Fixture f(2, 2, 9, [](int c, int r) { return double((c * 7 + r * 13) % 5); });
  f.add({0, 0}, {{0, 0}, {8, 0}, {8, 8}, {0, 8}, {8, 7}, {7, 8}},
        {{0, 1, 4}, {0, 4, 5}, {5, 4, 2}, {0, 5, 3}});
  f.add({1, 0}, {{8, 0}, {16, 0}, {16, 8}, {8, 8}, {8, 6}}, {{0, 1, 4}, {4, 1, 2}, {4, 2, 3}});
  f.add({0, 1}, {{0, 8}, {8, 8}, {8, 16}, {0, 16}, {6, 8}}, {{0, 4, 3}, {4, 1, 2}, {4, 2, 3}});
  f.add({1, 1}, {{8, 8}, {16, 8}, {16, 16}, {8, 16}}, {{0, 1, 2}, {0, 2, 3}});
  tb::DrawnMesh m;
  const td::SeamResult r = f.assemble(2, m);
  EXPECT_EQ(r.merged_pairs, 2u);
  EXPECT_FALSE(has_sample(m, f.hf, 8, 6) || has_sample(m, f.hf, 6, 8));
  for (int c : {0, 8, 16})
    for (int row : {0, 8, 16}) EXPECT_TRUE(has_sample(m, f.hf, c, row)) << c << "," << row;
  const auto w = terralod::test::check_watertight(m, f.grid, f.region());
  EXPECT_TRUE(w.ok()) << w.describe();
  // Tolerance 3 does not pull (8,7) or (7,8) into the corner either: the corner is matched.
  tb::DrawnMesh m3;
  f.assemble(3, m3);
  EXPECT_TRUE(has_sample(m3, f.hf, 8, 7) && has_sample(m3, f.hf, 7, 8));
}

TEST(SeamMerge, RefusedWhenTheMovedTrianglesWouldExceedTheBlocksBound) {
  // Heights z = (col - 8)^2 + row^2 / 4: no triangle with a corner off col 8 is exact, so the
  // moved triangles of a = 3, b = 5 have a measured error > 0. Blocks that report a bound of
  // 0.01 px refuse the merge; blocks that report the bound of their own exact error accept
  // it, and the frame's reported bound covers the measured error of every drawn triangle.
  auto z = [](int c, int r) { return double((c - 8) * (c - 8)) + r * r / 4.0; };
  Fixture tight(2, 1, 9, z);
  two_blocks(tight, 3, 5, true, /*bound_px=*/0.01);
  tb::DrawnMesh m;
  td::SeamResult r = tight.assemble(3, m);
  EXPECT_EQ(r.merged_pairs, 0u);
  EXPECT_EQ(r.refused_pairs, 1u);
  Fixture loose(2, 1, 9, z);
  two_blocks(loose, 3, 5);
  loose.set_patch_bounds();
  r = loose.assemble(3, m);
  std::printf(
      "block bounds %.3f, %.3f px; merged %zu, max moved-triangle error %.3f m, frame bound %.3f px\n",
      loose.patches[0].bound_px, loose.patches[1].bound_px, r.merged_pairs, r.max_merge_error_m, r.bound_px);
  EXPECT_EQ(r.merged_pairs, 1u);
  EXPECT_GT(r.max_merge_error_m, 0.0);
  const terralod::test::ScreenCheck c = terralod::test::check_screen_error(
      loose.hf, as_triangle_mesh(m), terralod::test::ScreenProjector(loose.camera));
  EXPECT_LE(c.max_error_px, r.bound_px + 1e-9) << c.describe();
}

namespace {

struct OnOff {
  double worst_off = 1, worst_on = 1;
  double worst_pm_off = 1, worst_pm_on = 1;  ///< of the seam triangles of refined (PM) blocks
  std::size_t slivers_off = 0, slivers_on = 0;
  std::size_t split_off = 0, split_on = 0;  ///< triangles the stitch re-triangulated
};

// Settles a session with merging off and one with merging on (tolerance `tol`) at poses along
// a scripted flight; both drawn meshes must be watertight, the merged one's measured screen
// error within its reported bound. Prints the seam triangles' worst aspect, on and off.
OnOff compare(const BlockedTerrain& t, double tau, double tol, double height_m, const char* label) {
  MemoryStore store;
  store.terrain = &t;
  OnOff r;
  tb::SessionOptions off, on;
  off.refinement.tolerance_px = on.refinement.tolerance_px = tau;
  off.merge_tolerance_samples = 0;
  on.merge_tolerance_samples = tol;
  tb::TerrainSession s0(terralod::test::memory_source(store), t.grid, t.summaries, off);
  tb::TerrainSession s1(terralod::test::memory_source(store), t.grid, t.summaries, on);
  const std::vector<pm::Camera> path = terralod::test::scripted_flight(t.hf, 240, height_m, -25.0);
  double t0 = 0, t1 = 0;
  for (std::size_t i = 0; i < path.size(); i += 60) {
    pm::Camera cam = path[i];
    cam.far_m = 5e4;
    settle(s0, cam, t0);
    settle(s1, cam, t1);
    const terralod::test::ScreenCheck c = terralod::test::check_screen_error(
        t.hf, as_triangle_mesh(s1.drawn_mesh()), terralod::test::ScreenProjector(cam));
    EXPECT_LE(c.max_error_px, s1.stats().bound_px + 1e-9) << label << " pose " << i << ": " << c.describe();
    for (const tb::TerrainSession* s : {&s0, &s1}) {
      const auto w =
          terralod::test::check_watertight(s->drawn_mesh(), s->grid(), terralod::test::region_rect(*s));
      EXPECT_TRUE(w.ok()) << label << " pose " << i << ": " << w.describe();
    }
    const SeamShape a = seam_shape(s0.drawn_mesh(), s0.grid(), terralod::test::region_rect(s0));
    const SeamShape b = seam_shape(s1.drawn_mesh(), s1.grid(), terralod::test::region_rect(s1));
    const SeamShape a_pm = seam_shape(s0.drawn_mesh(), s0.grid(), terralod::test::region_rect(s0),
                                      [&](tb::BlockKey k) { return s0.selection(k) != nullptr; });
    const SeamShape b_pm = seam_shape(s1.drawn_mesh(), s1.grid(), terralod::test::region_rect(s1),
                                      [&](tb::BlockKey k) { return s1.selection(k) != nullptr; });
    r.worst_pm_off = std::min(r.worst_pm_off, a_pm.worst_aspect);
    r.worst_pm_on = std::min(r.worst_pm_on, b_pm.worst_aspect);
    std::printf(
        "%s pose %3zu: seam triangles %4zu / %4zu, split by the stitch %3zu / %3zu, worst aspect %.4f / "
        "%.4f, slivers (< 0.05) %3zu / %3zu (off / on); bound %.3f / %.3f px, measured on %.3f px\n",
        label, i, a.triangles, b.triangles, s0.stats().seam_triangles, s1.stats().seam_triangles,
        a.worst_aspect, b.worst_aspect, a.slivers, b.slivers, s0.stats().bound_px, s1.stats().bound_px,
        c.max_error_px);
    r.worst_off = std::min(r.worst_off, a.worst_aspect);
    r.worst_on = std::min(r.worst_on, b.worst_aspect);
    r.slivers_off += a.slivers;
    r.slivers_on += b.slivers;
    r.split_off += s0.stats().seam_triangles;
    r.split_on += s1.stats().seam_triangles;
  }
  store.release();
  std::printf(
      "%s (tolerance %.0f samples): worst seam aspect %.4f off, %.4f on (PM blocks' own: %.4f off, %.4f on); "
      "slivers %zu off, %zu on; split triangles %zu off, %zu on\n",
      label, tol, r.worst_off, r.worst_on, r.worst_pm_off, r.worst_pm_on, r.slivers_off, r.slivers_on,
      r.split_off, r.split_on);
  return r;
}

}  // namespace

TEST(SeamMerge, GeneratedTerrainSessionsOnAndOff) {
  const BlockedTerrain t = terralod::test::make_blocked_terrain(257, 257, 33, /*seed=*/11, 30.0, 500.0);
  const OnOff r = compare(t, /*tau=*/1.0, /*tol=*/3.0, /*height_m=*/250.0, "generated");
  // Merged pairs need no insertion: fewer triangles are split. The worst seam triangles are
  // fans of large stand-in triangles against dense PM borders, which merging does not
  // change; merging must not make them worse.
  EXPECT_LT(r.split_on, r.split_off);
  EXPECT_LE(r.slivers_on, r.slivers_off);
  EXPECT_GE(r.worst_on, r.worst_off);
}

TEST(SeamMerge, N44W072SessionsOnAndOff) {
  std::optional<pm::Heightfield> hf = terralod::test::read_hgt_crop("N44W072.hgt", 400, 400, 257);
  if (!hf) GTEST_SKIP() << "N44W072.hgt not in TERRALOD_DATA_DIR";
  const BlockedTerrain t = terralod::test::block_terrain(std::move(*hf), 33);
  const OnOff r = compare(t, /*tau=*/1.0, /*tol=*/3.0, /*height_m=*/300.0, "N44W072 crop");
  // Merged pairs need no insertion: fewer triangles are split. The worst seam triangles are
  // fans of large stand-in triangles against dense PM borders, which merging does not
  // change; merging must not make them worse.
  EXPECT_LT(r.split_on, r.split_off);
  EXPECT_LE(r.slivers_on, r.slivers_off);
  EXPECT_GE(r.worst_on, r.worst_off);
}

TEST(SeamMerge, SessionRejectsANegativeTolerance) {
  static const BlockedTerrain t = terralod::test::make_blocked_terrain(65, 65, 33, /*seed=*/3, 30.0, 200.0);
  MemoryStore store;
  store.terrain = &t;
  tb::SessionOptions o;
  o.merge_tolerance_samples = -1;
  EXPECT_THROW(tb::TerrainSession(terralod::test::memory_source(store), t.grid, t.summaries, o),
               std::invalid_argument);
  o.merge_tolerance_samples = 0;  // off is valid
  EXPECT_NO_THROW(tb::TerrainSession(terralod::test::memory_source(store), t.grid, t.summaries, o));
}
