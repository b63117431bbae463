// Tests of the per-frame pipeline: option checks, the guaranteed screen-space bound of the
// whole stitched active region measured by the independent checker, the swap-in geomorph,
// and skirts.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "screen_error_checker.hpp"
#include "session_fixture.hpp"
#include "terralod/blocks/terrain_session.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
using terralod::test::BlockedTerrain;
using terralod::test::MemoryStore;

namespace {

const BlockedTerrain& terrain() {
  static const BlockedTerrain t = terralod::test::make_blocked_terrain(257, 257, 33, /*seed=*/5, 30.0, 400.0);
  return t;
}

// Runs frames at a fixed pose until every inner block is refined and nothing morphs.
void settle(tb::TerrainSession& s, const pm::Camera& cam, double& t) {
  for (int i = 0; i < 20000; ++i, t += 1.0 / 60) {
    const tb::SessionFrameStats& st = s.update(pm::View(cam), t);
    if (st.refined == st.inner && st.morphing_blocks == 0 && st.loading == 0) return;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  FAIL() << "session did not settle";
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
  // With geomorphs, a block that arrives first shows its base mesh (here the two-triangle
  // stand-in itself when base_is_tm), then its vertices rise over morph_seconds.
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
