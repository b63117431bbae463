// Tests of the one terrain runtime (blocks/terrain_runtime.hpp) over real block databases:
// the guarantee for what is drawn (an independent checker at every sample in view), coverage
// of the whole view at any altitude, watertight seams between every kind of node and PM
// blocks during geomorphs and loads, the memory budget, and live settings that read nothing.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <string>
#include <thread>

#include "drawn_frame_checker.hpp"
#include "session_fixture.hpp"
#include "run_command.hpp"
#include "screen_error_checker.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace tb = terralod::blocks;
namespace tp = terralod::pm;
namespace tt = terralod::test;

namespace {

// A generated 513 x 513 terrain (30 m spacing, 15 km across) in a database of 65-sample blocks
// (8 x 8 PM blocks) under a tree whose levels are grid, TIN, non-regular grid, then the best of
// the three per node (Auto) right above the blocks: every kind of coarse node meets the others
// and the PM blocks.
struct Terrain {
  tp::Heightfield hf;
  std::string db;
};

Terrain build_terrain(int width, int height, std::vector<tb::StrategyChoice> levels, const std::string& name) {
  Terrain r;
  tp::TerrainOptions to;
  to.width = width;
  to.height = height;
  to.seed = 16;
  to.spacing = 30.0;
  to.relief = 1200.0;
  to.quantize_to_metres = true;
  r.hf = tp::generate_terrain(to);
  // One database per process: ctest runs the tests of this file in parallel processes.
  r.db = (tt::process_temp_dir("runtime") / name).string();
  tb::DatabaseBuildOptions o;
  o.block_size = 65;
  o.threads = 2;
  o.tree.levels = std::move(levels);
  tb::build_database(r.hf, r.db, o);
  return r;
}

const Terrain& terrain() {
  static const Terrain t = build_terrain(513, 513,
                                         {tb::StrategyChoice::Grid, tb::StrategyChoice::Tin,
                                          tb::StrategyChoice::NonRegularGrid, tb::StrategyChoice::Auto},
                                         "runtime_513.db");
  return t;
}

tt::DrawnFrame frame_of(const tb::DrawnMesh& m) {
  tt::DrawnFrame f;
  f.samples = m.samples;
  for (const tp::Vec3& p : m.positions) f.z.push_back(p.z);
  f.triangles = m.triangles;
  return f;
}

tp::Camera pose(const tp::Heightfield& hf, double col, double row, double above, double yaw, double pitch) {
  tp::Camera c;
  const auto [x, y] = hf.transform.to_world(col, row);
  c.x = x, c.y = y;
  c.z = tt::ground_height(hf, x, y) + above;
  c.yaw_deg = yaw, c.pitch_deg = pitch;
  return c;
}

// Flies `path`, checking every `every`-th frame with the independent checker; with `wait`,
// frames wait for the loader (as headless runs do) except every fifth, so some frames have
// blocks missing and blends running.
struct FlightResult {
  std::size_t frames = 0, checked = 0, complete_frames = 0, missing_frames = 0, morph_frames = 0;
  double worst_ratio = 0;  // measured / bound
  double worst_bound_complete = 0;
  std::set<std::pair<int, int>> kind_pairs;  // strategies meeting across an edge
};

FlightResult fly(tb::TerrainRuntime& rt, const std::vector<tp::Camera>& path, double tau, int every, bool wait,
                 double t0 = 0, const Terrain& ter = terrain()) {
  FlightResult r;
  const tp::Heightfield& hf = ter.hf;
  for (std::size_t f = 0; f < path.size(); ++f) {
    tp::Camera cam = path[f];
    rt.fit_clip_planes(cam);
    const double t = t0 + double(f) / 60.0;
    const tb::RuntimeFrameStats* s = &rt.update(tp::View(cam), t);
    if (wait && f % 5 != 0)
      for (int i = 0; i < 400 && s->missing_in_view > 0 && rt.loading(); ++i) {
        rt.wait_for_loader(0.05);
        s = &rt.update(tp::View(cam), t);
      }
    ++r.frames;
    EXPECT_LE(s->resident_bytes, rt.options().budget_bytes) << "frame " << f;
    if (s->missing_in_view == 0) {
      ++r.complete_frames;
      r.worst_bound_complete = std::max(r.worst_bound_complete, s->bound_px / tau);
      EXPECT_LE(s->bound_px, tau) << "frame " << f << ": nothing missing, bound over tau";
    } else {
      ++r.missing_frames;
    }
    if (s->moving_vertices > 0) ++r.morph_frames;
    if (f % std::size_t(every) != 0) continue;
    ++r.checked;
    const tt::FrameCheck c = tt::check_drawn_frame(hf, frame_of(rt.drawn_mesh()), cam);
    EXPECT_LE(c.max_error_px, s->bound_px * (1 + 1e-9) + 1e-9) << "frame " << f << ": " << c.describe();
    EXPECT_EQ(c.uncovered_in_view, 0u) << "frame " << f << ": " << c.describe();
    EXPECT_TRUE(c.watertight()) << "frame " << f << ": " << c.describe();
    if (s->bound_px > 0) r.worst_ratio = std::max(r.worst_ratio, c.max_error_px / s->bound_px);
    // Kinds of nodes meeting across interior edges.
    const tb::DrawnMesh& m = rt.drawn_mesh();
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::size_t> edge_tri;
    for (std::size_t i = 0; i < m.triangles.size(); ++i)
      for (int e = 0; e < 3; ++e) edge_tri[{m.triangles[i][e], m.triangles[i][(e + 1) % 3]}] = i;
    for (const auto& [e, i] : edge_tri) {
      const auto o = edge_tri.find({e.second, e.first});
      if (o == edge_tri.end()) continue;
      const std::int64_t a = m.triangle_node[i], b = m.triangle_node[o->second];
      if (a == b) continue;
      const int ka = int(rt.tree().node(a).strategy), kb = int(rt.tree().node(b).strategy);
      r.kind_pairs.insert({std::min(ka, kb), std::max(ka, kb)});
    }
  }
  return r;
}

std::vector<tp::Camera> turning_flight(const tp::Heightfield& hf, int frames, double above, double pitch,
                                       double turn_deg_per_frame, double speed_cells) {
  std::vector<tp::Camera> out;
  double col = 0.3 * (hf.width() - 1), row = 0.6 * (hf.height() - 1), yaw = 60;
  for (int f = 0; f < frames; ++f) {
    out.push_back(pose(hf, col, row, above, yaw, pitch));
    yaw += turn_deg_per_frame;
    const double a = yaw * std::numbers::pi / 180;
    col = std::clamp(col + speed_cells * std::sin(a), 0.0, double(hf.width() - 1));
    row = std::clamp(row - speed_cells * std::cos(a), 0.0, double(hf.height() - 1));
  }
  return out;
}

}  // namespace

TEST(TerrainRuntime, LowFlightWithinBoundCoveredAndWatertight) {
  tb::RuntimeOptions o;
  o.tolerance_px = 1.0;
  o.morph_seconds = 0.5;
  tb::TerrainRuntime rt(terrain().db, o);
  const FlightResult r = fly(rt, tt::scripted_flight(terrain().hf, 180, 120.0, -12.0), 1.0, 3, /*wait=*/true);
  std::printf("low flight: %zu frames, %zu complete, %zu with missing blocks, %zu with moving vertices; "
              "measured / bound <= %.3f; bound / tau <= %.3f where complete\n",
              r.frames, r.complete_frames, r.missing_frames, r.morph_frames, r.worst_ratio, r.worst_bound_complete);
  EXPECT_GT(r.complete_frames, r.frames / 2);
  EXPECT_GT(r.morph_frames, 0u) << "the flight should exercise geomorphs";
}

TEST(TerrainRuntime, HighAndHorizonViewsDrawTheWholeTerrainInView) {
  const tp::Heightfield& hf = terrain().hf;
  for (double tau : {0.5, 1.0, 4.0}) {
    tb::RuntimeOptions o;
    o.tolerance_px = tau;
    tb::TerrainRuntime rt(terrain().db, o);
    std::vector<tp::Camera> path;
    // Climbing from 200 m to 12 km over the south-west corner, looking at the horizon across
    // the terrain, then straight down from high up.
    for (int f = 0; f < 40; ++f)
      path.push_back(pose(hf, 10 + 3 * f, hf.height() - 20 - 3 * f, 200.0 * std::pow(60.0, f / 39.0), 45, -2 + 0.05 * f));
    for (int f = 0; f < 10; ++f) path.push_back(pose(hf, 256, 256, 20000.0, 10 * f, -90));
    const FlightResult r = fly(rt, path, tau, 2, /*wait=*/true);
    std::printf("tau %.1f, high and horizon: %zu complete of %zu, measured / bound <= %.3f\n", tau, r.complete_frames,
                r.frames, r.worst_ratio);
  }
}

TEST(TerrainRuntime, FastTurnsAndEveryKindOfNodeMeeting) {
  std::set<std::pair<int, int>> pairs;
  for (double tau : {1.0, 6.0}) {
    tb::RuntimeOptions o;
    o.tolerance_px = tau;
    o.morph_seconds = 0.3;
    tb::TerrainRuntime rt(terrain().db, o);
    for (double above : {60.0, 600.0, 3000.0, 9000.0}) {
      const FlightResult r = fly(rt, turning_flight(terrain().hf, 45, above, above > 1000 ? -12 : -6, 8.0, 2.0), tau, 3,
                                 /*wait=*/true, rt.stats().time_s + 1);
      pairs.insert(r.kind_pairs.begin(), r.kind_pairs.end());
    }
  }
  std::string seen;
  for (const auto& [a, b] : pairs)
    seen += std::string(" ") + tb::strategy_name(tb::Strategy(a)) + "|" + tb::strategy_name(tb::Strategy(b));
  std::printf("node kinds meeting:%s\n", seen.c_str());
  const int pmk = int(tb::Strategy::PmBlock);
  EXPECT_TRUE(pairs.count({pmk, pmk})) << seen;
  EXPECT_TRUE(pairs.count({int(tb::Strategy::Grid), pmk})) << seen;
  EXPECT_TRUE(pairs.count({int(tb::Strategy::Grid), int(tb::Strategy::NonRegularGrid)})) << seen;
  EXPECT_GE(pairs.size(), 5u) << seen;
}

TEST(TerrainRuntime, EveryKindOfCoarseNodeMeetsPmBlocks) {
  // One small database per coarse kind (385 x 385 samples, 6 x 6 blocks of 65, every level
  // of that kind): its nodes are the only coarse ones, so the seams checked in every frame are
  // between that kind and PM blocks (and between two nodes of it). Large tolerances make the
  // coarse levels meet tau / 2 on a terrain this small.
  const int pmk = int(tb::Strategy::PmBlock);
  for (const auto& [choice, kind] : {std::pair{tb::StrategyChoice::Grid, tb::Strategy::Grid},
                                     std::pair{tb::StrategyChoice::Tin, tb::Strategy::Tin},
                                     std::pair{tb::StrategyChoice::NonRegularGrid, tb::Strategy::NonRegularGrid}}) {
    const Terrain ter = build_terrain(385, 385, {choice}, std::string("runtime_") + tb::strategy_name(kind) + ".db");
    std::set<std::pair<int, int>> pairs;
    for (double tau : {4.0, 12.0, 32.0}) {
      tb::RuntimeOptions o;
      o.tolerance_px = tau;
      o.morph_seconds = 0.3;
      tb::TerrainRuntime rt(ter.db, o);
      for (double above : {100.0, 500.0, 1500.0}) {
        const FlightResult r = fly(rt, turning_flight(ter.hf, 30, above, above > 1000 ? -20 : -4, 12.0, 2.0), tau, 3,
                                   /*wait=*/true, rt.stats().time_s + 1, ter);
        pairs.insert(r.kind_pairs.begin(), r.kind_pairs.end());
      }
    }
    std::string seen;
    for (const auto& [a, b] : pairs)
      seen += std::string(" ") + tb::strategy_name(tb::Strategy(a)) + "|" + tb::strategy_name(tb::Strategy(b));
    std::printf("%s tree, node kinds meeting:%s\n", tb::strategy_name(kind), seen.c_str());
    EXPECT_TRUE(pairs.count({std::min(int(kind), pmk), std::max(int(kind), pmk)})) << seen;
  }
}

TEST(TerrainRuntime, MemoryBudgetHeldEveryFrameAndMissingReported) {
  tb::RuntimeOptions o;
  o.tolerance_px = 1.0;
  o.budget_bytes = std::size_t(12) << 20;
  tb::TerrainRuntime rt(terrain().db, o);
  const FlightResult r = fly(rt, tt::scripted_flight(terrain().hf, 120, 80.0, -5.0), 1.0, 4, /*wait=*/true);
  std::printf("12 MB budget: %zu frames with missing blocks of %zu, peak resident %zu bytes\n", r.missing_frames,
              r.frames, rt.stats().peak_resident_bytes);
  EXPECT_LE(rt.stats().peak_resident_bytes, o.budget_bytes);
  EXPECT_GT(rt.stats().evicted_total + rt.stats().dropped_total, 0u) << "the budget should bind on this flight";
}

TEST(TerrainRuntime, ChangingTauMidFlightReadsNoBlock) {
  const tp::Heightfield& hf = terrain().hf;
  tb::RuntimeOptions o;
  o.tolerance_px = 1.0;
  o.morph_seconds = 0.25;
  tb::TerrainRuntime rt(terrain().db, o);
  tp::Camera cam = pose(hf, 200, 300, 400.0, 30, -20);
  rt.fit_clip_planes(cam);
  double t = 0;
  for (int i = 0; i < 2000 && (i < 5 || rt.loading() || rt.stats().missing_in_view > 0); ++i, t += 1.0 / 60) {
    rt.update(tp::View(cam), t);
    rt.wait_for_loader(0.02);
  }
  // One more frame: its statistics count every read the loader finished while we waited.
  rt.update(tp::View(cam), t);
  t += 1.0 / 60;
  ASSERT_FALSE(rt.loading());
  ASSERT_EQ(rt.stats().missing_in_view, 0u);
  const std::uint64_t read = rt.stats().bytes_read_total;
  for (double tau : {2.0, 1.0, 3.0, 1.0}) {
    o.tolerance_px = tau;
    rt.set_options(o);
    for (int i = 0; i < 30; ++i, t += 1.0 / 60) {
      const tb::RuntimeFrameStats& s = rt.update(tp::View(cam), t);
      EXPECT_EQ(s.tolerance_px, tau);
      EXPECT_EQ(s.missing_in_view, 0u);
      EXPECT_LE(s.bound_px, tau);
    }
    const tt::FrameCheck c = tt::check_drawn_frame(hf, frame_of(rt.drawn_mesh()), cam);
    EXPECT_LE(c.max_error_px, rt.stats().bound_px * (1 + 1e-9) + 1e-9) << c.describe();
  }
  EXPECT_EQ(rt.stats().bytes_read_total, read) << "a change of tau must read no block";
}

TEST(TerrainRuntime, BadOptionsAndBadDatabaseAreErrors) {
  tb::RuntimeOptions o;
  o.tolerance_px = 0;
  EXPECT_THROW(tb::TerrainRuntime(terrain().db, o), std::invalid_argument);
  o = {};
  o.morph_seconds = -1;
  EXPECT_THROW(tb::TerrainRuntime(terrain().db, o), std::invalid_argument);
  const std::string missing = std::string(TERRALOD_TEST_TMP) + "/no_such_runtime.db";
  try {
    tb::TerrainRuntime rt(missing);
    FAIL() << "opened a missing database";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_runtime.db"), std::string::npos) << e.what();
  }
  tb::TerrainRuntime rt(terrain().db);
  tp::Camera cam;
  rt.fit_clip_planes(cam);
  rt.update(tp::View(cam), 1.0);
  EXPECT_THROW(rt.update(tp::View(cam), 0.5), std::invalid_argument);
}

// Flight-path prefetch in the runtime: blocks read with a latency of 6 frames (the session
// fixture's in-memory source over the database's own blobs), 600 m/s; after the cold start,
// prediction must remove most of the blocks needed before they arrived.
namespace {

struct PrefetchTerrain {
  Terrain ter;
  terralod::test::BlockedTerrain blobs;  // the database's blocks, for the in-memory source
};

const PrefetchTerrain& prefetch_terrain() {
  static const PrefetchTerrain t = [] {
    PrefetchTerrain r;
    tp::TerrainOptions to;
    to.width = to.height = 385;
    to.seed = 21;
    to.spacing = 30.0;
    to.relief = 200.0;
    to.quantize_to_metres = true;
    r.ter.hf = tp::generate_terrain(to);
    r.ter.db = (tt::process_temp_dir("runtime") / "runtime_prefetch.db").string();
    tb::DatabaseBuildOptions o;
    o.block_size = 33;  // 12 x 12 blocks of 960 m
    o.threads = 2;
    tb::build_database(r.ter.hf, r.ter.db, o);
    const tb::BlockDatabase db = tb::BlockDatabase::open(r.ter.db);
    r.blobs.grid = tb::BlockGrid::from_info(db.info());
    for (tb::BlockKey k : db.blocks()) r.blobs.blobs[k] = db.read_block(k);
    return r;
  }();
  return t;
}

std::size_t runtime_misses(const std::vector<tp::Camera>& path, bool prefetch, std::size_t& needed) {
  const PrefetchTerrain& pt = prefetch_terrain();
  terralod::test::MemoryStore store;
  store.terrain = &pt.blobs;
  store.latency_frames = 6;
  tb::RuntimeOptions o;
  o.prefetch = prefetch;
  o.tolerance_px = 4;
  o.budget_bytes = std::size_t(64) << 20;
  tb::TerrainRuntime rt(pt.ter.db, o, terralod::test::memory_source(store));
  const terralod::test::ReleaseAtExit release{store};
  const std::size_t warm = 90;
  std::size_t cold_misses = 0, cold_needed = 0;
  for (std::size_t f = 0; f < path.size(); ++f) {
    tp::Camera cam = path[f];
    rt.fit_clip_planes(cam);
    const tb::RuntimeFrameStats& st = rt.update(tp::View(cam), double(f) / 60.0);
    store.advance_frame();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));  // the loader gets a core
    if (f + 1 == warm) {
      cold_misses = st.prefetch_misses_total;
      cold_needed = st.prefetch_hits_total + st.prefetch_misses_total;
    }
  }
  needed = rt.stats().prefetch_hits_total + rt.stats().prefetch_misses_total - cold_needed;
  return rt.stats().prefetch_misses_total - cold_misses;
}

tp::Camera prefetch_pose(double x, double y, double heading_rad) {
  tp::Camera c;
  c.x = x;
  c.y = y;
  c.z = tt::ground_height(prefetch_terrain().ter.hf, x, y) + 250;
  c.yaw_deg = heading_rad * 180 / std::numbers::pi;
  c.pitch_deg = -25;
  return c;
}

void compare_prefetch(const char* label, const std::vector<tp::Camera>& path) {
  std::size_t needed_on = 0, needed_off = 0;
  const std::size_t on = runtime_misses(path, true, needed_on), off = runtime_misses(path, false, needed_off);
  std::printf("runtime, %s (%zu frames, after the first 90): prefetch misses with prediction %zu of %zu blocks "
              "needed, without %zu of %zu\n",
              label, path.size(), on, needed_on, off, needed_off);
  EXPECT_GT(off, 4u);
  EXPECT_LE(on * 4, off) << "prediction should remove most misses";
}

}  // namespace

TEST(TerrainRuntime, StraightFlightMissesFarFewerBlocksWithPrediction) {
  // East along the middle row at 600 m/s, 12 s.
  std::vector<tp::Camera> path;
  const auto [x0, y0] = prefetch_terrain().ter.hf.transform.to_world(40, 192);
  for (int f = 0; f < 720; ++f) path.push_back(prefetch_pose(x0 + 600.0 * f / 60, y0, std::numbers::pi / 2));
  compare_prefetch("straight", path);
}

TEST(TerrainRuntime, CurvedFlightMissesFarFewerBlocksWithPrediction) {
  // Half a circle of radius 3.5 km around the centre at 600 m/s, clockwise.
  std::vector<tp::Camera> path;
  const auto [cx, cy] = prefetch_terrain().ter.hf.transform.to_world(192, 192);
  const double r = 3500, w = 600 / r;
  for (int f = 0; f < 1100; ++f) {
    const double a = w * f / 60;
    path.push_back(prefetch_pose(cx + r * std::sin(a), cy + r * std::cos(a), a + std::numbers::pi / 2));
  }
  compare_prefetch("curved", path);
}
