// Tests of the greedy-insertion TIN (rect and polygon) and the non-regular grid: hand-derived
// fixtures, the Delaunay property, exact cover of the domain, and the reported error against
// the independent brute-force checker and pm::LInfError.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#include "mesh_checker.hpp"
#include "printed_seed.hpp"
#include "screen_error_checker.hpp"
#include "terralod/blocks/greedy_tin.hpp"
#include "terralod/pm/linf_error.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace pm = terralod::pm;
namespace tb = terralod::blocks;
namespace tt = terralod::test;
using pm::ErrorMetric;

__extension__ typedef __int128 int128;

pm::Heightfield plane(int w, int h) {
  pm::Heightfield hf(w, h);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) hf.at(c, r) = 2.0 * c + 3.0 * r + 5.0;
  return hf;
}

pm::Heightfield terrain(int size, std::uint64_t seed, bool integer_heights = false) {
  pm::TerrainOptions o;
  o.width = o.height = size;
  o.seed = seed;
  o.quantize_to_metres = integer_heights;
  return pm::generate_terrain(o);
}

/// The sub-heightfield of `d` (same heights), so that the checker's domain is the TIN's domain.
pm::Heightfield crop(const pm::Heightfield& hf, tb::SampleRect d) {
  pm::Heightfield c(d.width(), d.height());
  for (int r = 0; r < d.height(); ++r)
    for (int col = 0; col < d.width(); ++col) c.at(col, r) = hf.at(d.col0 + col, d.row0 + r);
  return c;
}

/// The surface as a pm::TriangleMesh over `hf` whose sample (0,0) is (col0,row0) of the TIN's.
pm::TriangleMesh to_mesh(const pm::Heightfield& hf, const tb::TinSurface& s, int col0 = 0, int row0 = 0) {
  pm::TriangleMesh m;
  for (const auto& p : s.points)
    m.vertices.push_back(std::uint32_t((p[1] - row0) * hf.width() + (p[0] - col0)));
  m.triangles = s.triangles;
  m.error_bound = s.error;
  return m;
}

pm::GridPoint gp(const std::array<int, 2>& p) { return {p[0], p[1]}; }

/// Max over the triangles of pm::LInfError::triangle.
double linf_max(const pm::Heightfield& hf, const tb::TinSurface& s, ErrorMetric metric) {
  const pm::LInfError err(hf, metric);
  double e = 0.0;
  for (const auto& t : s.triangles)
    e = std::max(e, err.triangle(gp(s.points[t[0]]), gp(s.points[t[1]]), gp(s.points[t[2]])));
  return e;
}

/// Every triangle CCW, and no point strictly inside any triangle's circumcircle.
void expect_delaunay(const tb::TinSurface& s) {
  for (const auto& t : s.triangles) {
    const pm::GridPoint a = gp(s.points[t[0]]), b = gp(s.points[t[1]]), c = gp(s.points[t[2]]);
    ASSERT_GT(pm::orient2d(a, b, c), 0);
    for (const auto& q : s.points) {
      const std::int64_t adx = a.x - q[0], ady = a.y - q[1], bdx = b.x - q[0], bdy = b.y - q[1],
                         cdx = c.x - q[0], cdy = c.y - q[1];
      const int128 det = int128(adx * adx + ady * ady) * (bdx * cdy - cdx * bdy) +
                         int128(bdx * bdx + bdy * bdy) * (cdx * ady - adx * cdy) +
                         int128(cdx * cdx + cdy * cdy) * (adx * bdy - bdx * ady);
      ASSERT_LE(det, 0) << "point (" << q[0] << "," << q[1] << ") inside the circumcircle of (" << a.x << ","
                        << a.y << "),(" << b.x << "," << b.y << "),(" << c.x << "," << c.y << ")";
    }
  }
}

/// Exact cover and exact error of a rect-domain surface by the independent checker.
void expect_checked(const pm::Heightfield& hf, tb::SampleRect d, const tb::TinSurface& s,
                    ErrorMetric metric) {
  const pm::Heightfield c = crop(hf, d);
  tt::CheckOptions co;
  co.continuous = metric == ErrorMetric::Continuous;
  const tt::MeshCheck mc = tt::check_mesh(c, to_mesh(c, s, d.col0, d.row0), co);
  EXPECT_TRUE(mc.topology_ok()) << mc.describe();
  const double brute = co.continuous ? mc.max_continuous_error() : mc.max_sample_error;
  EXPECT_NEAR(s.error, brute, 1e-9 * (1 + brute)) << mc.describe();
  EXPECT_EQ(s.error, linf_max(hf, s, metric));  // the same formulas: bit-identical
}

// --- rect TIN ------------------------------------------------------------------------------

// A plane z = 2 col + 3 row + 5 on 9 x 9 samples: the 4 corners, 2 triangles, error 0.
TEST(GreedyTin, PlaneIsItsFourCorners) {
  const pm::Heightfield hf = plane(9, 9);
  for (ErrorMetric m : {ErrorMetric::Samples, ErrorMetric::Continuous}) {
    const tb::TinSurface s =
        tb::build_greedy_tin(hf, tb::SampleRect{0, 0, 8, 8}, {.max_error = 0.0, .metric = m});
    EXPECT_EQ(s.points.size(), 4u);
    EXPECT_EQ(s.triangles.size(), 2u);
    EXPECT_EQ(s.error, 0.0);
    expect_checked(hf, {0, 0, 8, 8}, s, m);
  }
}

// 9 x 9 zeros with a 10 m bump at (3,5):
//   row 0  . . . . . . . . .      The corners are flat, so the bump is the only sample with an
//   ...                           error (10) and is inserted first. The 5-point TIN is the fan of
//   row 5  . . . X . . . . .      4 triangles around it (the square's corners are cocircular and
//   ...                           the bump lies inside their circle). Worst remaining error: the
//   row 8  . . . . . . . . .      triangle on the right side x = 8 has height 10 (8 - x) / 5, so
//                                 (4,5) reads 8 where the terrain is 0; likewise (3,4) in the top
// triangle, 10 y / 5: the Samples error is 8. The continuous error is 9: the edge (3,5)-(8,0)
// crosses the grid diagonal (3,4)-(4,5) at (3.5,4.5), one tenth of the way, where the TIN is at
// 10 * 9/10 = 9 and the terrain at 0.
TEST(GreedyTin, SingleBumpIsInsertedFirst) {
  pm::Heightfield hf(9, 9);
  hf.at(3, 5) = 10.0;
  for (ErrorMetric m : {ErrorMetric::Samples, ErrorMetric::Continuous}) {
    const tb::TinSurface s =
        tb::build_greedy_tin(hf, tb::SampleRect{0, 0, 8, 8}, {.max_points = 5, .metric = m});
    ASSERT_EQ(s.points.size(), 5u);
    EXPECT_EQ(s.points[4], (std::array<int, 2>{3, 5}));
    EXPECT_EQ(s.triangles.size(), 4u);
    EXPECT_EQ(s.error, m == ErrorMetric::Samples ? 8.0 : 9.0);
    expect_checked(hf, {0, 0, 8, 8}, s, m);
    const tb::TinSurface four =
        tb::build_greedy_tin(hf, tb::SampleRect{0, 0, 8, 8}, {.max_points = 4, .metric = m});
    EXPECT_EQ(four.error, 10.0);
  }
}

// A 5 x 5 ridge, 10 m along column 2:
//   0 0 10 0 0
//   0 0 10 0 0     Exact only with columns 1, 2, 3 represented top and bottom (each strip between
//   0 0 10 0 0     consecutive columns is then a plane in x), so at least 10 points; every inserted
//   0 0 10 0 0     point lies on columns 1..3 (the others are already exact), and the first one
//   0 0 10 0 0     on column 2 (error 10, the only samples with an error before any insertion).
TEST(GreedyTin, RidgeIsExactWithColumnsOneToThree) {
  pm::Heightfield hf(5, 5);
  for (int r = 0; r < 5; ++r) hf.at(2, r) = 10.0;
  for (ErrorMetric m : {ErrorMetric::Samples, ErrorMetric::Continuous}) {
    const tb::TinSurface s = tb::build_greedy_tin(hf, tb::SampleRect{0, 0, 4, 4}, {.metric = m});
    EXPECT_EQ(s.error, 0.0);
    EXPECT_GE(s.points.size(), 10u);
    EXPECT_EQ(s.points[4][0], 2);
    std::set<std::array<int, 2>> pts(s.points.begin(), s.points.end());
    for (int c : {1, 2, 3})
      for (int r : {0, 4}) EXPECT_TRUE(pts.count({c, r})) << c << "," << r;
    for (std::size_t i = 4; i < s.points.size(); ++i) {
      EXPECT_GE(s.points[i][0], 1);
      EXPECT_LE(s.points[i][0], 3);
    }
    expect_checked(hf, {0, 0, 4, 4}, s, m);
    expect_delaunay(s);
  }
}

// White noise: every sample is a candidate, many cocircular ties; checks Delaunay, cover and error.
TEST(GreedyTin, RandomSetsAreDelaunayAndExact) {
  std::mt19937 rng = terralod::test::printed_seed_rng(20240611);
  for (int trial = 0; trial < 6; ++trial) {
    const int w = 9 + int(rng() % 30), h = 9 + int(rng() % 30);
    pm::Heightfield hf(w, h);
    for (double& z : hf.samples()) z = double(rng() % 200);
    const tb::SampleRect d{int(rng() % 4), int(rng() % 4), w - 1 - int(rng() % 4), h - 1 - int(rng() % 4)};
    const ErrorMetric m = trial % 2 ? ErrorMetric::Samples : ErrorMetric::Continuous;
    const std::size_t max_points = 4 + rng() % (d.samples() / 2);
    const tb::TinSurface s = tb::build_greedy_tin(hf, d, {.max_points = max_points, .metric = m});
    SCOPED_TRACE(testing::Message() << "trial " << trial << " " << w << "x" << h << " max_points "
                                    << max_points);
    EXPECT_LE(s.points.size(), max_points);
    // Euler: a triangulation of a convex domain with n points, b of them on its boundary, has
    // 2n - b - 2 triangles.
    std::size_t b = 0;
    for (const auto& p : s.points) b += p[0] == d.col0 || p[0] == d.col1 || p[1] == d.row0 || p[1] == d.row1;
    EXPECT_EQ(s.triangles.size(), 2 * s.points.size() - b - 2);
    expect_delaunay(s);
    expect_checked(hf, d, s, m);
    for (const auto& p : s.points) EXPECT_TRUE(d.contains(p[0], p[1]));
  }
}

// Generated terrain: the error never exceeds max_error and max_points is respected. Points only
// grow: a smaller budget or a larger max_error stops the same greedy sequence earlier, so its
// points are a prefix. (The error itself is not monotone in the point count: a Delaunay flip can
// make a triangle span worse terrain; on this terrain 175 of the first 600 insertions raise it.)
TEST(GreedyTin, ErrorBoundAndPointBudget) {
  const pm::Heightfield hf = terrain(65, 7);
  const tb::SampleRect d{0, 0, 64, 64};
  std::vector<std::array<int, 2>> last;
  for (double e : {50.0, 10.0, 2.0}) {
    const tb::TinSurface s = tb::build_greedy_tin(hf, d, {.max_error = e});
    EXPECT_LE(s.error, e);
    EXPECT_GE(s.points.size(), last.size());
    EXPECT_TRUE(std::equal(last.begin(), last.end(), s.points.begin())) << "not a prefix at " << e;
    last = s.points;
    expect_checked(hf, d, s, ErrorMetric::Continuous);
  }
  last.clear();
  for (std::size_t k : {4, 8, 16, 32, 64, 128, 256, 512}) {
    const tb::TinSurface s = tb::build_greedy_tin(hf, d, {.max_points = k, .metric = ErrorMetric::Samples});
    EXPECT_EQ(s.points.size(), k);
    EXPECT_TRUE(std::equal(last.begin(), last.end(), s.points.begin())) << "not a prefix at " << k;
    last = s.points;
    expect_checked(hf, d, s, ErrorMetric::Samples);
  }
}

// A sub-rectangle of a larger heightfield: only its samples count, only its samples are used.
TEST(GreedyTin, SubRectangleDomain) {
  const pm::Heightfield hf = terrain(80, 3, /*integer_heights=*/true);
  const tb::SampleRect d{17, 5, 60, 71};
  const tb::TinSurface s = tb::build_greedy_tin(hf, d, {.max_error = 3.0});
  EXPECT_LE(s.error, 3.0);
  for (const auto& p : s.points) EXPECT_TRUE(d.contains(p[0], p[1]));
  expect_checked(hf, d, s, ErrorMetric::Continuous);
}

// Holes are not terrain: a 20 m spike in a hole is neither inserted nor measured.
TEST(GreedyTin, HolesAreSkipped) {
  pm::Heightfield hf = plane(9, 9);
  std::vector<std::uint8_t> mask(81, 1);
  hf.at(4, 4) = 1000.0;
  mask[4 * 9 + 4] = 0;
  hf.set_mask(mask);
  for (ErrorMetric m : {ErrorMetric::Samples, ErrorMetric::Continuous}) {
    const tb::TinSurface s = tb::build_greedy_tin(hf, tb::SampleRect{0, 0, 8, 8}, {.metric = m});
    EXPECT_EQ(s.points.size(), 4u);
    EXPECT_EQ(s.error, 0.0);
  }
}

// --- polygon TIN ---------------------------------------------------------------------------

/// Point-in-closed-polygon for integer points (even-odd with exact boundary detection).
bool in_polygon(const std::vector<pm::GridPoint>& poly, pm::GridPoint p) {
  bool inside = false;
  for (std::size_t i = 0, n = poly.size(); i < n; ++i) {
    const pm::GridPoint a = poly[i], b = poly[(i + 1) % n];
    if (pm::orient2d(a, b, p) == 0 && std::min(a.x, b.x) <= p.x && p.x <= std::max(a.x, b.x) &&
        std::min(a.y, b.y) <= p.y && p.y <= std::max(a.y, b.y))
      return true;
    if ((a.y > p.y) != (b.y > p.y)) {
      const std::int64_t o = pm::orient2d(a, b, p);
      if ((o > 0) == (b.y > a.y)) inside = !inside;
    }
  }
  return inside;
}

/// Checks that s covers exactly the polygon and that its error over the samples inside is exact.
void expect_polygon_tin(const pm::Heightfield& hf, const std::vector<pm::GridPoint>& poly,
                        const tb::TinSurface& s, ErrorMetric m) {
  std::int64_t poly2 = 0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const pm::GridPoint a = poly[i], b = poly[(i + 1) % poly.size()];
    poly2 += std::int64_t(a.x) * b.y - std::int64_t(b.x) * a.y;
  }
  std::int64_t area2 = 0;
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
  for (const auto& t : s.triangles) {
    const pm::GridPoint a = gp(s.points[t[0]]), b = gp(s.points[t[1]]), c = gp(s.points[t[2]]);
    const std::int64_t o = pm::orient2d(a, b, c);
    ASSERT_GT(o, 0);
    area2 += o;
    for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
  }
  EXPECT_EQ(area2, std::abs(poly2));  // plan-view area of the TIN = the polygon's
  for (const auto& [e, n] : directed) {
    EXPECT_EQ(n, 1) << "edge used twice in one direction";
    if (!directed.count({e.second, e.first})) {  // boundary edge: on the polygon's boundary
      const pm::GridPoint a = gp(s.points[e.first]), b = gp(s.points[e.second]);
      bool on = false;
      for (std::size_t i = 0; i < poly.size() && !on; ++i) {
        const pm::GridPoint p = poly[i], q = poly[(i + 1) % poly.size()];
        on = pm::orient2d(p, q, a) == 0 && pm::orient2d(p, q, b) == 0 && in_polygon({p, q, p}, a) &&
             in_polygon({p, q, p}, b);
      }
      EXPECT_TRUE(on) << "boundary edge (" << a.x << "," << a.y << ")-(" << b.x << "," << b.y
                      << ") off the polygon";
    }
  }
  for (const auto& p : s.points) EXPECT_TRUE(in_polygon(poly, gp(p)));
  // Every sample inside the polygon lies in some closed triangle; the largest |TIN - z| over them
  // is the Samples error, recomputed in long double by barycentric weights.
  long double worst = 0;
  int x0 = hf.width(), x1 = 0, y0 = hf.height(), y1 = 0;
  for (const auto& q : poly)
    x0 = std::min(x0, q.x), x1 = std::max(x1, q.x), y0 = std::min(y0, q.y), y1 = std::max(y1, q.y);
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      if (!in_polygon(poly, {x, y})) continue;
      bool found = false;
      for (const auto& t : s.triangles) {
        const pm::GridPoint a = gp(s.points[t[0]]), b = gp(s.points[t[1]]), c = gp(s.points[t[2]]), p{x, y};
        const std::int64_t wa = pm::orient2d(b, c, p), wb = pm::orient2d(c, a, p), wc = pm::orient2d(a, b, p);
        if (wa < 0 || wb < 0 || wc < 0) continue;
        const long double z = (wa * (long double)hf.at(a.x, a.y) + wb * (long double)hf.at(b.x, b.y) +
                               wc * (long double)hf.at(c.x, c.y)) /
                              (long double)(wa + wb + wc);
        worst = std::max(worst, std::abs(z - (long double)hf.at(x, y)));
        found = true;
      }
      EXPECT_TRUE(found) << "sample (" << x << "," << y << ") inside the polygon is not covered";
    }
  if (m == ErrorMetric::Samples)
    EXPECT_NEAR(s.error, double(worst), 1e-9 * (1 + double(worst)));
  else
    EXPECT_GE(s.error, double(worst) - 1e-9);
  EXPECT_EQ(s.error, linf_max(hf, s, m));
}

// An L-shaped polygon (non-convex, given clockwise in (col,row), with fractional vertices that
// round to samples) over generated terrain with whole-metre heights (so that error 0 is exact).
TEST(GreedyTinPolygon, LShapeCoversExactlyThePolygon) {
  const pm::Heightfield hf = terrain(40, 11, /*integer_heights=*/true);
  const std::vector<std::array<double, 2>> poly = {{2.2, 3.1},   {2.0, 36.4},  {30.0, 36.0},
                                                   {29.6, 20.0}, {15.0, 20.2}, {15.0, 2.8}};
  // Rounded, and reversed to CCW in (col,row) (orient2d > 0), the order the TIN's points start with.
  const std::vector<pm::GridPoint> rounded = {{15, 3}, {15, 20}, {30, 20}, {30, 36}, {2, 36}, {2, 3}};
  for (ErrorMetric m : {ErrorMetric::Samples, ErrorMetric::Continuous})
    for (double e : {20.0, 5.0, 0.0}) {
      const tb::TinSurface s = tb::build_greedy_tin(hf, poly, {.max_error = e, .metric = m});
      EXPECT_LE(s.error, e);
      for (std::size_t i = 0; i < rounded.size(); ++i)
        EXPECT_EQ(s.points[i], (std::array<int, 2>{rounded[i].x, rounded[i].y}));
      expect_polygon_tin(hf, rounded, s, m);
    }
}

// A triangle on a plane: its 3 vertices, 1 triangle, error 0; samples on its slanted edge count.
TEST(GreedyTinPolygon, TriangleOnAPlane) {
  const pm::Heightfield hf = plane(12, 12);
  const tb::TinSurface s =
      tb::build_greedy_tin(hf, std::vector<std::array<double, 2>>{{1, 1}, {10, 1}, {1, 10}});
  EXPECT_EQ(s.points.size(), 3u);
  EXPECT_EQ(s.triangles.size(), 1u);
  EXPECT_EQ(s.error, 0.0);
}

// A star-shaped, strongly non-convex polygon on white noise, max_points respected.
TEST(GreedyTinPolygon, StarOnNoise) {
  std::mt19937 rng = terralod::test::printed_seed_rng(77);
  pm::Heightfield hf(41, 41);
  for (double& z : hf.samples()) z = double(rng() % 100);
  std::vector<std::array<double, 2>> poly;
  std::vector<pm::GridPoint> rounded;
  for (int i = 0; i < 10; ++i) {
    const double a = 2 * 3.14159265358979 * i / 10, r = i % 2 ? 7.0 : 19.0;
    const double x = 20 + r * std::cos(a), y = 20 + r * std::sin(a);
    poly.push_back({x, y});
    rounded.push_back({int(std::round(x)), int(std::round(y))});
  }
  std::reverse(rounded.begin(), rounded.end());  // CCW in (col,row), as the builder stores it
  for (std::size_t k : {10, 40, 200}) {
    const tb::TinSurface s =
        tb::build_greedy_tin(hf, poly, {.max_points = k, .metric = ErrorMetric::Samples});
    EXPECT_LE(s.points.size(), k);
    expect_polygon_tin(hf, rounded, s, ErrorMetric::Samples);
  }
}

TEST(GreedyTinPolygon, BadPolygonsThrow) {
  const pm::Heightfield hf = plane(20, 20);
  using Poly = std::vector<std::array<double, 2>>;
  EXPECT_THROW(tb::build_greedy_tin(hf, Poly{{1, 1}, {5, 1}}), std::invalid_argument);
  EXPECT_THROW(tb::build_greedy_tin(hf, Poly{{1, 1}, {5, 1}, {9, 1}}), std::invalid_argument);   // no area
  EXPECT_THROW(tb::build_greedy_tin(hf, Poly{{1, 1}, {25, 1}, {5, 9}}), std::invalid_argument);  // outside
  EXPECT_THROW(tb::build_greedy_tin(hf, Poly{{1, 1}, {9, 9}, {9, 1}, {1, 9}}),
               std::invalid_argument);  // bow tie
  EXPECT_THROW(tb::build_greedy_tin(hf, Poly{{1, 1}, {1.2, 1.3}, {0.9, 0.8}}),
               std::invalid_argument);  // one sample
}

// --- non-regular grid ----------------------------------------------------------------------

void expect_grid_checked(const pm::Heightfield& hf, tb::SampleRect d, const tb::NonRegularGrid& g,
                         ErrorMetric m) {
  EXPECT_TRUE(std::is_sorted(g.cols.begin(), g.cols.end()));
  EXPECT_TRUE(std::is_sorted(g.rows.begin(), g.rows.end()));
  EXPECT_EQ(g.cols.front(), d.col0);
  EXPECT_EQ(g.cols.back(), d.col1);
  EXPECT_EQ(g.rows.front(), d.row0);
  EXPECT_EQ(g.rows.back(), d.row1);
  EXPECT_EQ(g.surface.points.size(), g.cols.size() * g.rows.size());
  EXPECT_EQ(g.surface.triangles.size(), 2 * (g.cols.size() - 1) * (g.rows.size() - 1));
  EXPECT_EQ(g.error, g.surface.error);
  expect_checked(hf, d, g.surface, m);
}

TEST(NonRegularGrid, PlaneIsItsCorners) {
  const pm::Heightfield hf = plane(9, 7);
  const tb::NonRegularGrid g = tb::build_nonregular_grid(hf, {0, 0, 8, 6});
  EXPECT_EQ(g.cols, (std::vector<int>{0, 8}));
  EXPECT_EQ(g.rows, (std::vector<int>{0, 6}));
  EXPECT_EQ(g.error, 0.0);
  expect_grid_checked(hf, {0, 0, 8, 6}, g, ErrorMetric::Continuous);
}

// The bump of SingleBumpIsInsertedFirst: the first insertion adds column 3 and row 5, giving the
// 3 x 3 grid cols {0,3,8}, rows {0,5,8}. Cell [3,8]x[0,5] has (3,4) on its left side at height
// 10 * 4/5 = 8, and (4,5) on its bottom side at 10 * 4/5 = 8: error 8 (the diagonals' crossings
// next to those samples read at most 8 too).
TEST(NonRegularGrid, SingleBumpAddsItsRowAndColumn) {
  pm::Heightfield hf(9, 9);
  hf.at(3, 5) = 10.0;
  for (ErrorMetric m : {ErrorMetric::Samples, ErrorMetric::Continuous}) {
    const tb::NonRegularGrid g = tb::build_nonregular_grid(hf, {0, 0, 8, 8}, {.max_points = 9, .metric = m});
    EXPECT_EQ(g.cols, (std::vector<int>{0, 3, 8}));
    EXPECT_EQ(g.rows, (std::vector<int>{0, 5, 8}));
    EXPECT_EQ(g.error, 8.0);
    expect_grid_checked(hf, {0, 0, 8, 8}, g, m);
    const tb::NonRegularGrid g8 = tb::build_nonregular_grid(hf, {0, 0, 8, 8}, {.max_points = 8, .metric = m});
    EXPECT_EQ(g8.cols.size() * g8.rows.size(), 4u);  // 3 x 3 would exceed 8
    EXPECT_EQ(g8.error, 10.0);
  }
}

// The ridge: exact with columns 0..4 (1, 2, 3 added) and rows {0, 4}.
TEST(NonRegularGrid, RidgeNeedsThreeColumns) {
  pm::Heightfield hf(5, 5);
  for (int r = 0; r < 5; ++r) hf.at(2, r) = 10.0;
  const tb::NonRegularGrid g = tb::build_nonregular_grid(hf, {0, 0, 4, 4});
  EXPECT_EQ(g.error, 0.0);
  for (int c : {1, 2, 3}) EXPECT_TRUE(std::binary_search(g.cols.begin(), g.cols.end(), c));
  expect_grid_checked(hf, {0, 0, 4, 4}, g, ErrorMetric::Continuous);
}

TEST(NonRegularGrid, GeneratedTerrainBudgetsAndBounds) {
  const pm::Heightfield hf = terrain(70, 5);
  const tb::SampleRect d{3, 2, 66, 69};
  double last = 1e300;
  for (std::size_t s : {4, 9, 25, 100, 400}) {
    const tb::NonRegularGrid g = tb::build_nonregular_grid(hf, d, {.max_points = s});
    EXPECT_LE(g.cols.size() * g.rows.size(), s);
    EXPECT_LE(g.error, last * (1 + 1e-12) + 1e-9) << s;  // rows/columns only ever get added here
    last = g.error;
    expect_grid_checked(hf, d, g, ErrorMetric::Continuous);
  }
  const tb::NonRegularGrid g = tb::build_nonregular_grid(hf, d, {.max_error = 15.0});
  EXPECT_LE(g.error, 15.0);
  // At an equal point budget the TIN adapts better than the grid (the paper's comparison).
  const tb::TinSurface tin = tb::build_greedy_tin(hf, d, {.max_points = g.cols.size() * g.rows.size()});
  EXPECT_LT(tin.error, g.error);
}

// --- real data -----------------------------------------------------------------------------

TEST(GreedyTinRealData, N44W072Crop) {
  auto hf = tt::read_hgt_crop("N44W072.hgt", 300, 500, 257);
  if (!hf) GTEST_SKIP() << "N44W072.hgt not in " << TERRALOD_DATA_DIR;
  const tb::SampleRect d{0, 0, 256, 256};
  for (double e : {1.0, 5.0}) {
    const tb::TinSurface s = tb::build_greedy_tin(*hf, d, {.max_error = e});
    EXPECT_LE(s.error, e);
    expect_checked(*hf, d, s, ErrorMetric::Continuous);
    const tb::TinSurface ss = tb::build_greedy_tin(*hf, d, {.max_error = e, .metric = ErrorMetric::Samples});
    EXPECT_LE(ss.error, e);
    EXPECT_LE(ss.triangles.size(), s.triangles.size());
    expect_checked(*hf, d, ss, ErrorMetric::Samples);
  }
  const tb::NonRegularGrid g = tb::build_nonregular_grid(*hf, d, {.max_points = 1089});
  expect_grid_checked(*hf, d, g, ErrorMetric::Continuous);
}

}  // namespace
