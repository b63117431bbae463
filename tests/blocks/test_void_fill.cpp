// Tests for blocks::fill_voids and fill_voids_in_window: harmonic and bounded fills, bits that do
// not depend on the window or the thread count, open and capped regions, closeness to one joint
// solve of all voids, on a generated grid and a real SRTM tile with voids.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <limits>
#include <mutex>
#include <random>
#include <vector>

#include "printed_seed.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/void_fill.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
using tb::SampleRect;

const double kNaN = std::numeric_limits<double>::quiet_NaN();

bool same_bits(double a, double b) {
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

struct Grid {
  int w = 0, h = 0;
  std::vector<double> z;  // NaN = void
};

/// A 4-connected void region found by the test's own flood fill.
struct TestRegion {
  std::vector<std::size_t> cells;
  SampleRect bbox;
  double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  /// Its box: bbox + 1 ring, cut by the grid edge.
  SampleRect box(const Grid& g) const {
    return {std::max(bbox.col0 - 1, 0), std::max(bbox.row0 - 1, 0), std::min(bbox.col1 + 1, g.w - 1),
            std::min(bbox.row1 + 1, g.h - 1)};
  }
};

std::vector<TestRegion> regions_of(const Grid& g) {
  std::vector<TestRegion> out;
  std::vector<char> seen(g.z.size(), 0);
  for (std::size_t seed = 0; seed < g.z.size(); ++seed) {
    if (!std::isnan(g.z[seed]) || seen[seed]) continue;
    TestRegion R;
    const int sc = int(seed % g.w), sr = int(seed / g.w);
    R.bbox = {sc, sr, sc, sr};
    std::vector<std::size_t> stack = {seed};
    seen[seed] = 1;
    while (!stack.empty()) {
      const std::size_t i = stack.back();
      stack.pop_back();
      R.cells.push_back(i);
      const int c = int(i % g.w), r = int(i / g.w);
      R.bbox = {std::min(R.bbox.col0, c), std::min(R.bbox.row0, r), std::max(R.bbox.col1, c),
                std::max(R.bbox.row1, r)};
      const int dc[4] = {-1, 1, 0, 0}, dr[4] = {0, 0, -1, 1};
      for (int k = 0; k < 4; ++k) {
        const int cc = c + dc[k], rr = r + dr[k];
        if (cc < 0 || rr < 0 || cc >= g.w || rr >= g.h) continue;
        const std::size_t j = std::size_t(rr) * g.w + cc;
        if (!std::isnan(g.z[j])) {
          R.lo = std::min(R.lo, g.z[j]);
          R.hi = std::max(R.hi, g.z[j]);
        } else if (!seen[j]) {
          seen[j] = 1;
          stack.push_back(j);
        }
      }
    }
    out.push_back(std::move(R));
  }
  return out;
}

/// 320 x 256 smooth terrain with noise; voids: one disc of radius 40 (about 5000 samples),
/// 600 single samples, 100 random walks of 2-15 steps, 20 samples on the grid edge.
Grid synthetic(std::uint32_t seed) {
  std::mt19937 rng = terralod::test::printed_seed_rng(seed);
  Grid g{320, 256, {}};
  std::uniform_real_distribution<double> noise(-2.0, 2.0);
  for (int r = 0; r < g.h; ++r) {
    for (int c = 0; c < g.w; ++c) {
      g.z.push_back(500.0 + 200.0 * std::sin(c * 0.03) * std::cos(r * 0.05) + 0.5 * c - 0.3 * r + noise(rng));
    }
  }
  const auto at = [&](int c, int r) -> double& { return g.z[std::size_t(r) * g.w + c]; };
  for (int r = 0; r < g.h; ++r) {
    for (int c = 0; c < g.w; ++c) {
      if ((c - 160) * (c - 160) + (r - 128) * (r - 128) <= 40 * 40) at(c, r) = kNaN;
    }
  }
  std::uniform_int_distribution<int> col(0, g.w - 1), row(0, g.h - 1), dir(0, 3), len(2, 15);
  for (int k = 0; k < 600; ++k) at(col(rng), row(rng)) = kNaN;
  for (int k = 0; k < 100; ++k) {
    int c = col(rng), r = row(rng);
    for (int s = len(rng); s > 0; --s) {
      at(c, r) = kNaN;
      const int d = dir(rng);
      c = std::clamp(c + (d == 0 ? -1 : d == 1 ? 1 : 0), 0, g.w - 1);
      r = std::clamp(r + (d == 2 ? -1 : d == 3 ? 1 : 0), 0, g.h - 1);
    }
  }
  for (int k = 0; k < 5; ++k) {
    at(col(rng), 0) = at(col(rng), g.h - 1) = at(0, row(rng)) = at(g.w - 1, row(rng)) = kNaN;
  }
  return g;
}

std::vector<double> cut(const Grid& g, SampleRect win) {
  std::vector<double> out;
  for (int r = win.row0; r <= win.row1; ++r) {
    for (int c = win.col0; c <= win.col1; ++c) out.push_back(g.z[std::size_t(r) * g.w + c]);
  }
  return out;
}

std::vector<double> filled(const Grid& g, tb::VoidFillOptions opt = {}) {
  std::vector<double> z = g.z;
  (void)tb::fill_voids(z, g.w, g.h, opt);
  return z;
}

/// A window holding `inner`, its edges drawn at random between inner's and the grid's.
SampleRect random_window_around(const Grid& g, SampleRect inner, std::mt19937& rng) {
  const auto pick = [&](int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng); };
  return {pick(0, inner.col0), pick(0, inner.row0), pick(inner.col1, g.w - 1), pick(inner.row1, g.h - 1)};
}

/// Every window sample: filled ones equal the whole-grid fill bit for bit; the ones left void are
/// exactly those of the regions reported open or capped.
void expect_window_agrees(const Grid& g, const std::vector<double>& whole, SampleRect win,
                          const tb::VoidFillOptions& opt) {
  std::vector<double> part = cut(g, win);
  const tb::VoidFillStats s = tb::fill_voids_in_window(part, win, g.w, g.h, opt);
  std::size_t left = 0;
  for (int r = win.row0; r <= win.row1; ++r) {
    for (int c = win.col0; c <= win.col1; ++c) {
      const double v = part[std::size_t(r - win.row0) * win.width() + (c - win.col0)];
      const double ref = whole[std::size_t(r) * g.w + c];
      if (std::isnan(v)) {
        ++left;
      } else {
        ASSERT_TRUE(same_bits(v, ref))
            << "sample (" << c << ", " << r << ") in window " << win.col0 << "," << win.row0 << "-"
            << win.col1 << "," << win.row1 << ": " << v << " vs " << ref << " in the whole grid";
      }
    }
  }
  std::size_t open = 0;
  for (const tb::OpenVoidRegion& o : s.open) {
    open += o.samples;
    EXPECT_TRUE((o.extent.col0 == win.col0 && win.col0 > 0) || (o.extent.row0 == win.row0 && win.row0 > 0) ||
                (o.extent.col1 == win.col1 && win.col1 < g.w - 1) ||
                (o.extent.row1 == win.row1 && win.row1 < g.h - 1))
        << "an open region that touches no inner window edge";
  }
  EXPECT_EQ(left, open + s.capped_samples);
  EXPECT_EQ(s.filled + left, s.voids);
}

// ------------------------------------------------------------------------------------------

TEST(void_fill, WholeGridIsHarmonicAndWithinRegionBounds) {
  const Grid g = synthetic(20261202);
  const std::vector<TestRegion> regions = regions_of(g);
  std::vector<double> z = g.z;
  const tb::VoidFillStats s = tb::fill_voids(z, g.w, g.h);
  std::size_t voids = 0;
  for (const TestRegion& R : regions) voids += R.cells.size();
  EXPECT_EQ(s.voids, voids);
  EXPECT_EQ(s.filled, voids);
  EXPECT_EQ(s.regions, regions.size());
  EXPECT_EQ(s.filled_regions, regions.size());
  EXPECT_TRUE(s.open.empty());
  EXPECT_EQ(s.capped_regions, 0u);
  std::cout << regions.size() << " regions, " << voids << " voids; at most " << s.iterations
            << " CG iterations, " << s.sweeps << " sweeps\n";
  for (const TestRegion& R : regions) {
    const double scale = std::max({R.hi - R.lo, std::abs(R.hi), std::abs(R.lo)});
    for (std::size_t i : R.cells) {
      const int c = int(i % g.w), r = int(i / g.w);
      ASSERT_GE(z[i], R.lo) << "sample " << i;  // exact, no tolerance
      ASSERT_LE(z[i], R.hi) << "sample " << i;
      double sum = 0.0;
      int n = 0;
      if (c > 0) sum += z[i - 1], ++n;
      if (c + 1 < g.w) sum += z[i + 1], ++n;
      if (r > 0) sum += z[i - g.w], ++n;
      if (r + 1 < g.h) sum += z[i + g.w], ++n;
      // Within the solver's tolerance: 1e-10 of the region's height scale.
      ASSERT_NEAR(z[i], sum / n, 1e-10 * scale) << "sample (" << c << ", " << r << ") is not harmonic";
    }
  }
}

TEST(void_fill, ThreadCountDoesNotChangeBits) {
  const Grid g = synthetic(7);
  tb::VoidFillOptions one, four;
  one.threads = 1;
  four.threads = 4;
  const std::vector<double> a = filled(g, one), b = filled(g, four);
  for (std::size_t i = 0; i < a.size(); ++i) ASSERT_TRUE(same_bits(a[i], b[i])) << "sample " << i;
}

// on_solve: a pair of calls (before, after) for each region of notify_from samples or more,
// from whichever thread solves it, and none for smaller regions or regions left void.
TEST(void_fill, LargeRegionsAreToldBeforeAndAfterTheirSolve) {
  const int w = 60, h = 40;
  std::vector<double> z(std::size_t(w) * h);
  for (std::size_t i = 0; i < z.size(); ++i) z[i] = 10.0 + double(i % 7);
  const auto hole = [&](tb::SampleRect r) {
    for (int y = r.row0; y <= r.row1; ++y)
      for (int x = r.col0; x <= r.col1; ++x) z[std::size_t(y) * w + x] = std::nan("");
  };
  const tb::SampleRect a{2, 2, 11, 11}, b{20, 5, 29, 14}, small{40, 2, 48, 12}, capped{2, 20, 57, 38};
  for (const tb::SampleRect& r : {a, b, small, capped}) hole(r);  // 100, 100, 99 and 1,064 samples
  std::mutex m;
  std::vector<tb::VoidSolveNotice> told;
  tb::VoidFillOptions o;
  o.threads = 3;
  o.notify_from = 100;
  o.max_region_cells = 1000;  // the 56 x 19 region stays void
  o.on_solve = [&](const tb::VoidSolveNotice& n) {
    std::lock_guard lock(m);
    told.push_back(n);
  };
  const tb::VoidFillStats s = tb::fill_voids(z, w, h, o);
  EXPECT_EQ(s.filled_regions, 3u);
  ASSERT_EQ(told.size(), 4u);
  for (const tb::SampleRect& r : {a, b}) {
    int before = 0, after = 0;
    for (const tb::VoidSolveNotice& n : told) {
      if (!(n.extent == r)) continue;
      EXPECT_EQ(n.samples, 100u);
      if (n.seconds < 0) {
        ++before;
      } else {
        ++after;
        EXPECT_EQ(before, 1) << "the solve was told of after it ran";
      }
    }
    EXPECT_EQ(before, 1);
    EXPECT_EQ(after, 1);
  }
}

TEST(void_fill, RegionBitsDoNotDependOnTheWindow) {
  const Grid g = synthetic(20261202);
  const std::vector<TestRegion> regions = regions_of(g);
  const std::vector<double> whole = filled(g);
  std::mt19937 rng = terralod::test::printed_seed_rng(4242);
  tb::VoidFillOptions opt;
  opt.threads = 2;
  for (int t = 0; t < 150; ++t) {
    // Half of the windows hold the big disc (region with the most samples).
    const std::size_t k = t % 2 == 0 ? std::size_t(std::max_element(regions.begin(), regions.end(),
                                                                    [](const auto& a, const auto& b) {
                                                                      return a.cells.size() < b.cells.size();
                                                                    }) -
                                                   regions.begin())
                                     : std::uniform_int_distribution<std::size_t>(0, regions.size() - 1)(rng);
    const SampleRect win = random_window_around(g, regions[k].box(g), rng);
    std::vector<double> part = cut(g, win);
    (void)tb::fill_voids_in_window(part, win, g.w, g.h, opt);
    for (std::size_t i : regions[k].cells) {
      const int c = int(i % g.w), r = int(i / g.w);
      ASSERT_FALSE(std::isnan(part[std::size_t(r - win.row0) * win.width() + (c - win.col0)]))
          << "region " << k << " not filled although the window holds its box";
    }
    expect_window_agrees(g, whole, win, opt);
    if (HasFatalFailure()) return;
  }
}

TEST(void_fill, WindowThatCutsARegionReportsItOpenAndGrowingItGivesTheSameBits) {
  const Grid g = synthetic(20261202);
  const std::vector<TestRegion> regions = regions_of(g);
  const std::vector<double> whole = filled(g);
  const TestRegion& disc =
      *std::max_element(regions.begin(), regions.end(),
                        [](const auto& a, const auto& b) { return a.cells.size() < b.cells.size(); });
  // A window whose east edge runs through the middle of the disc.
  const int mid = (disc.bbox.col0 + disc.bbox.col1) / 2;
  SampleRect win{disc.bbox.col0 - 10, disc.bbox.row0 - 10, mid, disc.bbox.row1 + 10};
  std::vector<double> part = cut(g, win);
  tb::VoidFillStats s = tb::fill_voids_in_window(part, win, g.w, g.h);
  SampleRect seen{mid, g.h, 0, 0};
  std::size_t inside = 0;
  for (std::size_t i : disc.cells) {
    const int c = int(i % g.w), r = int(i / g.w);
    if (c > mid) continue;
    ++inside;
    seen = {std::min(seen.col0, c), std::min(seen.row0, r), mid, std::max(seen.row1, r)};
    EXPECT_TRUE(std::isnan(part[std::size_t(r - win.row0) * win.width() + (c - win.col0)]));
  }
  const auto it = std::find_if(s.open.begin(), s.open.end(), [&](const auto& o) { return o.extent == seen; });
  ASSERT_NE(it, s.open.end()) << "the cut disc is not reported open";
  EXPECT_EQ(it->samples, inside);
  expect_window_agrees(g, whole, win, {});

  // The out-of-core caller: grow the window over every open region until none is left.
  int rounds = 0;
  while (!s.open.empty() && rounds++ < 20) {
    for (const tb::OpenVoidRegion& o : s.open) {
      win = {std::max(0, std::min(win.col0, o.extent.col0 - 16)),
             std::max(0, std::min(win.row0, o.extent.row0 - 16)),
             std::min(g.w - 1, std::max(win.col1, o.extent.col1 + 16)),
             std::min(g.h - 1, std::max(win.row1, o.extent.row1 + 16))};
    }
    part = cut(g, win);
    s = tb::fill_voids_in_window(part, win, g.w, g.h);
  }
  EXPECT_TRUE(s.open.empty()) << "still open after 20 rounds";
  std::cout << "window grew in " << rounds << " rounds to " << win.width() << " x " << win.height() << "\n";
  for (std::size_t i : disc.cells) {
    const int c = int(i % g.w), r = int(i / g.w);
    ASSERT_TRUE(same_bits(part[std::size_t(r - win.row0) * win.width() + (c - win.col0)], whole[i]));
  }
}

TEST(void_fill, RegionsOverTheCapStayHolesInEveryWindow) {
  const Grid g = synthetic(99);
  const std::vector<TestRegion> regions = regions_of(g);
  const std::vector<double> uncapped = filled(g);
  tb::VoidFillOptions opt;
  opt.max_region_cells = 12;  // e.g. a 3 x 4 box is filled, a 4 x 4 or 13 x 1 one is not
  std::vector<double> z = g.z;
  const tb::VoidFillStats s = tb::fill_voids(z, g.w, g.h, opt);
  std::size_t capped = 0, capped_samples = 0;
  for (const TestRegion& R : regions) {
    const bool over = R.bbox.samples() > opt.max_region_cells;
    capped += over;
    capped_samples += over ? R.cells.size() : 0;
    for (std::size_t i : R.cells) {
      if (over) {
        ASSERT_TRUE(std::isnan(z[i])) << "a region over the cap was filled";
      } else {
        ASSERT_TRUE(same_bits(z[i], uncapped[i])) << "the cap changed a region under it";
      }
    }
  }
  ASSERT_GT(capped, 1u);
  ASSERT_LT(capped, regions.size());
  EXPECT_EQ(s.capped_regions, capped);
  EXPECT_EQ(s.capped_samples, capped_samples);
  EXPECT_EQ(s.filled + capped_samples, s.voids);
  std::mt19937 rng = terralod::test::printed_seed_rng(5);
  for (int t = 0; t < 40; ++t) {
    const auto k = std::uniform_int_distribution<std::size_t>(0, regions.size() - 1)(rng);
    expect_window_agrees(g, z, random_window_around(g, regions[k].box(g), rng), opt);
    if (HasFatalFailure()) return;
  }
}

/// All voids of `g` solved jointly by SOR (independent of the code under test) to convergence.
std::vector<double> joint_reference(const Grid& g) {
  std::vector<double> z = g.z;
  std::vector<std::size_t> voids;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < z.size(); ++i) {
    if (std::isnan(z[i])) {
      voids.push_back(i);
    } else {
      lo = std::min(lo, z[i]);
      hi = std::max(hi, z[i]);
    }
  }
  for (std::size_t i : voids) z[i] = 0.5 * (lo + hi);
  for (int sweep = 0; sweep < 200000; ++sweep) {
    double change = 0.0;
    for (std::size_t i : voids) {
      const int c = int(i % g.w), r = int(i / g.w);
      double sum = 0.0;
      int n = 0;
      if (c > 0) sum += z[i - 1], ++n;
      if (c + 1 < g.w) sum += z[i + 1], ++n;
      if (r > 0) sum += z[i - g.w], ++n;
      if (r + 1 < g.h) sum += z[i + g.w], ++n;
      const double next = z[i] + 1.9 * (sum / n - z[i]);
      change = std::max(change, std::abs(next - z[i]));
      z[i] = next;
    }
    if (change < 1e-13 * (hi - lo)) break;
  }
  return z;
}

void expect_close_to_joint_solve(const Grid& g, const std::vector<double>& z) {
  const std::vector<double> ref = joint_reference(g);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo, diff = 0.0;
  for (std::size_t i = 0; i < z.size(); ++i) {
    if (!std::isnan(g.z[i])) lo = std::min(lo, g.z[i]), hi = std::max(hi, g.z[i]);
    diff = std::max(diff, std::abs(z[i] - ref[i]));
  }
  std::cout << "largest difference from one joint solve: " << diff << " m (height range " << hi - lo
            << " m)\n";
  EXPECT_LE(diff, 1e-6 * (hi - lo));
}

TEST(void_fill, CloseToOneJointSolveOfAllVoids) {
  const Grid g = synthetic(20261202);
  expect_close_to_joint_solve(g, filled(g));
}

TEST(void_fill_real_data, KauaiTileWindowsAndJointSolve) {
  const fs::path path = fs::path(TERRALOD_DATA_DIR) / "N22W160.hgt";
  if (!fs::exists(path)) GTEST_SKIP() << path << " absent";
  tb::DemOptions holes;
  holes.fill_voids = false;
  const terralod::pm::Heightfield hh = tb::read_dem(path.string(), holes);
  Grid g{hh.width(), hh.height(), hh.samples()};
  for (std::size_t i = 0; i < g.z.size(); ++i) {
    if (!hh.valid(i)) g.z[i] = kNaN;
  }
  const std::vector<double> whole = filled(g);
  const terralod::pm::Heightfield hf = tb::read_dem(path.string());
  ASSERT_FALSE(hf.has_holes());
  for (std::size_t i = 0; i < whole.size(); ++i) {
    ASSERT_TRUE(same_bits(hf.samples()[i], whole[i])) << "read_dem does not fill as fill_voids does";
  }
  expect_close_to_joint_solve(g, whole);
  const std::vector<TestRegion> regions = regions_of(g);
  std::cout << regions.size() << " regions\n";
  std::mt19937 rng = terralod::test::printed_seed_rng(1201);
  for (int t = 0; t < 40; ++t) {
    const auto k = std::uniform_int_distribution<std::size_t>(0, regions.size() - 1)(rng);
    SampleRect box = regions[k].box(g);
    // Windows of block size or so around the region, as an out-of-core reader would read.
    box = {std::max(0, box.col0 - 150), std::max(0, box.row0 - 150), std::min(g.w - 1, box.col1 + 150),
           std::min(g.h - 1, box.row1 + 150)};
    expect_window_agrees(g, whole, random_window_around(g, box, rng), {});
    if (HasFatalFailure()) return;
  }
}

}  // namespace
