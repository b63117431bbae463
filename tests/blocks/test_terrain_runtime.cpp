// Tests of the one terrain runtime (blocks/terrain_runtime.hpp) over real block databases:
// the guarantee for what is drawn (an independent checker at every sample in view), coverage
// of the whole view at any altitude, watertight seams between every kind of node and PM
// blocks during geomorphs and loads, the memory budget, live settings that read nothing,
// flight-path prefetch, and loading from a slow, stalled or broken block source.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <thread>

#include "block_fixture.hpp"
#include "drawn_frame_checker.hpp"
#include "run_command.hpp"
#include "screen_error_checker.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/height_query.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/pm/timing.hpp"

namespace tb = terralod::blocks;
namespace tp = terralod::pm;
namespace tt = terralod::test;

namespace {

// A generated 513 x 513 terrain (30 m spacing, 15 km across) in a database of 65-sample blocks
// (8 x 8 PM blocks) under a tree whose levels are grid, TIN, non-regular grid, then the best of
// the four kinds (grid, TIN, non-regular, hybrid) per node (Auto) right above the blocks: coarse
// kinds meet each other and the PM blocks.
struct Terrain {
  tp::Heightfield hf;
  std::string db;
};

/// A generated terrain, 30 m between samples, heights in whole metres (like SRTM).
tp::Heightfield generated(int width, int height, std::uint64_t seed, double relief) {
  tp::TerrainOptions to;
  to.width = width;
  to.height = height;
  to.seed = seed;
  to.spacing = 30.0;
  to.relief = relief;
  to.quantize_to_metres = true;
  return tp::generate_terrain(to);
}

enum class Sharing { ThisProcess, ReadOnlyAcrossProcesses };

Terrain build_terrain(int width, int height, std::vector<tb::StrategyChoice> levels, const std::string& name,
                      Sharing sharing = Sharing::ThisProcess) {
  Terrain r;
  r.hf = generated(width, height, /*seed=*/16, /*relief=*/1200.0);
  const auto build = [&](const std::filesystem::path& p) {
    tb::DatabaseBuildOptions o;
    o.block_size = 65;
    o.threads = 2;
    o.tree.levels = levels;
    tb::build_database(r.hf, p.string(), o);
  };
  // A database the tests only read is built once for all the processes of this executable
  // (ctest runs each test as one); one a test changes is its process's own.
  if (sharing == Sharing::ReadOnlyAcrossProcesses) {
    r.db = tt::shared_file(name, build).string();
  } else {
    r.db = (tt::process_temp_dir("runtime") / name).string();
    build(r.db);
  }
  return r;
}

const Terrain& terrain() {
  static const Terrain t = build_terrain(513, 513,
                                         {tb::StrategyChoice::Grid, tb::StrategyChoice::Tin,
                                          tb::StrategyChoice::NonRegularGrid, tb::StrategyChoice::Auto},
                                         "runtime_513.db", Sharing::ReadOnlyAcrossProcesses);
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

FlightResult fly(tb::TerrainRuntime& rt, const std::vector<tp::Camera>& path, double tau, int every,
                 bool wait, double t0 = 0, const Terrain& ter = terrain()) {
  FlightResult r;
  const tp::Heightfield& hf = ter.hf;
  for (std::size_t f = 0; f < path.size(); ++f) {
    tp::Camera cam = path[f];
    rt.fit_camera(cam);
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

// Turning flights (`frames` frames each, 2 cells a frame, `turn` degrees a frame) at every tau
// and height above the terrain, one runtime per tau, every third frame checked by fly(): the
// pairs of node kinds that met across an edge, and the same as text.
struct KindsMeeting {
  std::set<std::pair<int, int>> pairs;
  std::string text;
  bool met(tb::Strategy a, tb::Strategy b) const {
    return pairs.count({std::min(int(a), int(b)), std::max(int(a), int(b))}) != 0;
  }
};
KindsMeeting kinds_meeting(const Terrain& ter, std::initializer_list<double> taus,
                           std::initializer_list<double> heights, int frames, double pitch_low,
                           double pitch_high, double turn) {
  KindsMeeting k;
  for (double tau : taus) {
    tb::RuntimeOptions o;
    o.tolerance_px = tau;
    o.morph_seconds = 0.3;
    tb::TerrainRuntime rt(ter.db, o);
    for (double above : heights) {
      const FlightResult r =
          fly(rt, turning_flight(ter.hf, frames, above, above > 1000 ? pitch_high : pitch_low, turn, 2.0),
              tau, 3, /*wait=*/true, rt.stats().time_s + 1, ter);
      k.pairs.insert(r.kind_pairs.begin(), r.kind_pairs.end());
    }
  }
  for (const auto& [a, b] : k.pairs)
    k.text +=
        std::string(" ") + tb::strategy_name(tb::Strategy(a)) + "|" + tb::strategy_name(tb::Strategy(b));
  return k;
}

}  // namespace

TEST(TerrainRuntime, LowFlightWithinBoundCoveredAndWatertight) {
  tb::RuntimeOptions o;
  o.tolerance_px = 1.0;
  o.morph_seconds = 0.5;
  tb::TerrainRuntime rt(terrain().db, o);
  const FlightResult r = fly(rt, tt::scripted_flight(terrain().hf, 180, 120.0, -12.0), 1.0, 3, /*wait=*/true);
  std::printf(
      "low flight: %zu frames, %zu complete, %zu with missing blocks, %zu with moving vertices; "
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
      path.push_back(pose(hf, 10 + 3 * f, hf.height() - 20 - 3 * f, 200.0 * std::pow(60.0, f / 39.0), 45,
                          -2 + 0.05 * f));
    for (int f = 0; f < 10; ++f) path.push_back(pose(hf, 256, 256, 20000.0, 10 * f, -90));
    const FlightResult r = fly(rt, path, tau, 2, /*wait=*/true);
    std::printf("tau %.1f, high and horizon: %zu complete of %zu, measured / bound <= %.3f\n", tau,
                r.complete_frames, r.frames, r.worst_ratio);
  }
}

TEST(TerrainRuntime, FastTurnsAndEveryKindOfNodeMeeting) {
  const KindsMeeting k =
      kinds_meeting(terrain(), {1.0, 6.0}, {60.0, 600.0, 3000.0, 9000.0}, 45, -6, -12, 8.0);
  const auto& pairs = k.pairs;
  const std::string& seen = k.text;
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
  for (const auto& [choice, kind] :
       {std::pair{tb::StrategyChoice::Grid, tb::Strategy::Grid},
        std::pair{tb::StrategyChoice::Tin, tb::Strategy::Tin},
        std::pair{tb::StrategyChoice::NonRegularGrid, tb::Strategy::NonRegularGrid},
        std::pair{tb::StrategyChoice::Hybrid, tb::Strategy::Hybrid}}) {
    const Terrain ter =
        build_terrain(385, 385, {choice}, std::string("runtime_") + tb::strategy_name(kind) + ".db");
    const KindsMeeting k = kinds_meeting(ter, {4.0, 12.0, 32.0}, {100.0, 500.0, 1500.0}, 30, -4, -20, 12.0);
    std::printf("%s tree, node kinds meeting:%s\n", tb::strategy_name(kind), k.text.c_str());
    EXPECT_TRUE(k.met(kind, tb::Strategy::PmBlock)) << k.text;
  }
}

// Every pair of coarse kinds side by side: the quadtree's 16 nodes right above the PM blocks
// (2 x 2 blocks each) are re-made as grid, TIN, non-regular grid and hybrid nodes in the pattern
// (i + 2 j) mod 4, so that horizontal neighbours differ by one kind and vertical ones by two:
// every pair of the four kinds shares edges, and each kind meets PM blocks where a neighbour is
// refined. Every frame is checked watertight and within its bound.
TEST(TerrainRuntime, EveryPairOfCoarseKindsMeetsWatertight) {
  const tp::Heightfield& hf = terrain().hf;
  Terrain ter{hf, (tt::process_temp_dir("runtime") / "runtime_kinds.db").string()};
  {
    tb::DatabaseBuildOptions o;
    o.block_size = 65;
    o.threads = 2;
    o.tree.levels = {tb::StrategyChoice::Grid};
    tb::build_database(hf, ter.db, o);
  }
  const std::array<tb::Strategy, 4> kinds{tb::Strategy::Grid, tb::Strategy::Tin, tb::Strategy::NonRegularGrid,
                                          tb::Strategy::Hybrid};
  const std::array<std::unique_ptr<tb::NodeStrategy>, 4> make{
      tb::make_grid_strategy(4), tb::make_tin_strategy(25, tp::ErrorMetric::Continuous),
      tb::make_nonregular_strategy(25, tp::ErrorMetric::Continuous),
      tb::make_hybrid_strategy(4, 25, tp::ErrorMetric::Continuous)};
  {
    tb::BlockDatabase db = tb::BlockDatabase::open(ter.db, tb::BlockDatabase::Mode::ReadWrite);
    const tb::ApproximationTree tree = tb::decode_tree(*db.read_blob("tree"), ter.db);
    std::vector<tb::TreeNode> nodes = tree.nodes();
    tb::ApproximationTree::Parameters params = tree.parameters();
    std::size_t remade = 0;
    for (tb::TreeNode& n : nodes) {
      if (n.leaf() || tree.node(n.children[0]).strategy != tb::Strategy::PmBlock) continue;
      const int i = n.domain.col0 / (n.domain.width() - 1), j = n.domain.row0 / (n.domain.height() - 1);
      const std::size_t k = std::size_t(i + 2 * j) % 4;
      n.strategy = kinds[k];
      n.surface = make[k]->approximate(hf, n.domain);
      n.error = tb::surface_error(hf, n.surface, tp::ErrorMetric::Continuous);
      params.max_points = std::max(params.max_points, n.surface.points.size());
      ++remade;
    }
    ASSERT_EQ(remade, 16u);
    db.put_blob("tree", tb::encode_tree(tb::ApproximationTree(params, std::move(nodes))));
  }
  const KindsMeeting k = kinds_meeting(ter, {1.0, 4.0, 12.0}, {150.0, 800.0, 3000.0}, 30, -6, -15, 12.0);
  std::printf("node kinds meeting:%s\n", k.text.c_str());
  // Each kind beside PM blocks is asserted by EveryKindOfCoarseNodeMeetsPmBlocks (one tree per
  // kind); here the coarse 5 x 5 grid nodes are refined wherever a neighbour is, so most but not
  // all kinds meet PM blocks.
  std::size_t meeting_pm = 0;
  for (std::size_t a = 0; a < kinds.size(); ++a) {
    meeting_pm += k.met(kinds[a], tb::Strategy::PmBlock);
    for (std::size_t b = a + 1; b < kinds.size(); ++b)
      EXPECT_TRUE(k.met(kinds[a], kinds[b]))
          << tb::strategy_name(kinds[a]) << " | " << tb::strategy_name(kinds[b]) << ":" << k.text;
  }
  EXPECT_GE(meeting_pm, 3u) << k.text;
}

// Seams are stitched in sample coordinates, so a tree whose coarse node has a point between
// samples (as a 'terralod hybrid' database's own tree has) is refused with the file's name.
TEST(TerrainRuntime, RefusesATreeWithPointsOffTheSamples) {
  const Terrain ter = build_terrain(129, 129, {tb::StrategyChoice::Hybrid}, "runtime_off_samples.db");
  {
    tb::BlockDatabase db = tb::BlockDatabase::open(ter.db, tb::BlockDatabase::Mode::ReadWrite);
    const tb::ApproximationTree tree = tb::decode_tree(*db.read_blob("tree"), ter.db);
    std::vector<tb::TreeNode> nodes = tree.nodes();
    ASSERT_EQ(nodes[0].strategy, tb::Strategy::Hybrid);
    nodes[0].surface.points[0][0] += 0.5;
    db.put_blob("tree", tb::encode_tree(tb::ApproximationTree(tree.parameters(), std::move(nodes))));
  }
  try {
    tb::TerrainRuntime rt(ter.db, {});
    ADD_FAILURE() << "opened";
  } catch (const tb::DatabaseError& e) {
    EXPECT_NE(std::string(e.what()).find(ter.db), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("off its domain's samples"), std::string::npos) << e.what();
  }
}

TEST(TerrainRuntime, MemoryBudgetHeldEveryFrameAndMissingReported) {
  tb::RuntimeOptions o;
  o.tolerance_px = 1.0;
  o.budget_bytes = std::size_t(12) << 20;
  tb::TerrainRuntime rt(terrain().db, o);
  const FlightResult r = fly(rt, tt::scripted_flight(terrain().hf, 120, 80.0, -5.0), 1.0, 4, /*wait=*/true);
  std::printf("12 MB budget: %zu frames with missing blocks of %zu, peak resident %zu bytes\n",
              r.missing_frames, r.frames, rt.stats().peak_resident_bytes);
  EXPECT_LE(rt.stats().peak_resident_bytes, o.budget_bytes);
  EXPECT_GT(rt.stats().evicted_total + rt.stats().dropped_total, 0u)
      << "the budget should bind on this flight";
}

#if defined(__GLIBC__)
// resident_bytes is what the runtime holds, not an estimate beside it: after every frame of a
// flight (loads settled, geomorphs and swap-in blends running), the heap the process gained
// since the runtime opened (glibc's count of allocated bytes over all arenas) is within
// resident_bytes, and so within the budget, less a small allowance for the bookkeeping that is
// not counted (malloc's own headers, the loader's queue and threads' objects). Before
// resident_bytes counted the frame's buffers, the blocks' drawn meshes and blend state, and
// the loader's blocks and SQLite caches, the heap was 20 % above it on N44W072.
TEST(TerrainRuntime, ResidentBytesCoverTheHeapTheRuntimeHolds) {
  using tp::heap_in_use_bytes;
  // The fixture, and what the process sets up once (SQLite's and the threads' first
  // allocations), before counting starts.
  const Terrain& ter = terrain();
  {
    tb::TerrainRuntime warm(ter.db);
    warm.update_until_loaded(tp::View(pose(ter.hf, 100, 100, 500, 0, -30)), 0);
  }
  for (std::size_t budget : {std::size_t(12) << 20, std::size_t(512) << 20}) {
    const double h0 = heap_in_use_bytes();
    double worst = -1e300, worst_resident = 0;
    std::size_t blending_frames = 0;
    {
      tb::RuntimeOptions o;
      o.tolerance_px = 1.0;
      o.morph_seconds = 0.5;
      o.budget_bytes = budget;
      tb::TerrainRuntime rt(ter.db, o);
      const std::vector<tp::Camera> path = tt::scripted_flight(ter.hf, 90, 80.0, -5.0);
      for (std::size_t f = 0; f < path.size(); ++f) {
        tp::Camera cam = path[f];
        rt.fit_camera(cam);
        rt.update_until_loaded(tp::View(cam), double(f) / 60.0);
        const tb::RuntimeFrameStats& s = rt.stats();
        blending_frames += s.morphing_blocks > 0;
        ASSERT_LE(s.resident_bytes, budget) << "frame " << f;
        // Not counted: malloc's header and rounding of every allocation (about 100 per resident
        // block: its DAG's, refinement's and meshes' arrays; a few thousand for the rest).
        const double allowance = double(64 << 10) + double(2 << 10) * double(s.blocks_resident);
        const double over = heap_in_use_bytes() - h0 - double(s.resident_bytes);
        if (over > worst) worst = over, worst_resident = double(s.resident_bytes);
        EXPECT_LE(over, allowance) << "frame " << f << ": the heap grew by "
                                   << (over + double(s.resident_bytes)) << " bytes, resident_bytes says "
                                   << s.resident_bytes;
      }
    }
    std::printf(
        "budget %zu MB: heap at most %.0f bytes above resident_bytes (%.0f bytes then), %zu frames "
        "blending\n",
        budget >> 20, worst, worst_resident, blending_frames);
    EXPECT_GT(blending_frames, 0u) << "the flight should run geomorphs";
  }
}
#endif

// Far blocks are loaded only down to the error their view needs (partial_load_factor): the
// same complete high view holds far less memory than with whole blocks, at the same bound; on
// the way down finer copies replace the coarse ones, and every frame keeps the guarantee as
// drawn (fly(): the independent checker, coverage, watertight seams, tau when nothing is
// missing) while they blend in.
TEST(TerrainRuntime, FarBlocksHoldOnlyTheirCoarseEndAndFinerCopiesReplaceThem) {
  const tp::Heightfield& hf = terrain().hf;
  // From a corner, 1000 m up, across the terrain (15 km) to its far corner.
  const auto high = [&] {
    return pose(hf, 0.02 * (hf.width() - 1), 0.98 * (hf.height() - 1), 1000.0, 45, -4);
  };
  std::size_t bytes[2] = {0, 0};
  const double tau = 4.0;  // far blocks need only their coarse end at this tau (15 km across)
  for (double factor : {0.0, 4.0}) {
    tb::RuntimeOptions o;
    o.tolerance_px = tau;
    o.partial_load_factor = factor;
    tb::TerrainRuntime rt(terrain().db, o);
    tp::Camera cam = high();
    rt.fit_camera(cam);
    rt.update_until_loaded(tp::View(cam), 0.0, 60.0);
    const tb::RuntimeFrameStats s = rt.stats();  // the last frame, with everything loaded
    ASSERT_EQ(s.missing_in_view, 0u);
    ASSERT_GT(s.needed_in_view, 4u) << "the view should need several blocks";
    EXPECT_LE(s.bound_px, tau);
    const tt::FrameCheck c = tt::check_drawn_frame(hf, frame_of(rt.drawn_mesh()), cam);
    EXPECT_LE(c.max_error_px, s.bound_px * (1 + 1e-9) + 1e-9) << c.describe();
    bytes[factor > 0] = s.resident_bytes;
    std::printf("partial_load_factor %g: %zu blocks resident (%zu partial), %zu bytes\n", factor,
                s.blocks_resident, s.partial_blocks, s.resident_bytes);
    if (factor == 0) {
      EXPECT_EQ(s.partial_blocks, 0u);
      continue;
    }
    EXPECT_GT(s.partial_blocks, 0u);
    // Down to 60 m over the middle in 4 s: finer copies replace the coarse ones.
    std::vector<tp::Camera> path;
    for (int f = 0; f < 240; ++f) {
      const double t = f / 239.0;
      path.push_back(pose(hf, (0.02 + 0.48 * t) * (hf.width() - 1), (0.98 - 0.48 * t) * (hf.height() - 1),
                          1000.0 * (1 - t) + 60.0 * t, 45, -4 - 11 * t));
    }
    const FlightResult r = fly(rt, path, tau, 4, /*wait=*/true, 1.0);
    EXPECT_GT(rt.stats().reloads_total, 0u);
    EXPECT_GT(r.complete_frames, r.frames / 2);
    std::printf("descent: %zu finer copies, %zu of %zu frames complete, worst measured / bound %.3f\n",
                rt.stats().reloads_total, r.complete_frames, r.frames, r.worst_ratio);
  }
  EXPECT_LT(bytes[1] * 10, bytes[0] * 7) << "partial blocks should hold far less memory (measured: half)";
}

// A block that finished after update() took the loader's results is never asked for again
// (set_queue skips finished keys), so loading() must stay true until an update() takes it: a
// caller looping "while blocks are missing and loading()" would otherwise stop one block short.
TEST(TerrainRuntime, FinishedBlocksCountAsLoadingUntilAnUpdateTakesThem) {
  const tp::Heightfield& hf = terrain().hf;
  tb::RuntimeOptions o;
  o.morph_seconds = 0;
  tb::TerrainRuntime rt(terrain().db, o);
  tp::Camera cam = pose(hf, 200, 300, 400.0, 30, -20);
  rt.fit_camera(cam);
  const std::size_t missing = rt.update(tp::View(cam), 0.0).missing_in_view;
  ASSERT_GT(missing, 0u) << "the first frame has nothing resident";
  while (rt.wait_for_loader(1.0)) {
  }  // every read finished; none taken
  EXPECT_TRUE(rt.loading()) << "finished blocks wait for update()";
  EXPECT_LT(rt.update(tp::View(cam), 1.0 / 60).missing_in_view, missing);
}

TEST(TerrainRuntime, ChangingTauMidFlightReadsNoBlock) {
  const tp::Heightfield& hf = terrain().hf;
  tb::RuntimeOptions o;
  o.tolerance_px = 1.0;
  o.morph_seconds = 0.25;
  tb::TerrainRuntime rt(terrain().db, o);
  tp::Camera cam = pose(hf, 200, 300, 400.0, 30, -20);
  rt.fit_camera(cam);
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

// drawn_height (a bucket grid over the drawn triangles) gives the height of the drawn surface:
// the same as a scan of every drawn triangle, at random points and at the samples drawn,
// and again after the mesh changes; NaN outside the terrain.
TEST(TerrainRuntime, DrawnHeightIsTheDrawnSurface) {
  const tp::Heightfield& hf = terrain().hf;
  tb::TerrainRuntime rt(terrain().db, {});
  const std::uint64_t W = std::uint64_t(hf.width());
  auto scan = [&](double col, double row) {
    const tb::DrawnMesh& m = rt.drawn_mesh();
    for (const auto& t : m.triangles) {
      double c[3], r[3], z[3];
      for (int k = 0; k < 3; ++k) {
        const std::uint64_t sm = m.samples[t[std::size_t(k)]];
        c[k] = double(sm % W), r[k] = double(sm / W), z[k] = m.positions[t[std::size_t(k)]].z;
      }
      const double det = (c[1] - c[0]) * (r[2] - r[0]) - (r[1] - r[0]) * (c[2] - c[0]);
      if (det == 0) continue;
      const double l1 = ((col - c[0]) * (r[2] - r[0]) - (row - r[0]) * (c[2] - c[0])) / det;
      const double l2 = ((c[1] - c[0]) * (row - r[0]) - (r[1] - r[0]) * (col - c[0])) / det;
      if (l1 >= -1e-9 && l2 >= -1e-9 && 1 - l1 - l2 >= -1e-9)
        return (1 - l1 - l2) * z[0] + l1 * z[1] + l2 * z[2];
    }
    return std::numeric_limits<double>::quiet_NaN();
  };
  std::mt19937_64 rng(5);
  for (const auto& [col, row, yaw] : {std::array{200.0, 300.0, 30.0}, std::array{60.0, 80.0, 200.0}}) {
    tp::Camera cam = pose(hf, col, row, 400.0, yaw, -20);
    rt.fit_camera(cam);
    rt.update_until_loaded(tp::View(cam), 0.0);
    std::uniform_real_distribution<double> uc(0, hf.width() - 1), ur(0, hf.height() - 1);
    int drawn = 0;
    for (int k = 0; k < 3000; ++k) {
      const double c = uc(rng), r = ur(rng);
      const auto [x, y] = hf.transform.to_world(c, r);
      const double want = scan(c, r), got = rt.drawn_height(x, y);
      if (std::isnan(want)) continue;  // on an edge the scan and the grid may disagree on NaN only
      ++drawn;
      ASSERT_NEAR(got, want, 1e-6) << "at sample (" << c << ", " << r << ")";
    }
    EXPECT_GT(drawn, 1000);
    const tb::DrawnMesh& m = rt.drawn_mesh();
    for (std::size_t v = 0; v < m.positions.size(); v += 7)
      EXPECT_NEAR(rt.drawn_height(m.positions[v].x, m.positions[v].y), m.positions[v].z, 1e-6);
  }
  const auto [x0, y0] = hf.transform.to_world(-5.0, -5.0);
  EXPECT_TRUE(std::isnan(rt.drawn_height(x0, y0)));
}

// terrain_height: the samples of the resident block under the point, whatever is drawn; NaN
// before anything is resident and outside the terrain.
TEST(TerrainRuntime, TerrainHeightIsTheResidentBlocksSamples) {
  const tp::Heightfield& hf = terrain().hf;
  tb::TerrainRuntime rt(terrain().db, {});
  const auto [xm, ym] = hf.transform.to_world(200.0, 300.0);
  EXPECT_TRUE(std::isnan(rt.terrain_height(xm, ym))) << "nothing is resident yet";
  tp::Camera cam = pose(hf, 200.0, 300.0, 400.0, 30.0, -20);
  rt.fit_camera(cam);
  rt.update_until_loaded(tp::View(cam), 0.0);
  EXPECT_EQ(rt.terrain_height(xm, ym), hf.at(200, 300)) << "under the eye";
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> uc(0, hf.width() - 1), ur(0, hf.height() - 1);
  int known = 0;
  for (int k = 0; k < 3000; ++k) {
    const double c = uc(rng), r = ur(rng);
    const auto [x, y] = hf.transform.to_world(c, r);
    const double got = rt.terrain_height(x, y);
    if (std::isnan(got)) continue;
    ++known;
    ASSERT_NEAR(got, tp::bilinear_height(hf, x, y), 1e-9) << "at sample (" << c << ", " << r << ")";
    const int ci = int(std::lround(c)), ri = int(std::lround(r));
    const auto [xs, ys] = hf.transform.to_world(ci, ri);
    const double at_sample = rt.terrain_height(xs, ys);
    if (!std::isnan(at_sample)) {
      ASSERT_EQ(at_sample, hf.at(ci, ri)) << ci << ", " << ri;
    }
  }
  EXPECT_GT(known, 300);
  const auto [x0, y0] = hf.transform.to_world(-5.0, -5.0);
  EXPECT_TRUE(std::isnan(rt.terrain_height(x0, y0)));
}

TEST(TerrainRuntime, BadOptionsAndBadDatabaseAreErrors) {
  tb::RuntimeOptions o;
  o.tolerance_px = 0;
  EXPECT_THROW(tb::TerrainRuntime(terrain().db, o), std::invalid_argument);
  o = {};
  o.morph_seconds = -1;
  EXPECT_THROW(tb::TerrainRuntime(terrain().db, o), std::invalid_argument);
  o = {};
  o.loader_threads = 0;
  EXPECT_THROW(tb::TerrainRuntime(terrain().db, o), std::invalid_argument);
  o = {};
  o.partial_load_factor = 0.5;
  EXPECT_THROW(tb::TerrainRuntime(terrain().db, o), std::invalid_argument);
  {
    tb::TerrainRuntime rt(terrain().db);
    o = {};
    o.loader_threads = 3;  // the threads started when it opened
    EXPECT_THROW(rt.set_options(o), std::invalid_argument);
  }
  // A budget that the tree and the summaries alone pass: no block could ever be resident, and
  // resident_bytes <= budget_bytes would be false from the first frame. Refused, naming both.
  {
    tb::TerrainRuntime rt(terrain().db);
    const std::size_t fixed = rt.stats().resident_bytes;  // before a frame: nothing but them
    ASSERT_GT(fixed, 0u);
    o = {};
    o.budget_bytes = fixed;
    EXPECT_NO_THROW(tb::TerrainRuntime(terrain().db, o));
    o.budget_bytes = fixed - 1;
    try {
      tb::TerrainRuntime small(terrain().db, o);
      FAIL() << "opened with a budget of " << o.budget_bytes << " bytes, under its " << fixed
             << " fixed bytes";
    } catch (const tb::DatabaseError& e) {
      EXPECT_NE(std::string(e.what()).find("tree and block summaries need"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(terrain().db), std::string::npos) << e.what();
    }
  }
  const std::string missing = std::string(TERRALOD_TEST_TMP) + "/no_such_runtime.db";
  try {
    tb::TerrainRuntime rt(missing);
    FAIL() << "opened a missing database";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_runtime.db"), std::string::npos) << e.what();
  }
  tb::TerrainRuntime rt(terrain().db);
  tp::Camera cam;
  rt.fit_camera(cam);
  rt.update(tp::View(cam), 1.0);
  EXPECT_THROW(rt.update(tp::View(cam), 0.5), std::invalid_argument);
}

// Flight-path prefetch in the runtime: blocks read with a latency of 6 frames (the in-memory
// source of tests/support/block_fixture.hpp over the database's own blobs), 600 m/s; after the cold start,
// prediction must remove most of the blocks needed before they arrived.
namespace {

struct PrefetchTerrain {
  Terrain ter;
  terralod::test::BlockedTerrain blobs;  // the database's blocks, for the in-memory source
};

// The blobs of a database, for the in-memory source.
terralod::test::BlockedTerrain blobs_of(const std::string& db_path) {
  terralod::test::BlockedTerrain b;
  const tb::BlockDatabase db = tb::BlockDatabase::open(db_path);
  b.grid = tb::BlockGrid::from_info(db.info());
  for (tb::BlockKey k : db.blocks()) b.blobs[k] = db.read_block(k);
  return b;
}

const PrefetchTerrain& prefetch_terrain() {
  static const PrefetchTerrain t = [] {
    PrefetchTerrain r;
    r.ter.hf = generated(385, 385, /*seed=*/21, /*relief=*/200.0);
    r.ter.db = tt::shared_file("runtime_prefetch.db", [&](const std::filesystem::path& p) {
                 tb::DatabaseBuildOptions o;
                 o.block_size = 33;  // 12 x 12 blocks of 960 m
                 o.threads = 2;
                 tb::build_database(r.ter.hf, p.string(), o);
               }).string();
    r.blobs = blobs_of(r.ter.db);
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
    rt.fit_camera(cam);
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
  std::printf(
      "runtime, %s (%zu frames, after the first 90): prefetch misses with prediction %zu of %zu blocks "
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

// Loading: what the runtime must do whatever its source does. A stalled reader never blocks a
// frame, a loader error is rethrown by update() naming the source and the block, blocks evicted
// under a smaller budget come back and draw the same mesh, and every frame of flights whose
// reads take a few frames (blocks arriving and blending while the camera moves) is watertight,
// covers the view and stays within its bound, on generated terrain, with TIN, grid and
// non-regular-grid stand-ins, and on a crop of N44W072.
namespace {

// A camera over the prefetch terrain at (col, row), `above` metres over the ground, looking
// north-east and down.
tp::Camera loading_pose(double col, double row, double above, double yaw = 45, double pitch = -30) {
  return pose(prefetch_terrain().ter.hf, col, row, above, yaw, pitch);
}

// A drawn mesh without its vertex order: per triangle (its node, its samples from the smallest,
// in order, and their displayed heights), sorted.
std::vector<std::pair<std::int64_t, std::array<std::pair<std::uint64_t, double>, 3>>> canonical(
    const tb::DrawnMesh& m) {
  std::vector<std::pair<std::int64_t, std::array<std::pair<std::uint64_t, double>, 3>>> out;
  for (std::size_t i = 0; i < m.triangles.size(); ++i) {
    std::array<std::pair<std::uint64_t, double>, 3> t;
    for (int k = 0; k < 3; ++k) t[k] = {m.samples[m.triangles[i][k]], m.positions[m.triangles[i][k]].z};
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    out.push_back({m.triangle_node[i], t});
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Checks one frame with the independent checker: error within the bound, the view covered,
// watertight. Returns false (after a failure) when it does not hold.
bool frame_holds(const tp::Heightfield& hf, const tb::TerrainRuntime& rt, const tp::Camera& cam,
                 const std::string& where) {
  const tb::RuntimeFrameStats& s = rt.stats();
  const tt::FrameCheck c = tt::check_drawn_frame(hf, frame_of(rt.drawn_mesh()), cam);
  const bool ok =
      c.max_error_px <= s.bound_px * (1 + 1e-9) + 1e-9 && c.uncovered_in_view == 0 && c.watertight();
  EXPECT_TRUE(ok) << where << " (" << s.pm_blocks << " PM blocks, " << s.standin_blocks << " stand-ins, "
                  << s.missing_in_view << " missing, " << s.moving_vertices << " moving vertices): bound "
                  << s.bound_px << " px; " << c.describe();
  return ok;
}

}  // namespace

TEST(TerrainRuntimeLoading, StalledReaderNeverBlocksAFrame) {
  // Every read waits until the test lets it go: frames go on with what is resident (the tree
  // and the stand-ins) and report the blocks they miss; then the blocks arrive and are drawn.
  const PrefetchTerrain& pt = prefetch_terrain();
  terralod::test::MemoryStore store;
  store.terrain = &pt.blobs;
  store.set_stalled(true);
  tb::RuntimeOptions o;
  o.tolerance_px = 1.0;
  o.morph_seconds = 0.25;
  tb::TerrainRuntime rt(pt.ter.db, o, terralod::test::memory_source(store));
  const terralod::test::ReleaseAtExit release{store};
  tp::Camera cam = loading_pose(190, 190, 300);
  rt.fit_camera(cam);
  int frame = 0;
  for (; frame < 30; ++frame) {
    const auto t0 = std::chrono::steady_clock::now();
    const tb::RuntimeFrameStats& s = rt.update(tp::View(cam), frame / 60.0);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_LT(ms, 2000.0);  // returns although the reader is stalled (a hang would time out)
    EXPECT_EQ(s.blocks_resident, 0u);
    EXPECT_EQ(s.pm_blocks, 0u);
    EXPECT_GT(s.missing_in_view, 0u);
    EXPECT_GT(s.blocks_loading, 0u);
    if (!frame_holds(pt.ter.hf, rt, cam, "stalled frame " + std::to_string(frame))) break;
  }
  // The reader really is stuck inside a read (on a loaded machine the loader thread may only
  // now reach it: wait for it, bounded, rather than race the 30 frames).
  for (int i = 0; i < 1000 && !store.reading.load(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_TRUE(store.reading.load());
  store.set_stalled(false);
  for (; frame < 5000; ++frame) {
    const tb::RuntimeFrameStats& s = rt.update(tp::View(cam), frame / 60.0);
    if (s.missing_in_view == 0 && s.morphing_blocks == 0 && !rt.loading()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const tb::RuntimeFrameStats& s = rt.stats();
  std::printf(
      "stalled reader: 30 frames drawn without a block; %d frames until %zu PM blocks were drawn, %zu bytes "
      "read\n",
      frame, s.pm_blocks, std::size_t(s.bytes_read_total));
  EXPECT_EQ(s.missing_in_view, 0u);
  EXPECT_GT(s.pm_blocks, 0u);
  EXPECT_GT(s.bytes_read_total, 0u);
  EXPECT_LE(s.bound_px, o.tolerance_px);
  frame_holds(pt.ter.hf, rt, cam, "after the stall");
}

TEST(TerrainRuntimeLoading, LoaderErrorsAreRethrownByUpdate) {
  // The block under a low camera is missing from the source: update() rethrows the loader's
  // error, which names the source and the block.
  const PrefetchTerrain& pt = prefetch_terrain();
  terralod::test::BlockedTerrain t = pt.blobs;
  tp::Camera cam = loading_pose(190, 190, 150, 45, -60);
  const tb::BlockKey k = t.grid.block_at(cam.x, cam.y);
  ASSERT_EQ(t.blobs.erase(k), 1u);
  terralod::test::MemoryStore store;
  store.terrain = &t;
  tb::TerrainRuntime rt(pt.ter.db, {}, terralod::test::memory_source(store));
  rt.fit_camera(cam);
  const std::string expect =
      "memory: block (" + std::to_string(k.col) + "," + std::to_string(k.row) + "): not in the database";
  try {
    for (int f = 0; f < 20000; ++f) {
      rt.update(tp::View(cam), f / 60.0);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), expect);
  }
}

TEST(TerrainRuntimeLoading, EvictedBlocksComeBackAndDrawTheSameMesh) {
  // Settled at home, the budget is cut to what home needs: flying away evicts home's blocks,
  // and coming back reads them again and draws the same triangles at the same heights as before
  // (no geomorphs, so the drawn mesh is the selection's).
  const PrefetchTerrain& pt = prefetch_terrain();
  tb::RuntimeOptions o;
  o.tolerance_px = 1.0;
  o.morph_seconds = 0;
  o.prefetch = false;
  tb::TerrainRuntime rt(pt.ter.db, o);
  double t = 0;
  auto settle = [&](tp::Camera cam, const char* where) {
    rt.fit_camera(cam);
    for (int i = 0; i < 5000; ++i, t += 1.0 / 60) {
      const tb::RuntimeFrameStats& s = rt.update(tp::View(cam), t);
      if (s.missing_in_view == 0 && !rt.loading()) break;
      rt.wait_for_loader(0.02);
    }
    for (int i = 0; i < 3; ++i, t += 1.0 / 60) rt.update(tp::View(cam), t);  // the selection at rest
    EXPECT_EQ(rt.stats().missing_in_view, 0u) << where;
    frame_holds(pt.ter.hf, rt, cam, where);
  };
  const tp::Camera home = loading_pose(90, 90, 300), away = loading_pose(300, 300, 300);
  settle(home, "home");
  const tb::DrawnMesh before = rt.drawn_mesh();
  const std::uint64_t read_home = rt.stats().bytes_read_total;
  o.budget_bytes = rt.stats().resident_bytes + rt.stats().resident_bytes / 10;
  rt.set_options(o);
  settle(away, "away");
  EXPECT_GT(rt.stats().evicted_total, 0u) << "the smaller budget should evict home's blocks";
  EXPECT_LE(rt.stats().resident_bytes, o.budget_bytes);
  const std::uint64_t read_away = rt.stats().bytes_read_total;
  settle(home, "home again");
  const tb::DrawnMesh& after = rt.drawn_mesh();
  std::printf(
      "evicted %zu blocks; %zu bytes read at home, %zu away, %zu coming back; %zu triangles at home\n",
      rt.stats().evicted_total, std::size_t(read_home), std::size_t(read_away - read_home),
      std::size_t(rt.stats().bytes_read_total - read_away), before.triangles.size());
  EXPECT_GT(rt.stats().bytes_read_total, read_away) << "home's blocks should have been read again";
  // The same triangles of the same nodes with the same heights (vertex order is not fixed).
  EXPECT_EQ(canonical(after), canonical(before));
}

namespace {

struct LoadingCounts {
  std::size_t frames = 0, missing = 0, moving = 0, with_pm = 0, standins_with_pm = 0;
};

// Flies `path` over the database `db` (blocks read from `blobs` with `latency` frames per read),
// checking every frame with the independent checker. Stops at the first failing frame.
LoadingCounts fly_while_loading(const std::string& db, const tp::Heightfield& hf,
                                const terralod::test::BlockedTerrain& blobs,
                                const std::vector<tp::Camera>& path, double tau, std::uint64_t latency,
                                const std::string& label) {
  terralod::test::MemoryStore store;
  store.terrain = &blobs;
  store.latency_frames = latency;
  tb::RuntimeOptions o;
  o.tolerance_px = tau;
  o.morph_seconds = 0.3;
  tb::TerrainRuntime rt(db, o, terralod::test::memory_source(store));
  const terralod::test::ReleaseAtExit release{store};
  LoadingCounts n;
  for (std::size_t f = 0; f < path.size(); ++f) {
    tp::Camera cam = path[f];
    rt.fit_camera(cam);
    const tb::RuntimeFrameStats& s = rt.update(tp::View(cam), double(f) / 60.0);
    store.advance_frame();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));  // the loader gets the processor too
    ++n.frames;
    n.missing += s.missing_in_view > 0;
    n.moving += s.moving_vertices > 0;
    n.with_pm += s.pm_blocks > 0;
    n.standins_with_pm += s.pm_blocks > 0 && s.standin_blocks > 0;
    if (!frame_holds(hf, rt, cam, label + " frame " + std::to_string(f))) break;
  }
  std::printf(
      "%s: %zu frames checked, %zu with blocks missing, %zu with moving vertices, %zu with PM blocks, %zu "
      "with stand-ins and PM blocks\n",
      label.c_str(), n.frames, n.missing, n.moving, n.with_pm, n.standins_with_pm);
  return n;
}

// A random low flight (constant speed, random turns, height above ground drifting between 150
// and 700 m, looking ahead and down).
std::vector<tp::Camera> random_flight(const tp::Heightfield& hf, std::mt19937_64& rng, int frames) {
  std::uniform_real_distribution<double> u(0, 1);
  const double w = (hf.width() - 1) * hf.transform.spacing_x(),
               h = (hf.height() - 1) * hf.transform.spacing_y();
  const auto [x0, y0] = hf.transform.to_world(0, hf.height() - 1);  // south-west corner
  double x = x0 + w * (0.2 + 0.6 * u(rng)), y = y0 + h * (0.2 + 0.6 * u(rng)),
         heading = 2 * std::numbers::pi * u(rng);
  double above = 150 + 550 * u(rng), turn = 0;
  const double speed = 150 + 250 * u(rng);
  std::vector<tp::Camera> path;
  for (int f = 0; f < frames; ++f) {
    if (f % 30 == 0) turn = (u(rng) - 0.5) * 1.2;
    heading += turn / 60;
    x += speed / 60 * std::sin(heading);
    y += speed / 60 * std::cos(heading);
    above = std::clamp(above + (u(rng) - 0.5) * 20, 150.0, 700.0);
    tp::Camera c;
    c.x = x;
    c.y = y;
    c.z = tt::ground_height(hf, x, y) + above;
    c.yaw_deg = heading * 180 / std::numbers::pi;
    c.pitch_deg = -20 - 15 * u(rng);
    path.push_back(c);
  }
  return path;
}

}  // namespace

TEST(TerrainRuntimeLoading, RandomFlightsWhileBlocksArriveAreWatertightAndWithinTheBound) {
  const std::uint64_t seed = 20251122;
  std::printf("seed %llu\n", static_cast<unsigned long long>(seed));
  std::mt19937_64 rng(seed);
  const PrefetchTerrain& pt = prefetch_terrain();
  LoadingCounts all;
  for (int flight = 0; flight < 3; ++flight) {
    const LoadingCounts n =
        fly_while_loading(pt.ter.db, pt.ter.hf, pt.blobs, random_flight(pt.ter.hf, rng, 90),
                          /*tau=*/2.0, /*latency=*/2, "random flight " + std::to_string(flight));
    all.missing += n.missing, all.moving += n.moving, all.with_pm += n.with_pm;
  }
  EXPECT_GT(all.missing, 0u);
  EXPECT_GT(all.moving, 0u);
  EXPECT_GT(all.with_pm, 0u);
}

TEST(TerrainRuntimeLoading, StandInsOfEveryKindBesidePmBlocksWhileBlocksArrive) {
  // One small database per stand-in kind (257 x 257 samples, 8 x 8 blocks of 33): along a
  // flight whose reads take 3 frames, stand-ins of that kind are drawn in the same frames as PM
  // blocks and blocks blending in; every frame is watertight and within its bound. (Two-triangle
  // stand-ins are left out: a block's two triangles never meet tau / 2 where its parent's
  // surface does not, so the runtime draws the parent instead.)
  for (const tb::StandinKind kind :
       {tb::StandinKind::Tin, tb::StandinKind::Grid, tb::StandinKind::NonRegularGrid}) {
    Terrain ter;
    ter.hf = generated(257, 257, /*seed=*/5, /*relief=*/400.0);
    ter.db = (tt::process_temp_dir("runtime") /
              (std::string("runtime_standin_") + tb::standin_kind_name(kind) + ".db"))
                 .string();
    tb::DatabaseBuildOptions o;
    o.block_size = 33;
    o.threads = 2;
    o.standin.kind = kind;
    o.standin.max_points = 32;
    tb::build_database(ter.hf, ter.db, o);
    const terralod::test::BlockedTerrain blobs = blobs_of(ter.db);
    const LoadingCounts n = fly_while_loading(
        ter.db, ter.hf, blobs, tt::scripted_flight(ter.hf, 120, 600.0, -25.0),
        /*tau=*/8.0, /*latency=*/3, std::string("stand-ins ") + tb::standin_kind_name(kind));
    EXPECT_GT(n.standins_with_pm, 0u) << tb::standin_kind_name(kind);
    EXPECT_GT(n.moving, 0u) << tb::standin_kind_name(kind);
  }
}

TEST(TerrainRuntimeLoading, ScriptedFlightOverN44W072WhileBlocksArrive) {
  std::optional<tp::Heightfield> hf = tt::read_hgt_crop("N44W072.hgt", 400, 400, 257);
  if (!hf) GTEST_SKIP() << "N44W072.hgt not in TERRALOD_DATA_DIR";
  Terrain ter;
  ter.hf = std::move(*hf);
  ter.db = (tt::process_temp_dir("runtime") / "runtime_n44w072.db").string();
  tb::DatabaseBuildOptions o;
  o.block_size = 33;
  o.threads = 2;
  tb::build_database(ter.hf, ter.db, o);
  const terralod::test::BlockedTerrain blobs = blobs_of(ter.db);
  const LoadingCounts n =
      fly_while_loading(ter.db, ter.hf, blobs, tt::scripted_flight(ter.hf, 120, 300.0, -20.0),
                        /*tau=*/1.0, /*latency=*/2, "N44W072 crop");
  EXPECT_GT(n.missing, 0u);
  EXPECT_GT(n.moving, 0u);
}
