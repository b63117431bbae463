// Tests of the hybrid grid + TIN model: the encoding reproduces the paper's cavity connectivity
// (Fig. 6), decoded triangles equal the direct convexification at every level, every extracted
// mesh (both schemes, uniform and mixed levels) covers the domain exactly once and is watertight
// with consistent heights, degenerate inputs give valid meshes or clear errors, and the blob
// round-trips and rejects corruption.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <fstream>
#include <map>
#include <random>
#include <set>

#include "plane_cover_check.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/greedy_tin.hpp"
#include "terralod/blocks/hybrid/hybrid_terrain.hpp"
#include "tin_fixture.hpp"

namespace hy = terralod::blocks::hybrid;
namespace pm = terralod::pm;
namespace tt = terralod::test;

namespace {

double orient(const std::array<double, 3>& a, const std::array<double, 3>& b,
              const std::array<double, 3>& c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/// Heights (TIN vertices keep their TIN height, grid nodes that are no TIN vertex keep the DEM
/// height), then check_plane_cover: exact single cover of [0,W]x[0,H], watertight.
std::string check_cover(const hy::HybridMesh& m, double W, double H, const pm::Heightfield& hf, int step,
                        const hy::TinMesh& tin) {
  std::map<std::pair<double, double>, std::uint32_t> at;
  for (std::uint32_t v = 0; v < m.points.size(); ++v)
    if (!at.emplace(std::make_pair(m.points[v][0], m.points[v][1]), v).second)
      return "two vertices at (" + std::to_string(m.points[v][0]) + "," + std::to_string(m.points[v][1]) +
             ")";
  std::set<std::pair<double, double>> tin_pos;
  for (const auto& p : tin.points) {
    tin_pos.insert({p[0], p[1]});
    auto it = at.find({p[0], p[1]});
    if (it != at.end() && m.points[it->second][2] != p[2]) return "TIN vertex height changed";
  }
  for (const auto& p : m.points) {
    const double c = p[0] / step, r = p[1] / step;
    if (c == std::floor(c) && r == std::floor(r) && !tin_pos.count({p[0], p[1]}) &&
        p[2] != hf.at(int(p[0]), int(p[1])) && std::abs(p[2] - tt::tin_height(p[0], p[1])) > 1e-9)
      return "grid node (" + std::to_string(p[0]) + "," + std::to_string(p[1]) +
             ") has neither the DEM nor the TIN height";
  }
  return tt::check_plane_cover(m.points, m.triangles, W, H);
}

/// Every level: decoded == direct (triangle for triangle); both schemes and a mixed-level
/// checkerboard cover the domain exactly once.
void check_model(const hy::HybridTerrain& h, const pm::Heightfield& hf, const hy::TinMesh& tin) {
  const double W = h.domain_width(), H = h.domain_height();
  for (int l = 0; l < h.levels(); ++l) {
    const auto& enc = h.level(l);
    for (const auto& pc : enc.vc) {
      auto canon = [](std::vector<std::array<std::uint32_t, 3>> v) {
        for (auto& t : v) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
        std::sort(v.begin(), v.end());
        return v;
      };
      EXPECT_EQ(canon(h.decoded_fill(l, pc.cell)), canon(h.direct_fill(l, pc.cell)))
          << "level " << l << " cell " << pc.cell;
    }
    for (hy::Scheme s : {hy::Scheme::Triangles, hy::Scheme::SubCells}) {
      const auto m = h.extract(l, s);
      EXPECT_EQ(check_cover(m, W, H, hf, h.grid_step(), tin), "") << "level " << l << " scheme " << int(s);
      // Each T-junction split replaces one triangle by at least two.
      const std::size_t parts =
          m.grid_triangles + m.tin_triangles + m.convexification_triangles + m.corner_triangles;
      EXPECT_GE(m.triangles.size(), parts + m.split_edges);
    }
  }
  const auto& top = h.level(h.levels() - 1);
  for (int phase = 0; phase < 2; ++phase) {
    std::vector<int> lv(std::size_t(top.cells_x) * top.cells_y);
    for (int j = 0; j < top.cells_y; ++j)
      for (int i = 0; i < top.cells_x; ++i)
        lv[std::size_t(j) * top.cells_x + i] = ((i + j + phase) % 2) ? 0 : h.levels() - 1;
    for (hy::Scheme s : {hy::Scheme::Triangles, hy::Scheme::SubCells})
      EXPECT_EQ(check_cover(h.extract_mixed(lv, s), W, H, hf, h.grid_step(), tin), "")
          << "mixed phase " << phase;
  }
}

// The TIN of the Fig. 6 test: a rectangle [2,14]x[6,14] whose top edge (row 6) has a U-shaped
// notch inside finest cell (1,1) = [4,8]x[4,8] (grid step 4):
//
//   row 6:  (2,6) ... (4,6)* (5,6)=v20              v25=(7,6) (8,6)* ... (14,6)
//                            \ v21 (5.25,6.75)  v24 (6.75,6.75) /
//                              v22 (5.75,7.5) v23 (6.25,7.5)
//   (* = intersection vertices with the cell border). The notch is a cavity fanned from v20.
std::vector<std::array<double, 2>> notch_polygon() {
  return {{2, 6},       {5, 6}, {5.25, 6.75}, {5.75, 7.5}, {6.25, 7.5},
          {6.75, 6.75}, {7, 6}, {14, 6},      {14, 14},    {2, 14}};
}

}  // namespace

TEST(HybridTerrain, Fig6CavityConnectivity) {
  const auto hf = tt::bumpy_grid(17, 17);
  const auto tin = tt::fan_tin(notch_polygon(), {6, 10});
  const auto h = hy::HybridTerrain::build(hf, tin, {.grid_step = 4, .levels = 2});
  // Find v20 = (5,6) in the TB array.
  std::int64_t t20 = -1;
  for (std::uint32_t t = 0; t < h.tb().size(); ++t)
    if (h.tb_point(t) == hy::PlanPoint{5, 6}) t20 = t;
  ASSERT_GE(t20, 0);
  // TB = {20(5), 21(1), 22(1), 23(1), 24(1), 25(-)}.
  std::vector<std::uint32_t> conn;
  for (std::uint32_t k = 0; k < 5; ++k) conn.push_back(h.connectivity()[std::size_t(t20 + k)]);
  EXPECT_EQ(conn, (std::vector<std::uint32_t>{5, 1, 1, 1, 1}));
  EXPECT_EQ(h.tb_point(std::uint32_t(t20 + 5)), (hy::PlanPoint{7, 6}));
  // Triangles {20,21,22}, {20,22,23}, {20,23,24}, {20,24,25} in finest cell (1,1).
  const std::uint32_t cell = 1 * std::uint32_t(h.level(0).cells_x) + 1;
  auto fill = h.decoded_fill(0, cell);
  std::set<std::set<std::uint32_t>> got, want;
  for (auto& t : fill) got.insert({t[0], t[1], t[2]});
  const std::uint32_t b = std::uint32_t(t20);
  for (std::uint32_t k = 1; k <= 4; ++k) want.insert({b, b + k, b + k + 1});
  EXPECT_EQ(got, want);
  // Grid classification of level 0 row 1 (cells (0..3,1)): the notch row is PC everywhere
  // except none; cells of rows 2 (rows 8..12) are CC inside the rectangle.
  EXPECT_EQ(h.level(0).gc[1 * 4 + 1], hy::CellClass::PC);
  EXPECT_EQ(h.level(0).gc[2 * 4 + 1], hy::CellClass::CC);
  EXPECT_EQ(h.level(0).gc[0], hy::CellClass::NC);
  check_model(h, hf, tin);
}

TEST(HybridTerrain, RandomStarTinsAllLevels) {
  // Smooth random star-shaped TINs (radius = sum of three random sinusoids) on a 65 x 65 grid,
  // grid step 4, three levels (cells of 4, 8 and 16 samples).
  const auto hf = tt::bumpy_grid(65, 65);
  int built = 0;
  for (unsigned seed : {1u, 2u, 3u, 4u, 5u, 6u, 7u, 8u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::printf("random star TIN, seed %u\n", seed);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> amp(0.0, 3.0), phase(0.0, 2 * M_PI);
    const double a1 = amp(rng), a2 = amp(rng), a3 = amp(rng) / 2, p1 = phase(rng), p2 = phase(rng),
                 p3 = phase(rng);
    std::vector<std::array<double, 2>> poly;
    const int n = 60;
    for (int i = 0; i < n; ++i) {
      const double a = 2 * M_PI * i / n;
      const double r = 17 + a1 * std::sin(2 * a + p1) + a2 * std::sin(3 * a + p2) + a3 * std::sin(5 * a + p3);
      poly.push_back(
          {std::round((32.3 + r * std::cos(a)) * 16) / 16, std::round((31.7 + r * std::sin(a)) * 16) / 16});
    }
    const auto tin = tt::fan_tin(poly, {32.3, 31.7});
    try {
      const auto h = hy::HybridTerrain::build(hf, tin, {.grid_step = 4, .levels = 3});
      ++built;
      check_model(h, hf, tin);
    } catch (const hy::HybridError& e) {
      // Only the documented unsupported configurations may be refused, with a clear message.
      const std::string what = e.what();
      EXPECT_NE(what.find("test TIN: level"), std::string::npos) << what;
      std::printf("  refused: %s\n", what.c_str());
    }
  }
  EXPECT_GE(built, 6);
}

TEST(HybridTerrain, BoundaryThroughGridCornersAndCoveredCells) {
  // A TIN whose vertices lie on grid lines: its boundary runs along cell borders and passes
  // through grid corners; it covers whole cells (CC) at every level.
  const auto hf = tt::bumpy_grid(33, 33);
  const auto tin = tt::grid_tin(4, 4, 8, 8, 2);  // [4,20] x [4,20]
  const auto h = hy::HybridTerrain::build(hf, tin, {.grid_step = 4, .levels = 3});
  EXPECT_EQ(h.level(0).gc[2 * 8 + 2], hy::CellClass::CC);  // [8,12]^2
  EXPECT_EQ(h.level(0).gc[1 * 8 + 1], hy::CellClass::CC);  // [4,8]^2: covered, corners on the boundary
  EXPECT_EQ(h.level(0).gc[0], hy::CellClass::NC);
  check_model(h, hf, tin);
}

TEST(HybridTerrain, TouchingCellBordersAtOnePoint) {
  // A diamond whose top vertex (10,8) and bottom vertex (10,12) lie on grid lines (step 4):
  //            (10,8)
  //   (7,10)          (13,10)
  //            (10,12)
  const auto hf = tt::bumpy_grid(33, 33);
  const auto diamond = tt::fan_tin({{10, 8}, {13, 10}, {10, 12}, {7, 10}}, {10, 10});
  const auto h = hy::HybridTerrain::build(hf, diamond, {.grid_step = 4, .levels = 2});
  // The cell above the top vertex only touches the TIN: no TIN inside, hence NC, and the
  // extraction splits its bottom edge at the TIN vertex.
  EXPECT_EQ(h.level(0).gc[1 * 8 + 2], hy::CellClass::NC);  // [8,12] x [4,8]
  EXPECT_EQ(h.level(0).gc[2 * 8 + 2], hy::CellClass::PC);
  check_model(h, hf, diamond);
  // An uncovered notch whose tip touches a grid line from the uncovered side.
  const auto notch = tt::fan_tin({{2, 6}, {8, 6}, {9, 8}, {10, 6}, {14, 6}, {14, 14}, {2, 14}}, {9, 11});
  const auto h2 = hy::HybridTerrain::build(hf, notch, {.grid_step = 4, .levels = 2});
  check_model(h2, hf, notch);
}

TEST(HybridTerrain, SeveralSectionsInOneCell) {
  // A thin strip [1,31] x [9.5,11.5] crosses every cell of its row: two sections per cell, one
  // above and one below, each with its own uncovered region and corners.
  const auto hf = tt::bumpy_grid(33, 33);
  const auto strip = tt::grid_tin(1, 9.5, 15, 1, 2);
  const auto h = hy::HybridTerrain::build(hf, strip, {.grid_step = 4, .levels = 3});
  const auto& vc = h.level(0).vc;
  const auto it = std::find_if(vc.begin(), vc.end(), [](const hy::PcCell& p) { return p.cell == 2 * 8 + 3; });
  ASSERT_NE(it, vc.end());
  ASSERT_EQ(it->sections.size(), 2u);  // VC = {2; (A0,L0)(C0,I0); (A1,L1)(C1,I1)}
  EXPECT_EQ(it->sections[0].I + it->sections[1].I, 4);
  check_model(h, hf, strip);
}

TEST(HybridTerrain, ClearErrors) {
  const auto hf = tt::bumpy_grid(33, 33);
  // Inside one coarsest cell (16 samples): refused with a hint.
  try {
    hy::HybridTerrain::build(hf, tt::fan_tin({{2, 2}, {6, 2}, {6, 6}, {2, 6}}, {4, 4}),
                             {.grid_step = 4, .levels = 3});
    ADD_FAILURE() << "no error";
  } catch (const hy::HybridError& e) {
    EXPECT_NE(std::string(e.what()).find("inside one coarsest grid cell"), std::string::npos) << e.what();
  }
  // Outside the domain.
  EXPECT_THROW(hy::HybridTerrain::build(hf, tt::fan_tin({{20, 20}, {40, 20}, {40, 30}, {20, 30}}, {30, 25})),
               hy::HybridError);
  // Two overlapping TINs.
  const auto a = tt::grid_tin(4, 4, 4, 4, 2), b = tt::grid_tin(6, 6, 4, 4, 2);
  EXPECT_THROW(hy::HybridTerrain::build(hf, hy::merge_tins({a, b})), hy::HybridError);
  // A grid too small for the levels.
  EXPECT_THROW(hy::HybridTerrain::build(tt::bumpy_grid(9, 9), a, {.grid_step = 4, .levels = 3}),
               hy::HybridError);
}

TEST(HybridTerrain, BlobRoundTripAndCorruption) {
  const auto hf = tt::bumpy_grid(33, 33);
  const auto tin = tt::fan_tin(notch_polygon(), {6, 10});
  const auto h = hy::HybridTerrain::build(hf, tin, {.grid_step = 4, .levels = 2});
  const auto blob = h.encode();
  const auto back = hy::HybridTerrain::decode(blob, "mem");
  for (int l = 0; l < h.levels(); ++l) {
    EXPECT_EQ(back.level(l), h.level(l));
    for (hy::Scheme s : {hy::Scheme::Triangles, hy::Scheme::SubCells}) {
      const auto m1 = h.extract(l, s), m2 = back.extract(l, s);
      EXPECT_EQ(m1.points, m2.points);
      EXPECT_EQ(m1.triangles, m2.triangles);
    }
  }
  EXPECT_EQ(back.connectivity(), h.connectivity());
  auto bad = blob;
  bad[bad.size() / 2] ^= 0x10;
  try {
    hy::HybridTerrain::decode(bad, "x.db");
    ADD_FAILURE() << "corruption not detected";
  } catch (const hy::HybridError& e) {
    EXPECT_NE(std::string(e.what()).find("x.db: hybrid blob: checksum mismatch"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(hy::HybridTerrain::decode(std::span(blob).first(blob.size() / 3), "x.db"), hy::HybridError);
  EXPECT_THROW(hy::HybridTerrain::decode({}, "x.db"), hy::HybridError);
}

TEST(HybridTerrain, StorageReportCounts) {
  const auto hf = tt::bumpy_grid(33, 33);
  const auto tin = tt::fan_tin(notch_polygon(), {6, 10});
  const auto h = hy::HybridTerrain::build(hf, tin, {.grid_step = 4, .levels = 2});
  const auto r = h.storage_report();
  ASSERT_EQ(r.levels.size(), 2u);
  for (const auto& lr : r.levels) {
    EXPECT_EQ(lr.nc + lr.cc + lr.pc, lr.cells);
    EXPECT_EQ(lr.gc_bits, std::uint64_t(lr.nc) + 2 * std::uint64_t(lr.cc + lr.pc));  // codes 0 / 10 / 11
    EXPECT_EQ(lr.bits_per_section, r.address_bits + int(std::bit_width(lr.l_max)) + 4);
  }
  // The notch cavity (offset 5) is closed inside its finest cell.
  EXPECT_EQ(r.levels[0].max_connectivity, 5u);
  // Level 1 PC cells are subdivided once: 4 codes each, 1 or 2 bits.
  EXPECT_GE(r.levels[1].tree_bits_per_pc, 4.0);
  EXPECT_LE(r.levels[1].tree_bits_per_pc, 8.0);
  EXPECT_EQ(r.levels[0].tree_bits_per_pc, 0.0);
}

// The realistic example on a crop of N44W072 (cols 384..592, rows 336..704 of the 1201^2 SRTM
// tile): a reference grid every 4th sample with 3 levels, and a greedy TIN (5 m) of the
// full-resolution samples inside the valley polygon committed in examples/hybrid/.
TEST(HybridTerrain, RealValleyN44W072) {
  const std::string dem_path = std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt";
  if (!std::ifstream(dem_path)) GTEST_SKIP() << dem_path << " is absent";
  // The polygon: world metres -> (col,row) of the crop.
  std::ifstream csv(std::string(TERRALOD_EXAMPLES_DIR) + "/hybrid/valley_N44W072.csv");
  ASSERT_TRUE(csv) << "examples/hybrid/valley_N44W072.csv missing";
  const tt::Valley valley = tt::valley_of(terralod::blocks::read_dem(dem_path), csv);
  const pm::Heightfield& crop = valley.crop;
  ASSERT_EQ(valley.polygon.size(), 34u);
  const auto h = hy::HybridTerrain::build(crop, tt::valley_tin(valley), {.grid_step = 4, .levels = 3});
  const auto r = h.storage_report();
  for (const auto& l : r.levels) {
    std::printf(
        "LOD %d: PC %d of %d (%.2f%%), max connectivity %u, L max %u, %d bits/section, tree %.2f bits/PC\n",
        l.level, l.pc, l.cells, l.pc_percent, l.max_connectivity, l.l_max, l.bits_per_section,
        l.tree_bits_per_pc);
    EXPECT_GT(l.pc, 0);
  }
  // Grid heights at the nodes, TIN heights at the TIN samples: check_cover compares with `crop`
  // (the TIN's heights are the DEM's own here).
  const double W = h.domain_width(), H = h.domain_height();
  for (int l = 0; l < h.levels(); ++l)
    for (hy::Scheme s : {hy::Scheme::Triangles, hy::Scheme::SubCells}) {
      const auto m = h.extract(l, s);
      std::set<std::pair<double, double>> seen;
      double area = 0;
      std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
      bool ok = true;
      for (const auto& t : m.triangles) {
        const double o = orient(m.points[t[0]], m.points[t[1]], m.points[t[2]]);
        ok = ok && o > 0;
        area += o / 2;
        for (int k = 0; k < 3; ++k) ok = ok && edges.insert({t[k], t[(k + 1) % 3]}).second;
      }
      std::size_t open_inside = 0;
      for (const auto& [a, b] : edges) {
        if (edges.count({b, a})) continue;
        const auto& p = m.points[a];
        const auto& q = m.points[b];
        if (!((p[0] == 0 && q[0] == 0) || (p[0] == W && q[0] == W) || (p[1] == 0 && q[1] == 0) ||
              (p[1] == H && q[1] == H)))
          ++open_inside;
      }
      EXPECT_TRUE(ok) << "level " << l;
      EXPECT_EQ(open_inside, 0u) << "level " << l;
      EXPECT_NEAR(area, W * H, 1e-9 * W * H) << "level " << l;
    }
}
