// LInfError over windows of the grid (GridWindow): over any tiling of the grid into windows that
// share their border rows and columns, the maximum of the windows' values is the whole-grid
// value bit for bit (triangles of both orientations, degenerate ones, both metrics, integer and
// real heights, holes skipped or not), and over the whole grid the explicit-height entry points
// equal the ones that read the corners.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/linf_error.hpp"

namespace {

namespace pm = terralod::pm;

/// Cuts first .. last into pieces that share their ends, at random places (pieces of 1 .. 9 cells).
std::vector<std::array<int, 2>> random_cuts(std::mt19937& rng, int first, int last) {
  std::vector<std::array<int, 2>> out;
  for (int a = first; a < last;) {
    const int b = std::min(last, a + 1 + int(rng() % 9));
    out.push_back({a, b});
    a = b;
  }
  return out;
}

/// The samples (c0 .. c1, r0 .. r1) of hf, with their mask.
pm::Heightfield window_of(const pm::Heightfield& hf, int c0, int r0, int c1, int r1) {
  pm::Heightfield w(c1 - c0 + 1, r1 - r0 + 1);
  std::vector<std::uint8_t> mask;
  for (int r = r0; r <= r1; ++r)
    for (int c = c0; c <= c1; ++c) {
      w.at(c - c0, r - r0) = hf.at(c, r);
      mask.push_back(hf.valid(c, r) ? 1 : 0);
    }
  if (hf.has_holes()) w.set_mask(std::move(mask));
  return w;
}

TEST(LInfWindow, MaxOverAnyTilingIsTheWholeGridValue) {
  const unsigned seed = 20261203;
  std::printf("seed %u\n", seed);
  std::mt19937 rng(seed);
  for (int trial = 0; trial < 40; ++trial) {
    const int w = 2 + int(rng() % 30), h = 2 + int(rng() % 30);
    const bool integer = trial % 2 == 0, holes = trial % 3 == 0;
    pm::Heightfield hf(w, h);
    std::uniform_real_distribution<double> u(-80.0, 80.0);
    for (double& z : hf.samples()) z = integer ? std::round(u(rng)) : u(rng);
    if (holes) {
      std::vector<std::uint8_t> mask(hf.samples().size());
      for (auto& m : mask) m = rng() % 6 != 0;
      hf.set_mask(std::move(mask));
    }
    // The windows: a random tiling sharing border rows and columns.
    std::vector<pm::Heightfield> wins;
    std::vector<pm::GridPoint> origins;
    for (const auto& rr : random_cuts(rng, 0, h - 1))
      for (const auto& cc : random_cuts(rng, 0, w - 1)) {
        wins.push_back(window_of(hf, cc[0], rr[0], cc[1], rr[1]));
        origins.push_back({cc[0], rr[0]});
      }
    for (pm::ErrorMetric m : {pm::ErrorMetric::Samples, pm::ErrorMetric::Continuous})
      for (bool skip : {false, true}) {
        const pm::LInfError whole(hf, m, {.skip_holes = skip});
        for (int k = 0; k < 60; ++k) {
          pm::GridPoint a{int(rng() % unsigned(w)), int(rng() % unsigned(h))};
          pm::GridPoint b{int(rng() % unsigned(w)), int(rng() % unsigned(h))};
          pm::GridPoint c{int(rng() % unsigned(w)), int(rng() % unsigned(h))};
          if (k % 6 == 0) c = {a.x + (b.x - a.x) / 2, a.y + (b.y - a.y) / 2};  // collinear when exact
          const std::array<double, 3> z{hf.at(a.x, a.y), hf.at(b.x, b.y), hf.at(c.x, c.y)};
          const double want = whole.triangle(a, b, c, z);
          EXPECT_EQ(want, whole.triangle(a, b, c));
          double tri = 0.0, seg = 0.0;
          for (std::size_t i = 0; i < wins.size(); ++i) {
            const pm::LInfError part(wins[i], m, {.origin = origins[i], .skip_holes = skip});
            tri = std::max(tri, part.triangle(a, b, c, z));
            seg = std::max(seg, part.segment(a, b, z[0], z[1]));
          }
          EXPECT_EQ(tri, want) << "trial " << trial << " triangle " << k << " metric " << int(m) << " skip "
                               << skip;
          EXPECT_EQ(seg, whole.segment(a, b, z[0], z[1])) << "trial " << trial << " segment " << k;
        }
      }
  }
}

// Skipping holes drops exactly the hole samples: a 5 x 5 grid with one raised hole in the middle
// of a flat triangle measures 0 with skip_holes and the raised height without.
TEST(LInfWindow, SkippedHoleByHand) {
  pm::Heightfield hf(5, 5);
  hf.at(2, 2) = 9.0;
  std::vector<std::uint8_t> mask(25, 1);
  mask[2 * 5 + 2] = 0;
  hf.set_mask(mask);
  for (pm::ErrorMetric m : {pm::ErrorMetric::Samples, pm::ErrorMetric::Continuous}) {
    EXPECT_EQ(pm::LInfError(hf, m).triangle({0, 0}, {4, 0}, {4, 4}), 9.0);
    EXPECT_EQ(pm::LInfError(hf, m, {.skip_holes = true}).triangle({0, 0}, {4, 0}, {4, 4}), 0.0);
  }
}

}  // namespace
