// Flight-path prefetch: the prefetch misses (blocks needed in view before they were resident) with and without
// prediction on a straight and on a curved scripted flight, with reads that take 6 frames.
#include <gtest/gtest.h>

#include <cmath>
#include <chrono>
#include <cstdio>
#include <thread>

#include "screen_error_checker.hpp"
#include "session_fixture.hpp"
#include "terralod/blocks/flight_predictor.hpp"
#include "terralod/blocks/terrain_session.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
using terralod::test::BlockedTerrain;
using terralod::test::MemoryStore;

namespace {

const BlockedTerrain& terrain() {
  // 12 x 12 blocks of 33 samples (960 m), relief 200 m.
  static const BlockedTerrain t = terralod::test::make_blocked_terrain(385, 385, 33, /*seed=*/21, 30.0, 200.0);
  return t;
}

// Flies `path` with reads of 6 frames; returns the prefetch misses after the first 1.5 s (the
// cold start, when every block is missing whatever the prediction). Each frame also sleeps
// 2 ms: the loader thread then gets the processor on a loaded machine too, so that the reads
// really take about 6 frames each.
std::size_t misses(const std::vector<pm::Camera>& path, bool prefetch, std::size_t& needed) {
  MemoryStore store;
  store.terrain = &terrain();
  store.latency_frames = 6;
  tb::SessionOptions opt;
  opt.prefetch = prefetch;
  opt.refinement.tolerance_px = 4;
  opt.cache.budget_bytes = std::size_t(64) << 20;
  tb::TerrainSession s(terralod::test::memory_source(store), terrain().grid, terrain().summaries, opt);
  const terralod::test::ReleaseAtExit release{store};
  const std::size_t warm = 90;
  std::size_t cold_misses = 0, cold_needed = 0;
  for (std::size_t f = 0; f < path.size(); ++f) {
    const tb::SessionFrameStats& st = s.update(pm::View(path[f]), double(f) / 60.0);
    store.advance_frame();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    if (f + 1 == warm) {
      cold_misses = st.prefetch_misses_total;
      cold_needed = st.prefetch_hits_total + st.prefetch_misses_total;
    }
  }
  needed = s.stats().prefetch_hits_total + s.stats().prefetch_misses_total - cold_needed;
  return s.stats().prefetch_misses_total - cold_misses;
}

pm::Camera pose(double x, double y, double heading_rad) {
  pm::Camera c;
  c.x = x;
  c.y = y;
  c.z = terralod::test::ground_height(terrain().hf, x, y) + 250;
  c.yaw_deg = heading_rad * 180 / M_PI;
  c.pitch_deg = -25;
  c.far_m = 3e4;
  return c;
}

void compare(const char* label, const std::vector<pm::Camera>& path) {
  std::size_t needed_on = 0, needed_off = 0;
  const std::size_t on = misses(path, true, needed_on), off = misses(path, false, needed_off);
  std::printf("%s (%zu frames, after the first 90): prefetch misses with prediction %zu of %zu blocks needed, "
              "without %zu of %zu\n", label,
              path.size(), on, needed_on, off, needed_off);
  EXPECT_GT(off, 4u);
  EXPECT_LE(on * 4, off) << "prediction should remove most misses";
}

}  // namespace

TEST(Prefetch, StraightFlightMissesFarFewerBlocksWithPrediction) {
  // East along the middle row at 600 m/s (a block every 1.6 s), 12 s.
  std::vector<pm::Camera> path;
  const auto [x0, y0] = terrain().hf.transform.to_world(40, 192);
  for (int f = 0; f < 720; ++f) path.push_back(pose(x0 + 600.0 * f / 60, y0, M_PI / 2));
  compare("straight", path);
}

TEST(Prefetch, CurvedFlightMissesFarFewerBlocksWithPrediction) {
  // Half a circle of radius 3.5 km around the centre at 600 m/s (0.17 rad/s), clockwise.
  std::vector<pm::Camera> path;
  const auto [cx, cy] = terrain().hf.transform.to_world(192, 192);
  const double r = 3500, w = 600 / r;
  for (int f = 0; f < 1100; ++f) {
    const double a = w * f / 60;  // angle from north, clockwise
    const double x = cx + r * std::sin(a), y = cy + r * std::cos(a);
    path.push_back(pose(x, y, a + M_PI / 2));
  }
  compare("curved", path);
}
