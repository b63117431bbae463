// Extruded shapes (blocks/object_shapes.hpp): roof triangulations checked on hand polygons and
// on random star- and comb-shaped polygons with holes (area, coverage, orientation, every
// ring edge in one roof triangle), then buildings of a real block database extruded every frame
// of a flight with geomorphs and loads, checked against a scan of every drawn triangle (never
// above the ground, roof `height` above it, closed, outward, the right volume).
//
// The terrain: 129 x 129 generated samples (30 m, relief 900 m, heights in whole metres),
// blocks of 33 samples, in UTM zone 33N: sample (col, row) at easting 500015 + 30 col, northing
// 5001935 - 30 row (as in test_object_placement.cpp). The layer "buildings" (GeoPackage,
// EPSG:32633, fields name and height):
//   L          (40,40) (42,40) (42,41) (41,41) (41,43) (40,43): an L, 60 x 90 m, height 12
//   Court      (60,60)..(64,64) with the hole (61,61)..(63,63): 120 m square with a courtyard,
//              height 25
//   Slope<k>   squares of 2 x 2 samples turned by 30 degrees on the 6 steepest spots, height 8
//   r<k>       kRandom random star-shaped footprints (radius 15..50 m), heights 5..40 m
//   NoHeight   a square with a null height; BadHeight: height -5 (both: the default, 10 m)
//   Flat       a zero-area polygon (three collinear points): an empty plan
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "object_terrain.hpp"
#include "printed_seed.hpp"
#include "run_command.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/object_layers.hpp"
#include "terralod/blocks/object_placement.hpp"
#include "terralod/blocks/object_shapes.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace tb = terralod::blocks;
namespace tp = terralod::pm;
namespace tt = terralod::test;
using Ring = std::vector<tb::WorldPoint>;
using Rings = std::vector<Ring>;

// ---------------------------------------------------------------- the test's own geometry

double ring_area(const Ring& r, tb::WorldPoint o) {  // signed, shoelace, relative to o
  double a = 0;
  for (std::size_t k = 0; k < r.size(); ++k) {
    const tb::WorldPoint &u = r[k], &w = r[(k + 1) % r.size()];
    a += (u.x - o.x) * (w.y - o.y) - (w.x - o.x) * (u.y - o.y);
  }
  return 0.5 * a;
}

double polygon_area(const Rings& rs) {
  double a = std::abs(ring_area(rs[0], rs[0][0]));
  for (std::size_t r = 1; r < rs.size(); ++r) a -= std::abs(ring_area(rs[r], rs[0][0]));
  return a;
}

bool in_ring(const Ring& r, double x, double y) {  // crossing number
  bool in = false;
  for (std::size_t k = 0, j = r.size() - 1; k < r.size(); j = k++)
    if ((r[k].y > y) != (r[j].y > y) && x < r[j].x + (y - r[j].y) / (r[k].y - r[j].y) * (r[k].x - r[j].x))
      in = !in;
  return in;
}

bool in_polygon(const Rings& rs, double x, double y) {
  if (!in_ring(rs[0], x, y)) return false;
  for (std::size_t r = 1; r < rs.size(); ++r)
    if (in_ring(rs[r], x, y)) return false;
  return true;
}

double tri_area(tb::WorldPoint a, tb::WorldPoint b, tb::WorldPoint c) {
  return 0.5 * ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x));
}

// Every invariant of a plan of `rs` (expected to be a simple polygon with holes inside it).
std::size_t slivers = 0;  // roof triangles of collinear vertices (within the grid), all tests

void check_plan(const Rings& rs, std::mt19937& rng, const std::string& what) {
  SCOPED_TRACE(what);
  const tb::ShapeFootprint f = tb::plan_footprint(rs);
  ASSERT_EQ(f.status, tb::ShapeFootprint::Status::Ok);
  const double area = polygon_area(rs);
  EXPECT_NEAR(f.area, area, 1e-9 * area);
  const tb::WorldPoint o = rs[0][0];
  double sum = 0;
  for (const auto& t : f.roof) {
    const tb::WorldPoint a{f.points[t[0]].x - o.x, f.points[t[0]].y - o.y};
    const tb::WorldPoint b{f.points[t[1]].x - o.x, f.points[t[1]].y - o.y};
    const tb::WorldPoint c{f.points[t[2]].x - o.x, f.points[t[2]].y - o.y};
    const double ta = tri_area(a, b, c);
    sum += ta;
    // Counter-clockwise on the snapping grid (side / 2^30): a triangle of three vertices
    // collinear within the grid may have an area of either sign within its perimeter x grid.
    const double grid = std::max(f.max.x - f.min.x, f.max.y - f.min.y) / 1073741824.0;
    const double perimeter = std::hypot(b.x - a.x, b.y - a.y) + std::hypot(c.x - b.x, c.y - b.y) +
                             std::hypot(a.x - c.x, a.y - c.y);
    if (ta <= 2 * grid * perimeter) {
      EXPECT_GT(ta, -2 * grid * perimeter) << "not counter-clockwise";
      ++slivers;
      continue;
    }
    std::uniform_real_distribution<double> u(0.02, 0.98);
    for (int s = 0; s < 3; ++s) {  // points inside the triangle are inside the polygon
      double l1 = u(rng), l2 = u(rng);
      if (l1 + l2 > 1) l1 = 1 - l1, l2 = 1 - l2;
      const double x = o.x + a.x + l1 * (b.x - a.x) + l2 * (c.x - a.x);
      const double y = o.y + a.y + l1 * (b.y - a.y) + l2 * (c.y - a.y);
      EXPECT_TRUE(in_polygon(rs, x, y))
          << "roof triangle outside the polygon or in a hole at " << x << " " << y;
    }
  }
  EXPECT_NEAR(sum, area, 1e-9 * area) << "the roof's area is not the polygon's";
  const std::size_t holes = f.ring_start.size() - 2;
  EXPECT_EQ(f.roof.size(), f.points.size() + 2 * holes - 2);
  // Every ring edge (the solid on its left) is an edge of exactly one roof triangle, same way.
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
  for (const auto& t : f.roof)
    for (int k = 0; k < 3; ++k) ++edges[{t[k], t[(k + 1) % 3]}];
  for (std::size_t r = 0; r + 1 < f.ring_start.size(); ++r)
    for (std::uint32_t k = f.ring_start[r]; k < f.ring_start[r + 1]; ++k) {
      const std::uint32_t n = k + 1 == f.ring_start[r + 1] ? f.ring_start[r] : k + 1;
      EXPECT_EQ(edges[std::pair(k, n)], 1) << "ring " << r << " edge " << k;
      EXPECT_EQ(edges[std::pair(n, k)], 0) << "ring " << r << " edge " << k << " reversed";
    }
  // Coverage: random points of the polygon lie in exactly one roof triangle.
  std::uniform_real_distribution<double> ux(f.min.x, f.max.x), uy(f.min.y, f.max.y);
  for (int s = 0; s < 200; ++s) {
    const double x = ux(rng), y = uy(rng);
    if (!in_polygon(rs, x, y)) continue;
    int n = 0;
    for (const auto& t : f.roof) {
      const tb::WorldPoint &a = f.points[t[0]], &b = f.points[t[1]], &c = f.points[t[2]];
      const auto side = [&](const tb::WorldPoint& p, const tb::WorldPoint& q) {
        return (q.x - p.x) * (y - p.y) - (q.y - p.y) * (x - p.x);
      };
      n += side(a, b) > 0 && side(b, c) > 0 && side(c, a) > 0;
    }
    EXPECT_EQ(n, 1) << "point " << x << " " << y;
  }
}

// A star-shaped ring around (cx, cy): n vertices at angles 2 pi (j + 0.4 u) / n, u in [0, 1)
// (gaps under 2 pi 1.4 / n), at radii in [rmin, rmax]; with n >= 8 every edge stays farther
// than rmin cos(32 degrees) from the centre.
Ring star(std::mt19937& rng, double cx, double cy, double rmin, double rmax, int n) {
  std::uniform_real_distribution<double> u(0, 0.4), ur(rmin, rmax);
  Ring r;
  for (int j = 0; j < n; ++j) {
    const double a = 2 * std::numbers::pi * (j + u(rng)) / n, rad = ur(rng);
    r.push_back({cx + rad * std::cos(a), cy + rad * std::sin(a)});
  }
  return r;
}

// A comb: a bar [0, W] x [0, 10] with `teeth` teeth upwards, a square hole under each tooth.
Rings comb(std::mt19937& rng, int teeth) {
  std::uniform_real_distribution<double> uw(4, 12), uh(15, 60);
  std::vector<double> xa, xb, h;
  double x = 0;
  for (int i = 0; i < teeth; ++i) {
    xa.push_back(x), x += uw(rng), xb.push_back(x), h.push_back(uh(rng));
    if (i + 1 < teeth) x += uw(rng);
  }
  Rings rs(1);
  rs[0] = {{0, 0}, {x, 0}};
  for (int i = teeth - 1; i >= 0; --i) {
    rs[0].push_back({xb[i], h[i]});
    rs[0].push_back({xa[i], h[i]});
    if (i > 0) rs[0].push_back({xa[i], 10}), rs[0].push_back({xb[i - 1], 10});
  }
  for (int i = 0; i < teeth; ++i) {
    const double m = 0.25 * (xb[i] - xa[i]);
    rs.push_back({{xa[i] + m, 3}, {xb[i] - m, 3}, {xb[i] - m, 7}, {xa[i] + m, 7}});
  }
  return rs;
}

// The same polygon as a GIS file might give it: far from the origin, rings of either
// orientation, sometimes closed by a repeated first vertex, with collinear vertices.
Rings disguise(Rings rs, std::mt19937& rng) {
  std::bernoulli_distribution coin(0.5), rare(0.3);
  for (Ring& r : rs) {
    for (tb::WorldPoint& p : r) p.x += 512345.0, p.y += 5012345.0;
    if (rare(rng)) {  // a collinear vertex halfway along every other edge
      Ring q;
      for (std::size_t k = 0; k < r.size(); ++k) {
        q.push_back(r[k]);
        const tb::WorldPoint& n = r[(k + 1) % r.size()];
        if (k % 2 == 0) q.push_back({0.5 * (r[k].x + n.x), 0.5 * (r[k].y + n.y)});
      }
      r = q;
    }
    if (coin(rng)) std::reverse(r.begin(), r.end());
    if (coin(rng)) r.push_back(r.front());
  }
  return rs;
}

TEST(ShapePlan, HandPolygons) {
  std::mt19937 rng = tt::printed_seed_rng(19);
  const Rings l = {{{0, 0}, {20, 0}, {20, 10}, {10, 10}, {10, 30}, {0, 30}}};  // 200 + 200
  const Rings u = {
      {{0, 0}, {30, 0}, {30, 20}, {20, 20}, {20, 10}, {10, 10}, {10, 20}, {0, 20}}};  // 600 - 100
  const Rings court = {{{0, 0}, {20, 0}, {20, 20}, {0, 20}},
                       {{5, 5}, {15, 5}, {15, 15}, {5, 15}}};  // 400 - 100
  const Rings comb3 = {{{0, 0},
                        {50, 0},
                        {50, 30},
                        {40, 30},
                        {40, 10},
                        {30, 10},
                        {30, 30},
                        {20, 30},
                        {20, 10},
                        {10, 10},
                        {10, 30},
                        {0, 30}}};  // 500 + 3 * 200
  EXPECT_DOUBLE_EQ(tb::plan_footprint(l).area, 400.0);
  EXPECT_DOUBLE_EQ(tb::plan_footprint(u).area, 500.0);
  EXPECT_DOUBLE_EQ(tb::plan_footprint(court).area, 300.0);
  EXPECT_DOUBLE_EQ(tb::plan_footprint(comb3).area, 1100.0);
  for (const auto& [rs, name] : {std::pair{l, "L"}, {u, "U"}, {court, "courtyard"}, {comb3, "comb"}}) {
    check_plan(rs, rng, name);
    Rings cw = rs;  // clockwise exterior, counter-clockwise hole, closing vertices repeated
    for (Ring& r : cw) std::reverse(r.begin(), r.end()), r.push_back(r.front());
    check_plan(cw, rng, std::string(name) + " reversed and closed");
  }
  // The hole's vertices are the roof's too: 8 vertices, 1 hole: 8 triangles.
  EXPECT_EQ(tb::plan_footprint(court).roof.size(), 8u);
  // Two holes side by side in a bar, sharing the same largest x.
  check_plan({{{0, 0}, {40, 0}, {40, 10}, {0, 10}},
              {{5, 2}, {15, 2}, {15, 4}, {5, 4}},
              {{5, 6}, {15, 6}, {15, 8}, {5, 8}}},
             rng, "two holes");
}

TEST(ShapePlan, DegenerateFootprintsGiveNoRoofAndNoError) {
  using S = tb::ShapeFootprint::Status;
  EXPECT_EQ(tb::plan_footprint({}).status, S::Degenerate);
  EXPECT_EQ(tb::plan_footprint({{}}).status, S::Degenerate);
  EXPECT_EQ(tb::plan_footprint({{{1, 1}, {2, 2}}}).status, S::Degenerate);
  const tb::ShapeFootprint flat = tb::plan_footprint({{{0, 0}, {1, 1}, {3, 3}, {2, 2}, {0, 0}}});
  EXPECT_EQ(flat.status, S::Degenerate);
  EXPECT_TRUE(flat.empty());
  EXPECT_EQ(tb::plan_footprint({{{5, 5}, {5, 5}, {5, 5}}}).status, S::Degenerate);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(tb::plan_footprint({{{0, 0}, {1, 0}, {nan, 1}}}).status, S::Degenerate);
  // A hole without area is dropped; repeated vertices are merged.
  const tb::ShapeFootprint sq =
      tb::plan_footprint({{{0, 0}, {10, 0}, {10, 0}, {10, 10}, {0, 10}, {0, 10}}, {{2, 2}, {4, 4}, {3, 3}}});
  EXPECT_EQ(sq.status, S::Ok);
  EXPECT_EQ(sq.points.size(), 4u);
  EXPECT_EQ(sq.roof.size(), 2u);
  EXPECT_DOUBLE_EQ(sq.area, 100.0);
  // A hole outside the exterior ring: not a polygon with holes.
  const tb::ShapeFootprint out =
      tb::plan_footprint({{{0, 0}, {10, 0}, {10, 10}, {0, 10}}, {{20, 0}, {21, 0}, {21, 1}}});
  EXPECT_EQ(out.status, S::NotSimple);
  EXPECT_TRUE(out.empty());
  // A hole in the notch of an L (inside its box, outside the L): no bridge can reach it.
  const tb::ShapeFootprint notch = tb::plan_footprint(
      {{{0, 0}, {20, 0}, {20, 10}, {10, 10}, {10, 30}, {0, 30}}, {{14, 14}, {16, 14}, {16, 16}, {14, 16}}});
  EXPECT_EQ(notch.status, S::NotSimple);
  EXPECT_TRUE(notch.empty());
}

TEST(ShapePlan, RandomStarsAndCombsWithHoles) {
  std::mt19937 rng = tt::printed_seed_rng(2026);
  std::uniform_int_distribution<int> un(3, 40), uk(0, 4), uhn(3, 10), uteeth(2, 8);
  // Holes (centres 30 m out, radius <= 8 m) need an exterior ring of >= 8 vertices: its edges
  // stay >= 60 cos(32 deg) = 50.9 m from the centre.
  std::uniform_real_distribution<double> uphase(0, 2 * std::numbers::pi), uhr(3, 8);
  for (int trial = 0; trial < 300; ++trial) {
    const int n = un(rng), k = n >= 8 ? uk(rng) : 0;
    Rings rs = {star(rng, 0, 0, 60, 100, n)};
    const double phase = uphase(rng);
    for (int j = 0; j < k; ++j) {  // 2 * 30 sin(pi / 4) = 42 m apart: disjoint
      const double a = phase + 2 * std::numbers::pi * j / k;
      rs.push_back(star(rng, 30 * std::cos(a), 30 * std::sin(a), 2, uhr(rng), uhn(rng)));
    }
    check_plan(disguise(rs, rng), rng, "star " + std::to_string(trial));
  }
  std::printf("%zu of the roof triangles are slivers of collinear vertices\n", slivers);
  for (int trial = 0; trial < 100; ++trial)
    check_plan(disguise(comb(rng, uteeth(rng)), rng), rng, "comb " + std::to_string(trial));
}

// ---------------------------------------------------------------- buildings on a flight

const std::string& objects_name(const tb::ObjectPlacer& placer, std::uint32_t i) {
  return placer.objects().at(i).name;
}

constexpr int kSize = 129, kRandom = 40;
const tp::GridTransform kUtm = tt::object_terrain_transform();

// A polygon's WKT from rings of (col, row) samples (each ring closed here).
std::string polygon_wkt(const std::vector<std::vector<std::pair<double, double>>>& rings) {
  std::string w = "POLYGON (";
  for (std::size_t r = 0; r < rings.size(); ++r) {
    w += r ? ", (" : "(";
    for (std::size_t k = 0; k <= rings[r].size(); ++k) {
      const auto [c, row] = rings[r][k % rings[r].size()];
      const auto [x, y] = kUtm.to_world(c, row);
      char text[80];
      std::snprintf(text, sizeof text, "%s%.9f %.9f", k ? ", " : "", x, y);
      w += text;
    }
    w += ")";
  }
  return w + ")";
}

struct Building {
  std::string wkt, name, height;  // height: "" = null
};

void write_buildings(const std::string& path, const std::vector<Building>& buildings) {
  GDALAllRegister();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GPKG");
  ASSERT_NE(drv, nullptr);
  GDALDatasetUniquePtr ds(drv->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  ASSERT_TRUE(ds) << path;
  OGRSpatialReference srs;
  srs.importFromEPSG(32633);
  OGRLayer* layer = ds->CreateLayer("buildings", &srs, wkbPolygon, nullptr);
  ASSERT_NE(layer, nullptr);
  OGRFieldDefn name("name", OFTString), height("height", OFTReal);
  ASSERT_EQ(layer->CreateField(&name), OGRERR_NONE);
  ASSERT_EQ(layer->CreateField(&height), OGRERR_NONE);
  for (const Building& b : buildings) {
    OGRFeatureUniquePtr f(OGRFeature::CreateFeature(layer->GetLayerDefn()));
    f->SetField("name", b.name.c_str());
    if (b.height.empty())
      f->SetFieldNull(f->GetFieldIndex("height"));
    else
      f->SetField("height", std::stod(b.height));
    OGRGeometry* g = nullptr;
    ASSERT_EQ(OGRGeometryFactory::createFromWkt(b.wkt.c_str(), nullptr, &g), OGRERR_NONE) << b.wkt;
    f->SetGeometryDirectly(g);
    ASSERT_EQ(layer->CreateFeature(f.get()), OGRERR_NONE);
  }
}

struct Scene {
  tp::Heightfield hf;
  std::string db;
  std::map<std::string, double> height;  // building name -> its expected extrusion height
  std::vector<std::string> slopes;       // the buildings on the steepest spots
};

const Scene& scene() {
  static const Scene s = [] {
    Scene r;
    tt::ObjectTerrain t = tt::make_object_terrain("shapes", 21);
    r.hf = std::move(t.hf);
    r.db = t.db;
    const std::filesystem::path dir = std::filesystem::path(r.db).parent_path();
    std::vector<Building> b;
    const auto add = [&](const std::string& name,
                         const std::vector<std::vector<std::pair<double, double>>>& rings,
                         const std::string& height, double expected) {
      b.push_back({polygon_wkt(rings), name, height});
      r.height[name] = expected;
    };
    add("L", {{{40, 40}, {42, 40}, {42, 41}, {41, 41}, {41, 43}, {40, 43}}}, "12", 12);
    add("Court", {{{60, 60}, {64, 60}, {64, 64}, {60, 64}}, {{61, 61}, {63, 61}, {63, 63}, {61, 63}}}, "25",
        25);
    add("NoHeight", {{{70, 50}, {71, 50}, {71, 51}, {70, 51}}}, "", 10);
    add("BadHeight", {{{72, 50}, {73, 50}, {73, 51}, {72, 51}}}, "-5", 10);
    add("Flat", {{{74, 50}, {75, 51}, {76, 52}}}, "5", 5);
    add("Edge", {{{-1, 60}, {1, 60}, {1, 62}, {-1, 62}}}, "10", 10);  // half off the terrain
    // The steepest spots (largest height difference between neighbours), 8 samples apart.
    std::vector<std::tuple<double, int, int>> steep;
    for (int row = 8; row < kSize - 8; ++row)
      for (int col = 8; col < kSize - 8; ++col)
        steep.emplace_back(std::hypot(r.hf.at(col + 1, row) - r.hf.at(col - 1, row),
                                      r.hf.at(col, row + 1) - r.hf.at(col, row - 1)),
                           col, row);
    std::sort(steep.rbegin(), steep.rend());
    std::vector<std::pair<int, int>> spots;
    for (const auto& [g, col, row] : steep) {
      if (spots.size() == 6) break;
      if (std::none_of(spots.begin(), spots.end(),
                       [&](auto p) { return std::abs(p.first - col) < 8 && std::abs(p.second - row) < 8; }))
        spots.push_back({col, row});
    }
    for (std::size_t k = 0; k < spots.size(); ++k) {  // 2 x 2 samples turned by 30 degrees
      std::vector<std::pair<double, double>> sq;
      for (int j = 0; j < 4; ++j) {
        const double a = std::numbers::pi * (30.0 + 90.0 * j) / 180.0;
        sq.push_back(
            {spots[k].first + std::sqrt(2.0) * std::cos(a), spots[k].second + std::sqrt(2.0) * std::sin(a)});
      }
      r.slopes.push_back("Slope" + std::to_string(k));
      add(r.slopes.back(), {sq}, "8", 8);
    }
    std::mt19937 rng = tt::printed_seed_rng(44);
    std::uniform_real_distribution<double> uc(8.0, kSize - 9.0), uh(5.0, 40.0);
    std::uniform_int_distribution<int> un(3, 12);
    for (int k = 0; k < kRandom; ++k) {
      const double c = uc(rng), row = uc(rng), h = std::round(uh(rng));
      std::vector<std::pair<double, double>> ring;
      for (const tb::WorldPoint& p : star(rng, c, row, 0.5, 1.7, un(rng))) ring.push_back({p.x, p.y});
      add("r" + std::to_string(k), {ring}, std::to_string(int(h)), h);
    }
    write_buildings((dir / "buildings.gpkg").string(), b);
    auto db = tb::BlockDatabase::open(r.db, tb::BlockDatabase::Mode::ReadWrite);
    tb::ObjectLayerOptions lo;
    lo.name = "buildings";
    lo.input = (dir / "buildings.gpkg").string();
    lo.height_field = "height";
    tb::add_object_layer(db, lo);
    return r;
  }();
  return s;
}

// The drawn triangles whose plan box meets [x0, x1] x [y0, y1]: a scan of all of them.
std::vector<std::size_t> triangles_near(const tb::DrawnMesh& m, double x0, double y0, double x1, double y1) {
  std::vector<std::size_t> out;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const tp::Vec3 &a = m.positions[m.triangles[t][0]], &b = m.positions[m.triangles[t][1]],
                   &c = m.positions[m.triangles[t][2]];
    if (std::max({a.x, b.x, c.x}) >= x0 - 1e-6 && std::min({a.x, b.x, c.x}) <= x1 + 1e-6 &&
        std::max({a.y, b.y, c.y}) >= y0 - 1e-6 && std::min({a.y, b.y, c.y}) <= y1 + 1e-6)
      out.push_back(t);
  }
  return out;
}

// The heights of every drawn triangle (of `near`) containing (x, y): the drawn surface there.
std::vector<double> drawn_heights_at(const tb::DrawnMesh& m, const std::vector<std::size_t>& near, double x,
                                     double y) {
  std::vector<double> out;
  for (const std::size_t t : near) {
    const tp::Vec3 &a = m.positions[m.triangles[t][0]], &b = m.positions[m.triangles[t][1]],
                   &c = m.positions[m.triangles[t][2]];
    const double det = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (det == 0) continue;
    const double l1 = ((x - a.x) * (c.y - a.y) - (y - a.y) * (c.x - a.x)) / det;
    const double l2 = ((b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x)) / det;
    if (l1 >= -1e-9 && l2 >= -1e-9 && 1 - l1 - l2 >= -1e-9)
      out.push_back((1 - l1 - l2) * a.z + l1 * b.z + l2 * c.z);
  }
  return out;
}

tp::Camera camera_at(const Scene& s, double col, double row, double above, double yaw, double pitch) {
  return tt::camera_over(s.hf, col, row, above, yaw, pitch);
}

}  // namespace

namespace {

tp::Vec3 operator-(const tp::Vec3& a, const tp::Vec3& b) { return tp::sub(a, b); }
using Key = std::array<double, 6>;  // a directed edge by its end positions

// Every check of one solid (the triangles `tris` of `mesh`) of the footprint `rs` extruded by
// `height`, against the drawn triangles `near` of `drawn`. Returns roof - height - base (the
// drawn relief the solid spans) and counts the points checked.
double check_solid(const tb::ObjectMesh& mesh, const std::vector<std::size_t>& tris, const Rings& rs,
                   double height, const tb::DrawnMesh& drawn, const std::vector<std::size_t>& near,
                   std::mt19937& rng, std::size_t& points) {
  double base = std::numeric_limits<double>::infinity(), roof = -base;
  std::map<Key, int> edges;
  for (const std::size_t t : tris)
    for (int k = 0; k < 3; ++k) {
      const tp::Vec3 &p = mesh.positions[mesh.triangles[t][k]],
                     &q = mesh.positions[mesh.triangles[t][(k + 1) % 3]];
      base = std::min(base, p.z), roof = std::max(roof, p.z);
      ++edges[{p.x, p.y, p.z, q.x, q.y, q.z}];
    }
  // Closed: every edge once each way.
  for (const auto& [e, count] : edges) {
    EXPECT_EQ(count, 1) << "edge used " << count << " times";
    const auto back = edges.find({e[3], e[4], e[5], e[0], e[1], e[2]});
    EXPECT_TRUE(back != edges.end() && back->second == 1) << "edge without its twin";
  }
  EXPECT_GE(roof - base, height - 1e-9);
  // Volume (divergence theorem, relative to one vertex): positive and area x (roof - base).
  const tp::Vec3 o = mesh.positions[mesh.triangles[tris[0]][0]];
  double volume = 0;
  for (const std::size_t t : tris) {
    const tp::Vec3 a = mesh.positions[mesh.triangles[t][0]] - o, b = mesh.positions[mesh.triangles[t][1]] - o,
                   c = mesh.positions[mesh.triangles[t][2]] - o;
    volume += tp::dot(a, tp::cross(b, c)) / 6.0;
    // Normals: unit, and those of the face (so outward, the volume being positive).
    const tp::Vec3 n = tp::cross(b - a, c - a);
    const double len = std::sqrt(tp::dot(n, n));
    if (len < 1e-9 * (roof - base + 1.0)) continue;  // a sliver of collinear roof vertices
    for (int k = 0; k < 3; ++k) {
      const tp::Vec3& vn = mesh.normals[mesh.triangles[t][k]];
      EXPECT_NEAR(tp::dot(vn, vn), 1.0, 1e-12);
      EXPECT_GT(tp::dot(vn, n) / len, 1.0 - 1e-9) << "a normal not the face's";
    }
  }
  const double expected = polygon_area(rs) * (roof - base);
  EXPECT_GT(volume, 0.0);
  EXPECT_NEAR(volume, expected, 1e-6 * expected);
  // Never above the drawn ground; the roof `height` above it: on the boundary and inside.
  std::vector<std::pair<double, double>> at;
  for (const Ring& r : rs)
    for (std::size_t k = 0; k < r.size(); ++k)
      for (const double t : {0.0, 0.25, 0.5, 0.75}) {
        const tb::WorldPoint &u = r[k], &w = r[(k + 1) % r.size()];
        at.push_back({u.x + t * (w.x - u.x), u.y + t * (w.y - u.y)});
      }
  tb::WorldPoint lo = rs[0][0], hi = lo;
  for (const tb::WorldPoint& p : rs[0])
    lo.x = std::min(lo.x, p.x), lo.y = std::min(lo.y, p.y), hi.x = std::max(hi.x, p.x),
    hi.y = std::max(hi.y, p.y);
  std::uniform_real_distribution<double> ux(lo.x, hi.x), uy(lo.y, hi.y);
  for (int k = 0, inside = 0; k < 400 && inside < 30; ++k) {
    const double x = ux(rng), y = uy(rng);
    if (in_polygon(rs, x, y)) at.push_back({x, y}), ++inside;
  }
  for (const auto& [x, y] : at) {
    const std::vector<double> hs = drawn_heights_at(drawn, near, x, y);
    EXPECT_FALSE(hs.empty()) << "nothing drawn under " << x << " " << y;
    for (const double h : hs) {
      EXPECT_GE(h, base - 1e-6) << "the solid floats at " << x << " " << y;
      EXPECT_LE(h, roof - height + 1e-6)
          << "the roof is less than its height above the ground at " << x << " " << y;
    }
    ++points;
  }
  return roof - height - base;
}

TEST(ShapeExtrusion, BuildingsStandOnTheDrawnTerrainAlongAFlightWithGeomorphsAndLoads) {
  const Scene& s = scene();
  const auto db = tb::BlockDatabase::open(s.db);
  tb::ObjectPlacer placer(db, {"buildings"});
  tb::ShapeExtruder shapes(placer);
  const std::vector<tb::MapObject>& objects = placer.objects();
  ASSERT_EQ(objects.size(), s.height.size());
  EXPECT_EQ(shapes.plan_stats().polygons, objects.size());
  EXPECT_EQ(shapes.plan_stats().degenerate, 1u);  // Flat
  EXPECT_EQ(shapes.plan_stats().not_simple, 0u);
  EXPECT_EQ(shapes.plan_stats().default_heights, 2u);  // NoHeight, BadHeight
  for (std::size_t i = 0; i < objects.size(); ++i) EXPECT_EQ(shapes.height(i), s.height.at(objects[i].name));
  tb::RuntimeOptions ro;
  ro.morph_seconds = 0.5;
  tb::TerrainRuntime rt(s.db, ro);
  tb::ObjectMesh mesh;
  std::mt19937 rng = tt::printed_seed_rng(5);
  std::size_t solids = 0, points = 0, morph_frames = 0, missing_frames = 0;
  double slope_relief = 0;
  for (int f = 0; f < 24; ++f) {
    // Low over the terrain, heading north-east then turning: blocks load and morph in.
    tp::Camera cam = camera_at(s, 15 + 3.5 * f, 110 - 3.0 * f, 250.0 + 20 * f, 45.0 + 4 * f, -20.0);
    rt.fit_camera(cam);
    const tp::View view(cam);
    const double t = f / 60.0;
    const tb::RuntimeFrameStats st = f % 3 == 2 ? rt.update(view, t) : rt.update_until_loaded(view, t);
    morph_frames += rt.stats().moving_vertices > 0;
    missing_frames += st.missing_in_view > 0;
    const std::vector<tb::PlacedObject>& placed = placer.place(rt, view);
    shapes.extrude(rt, placed, mesh);
    ASSERT_EQ(mesh.normals.size(), mesh.positions.size());
    ASSERT_EQ(mesh.triangle_object.size(), mesh.triangles.size());
    std::map<std::uint32_t, std::vector<std::size_t>> by_object;
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) by_object[mesh.triangle_object[t]].push_back(t);
    EXPECT_EQ(shapes.stats().shapes, by_object.size());
    const tb::DrawnMesh& drawn = rt.drawn_mesh();
    for (const tb::PlacedObject& p : placed) {
      const tb::MapObject& m = *p.object;
      const auto i = std::uint32_t(p.object - objects.data());
      SCOPED_TRACE("frame " + std::to_string(f) + ", " + m.name);
      const std::vector<std::size_t> near =
          triangles_near(drawn, m.feature.min.x, m.feature.min.y, m.feature.max.x, m.feature.max.y);
      bool over_drawn = true;
      for (const Ring& r : m.feature.rings)
        for (const tb::WorldPoint& q : r)
          over_drawn = over_drawn && !drawn_heights_at(drawn, near, q.x, q.y).empty();
      const auto solid = by_object.find(i);
      if (m.name == "Flat" || !over_drawn) {
        EXPECT_TRUE(solid == by_object.end()) << "a solid for an empty plan or over nothing drawn";
        continue;
      }
      ASSERT_TRUE(solid != by_object.end());
      const double relief =
          check_solid(mesh, solid->second, m.feature.rings, s.height.at(m.name), drawn, near, rng, points);
      if (std::find(s.slopes.begin(), s.slopes.end(), m.name) != s.slopes.end())
        slope_relief = std::max(slope_relief, relief);
      ++solids;
    }
  }
  std::printf(
      "%zu solids and %zu ground points checked; largest drawn relief under a slope building %.1f m\n",
      solids, points, slope_relief);
  EXPECT_GT(solids, 100u);
  EXPECT_GT(slope_relief, 10.0) << "the slope buildings must stand on slopes";
  EXPECT_GT(morph_frames, 0u) << "the flight must exercise geomorphs";
  EXPECT_GT(missing_frames, 0u) << "the flight must draw blocks still loading";
  // Steady state: the same frame again reuses the mesh's storage.
  const tp::Vec3* positions = mesh.positions.data();
  const auto* triangles = mesh.triangles.data();
  shapes.extrude(rt, placer.placed(), mesh);
  EXPECT_EQ(mesh.positions.data(), positions);
  EXPECT_EQ(mesh.triangles.data(), triangles);
}

TEST(ShapeExtrusion, ADefaultHeightThatIsNotAPositiveNumberIsRefused) {
  const auto db = tb::BlockDatabase::open(scene().db);
  tb::ObjectPlacer placer(db, {"buildings"});
  for (const double h :
       {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()})
    EXPECT_THROW(tb::ShapeExtruder(placer, {.default_height_m = h}), std::invalid_argument) << h;
  EXPECT_EQ(tb::ShapeExtruder(placer, {.default_height_m = 3.0}).height(0), 12.0);  // L keeps its own
}

TEST(ShapeExtrusion, FootprintsOverNothingDrawnAreSkippedAndCounted) {
  const Scene& s = scene();
  const auto db = tb::BlockDatabase::open(s.db);
  tb::ObjectPlacer placer(db, {"buildings"});
  tb::ShapeExtruder shapes(placer);
  tb::TerrainRuntime rt(s.db);
  // 360 m east of the west edge, looking west and down at Edge (anchor on the edge, half off it).
  tp::Camera cam = camera_at(s, 12, 61, 400.0, 270.0, -50.0);
  rt.fit_camera(cam);
  const tp::View view(cam);
  rt.update_until_loaded(view, 0.0);
  const std::vector<tb::PlacedObject>& placed = placer.place(rt, view);
  ASSERT_TRUE(std::any_of(placed.begin(), placed.end(),
                          [](const tb::PlacedObject& p) { return p.object->name == "Edge"; }));
  tb::ObjectMesh mesh;
  shapes.extrude(rt, placed, mesh);
  EXPECT_EQ(shapes.stats().skipped_undrawn, 1u);
  for (const std::uint32_t o : mesh.triangle_object) EXPECT_NE(objects_name(placer, o), "Edge");
}

}  // namespace
