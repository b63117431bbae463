// Tests of GridTriangle's rasterisation: the spans for_each_span steps row by row must be
// exactly the samples whose three edge functions are >= 0 (the closed triangle), the same spans
// row_span divides out, on hand-drawn and on random triangles (fixed, printed seed).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <random>
#include <vector>

#include "terralod/pm/grid_triangle.hpp"

namespace {

namespace pm = terralod::pm;

struct Span {
  int y;
  std::int64_t xl, xr;
  bool operator==(const Span&) const = default;
};

std::vector<Span> stepped(const pm::GridTriangle& t) {
  std::vector<Span> s;
  t.for_each_span([&](int y, std::int64_t xl, std::int64_t xr) { s.push_back({y, xl, xr}); });
  return s;
}

// Every sample of the bounding box tested against the edge functions: no division at all.
std::vector<Span> brute_force(const pm::GridTriangle& t) {
  std::vector<Span> s;
  for (int y = t.y_min; y <= t.y_max; ++y) {
    std::int64_t xl = INT64_MAX, xr = INT64_MIN;
    for (int x = t.x_min; x <= t.x_max; ++x) {
      bool inside = true;
      for (int k = 0; k < 3; ++k) inside = inside && t.A[k] * x + t.B[k] * y + t.C[k] >= 0;
      if (inside) xl = std::min<std::int64_t>(xl, x), xr = std::max<std::int64_t>(xr, x);
    }
    if (xl <= xr) s.push_back({y, xl, xr});
  }
  return s;
}

std::vector<Span> divided(const pm::GridTriangle& t) {
  std::vector<Span> s;
  for (int y = t.y_min; y <= t.y_max; ++y) {
    std::int64_t xl = t.x_min, xr = t.x_max;
    t.row_span(y, xl, xr);
    if (xl <= xr) s.push_back({y, xl, xr});
  }
  return s;
}

//  y=0  a . . . b        The right triangle a (0,0), b (4,0), c (0,4):
//  y=1  . . . .          row y holds x = 0 .. 4 - y.
//  y=2  . . .
//  y=3  . .
//  y=4  c
TEST(GridTriangle, RightTriangleSpansByHand) {
  pm::GridPoint a{0, 0}, b{4, 0}, c{0, 4};
  const auto t = pm::GridTriangle::ccw(a, b, c);
  const std::vector<Span> want = {{0, 0, 4}, {1, 0, 3}, {2, 0, 2}, {3, 0, 1}, {4, 0, 0}};
  EXPECT_EQ(stepped(t), want);
}

// A sliver with edges of every slope sign, negative coordinates included: (-3, -7), (5, 2),
// (4, 3). Rows with no sample inside are skipped.
TEST(GridTriangle, SliverSkipsEmptyRows) {
  pm::GridPoint a{-3, -7}, b{5, 2}, c{4, 3};
  const auto t = pm::GridTriangle::ccw(a, b, c);
  const auto s = stepped(t);
  EXPECT_EQ(s, brute_force(t));
  EXPECT_LT(s.size(), std::size_t(t.y_max - t.y_min + 1));  // some rows are empty
}

TEST(GridTriangle, SteppedSpansAreTheClosedTriangleOnRandomTriangles) {
  const unsigned seed = 20261202;
  std::printf("seed %u\n", seed);
  std::mt19937 rng(seed);
  for (int range : {3, 9, 40, 300}) {
    std::uniform_int_distribution<int> coord(-range, range);
    for (int i = 0; i < 3000; ++i) {
      pm::GridPoint a{coord(rng), coord(rng)}, b{coord(rng), coord(rng)}, c{coord(rng), coord(rng)};
      const auto t = pm::GridTriangle::ccw(a, b, c);  // degenerate ones included
      const auto s = stepped(t);
      ASSERT_EQ(s, brute_force(t)) << "triangle (" << a.x << "," << a.y << ") (" << b.x << "," << b.y << ") ("
                                   << c.x << "," << c.y << ")";
      ASSERT_EQ(s, divided(t));
    }
  }
}

// for_each_span clipped to a window: the whole scan's spans cut to the window's columns and
// rows, whichever row the window starts at (the stepping starts there).
TEST(GridTriangle, ClippedSpansAreTheWholeSpansCut) {
  const unsigned seed = 20261203;
  std::printf("seed %u\n", seed);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> coord(-40, 40), side(0, 30);
  for (int i = 0; i < 3000; ++i) {
    pm::GridPoint a{coord(rng), coord(rng)}, b{coord(rng), coord(rng)}, c{coord(rng), coord(rng)};
    const auto t = pm::GridTriangle::ccw(a, b, c);
    const int c0 = coord(rng), r0 = coord(rng), c1 = c0 + side(rng), r1 = r0 + side(rng);
    std::vector<Span> want;
    for (const Span& s : brute_force(t)) {
      const Span cut{s.y, std::max<std::int64_t>(s.xl, c0), std::min<std::int64_t>(s.xr, c1)};
      if (s.y >= r0 && s.y <= r1 && cut.xl <= cut.xr) want.push_back(cut);
    }
    std::vector<Span> got;
    t.for_each_span(c0, r0, c1, r1, [&](int y, std::int64_t xl, std::int64_t xr) {
      got.push_back({y, xl, xr});
    });
    ASSERT_EQ(got, want) << "triangle (" << a.x << "," << a.y << ") (" << b.x << "," << b.y << ") (" << c.x
                         << "," << c.y << ") window " << c0 << "," << r0 << " .. " << c1 << "," << r1;
  }
}

}  // namespace
