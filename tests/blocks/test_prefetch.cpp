// Flight-path prediction and prefetch: the predictor's estimates on exact motions, and the
// prefetch misses (blocks needed in view before they were resident) with and without
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

TEST(FlightPredictor, StraightLineIsExtrapolatedExactly) {
  // 100 m/s east, 2 m/s up, sampled at 60 Hz: the prediction 2 s ahead is 200 m east, 4 m up.
  tb::FlightPredictor p;
  for (int f = 0; f <= 60; ++f) p.observe(f / 60.0, {1000 + 100.0 * f / 60, 50, 300 + 2.0 * f / 60});
  EXPECT_NEAR(p.velocity().x, 100, 1e-9);
  EXPECT_NEAR(p.velocity().y, 0, 1e-9);
  EXPECT_NEAR(p.turn_rate(), 0, 1e-9);
  const std::vector<tb::PredictedPoint> q = p.predict(2.0, 0.5);
  ASSERT_EQ(q.size(), 5u);  // dt = 0, 0.5, 1, 1.5, 2
  EXPECT_EQ(q[0].dt, 0.0);
  EXPECT_NEAR(q[4].position.x, 1100 + 200, 1e-6);
  EXPECT_NEAR(q[4].position.y, 50, 1e-6);
  EXPECT_NEAR(q[4].position.z, 302 + 4, 1e-6);
}

TEST(FlightPredictor, CircleIsFollowed) {
  // A circle of radius 1000 m at 0.2 rad/s (200 m/s), counter-clockwise in (x, y). The
  // half-window chords underestimate the speed by sin(x)/x (< 0.1 % here); a quarter turn
  // (7.85 s) ahead the prediction stays within 10 m of the circle.
  const double r = 1000, w = 0.2;
  tb::FlightPredictor p;
  double t = 0;
  for (int f = 0; f <= 120; ++f) {
    t = f / 60.0;
    p.observe(t, {r * std::cos(w * t), r * std::sin(w * t), 500});
  }
  EXPECT_NEAR(p.turn_rate(), w, 1e-6);
  const double ahead = M_PI / 2 / w;
  const std::vector<tb::PredictedPoint> q = p.predict(ahead, ahead);
  ASSERT_EQ(q.size(), 2u);
  const double te = t + ahead;
  EXPECT_NEAR(q[1].position.x, r * std::cos(w * te), 10);
  EXPECT_NEAR(q[1].position.y, r * std::sin(w * te), 10);
  // A still camera predicts itself only.
  tb::FlightPredictor still;
  still.observe(0, {1, 2, 3});
  still.observe(1, {1, 2, 3});
  EXPECT_EQ(still.predict(3, 0.5).size(), 1u);
}

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
