// Block databases over terrains with holes (mask 0), as every geographic DEM read with
// DemOptions::crs = "auto" has at its warped edges: every block with a sample has a stand-in
// whose error is measured over its existing samples, a block without any sample has neither a
// stand-in nor a PM, and a TerrainRuntime flight over it draws within its bound, covers every
// existing sample in view and never waits for the empty block.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "drawn_frame_checker.hpp"
#include "run_command.hpp"
#include "screen_error_checker.hpp"
#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace tb = terralod::blocks;
namespace tp = terralod::pm;
namespace tt = terralod::test;

namespace {

constexpr int kSize = 257, kBlock = 65;  // 4 x 4 blocks of 65 samples

// A generated 257 x 257 terrain (30 m spacing) with three kinds of holes: a wedge over the
// south-west corner (col + row < 90: block (0,0) loses its corner and part of two edges), a
// strip along the north edge (rows 0..6, cols 100..180: blocks (1,0) and (2,0)), and the whole
// of block (3,3) with its borders (cols and rows 192..256).
tp::Heightfield holed_terrain() {
  tp::TerrainOptions to;
  to.width = kSize;
  to.height = kSize;
  to.seed = 23;
  to.spacing = 30.0;
  to.relief = 900.0;
  to.quantize_to_metres = true;
  tp::Heightfield hf = tp::generate_terrain(to);
  std::vector<std::uint8_t> mask(hf.size(), 1);
  for (int r = 0; r < kSize; ++r)
    for (int c = 0; c < kSize; ++c) {
      const bool wedge = c + (kSize - 1 - r) < 90;  // row kSize-1 is the south edge
      const bool strip = r <= 6 && c >= 100 && c <= 180;
      const bool block = c >= 192 && r >= 192;
      if (wedge || strip || block) mask[std::size_t(r) * kSize + c] = 0;
    }
  hf.set_mask(std::move(mask));
  return hf;
}

struct Holed {
  tp::Heightfield hf;
  std::string db;
};

const Holed& holed() {
  static const Holed h = [] {
    Holed r{holed_terrain(), ""};
    r.db = tt::shared_file("holes_257.db", [&](const std::filesystem::path& p) {
             tb::DatabaseBuildOptions o;
             o.block_size = kBlock;
             o.threads = 2;
             o.tree.levels = {tb::StrategyChoice::Grid, tb::StrategyChoice::Tin};
             tb::build_database(r.hf, p.string(), o);
           }).string();
    return r;
  }();
  return h;
}

tt::DrawnFrame frame_of(const tb::DrawnMesh& m) {
  tt::DrawnFrame f;
  f.samples = m.samples;
  for (const tp::Vec3& p : m.positions) f.z.push_back(p.z);
  f.triangles = m.triangles;
  return f;
}

}  // namespace

TEST(TerrainHoles, EveryBlockWithSamplesHasAStandInTheEmptyOneNone) {
  const Holed& h = holed();
  const tb::BlockDatabase db = tb::BlockDatabase::open(h.db);
  ASSERT_TRUE(db.read_blob(tb::kBlockSummariesBlob)) << "no stand-ins: a block with holes stopped them";
  const tb::BlockGrid grid = tb::BlockGrid::from_info(db.info());
  const std::vector<tb::BlockSummary> sums = tb::read_block_summaries(db, grid);
  ASSERT_EQ(sums.size(), 16u);
  for (std::size_t i = 0; i < sums.size(); ++i) {
    const tb::BlockKey k = grid.key(i);
    const tb::SampleRect d = grid.domain(k);
    bool any = false;
    double zlo = 1e300, zhi = -1e300;
    for (int r = d.row0; r <= d.row1; ++r)
      for (int c = d.col0; c <= d.col1; ++c)
        if (h.hf.valid(c, r))
          any = true, zlo = std::min(zlo, h.hf.at(c, r)), zhi = std::max(zhi, h.hf.at(c, r));
    const std::string name = "block (" + std::to_string(k.col) + "," + std::to_string(k.row) + ")";
    if (!any) {
      EXPECT_TRUE(sums[i].points.empty() && sums[i].triangles.empty()) << name << " has no sample";
      // Its PM (kept so that every block of the grid has one) has no vertex: nothing to draw.
      const tp::ProgressiveMesh pm = tp::decode_pm(db.read_block(k), name);
      EXPECT_EQ(pm.full_vertex_count(), 0u) << name << " has no sample";
      continue;
    }
    ASSERT_GE(sums[i].triangles.size(), 1u) << name;
    // The range holds the existing samples and the stand-in's points (a corner may be a hole).
    for (const tb::StandinPoint& p : sums[i].points) zlo = std::min(zlo, p.z), zhi = std::max(zhi, p.z);
    EXPECT_EQ(sums[i].zmin, zlo) << name;
    EXPECT_EQ(sums[i].zmax, zhi) << name;
    // The stand-in's error, at every existing sample, against the independent plane of its
    // triangle: within standin_error.
    double worst = 0;
    for (const auto& t : sums[i].triangles) {
      const tb::StandinPoint &a = sums[i].points[t[0]], &b = sums[i].points[t[1]], &c = sums[i].points[t[2]];
      const double det = double(b.col - a.col) * (c.row - a.row) - double(c.col - a.col) * (b.row - a.row);
      for (int r = std::min({a.row, b.row, c.row}); r <= std::max({a.row, b.row, c.row}); ++r)
        for (int col = std::min({a.col, b.col, c.col}); col <= std::max({a.col, b.col, c.col}); ++col) {
          const double u = (double(b.col - col) * (c.row - r) - double(c.col - col) * (b.row - r)) / det;
          const double v = (double(c.col - col) * (a.row - r) - double(a.col - col) * (c.row - r)) / det;
          const double w = 1 - u - v;
          if (u < -1e-12 || v < -1e-12 || w < -1e-12) continue;
          if (!h.hf.valid(d.col0 + col, d.row0 + r)) continue;
          worst = std::max(worst, std::abs(u * a.z + v * b.z + w * c.z - h.hf.at(d.col0 + col, d.row0 + r)));
        }
    }
    EXPECT_LE(worst, sums[i].standin_error + 1e-9) << name;
  }
}

TEST(TerrainHoles, FlightDrawsWithinTheBoundAndCoversEveryExistingSample) {
  const Holed& h = holed();
  for (double tau : {1.0, 8.0}) {
    tb::RuntimeOptions o;
    o.tolerance_px = tau;
    o.morph_seconds = 0;
    tb::TerrainRuntime rt(h.db, o);
    std::vector<tp::Camera> path = tt::scripted_flight(h.hf, 60, 150.0, -15.0);
    // High views over the holes: the whole terrain in view, drawn from stand-ins and coarse nodes.
    for (int f = 0; f < 12; ++f) {
      tp::Camera c = path.front();
      const auto [x, y] = h.hf.transform.to_world(40 + 15 * f, 200 - 10 * f);
      c.x = x, c.y = y, c.z = 3000.0 + 2000.0 * f, c.yaw_deg = 30.0 * f, c.pitch_deg = -60;
      path.push_back(c);
    }
    std::size_t standins = 0, complete = 0;
    for (std::size_t f = 0; f < path.size(); ++f) {
      tp::Camera cam = path[f];
      rt.fit_camera(cam);
      const tb::RuntimeFrameStats* s = &rt.update(tp::View(cam), double(f) / 60.0);
      for (int i = 0; i < 400 && s->missing_in_view > 0 && rt.loading(); ++i) {
        rt.wait_for_loader(0.05);
        s = &rt.update(tp::View(cam), double(f) / 60.0);
      }
      EXPECT_EQ(s->missing_in_view, 0u) << "frame " << f << ": a block is missing after the loader finished";
      if (s->missing_in_view == 0) {
        ++complete;
        EXPECT_LE(s->bound_px, tau) << "frame " << f;
      }
      standins += s->standin_blocks;
      const tt::FrameCheck c = tt::check_drawn_frame(h.hf, frame_of(rt.drawn_mesh()), cam);
      EXPECT_LE(c.max_error_px, s->bound_px * (1 + 1e-9) + 1e-9) << "frame " << f << ": " << c.describe();
      EXPECT_EQ(c.uncovered_in_view, 0u) << "frame " << f << ": " << c.describe();
      EXPECT_TRUE(c.watertight()) << "frame " << f << ": " << c.describe();
    }
    std::printf("tau %.0f: %zu frames, %zu complete, %zu stand-ins drawn\n", tau, path.size(), complete,
                standins);
    EXPECT_GT(standins, 0u) << "the high views should draw stand-ins";
  }
}
