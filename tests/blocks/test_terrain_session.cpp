// Tests of the per-frame pipeline: option checks, the guaranteed screen-space bound of the
// whole stitched active region measured by the independent checker, the swap-in geomorph,
// skirts, and stand-ins of every kind (bound, cracks against PM blocks, no pop at swap-in).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <set>
#include <thread>
#include <unordered_map>

#include "screen_error_checker.hpp"
#include "session_fixture.hpp"
#include "terralod/blocks/terrain_session.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
using terralod::test::BlockedTerrain;
using terralod::test::MemoryStore;
using terralod::test::settle;

namespace {

const BlockedTerrain& terrain() {
  static const BlockedTerrain t = terralod::test::make_blocked_terrain(257, 257, 33, /*seed=*/5, 30.0, 400.0);
  return t;
}

pm::TriangleMesh as_triangle_mesh(const tb::DrawnMesh& m) {
  pm::TriangleMesh t;
  for (std::uint64_t s : m.samples) t.vertices.push_back(std::uint32_t(s));
  t.triangles = m.triangles;
  return t;
}

}  // namespace

TEST(TerrainSession, RejectsBadOptions) {
  MemoryStore store;
  store.terrain = &terrain();
  tb::SessionOptions o;
  o.refinement.morph_mode = pm::MorphMode::Full;
  EXPECT_THROW(tb::TerrainSession(terralod::test::memory_source(store), terrain().grid, terrain().summaries, o),
               std::invalid_argument);
  o = {};
  o.region.theta_deg = 90;
  EXPECT_THROW(tb::TerrainSession(terralod::test::memory_source(store), terrain().grid, terrain().summaries, o),
               std::invalid_argument);
  o = {};
  o.region.n_min = 3;
  o.region.n_max = 2;
  EXPECT_THROW(tb::TerrainSession(terralod::test::memory_source(store), terrain().grid, terrain().summaries, o),
               std::invalid_argument);
  EXPECT_THROW(tb::TerrainSession(terralod::test::memory_source(store), terrain().grid, {}, {}), std::invalid_argument);
  tb::TerrainSession s(terralod::test::memory_source(store), terrain().grid, terrain().summaries, {});
  pm::Camera cam;
  s.update(pm::View(cam), 1.0);
  EXPECT_THROW(s.update(pm::View(cam), 0.5), std::invalid_argument);
}

TEST(TerrainSession, ReportedBoundHoldsOverTheWholeStitchedRegion) {
  // The independent checker projects every vertical error segment of every drawn triangle
  // (including the triangles the stitch created and the two-triangle rings) exactly.
  MemoryStore store;
  store.terrain = &terrain();
  for (double tau : {1.0, 4.0}) {
    tb::SessionOptions opt;
    opt.refinement.tolerance_px = tau;
    tb::TerrainSession s(terralod::test::memory_source(store), terrain().grid, terrain().summaries, opt);
    std::vector<pm::Camera> path = terralod::test::scripted_flight(terrain().hf, 240, /*height_m=*/250.0);
    double t = 0;
    std::size_t stitched = 0;
    for (std::size_t i = 0; i < path.size(); i += 40) {
      pm::Camera cam = path[i];
      cam.far_m = 3e4;
      settle(s, cam, t);
      const tb::SessionFrameStats& st = s.stats();
      const terralod::test::ScreenCheck c =
          terralod::test::check_screen_error(terrain().hf, as_triangle_mesh(s.drawn_mesh()),
                                             terralod::test::ScreenProjector(cam));
      EXPECT_LE(c.max_error_px, st.bound_px + 1e-9) << "tau " << tau << " pose " << i << ": " << c.describe();
      EXPECT_GT(c.segments_visible, 0u);
      const auto w = terralod::test::check_watertight(s.drawn_mesh(), s.grid(), terralod::test::region_rect(s));
      EXPECT_TRUE(w.ok()) << w.describe();
      stitched += st.seam_triangles;
      std::printf("tau %.0f pose %zu: n %d, %zu blocks, %zu triangles (%zu stitched), measured %.3f px <= bound %.3f px "
                  "(max inserted delta %.2f m)\n",
                  tau, i, st.n, st.active, st.triangles, st.seam_triangles, c.max_error_px, st.bound_px,
                  st.max_stitch_delta_m);
    }
    EXPECT_GT(stitched, 0u);  // the stitch really ran
  }
}

TEST(TerrainSession, SwapInStartsAtTheStandInAndMorphs) {
  // With geomorphs, a block that arrives first shows its old surface (its stand-in, stitched),
  // then its vertices move to the selection over morph_seconds.
  MemoryStore store;
  store.terrain = &terrain();
  tb::SessionOptions opt;
  opt.refinement.morph_seconds = 0.5;
  opt.prefetch = false;
  tb::TerrainSession s(terralod::test::memory_source(store), terrain().grid, terrain().summaries, opt);
  pm::Camera cam = terralod::test::scripted_flight(terrain().hf, 10, 250.0)[0];
  cam.far_m = 3e4;
  double t = 0;
  std::size_t swapped = 0, morphing_frames = 0;
  for (int i = 0; i < 20000 && swapped == 0; ++i, t += 1.0 / 60) {
    swapped = s.update(pm::View(cam), t).swapped_in;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  ASSERT_GT(swapped, 0u);
  EXPECT_GT(s.stats().morphing_blocks, 0u);
  const double t_swap = t - 1.0 / 60;
  for (int i = 0; i < 120; ++i, t += 1.0 / 60) {
    const tb::SessionFrameStats& st = s.update(pm::View(cam), t);
    if (st.morphing_blocks > 0) ++morphing_frames;
    const auto w = terralod::test::check_watertight(s.drawn_mesh(), s.grid(), terralod::test::region_rect(s));
    ASSERT_TRUE(w.ok()) << "frame " << i << ": " << w.describe();
  }
  EXPECT_GT(morphing_frames, 0u);
  settle(s, cam, t);
  EXPECT_GT(t - t_swap, 0.4);  // the morph took about morph_seconds
  // Once settled the displayed heights are the samples' own.
  const tb::DrawnMesh& m = s.drawn_mesh();
  for (std::size_t v = 0; v < m.samples.size(); ++v)
    ASSERT_EQ(m.positions[v].z, terrain().hf[m.samples[v]]) << "vertex " << v;
}

TEST(TerrainSession, SkirtsHangWallsInsteadOfStitching) {
  MemoryStore store;
  store.terrain = &terrain();
  tb::SessionOptions opt;
  opt.seams = tb::SeamMode::Skirts;
  opt.skirt_depth_m = 50;
  tb::TerrainSession s(terralod::test::memory_source(store), terrain().grid, terrain().summaries, opt);
  pm::Camera cam = terralod::test::scripted_flight(terrain().hf, 10, 250.0)[0];
  cam.far_m = 3e4;
  double t = 0;
  settle(s, cam, t);
  const tb::DrawnMesh& m = s.drawn_mesh();
  EXPECT_EQ(s.stats().seam_triangles, 0u);
  std::size_t bottoms = 0;
  for (std::uint64_t sample : m.samples) bottoms += sample == tb::DrawnMesh::kNoSample;
  EXPECT_GT(bottoms, 0u);
  // Every wall triangle is vertical (zero plan area) and reaches 50 m below a top vertex.
  std::size_t walls = 0;
  for (const auto& tri : m.triangles) {
    const bool wall = m.samples[tri[0]] == tb::DrawnMesh::kNoSample || m.samples[tri[1]] == tb::DrawnMesh::kNoSample ||
                      m.samples[tri[2]] == tb::DrawnMesh::kNoSample;
    if (!wall) continue;
    ++walls;
    const pm::Vec3 &a = m.positions[tri[0]], &b = m.positions[tri[1]], &c = m.positions[tri[2]];
    EXPECT_EQ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x), 0.0);
  }
  EXPECT_EQ(walls, bottoms);  // two wall triangles and two bottom vertices per border edge
}

// ---------------------------------------------------------------------------------------------
// Stand-ins (BlockSummary surfaces of every kind): bound, cracks, swap-in continuity.

namespace {

std::vector<tb::StandinOptions> all_kinds() {
  std::vector<tb::StandinOptions> v(4);
  v[0].kind = tb::StandinKind::Tin;
  v[1].kind = tb::StandinKind::Grid;
  v[2].kind = tb::StandinKind::NonRegularGrid;
  v[3].kind = tb::StandinKind::TwoTriangles;
  for (auto& o : v) o.max_points = 32;
  return v;
}

// Blocks of (col + 2 row) % 4: TIN, grid, non-regular grid, two triangles; neighbours differ.
const BlockedTerrain& mixed_terrain() {
  static const BlockedTerrain t = terralod::test::with_standins(terrain(), all_kinds());
  return t;
}

// Height of the drawn mesh at grid point (col,row): the first triangle containing it (plan
// view, exact integer test), NaN when none does.
double drawn_height(const tb::DrawnMesh& m, std::uint64_t W, std::int64_t col, std::int64_t row) {
  for (const auto& t : m.triangles) {
    std::array<std::int64_t, 3> c, r;
    for (int i = 0; i < 3; ++i) {
      if (m.samples[t[i]] == tb::DrawnMesh::kNoSample) return std::nan("");
      c[i] = std::int64_t(m.samples[t[i]] % W);
      r[i] = std::int64_t(m.samples[t[i]] / W);
    }
    if (col < std::min({c[0], c[1], c[2]}) || col > std::max({c[0], c[1], c[2]}) || row < std::min({r[0], r[1], r[2]}) ||
        row > std::max({r[0], r[1], r[2]}))
      continue;
    const std::int64_t det = (c[1] - c[0]) * (r[2] - r[0]) - (r[1] - r[0]) * (c[2] - c[0]);
    const std::int64_t a1 = (col - c[0]) * (r[2] - r[0]) - (row - r[0]) * (c[2] - c[0]);
    const std::int64_t a2 = (c[1] - c[0]) * (row - r[0]) - (r[1] - r[0]) * (col - c[0]);
    if (a1 < 0 || a2 < 0 || a1 + a2 > det) continue;
    const double l1 = double(a1) / double(det), l2 = double(a2) / double(det);
    return (1 - l1 - l2) * m.positions[t[0]].z + l1 * m.positions[t[1]].z + l2 * m.positions[t[2]].z;
  }
  return std::nan("");
}

}  // namespace

TEST(TerrainSessionStandins, BoundFromTheStandInHoldsAndBeatsTwoTriangles) {
  // A stalled reader: every active block is drawn as its stand-in. On the terrain with the four
  // kinds mixed (neighbours of different kinds, stitched) the independent checker measures
  // every drawn triangle against the samples: measured <= reported. The default stand-ins (TIN
  // of 32 points) report a smaller median bound over the poses than two triangles.
  std::vector<tb::StandinOptions> two(1);
  two[0].kind = tb::StandinKind::TwoTriangles;
  static const BlockedTerrain tm = terralod::test::with_standins(terrain(), two);
  const BlockedTerrain& mixed = mixed_terrain();
  const BlockedTerrain& tin = terrain();  // the same samples, default stand-ins
  std::array<MemoryStore, 3> stores;
  std::array<const BlockedTerrain*, 3> ts{&mixed, &tin, &tm};
  std::vector<std::unique_ptr<tb::TerrainSession>> sessions;
  tb::SessionOptions opt;
  opt.refinement.tolerance_px = 1.0;
  for (std::size_t i = 0; i < 3; ++i) {
    stores[i].terrain = ts[i];
    stores[i].set_stalled(true);
    sessions.push_back(std::make_unique<tb::TerrainSession>(terralod::test::memory_source(stores[i]), ts[i]->grid,
                                                            ts[i]->summaries, opt));
  }
  const terralod::test::ReleaseAtExit r0{stores[0]}, r1{stores[1]}, r2{stores[2]};
  const std::vector<pm::Camera> path = terralod::test::scripted_flight(mixed.hf, 200, /*height_m=*/250.0);
  std::vector<double> bound_tin, bound_tm;
  for (std::size_t i = 0; i < path.size(); i += 50) {
    pm::Camera cam = path[i];
    cam.far_m = 3e4;
    tb::TerrainSession& a = *sessions[0];
    const tb::SessionFrameStats& sa = a.update(pm::View(cam), double(i) / 60);
    ASSERT_EQ(sa.refined, 0u);
    std::set<tb::StandinKind> kinds;
    for (const tb::BlockKey k : a.region().inner) kinds.insert(mixed.summaries[mixed.grid.index(k)].standin);
    const terralod::test::ScreenCheck c = terralod::test::check_screen_error(
        mixed.hf, as_triangle_mesh(a.drawn_mesh()), terralod::test::ScreenProjector(cam));
    EXPECT_LE(c.max_error_px, sa.bound_px + 1e-9) << "pose " << i << ": " << c.describe();
    EXPECT_GT(c.segments_visible, 0u);
    const auto w = terralod::test::check_watertight(a.drawn_mesh(), a.grid(), terralod::test::region_rect(a));
    EXPECT_TRUE(w.ok()) << "pose " << i << ": " << w.describe();
    bound_tin.push_back(sessions[1]->update(pm::View(cam), double(i) / 60).bound_px);
    bound_tm.push_back(sessions[2]->update(pm::View(cam), double(i) / 60).bound_px);
    std::printf("pose %zu: %zu stand-in kinds inner, measured %.2f px <= bound %.2f px; all TIN: %.2f px, all two "
                "triangles: %.2f px\n",
                i, kinds.size(), c.max_error_px, sa.bound_px, bound_tin.back(), bound_tm.back());
  }
  std::sort(bound_tin.begin(), bound_tin.end());
  std::sort(bound_tm.begin(), bound_tm.end());
  EXPECT_LT(bound_tin[bound_tin.size() / 2], bound_tm[bound_tm.size() / 2]);
}

TEST(TerrainSessionStandins, NoCrackWhereStandInsOfEveryKindMeetPmBlocks) {
  // A flight whose reads take 3 frames: blocks swap in while the camera moves, so every frame
  // mixes refined PM blocks, blending blocks and stand-ins of the four kinds. Every frame is
  // watertight, and each kind is seen next to a refined block.
  const BlockedTerrain& t = mixed_terrain();
  MemoryStore store;
  store.terrain = &t;
  store.latency_frames = 3;
  tb::SessionOptions opt;
  opt.refinement.tolerance_px = 1.0;
  opt.refinement.morph_seconds = 0.3;
  tb::TerrainSession s(terralod::test::memory_source(store), t.grid, t.summaries, opt);
  const terralod::test::ReleaseAtExit release{store};
  std::vector<pm::Camera> path = terralod::test::scripted_flight(t.hf, 150, /*height_m=*/200.0, -20.0);
  std::map<tb::StandinKind, std::size_t> met;
  std::size_t blending_frames = 0;
  for (std::size_t f = 0; f < path.size(); ++f) {
    path[f].far_m = 3e4;
    const tb::SessionFrameStats& st = s.update(pm::View(path[f]), double(f) / 60.0);
    store.advance_frame();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    blending_frames += st.morphing_blocks > 0;
    const tb::ActiveRegion& r = s.region();
    for (tb::BlockKey k : r.inner) {
      if (!s.selection(k)) continue;
      for (tb::BlockKey n : {tb::BlockKey{k.col - 1, k.row}, tb::BlockKey{k.col + 1, k.row}, tb::BlockKey{k.col, k.row - 1},
                             tb::BlockKey{k.col, k.row + 1}})
        if (r.is_active(n) && t.grid.contains(n) && !s.selection(n)) ++met[t.summaries[t.grid.index(n)].standin];
    }
    const auto c = terralod::test::check_watertight(s.drawn_mesh(), s.grid(), terralod::test::region_rect(s));
    ASSERT_TRUE(c.ok()) << "frame " << f << " (" << st.refined << " refined, " << st.stand_ins << " stand-ins, "
                        << st.morphing_blocks << " morphing): " << c.describe();
  }
  std::printf("PM block next to stand-in (block-frames): tin %zu, grid %zu, nonregular %zu, two-triangle %zu; %zu frames "
              "with blending or morphing blocks\n",
              met[tb::StandinKind::Tin], met[tb::StandinKind::Grid], met[tb::StandinKind::NonRegularGrid],
              met[tb::StandinKind::TwoTriangles], blending_frames);
  for (tb::StandinKind k : {tb::StandinKind::Tin, tb::StandinKind::Grid, tb::StandinKind::NonRegularGrid,
                            tb::StandinKind::TwoTriangles})
    EXPECT_GT(met[k], 0u) << tb::standin_kind_name(k);
  EXPECT_GT(blending_frames, 0u);
}

TEST(TerrainSessionStandins, SwapInDoesNotPop) {
  // Fixed camera, reads of 2 frames each (blocks arrive one after another): at every frame,
  // a vertex drawn before moves by at most (height range) x dt / morph_seconds (the blend is
  // linear in time), and a vertex that appears starts on the surface drawn the frame before
  // (the old stand-in surface, stitched border included). Vertices put at their refinement
  // heights at once (no blend), or at the PM's two-triangle base mesh, fail the second check
  // by up to the stand-in's error.
  const BlockedTerrain& t = terrain();
  MemoryStore store;
  store.terrain = &t;
  store.latency_frames = 2;
  tb::SessionOptions opt;
  opt.refinement.tolerance_px = 1.0;
  opt.refinement.morph_seconds = 0.5;
  opt.prefetch = false;
  opt.merge_tolerance_samples = 0;  // sliver merges move border vertices: not under test here
  tb::TerrainSession s(terralod::test::memory_source(store), t.grid, t.summaries, opt);
  const terralod::test::ReleaseAtExit release{store};
  pm::Camera cam = terralod::test::scripted_flight(t.hf, 10, 250.0)[0];
  cam.far_m = 3e4;
  double zlo = 1e300, zhi = -1e300;
  for (const tb::BlockSummary& b : t.summaries) zlo = std::min(zlo, b.zmin), zhi = std::max(zhi, b.zmax);
  const double dt = 1.0 / 60, step_limit = (zhi - zlo) * dt / opt.refinement.morph_seconds;
  const std::uint64_t W = std::uint64_t(t.grid.grid_width());
  tb::DrawnMesh prev;
  std::size_t swaps = 0, appeared = 0, frames = 0;
  double worst_step = 0, worst_appear = 0;
  for (int f = 0; f < 3000; ++f) {
    const tb::SessionFrameStats& st = s.update(pm::View(cam), f * dt);
    store.advance_frame();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    swaps += st.swapped_in;
    const tb::DrawnMesh& m = s.drawn_mesh();
    if (f > 0) {
      ++frames;
      std::unordered_map<std::uint64_t, double> before;
      for (std::size_t v = 0; v < prev.samples.size(); ++v) before.emplace(prev.samples[v], prev.positions[v].z);
      for (std::size_t v = 0; v < m.samples.size(); ++v) {
        const auto it = before.find(m.samples[v]);
        if (it != before.end()) {
          worst_step = std::max(worst_step, std::abs(m.positions[v].z - it->second));
          continue;
        }
        ++appeared;
        const double z0 = drawn_height(prev, W, std::int64_t(m.samples[v] % W), std::int64_t(m.samples[v] / W));
        ASSERT_FALSE(std::isnan(z0));
        worst_appear = std::max(worst_appear, std::abs(m.positions[v].z - z0));
      }
    }
    prev = m;
    if (st.refined == st.inner && st.morphing_blocks == 0 && st.loading == 0) break;
  }
  std::printf("%zu swap-ins over %zu frames: %zu vertices appeared, worst start offset %.3g m; worst per-frame step "
              "%.3f m (limit %.3f m)\n",
              swaps, frames, appeared, worst_appear, worst_step, step_limit);
  EXPECT_EQ(s.stats().refined, s.stats().inner);
  EXPECT_GT(swaps, 1u);
  EXPECT_GT(appeared, 0u);
  EXPECT_LE(worst_appear, 1e-6 * (std::abs(zhi) + 1));
  EXPECT_LE(worst_step, step_limit + 1e-9);
  EXPECT_GT(worst_step, 0.0);  // something really moved
}

TEST(TerrainSessionStandins, HandFilledSummariesGetTwoTriangles) {
  // Summaries without a surface (corners, range and tm_error only) are drawn as the two
  // triangles of their corners; a surface without one error per triangle is rejected.
  const BlockedTerrain& t = terrain();
  std::vector<tb::BlockSummary> bare = t.summaries;
  for (tb::BlockSummary& b : bare) {
    b.points.clear();
    b.triangles.clear();
    b.triangle_errors.clear();
  }
  MemoryStore store;
  store.terrain = &t;
  store.set_stalled(true);
  tb::TerrainSession s(terralod::test::memory_source(store), t.grid, bare, {});
  const terralod::test::ReleaseAtExit release{store};
  pm::Camera cam = terralod::test::scripted_flight(t.hf, 10, 250.0)[0];
  cam.far_m = 3e4;
  const tb::SessionFrameStats& st = s.update(pm::View(cam), 0.0);
  EXPECT_EQ(st.triangles, 2 * st.active);  // corners are shared: nothing to stitch
  for (const tb::BlockSummary& b : s.summaries()) {
    EXPECT_EQ(b.standin, tb::StandinKind::TwoTriangles);
    EXPECT_EQ(b.standin_error, b.tm_error);
  }
  std::vector<tb::BlockSummary> broken = t.summaries;
  broken[3].triangle_errors.pop_back();
  EXPECT_THROW(tb::TerrainSession(terralod::test::memory_source(store), t.grid, broken, {}), std::invalid_argument);
}
