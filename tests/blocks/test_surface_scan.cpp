// The node surfaces' exact error and the domain's z range streamed window by window through a
// DemSource (blocks/src/surface_scan.hpp, issue 17) against surface_error and a direct scan of the
// z range over the whole heightfield: equal bit for bit, for every strategy's surfaces, both
// metrics, holes and cliffs, and window budgets from 4 samples to more than the domain.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "printed_seed.hpp"
#include "surface_scan.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/node_strategy.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/linf_error.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
using tb::detail::scan_surfaces;
using tb::detail::scan_windows;

namespace {

/// A random w x h terrain: smooth relief plus noise, integer heights or not, a cliff along a
/// random line, and (with holes) a few rectangular voids whose stored heights are arbitrary.
pm::Heightfield random_terrain(std::mt19937& rng, int w, int h, bool integer, bool holes) {
  pm::Heightfield hf(w, h);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double fx = 0.05 + 0.3 * u(rng), fy = 0.05 + 0.3 * u(rng), cliff = 200.0 * u(rng);
  const double lx = u(rng) * w, ly = u(rng) * h, dx = u(rng) - 0.5, dy = u(rng) - 0.5;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      double z = 100.0 * std::sin(fx * c) * std::cos(fy * r) + 7.3 * u(rng);
      if ((c - lx) * dy - (r - ly) * dx > 0) z += cliff;
      hf.at(c, r) = integer ? std::round(z) : z;
    }
  if (holes) {
    std::vector<std::uint8_t> mask(std::size_t(w) * std::size_t(h), 1);
    const int voids = 1 + int(rng() % 4);
    for (int v = 0; v < voids; ++v) {
      const int c0 = int(rng() % unsigned(w)), r0 = int(rng() % unsigned(h));
      const int c1 = std::min(w - 1, c0 + int(rng() % 9)), r1 = std::min(h - 1, r0 + int(rng() % 9));
      for (int r = r0; r <= r1; ++r)
        for (int c = c0; c <= c1; ++c) mask[std::size_t(r) * std::size_t(w) + std::size_t(c)] = 0;
    }
    hf.set_mask(std::move(mask));
  }
  return hf;
}

/// domain_box's z range (tree_builder.cpp), computed directly: min and max of the valid samples.
std::pair<double, double> z_range(const pm::Heightfield& hf, tb::SampleRect d) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (int r = d.row0; r <= d.row1; ++r)
    for (int c = d.col0; c <= d.col1; ++c)
      if (hf.valid(c, r)) lo = std::min(lo, hf.at(c, r)), hi = std::max(hi, hf.at(c, r));
  if (lo > hi) lo = hi = 0.0;
  return {lo, hi};
}

/// Scans `surfaces` over `domain` with every budget and checks each against surface_error.
void expect_scan_equal(const pm::Heightfield& hf, tb::SampleRect domain,
                       const std::vector<const tb::NodeSurface*>& surfaces, pm::ErrorMetric metric,
                       const std::string& what) {
  const auto src = tb::heightfield_source(hf);
  std::vector<double> want;
  for (const tb::NodeSurface* s : surfaces) want.push_back(tb::surface_error(hf, *s, metric));
  const auto [zlo, zhi] = z_range(hf, domain);
  for (std::size_t budget : {std::size_t(4), std::size_t(5), std::size_t(9), std::size_t(12), std::size_t(50),
                             std::size_t(300), domain.samples(), domain.samples() * 4}) {
    for (int threads : {1, 3}) {
      const tb::detail::SurfaceScan got = scan_surfaces(*src, domain, surfaces, metric, budget, threads);
      ASSERT_EQ(got.errors.size(), surfaces.size());
      for (std::size_t i = 0; i < surfaces.size(); ++i)
        EXPECT_EQ(got.errors[i], want[i])
            << what << " surface " << i << " budget " << budget << " threads " << threads;
      EXPECT_EQ(got.zlo, zlo) << what << " budget " << budget;
      EXPECT_EQ(got.zhi, zhi) << what << " budget " << budget;
    }
  }
}

}  // namespace

// The windows: each within the budget, inside the domain, neighbours sharing exactly one sample
// row or column, together covering it.
TEST(SurfaceScan, WindowsTileTheDomainWithOneSampleOverlap) {
  const tb::SampleRect d{3, 5, 40, 22};
  for (std::size_t budget : {4u, 5u, 17u, 100u, 684u, 5000u}) {
    const std::vector<tb::SampleRect> ws = scan_windows(d, budget);
    std::vector<int> cover(d.samples(), 0);
    for (const tb::SampleRect& w : ws) {
      EXPECT_LE(w.samples(), budget);
      EXPECT_TRUE(d.contains(w.col0, w.row0) && d.contains(w.col1, w.row1));
      for (int r = w.row0; r <= w.row1; ++r)
        for (int c = w.col0; c <= w.col1; ++c)
          ++cover[std::size_t(r - d.row0) * std::size_t(d.width()) + std::size_t(c - d.col0)];
    }
    for (int x : cover) EXPECT_GE(x, 1) << "budget " << budget;
    // Every cell (with both its edges and diagonal) lies in one window.
    for (int r = d.row0; r < d.row1; ++r)
      for (int c = d.col0; c < d.col1; ++c)
        EXPECT_TRUE(std::any_of(
            ws.begin(), ws.end(),
            [&](const tb::SampleRect& w) { return w.contains(c, r) && w.contains(c + 1, r + 1); }))
            << "cell " << c << "," << r << " budget " << budget;
  }
}

// By hand: a 3 x 3 grid, zero but for 6 m in the middle; the two triangles of the whole domain
// (grid P = 1) split along (0,0)-(2,2), which passes through the middle sample, so both metrics
// see 6 m there, in each of the four 2 x 2 windows of a 4-sample budget.
TEST(SurfaceScan, RaisedCentreByHand) {
  pm::Heightfield hf(3, 3);
  hf.at(1, 1) = 6.0;
  const tb::SampleRect d{0, 0, 2, 2};
  const tb::NodeSurface s = tb::make_grid_strategy(1)->approximate(hf, d);
  const tb::NodeSurface* one[] = {&s};
  for (pm::ErrorMetric m : {pm::ErrorMetric::Samples, pm::ErrorMetric::Continuous}) {
    const auto got = scan_surfaces(*tb::heightfield_source(hf), d, one, m, 4);
    EXPECT_EQ(got.errors[0], 6.0);
    EXPECT_EQ(got.zlo, 0.0);
    EXPECT_EQ(got.zhi, 6.0);
  }
  EXPECT_EQ(scan_windows(d, 4).size(), 4u);
}

// Every strategy's surfaces over random domains of random terrains, with and without holes.
TEST(SurfaceScan, EveryStrategyEqualsSurfaceErrorBitForBit) {
  std::mt19937 rng = terralod::test::printed_seed_rng(20261203);
  int hybrid_with_tin = 0;  // hybrid surfaces that are more than their grid (the microstructure is exercised)
  for (int trial = 0; trial < 24; ++trial) {
    const int w = 12 + int(rng() % 40), h = 12 + int(rng() % 40);
    const bool integer = trial % 2 == 0, holes = trial % 4 >= 2;
    const pm::Heightfield hf = random_terrain(rng, w, h, integer, holes);
    const int c0 = int(rng() % unsigned(w / 3)), r0 = int(rng() % unsigned(h / 3));
    const int c1 = w - 1 - int(rng() % unsigned(w / 3)), r1 = h - 1 - int(rng() % unsigned(h / 3));
    const tb::SampleRect d{c0, r0, c1, r1};
    for (pm::ErrorMetric m : {pm::ErrorMetric::Samples, pm::ErrorMetric::Continuous}) {
      const std::size_t s = 4 + rng() % 40;
      const int patch = 1 + int(rng() % 6);
      std::vector<tb::NodeSurface> surf;
      surf.push_back(tb::make_grid_strategy(patch)->approximate(hf, d));
      surf.push_back(tb::make_tin_strategy(s, m)->approximate(hf, d));
      surf.push_back(tb::make_nonregular_strategy(s, m)->approximate(hf, d));
      surf.push_back(tb::make_hybrid_strategy(patch, s, m)->approximate(hf, d));
      hybrid_with_tin += surf[3].points.size() != surf[0].points.size();
      std::vector<const tb::NodeSurface*> ptrs;
      for (const tb::NodeSurface& x : surf) {
        // What the scan relies on: every point a sample of the domain at its height, bit for bit.
        for (const auto& p : x.points) {
          ASSERT_TRUE(d.contains(int(p[0]), int(p[1])));
          ASSERT_EQ(p[2], hf.at(int(p[0]), int(p[1])));
        }
        ptrs.push_back(&x);
      }
      char what[96];
      std::snprintf(what, sizeof what, "trial %d (%dx%d, %s, %s) metric %d", trial, w, h,
                    integer ? "integer" : "real", holes ? "holes" : "no holes", int(m));
      expect_scan_equal(hf, d, ptrs, m, what);
    }
  }
  EXPECT_GT(hybrid_with_tin, 0);
  std::printf("%d hybrid surfaces with a TIN microstructure\n", hybrid_with_tin);
}

// A hand-built surface with a degenerate triangle (three collinear corners), measured as its
// segments, next to ordinary ones; and a domain that is all holes (z range 0, 0).
TEST(SurfaceScan, DegenerateTriangleAndAllHoles) {
  std::mt19937 rng = terralod::test::printed_seed_rng(17);
  for (bool holes : {false, true}) {
    const pm::Heightfield hf = random_terrain(rng, 30, 24, /*integer=*/false, holes);
    tb::NodeSurface s;
    auto add = [&](int c, int r) {
      s.points.push_back({double(c), double(r), hf.at(c, r)});
      return std::uint32_t(s.points.size() - 1);
    };
    const std::uint32_t a = add(2, 3), b = add(11, 9), c = add(26, 19), e = add(26, 3), f = add(2, 19);
    s.triangles = {{a, b, c}, {a, e, c}, {a, c, f}};
    for (pm::ErrorMetric m : {pm::ErrorMetric::Samples, pm::ErrorMetric::Continuous})
      expect_scan_equal(hf, {2, 3, 26, 19}, {&s}, m, holes ? "degenerate, holes" : "degenerate");
    // The degenerate triangle alone (even for the sample metric) is its three segments' crossing
    // error, not zero.
    tb::NodeSurface seg;
    seg.points = {s.points[a], s.points[b], s.points[c]};
    seg.triangles = {{0, 1, 2}};
    const tb::NodeSurface* only[] = {&seg};
    const auto got =
        scan_surfaces(*tb::heightfield_source(hf), {2, 3, 26, 19}, only, pm::ErrorMetric::Samples, 9);
    if (!holes) {
      const pm::LInfError linf(hf, pm::ErrorMetric::Samples);
      EXPECT_EQ(got.errors[0], std::max({linf.segment({2, 3}, {11, 9}), linf.segment({11, 9}, {26, 19}),
                                         linf.segment({2, 3}, {26, 19})}));
    }
    EXPECT_GT(got.errors[0], 0.0);
  }
  pm::Heightfield void_hf(6, 6);
  void_hf.at(2, 2) = 5.0;
  void_hf.set_mask(std::vector<std::uint8_t>(36, 0));
  const tb::NodeSurface g = tb::make_grid_strategy(2)->approximate(void_hf, {0, 0, 5, 5});
  const tb::NodeSurface* one[] = {&g};
  const auto got =
      scan_surfaces(*tb::heightfield_source(void_hf), {0, 0, 5, 5}, one, pm::ErrorMetric::Continuous, 4);
  EXPECT_EQ(got.errors[0], 0.0);
  EXPECT_EQ(got.zlo, 0.0);
  EXPECT_EQ(got.zhi, 0.0);
}

// The real tiles (read_dem, served by heightfield_source: open_dem_source is not implemented yet):
// N44W072 and N22W160 (sea at 0 m, cliffs, voids filled by read_dem), a grid and a TIN surface
// over the whole tile, both metrics.
TEST(SurfaceScan, RealTiles) {
  int found = 0;
  for (const char* name : {"N44W072.hgt", "N22W160.hgt"}) {
    const std::string path = std::string(TERRALOD_DATA_DIR) + "/" + name;
    if (!std::ifstream(path)) {
      std::printf("%s is absent: skipped\n", path.c_str());
      continue;
    }
    ++found;
    const pm::Heightfield hf = tb::read_dem(path);
    const auto src = tb::heightfield_source(hf);
    const tb::SampleRect d{0, 0, hf.width() - 1, hf.height() - 1};
    for (pm::ErrorMetric m : {pm::ErrorMetric::Samples, pm::ErrorMetric::Continuous}) {
      const tb::NodeSurface g = tb::make_grid_strategy(8)->approximate(hf, d);
      const tb::NodeSurface t = tb::make_tin_strategy(64, m)->approximate(hf, d);
      const tb::NodeSurface* both[] = {&g, &t};
      const auto got = scan_surfaces(*src, d, both, m, 129 * 129, /*threads=*/2);
      EXPECT_EQ(got.errors[0], tb::surface_error(hf, g, m)) << name;
      EXPECT_EQ(got.errors[1], tb::surface_error(hf, t, m)) << name;
      const auto [zlo, zhi] = z_range(hf, d);
      EXPECT_EQ(got.zlo, zlo) << name;
      EXPECT_EQ(got.zhi, zhi) << name;
      std::printf("%s metric %d: grid %.3f m, tin %.3f m, z %.1f .. %.1f, holes %d\n", name, int(m),
                  got.errors[0], got.errors[1], got.zlo, got.zhi, int(hf.has_holes()));
    }
  }
  if (found == 0) GTEST_SKIP() << "no SRTM tile in " << TERRALOD_DATA_DIR;
}
