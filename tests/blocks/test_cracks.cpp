// Crack tests of the drawn active region along random and scripted flights, on generated
// terrain and on an N44W072 crop: every frame, including frames in the middle of geomorphs
// and of block swaps (blocks arriving while the camera moves), must be watertight: interior
// edges used once in each direction, boundary edges only on the region's outer border, no
// T-junction, plan area equal to the region's, one position per sample (bit-identical).
// Every flight runs with the sliver merge of close unmatched border vertices on (the default
// tolerance, and a wide one on the scripted flight so that many vertices move).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <thread>

#include "screen_error_checker.hpp"
#include "session_fixture.hpp"
#include "terralod/blocks/terrain_session.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
using terralod::test::BlockedTerrain;
using terralod::test::MemoryStore;

namespace {

struct FlightCounts {
  std::size_t frames = 0, morphing = 0, mid_swap = 0, stitched = 0;
};

// Flies `path`, checking every frame. Reads take `latency` frames, so blocks arrive (and swap
// in with a geomorph) while the camera moves.
FlightCounts fly_and_check(const BlockedTerrain& t, const std::vector<pm::Camera>& path, double tau,
                           std::uint64_t latency, const char* label,
                           double merge_tolerance = tb::SessionOptions{}.merge_tolerance_samples) {
  MemoryStore store;
  store.terrain = &t;
  store.latency_frames = latency;
  tb::SessionOptions opt;
  opt.refinement.tolerance_px = tau;
  opt.refinement.morph_seconds = 0.3;
  opt.merge_tolerance_samples = merge_tolerance;
  EXPECT_GT(merge_tolerance, 0.0);  // the flights check the merge too
  tb::TerrainSession s(terralod::test::memory_source(store), t.grid, t.summaries, opt);
  const terralod::test::ReleaseAtExit release{store};
  FlightCounts n;
  for (std::size_t f = 0; f < path.size(); ++f) {
    const tb::SessionFrameStats& st = s.update(pm::View(path[f]), double(f) / 60.0);
    store.advance_frame();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));  // the loader gets the processor too
    ++n.frames;
    if (st.morphing_blocks > 0) ++n.morphing;
    if (st.stand_ins > 0 && st.refined > 0) ++n.mid_swap;
    if (st.seam_triangles > 0) ++n.stitched;
    const terralod::test::WatertightCheck c =
        terralod::test::check_watertight(s.drawn_mesh(), s.grid(), terralod::test::region_rect(s));
    if (!c.ok()) {
      ADD_FAILURE() << label << " frame " << f << " (" << st.refined << " refined, " << st.stand_ins
                    << " stand-ins, " << st.morphing_blocks << " morphing): " << c.describe();
      break;
    }
  }
  std::printf("%s: %zu frames checked, %zu mid-geomorph, %zu mid-swap, %zu with stitched seams\n", label,
              n.frames, n.morphing, n.mid_swap, n.stitched);
  return n;
}

// A random flight: constant speed, heading changing at a random turn rate, height above
// ground drifting between 150 and 700 m, looking ahead and down.
std::vector<pm::Camera> random_flight(const pm::Heightfield& hf, std::mt19937_64& rng, int frames) {
  std::uniform_real_distribution<double> u(0, 1);
  const double w = (hf.width() - 1) * hf.transform.spacing_x(),
               h = (hf.height() - 1) * hf.transform.spacing_y();
  const auto [x0, y0] = hf.transform.to_world(0, hf.height() - 1);  // south-west corner
  double x = x0 + w * (0.2 + 0.6 * u(rng)), y = y0 + h * (0.2 + 0.6 * u(rng)), heading = 2 * M_PI * u(rng);
  double above = 150 + 550 * u(rng), turn = 0;
  const double speed = 150 + 250 * u(rng);
  std::vector<pm::Camera> path;
  for (int f = 0; f < frames; ++f) {
    if (f % 30 == 0) turn = (u(rng) - 0.5) * 1.2;
    heading += turn / 60;
    x += speed / 60 * std::sin(heading);
    y += speed / 60 * std::cos(heading);
    above = std::clamp(above + (u(rng) - 0.5) * 20, 150.0, 700.0);
    pm::Camera c;
    c.x = x;
    c.y = y;
    c.z = terralod::test::ground_height(hf, x, y) + above;
    c.yaw_deg = heading * 180 / M_PI;
    c.pitch_deg = -20 - 15 * u(rng);
    c.fovy_deg = 60;
    c.far_m = 3e4;
    path.push_back(c);
  }
  return path;
}

}  // namespace

TEST(Cracks, RandomFlightsOverGeneratedTerrain) {
  const std::uint64_t seed = 20251122;
  std::printf("seed %llu\n", static_cast<unsigned long long>(seed));
  std::mt19937_64 rng(seed);
  const BlockedTerrain t = terralod::test::make_blocked_terrain(257, 257, 33, /*seed=*/7, 30.0, 500.0);
  FlightCounts all;
  for (int flight = 0; flight < 3; ++flight) {
    const std::vector<pm::Camera> path = random_flight(t.hf, rng, 90);
    const std::string label = "random flight " + std::to_string(flight);
    const FlightCounts n = fly_and_check(t, path, /*tau=*/2.0, /*latency=*/2, label.c_str());
    all.morphing += n.morphing;
    all.mid_swap += n.mid_swap;
    all.stitched += n.stitched;
  }
  EXPECT_GT(all.morphing, 0u);
  EXPECT_GT(all.mid_swap, 0u);
  EXPECT_GT(all.stitched, 0u);
}

TEST(Cracks, ScriptedFlightOverGeneratedTerrain) {
  const BlockedTerrain t = terralod::test::make_blocked_terrain(257, 193, 17, /*seed=*/9, 30.0, 600.0);
  std::vector<pm::Camera> path = terralod::test::scripted_flight(t.hf, 150, /*height_m=*/200.0, -20.0);
  for (pm::Camera& c : path) c.far_m = 3e4;
  const FlightCounts n =
      fly_and_check(t, path, /*tau=*/1.0, /*latency=*/3, "scripted flight", /*merge_tolerance=*/9.0);
  EXPECT_GT(n.morphing, 0u);
  EXPECT_GT(n.mid_swap, 0u);
}

TEST(Cracks, ScriptedFlightOverN44W072) {
  std::optional<pm::Heightfield> hf = terralod::test::read_hgt_crop("N44W072.hgt", 400, 400, 257);
  if (!hf) GTEST_SKIP() << "N44W072.hgt not in TERRALOD_DATA_DIR";
  const BlockedTerrain t = terralod::test::block_terrain(std::move(*hf), 33);
  std::vector<pm::Camera> path = terralod::test::scripted_flight(t.hf, 120, /*height_m=*/300.0, -20.0);
  for (pm::Camera& c : path) c.far_m = 5e4;
  const FlightCounts n = fly_and_check(t, path, /*tau=*/1.0, /*latency=*/2, "N44W072 crop");
  EXPECT_GT(n.morphing, 0u);
  EXPECT_GT(n.stitched, 0u);
}
