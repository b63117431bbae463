// Map objects on the terrain as drawn (blocks/object_placement.hpp) over a real block database:
// along a flight with geomorphs and block loads, every placed object stands on the drawn mesh
// (checked against a scan of every drawn triangle, not drawn_height) at its feature's world
// coordinates, exactly the objects in the frustum are returned, hidden layers return nothing,
// and picking returns the object under a pixel, or the ground point where the ray meets the
// drawn triangles.
//
// The terrain: 129 x 129 generated samples (30 m, heights in whole metres), blocks of 33
// samples (4 x 4 PM blocks), in UTM zone 33N: sample (col, row) at easting 500015 + 30 col,
// northing 5001935 - 30 row. The layers (GeoPackage, EPSG:32633):
//   points  kPoints points at seeded random (col, row) in [2, 126]^2, named "p<k>", plus
//           "Summit" at (64.5, 64.5)
//   trail   one line (10,10) -> (30,10) -> (30,50): 20 + 40 = 60 samples long, so its anchor
//           (halfway, 30 samples along) is (30, 20)
//   lake    the square (60,60)..(80,80) with the hole (60,60)..(70,70) (an L, area 400 - 100):
//           centroid ((400 * 70 - 100 * 65) / 300, same) = (71.6667, 71.6667)
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
#include <vector>

#include "object_terrain.hpp"
#include "printed_seed.hpp"
#include "run_command.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/object_layers.hpp"
#include "terralod/blocks/object_placement.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace tb = terralod::blocks;
namespace tp = terralod::pm;
namespace tt = terralod::test;

constexpr int kSize = 129, kPoints = 150;
const tp::GridTransform kUtm = tt::object_terrain_transform();

std::string strf(const char* format, int k) {
  char text[32];
  std::snprintf(text, sizeof text, format, k);
  return text;
}

std::string at(double col, double row) {
  const auto [x, y] = kUtm.to_world(col, row);
  return std::to_string(x) + " " + std::to_string(y);
}

// Writes one layer of `wkts` (with a "name" field) as a GeoPackage in EPSG:32633.
void write_layer(const std::string& path, const std::vector<std::pair<std::string, std::string>>& features) {
  GDALAllRegister();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GPKG");
  ASSERT_NE(drv, nullptr);
  GDALDatasetUniquePtr ds(drv->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  ASSERT_TRUE(ds) << path;
  OGRSpatialReference srs;
  srs.importFromEPSG(32633);
  OGRLayer* layer = ds->CreateLayer("objects", &srs, wkbUnknown, nullptr);
  ASSERT_NE(layer, nullptr);
  OGRFieldDefn name("name", OFTString);
  ASSERT_EQ(layer->CreateField(&name), OGRERR_NONE);
  for (const auto& [wkt, n] : features) {
    OGRFeatureUniquePtr f(OGRFeature::CreateFeature(layer->GetLayerDefn()));
    f->SetField("name", n.c_str());
    OGRGeometry* g = nullptr;
    ASSERT_EQ(OGRGeometryFactory::createFromWkt(wkt.c_str(), nullptr, &g), OGRERR_NONE) << wkt;
    f->SetGeometryDirectly(g);
    ASSERT_EQ(layer->CreateFeature(f.get()), OGRERR_NONE);
  }
}

// Icons up to 1000 m, labels to 2000 m, nothing beyond; labels ranked by the number in the name.
const char* kNearRules = R"({"ranges": [{"max_distance_m": 1000, "draw": "icon"},
  {"max_distance_m": 2000, "draw": "label"}, {"draw": "none"}], "priority_field": "name"})";
// Icons of 30 m while they cover at least 20 px: up to 30 focal / 20 metres away.
const char* kSizedRules = R"({"ranges": [{"min_screen_px": 20, "draw": "icon"}, {"draw": "none"}],
  "icon_size_m": 30})";

struct Scene {
  tp::Heightfield hf;
  std::string db;
  std::map<std::string, std::pair<double, double>> where;  // object name -> its (col, row)
};

const Scene& scene() {
  static const Scene s = [] {
    Scene r;
    tt::ObjectTerrain t = tt::make_object_terrain("placement", 21);
    r.hf = std::move(t.hf);
    r.db = t.db;
    const std::filesystem::path dir = std::filesystem::path(r.db).parent_path();
    std::mt19937 rng = tt::printed_seed_rng(7);
    std::uniform_real_distribution<double> u(2.0, kSize - 3.0);
    std::vector<std::pair<std::string, std::string>> points;
    for (int k = 0; k < kPoints; ++k) {
      const double c = u(rng), w = u(rng);
      const std::string name = strf("p%d", k);
      points.push_back({"POINT (" + at(c, w) + ")", name});
      r.where[name] = {c, w};
    }
    points.push_back({"POINT (" + at(64.5, 64.5) + ")", "Summit"});
    r.where["Summit"] = {64.5, 64.5};
    write_layer((dir / "points.gpkg").string(), points);
    write_layer((dir / "trail.gpkg").string(),
                {{"LINESTRING (" + at(10, 10) + ", " + at(30, 10) + ", " + at(30, 50) + ")", "Trail"}});
    r.where["Trail"] = {30, 20};
    write_layer((dir / "lake.gpkg").string(),
                {{"POLYGON ((" + at(60, 60) + ", " + at(80, 60) + ", " + at(80, 80) + ", " + at(60, 80) +
                      ", " + at(60, 60) + "), (" + at(60, 60) + ", " + at(70, 60) + ", " + at(70, 70) + ", " +
                      at(60, 70) + ", " + at(60, 60) + "))",
                  "Lake"}});
    r.where["Lake"] = {215.0 / 3.0, 215.0 / 3.0};
    auto db = tb::BlockDatabase::open(r.db, tb::BlockDatabase::Mode::ReadWrite);
    for (const char* name : {"points", "trail", "lake"}) {
      tb::ObjectLayerOptions lo;
      lo.name = name;
      lo.input = (dir / (std::string(name) + ".gpkg")).string();
      tb::add_object_layer(db, lo);
    }
    // The same points twice more, with rules by distance and by size on screen.
    for (const auto& [name, rules] : {std::pair{"near", kNearRules}, std::pair{"sized", kSizedRules}}) {
      tb::ObjectLayerOptions lo;
      lo.name = name;
      lo.input = (dir / "points.gpkg").string();
      lo.rules_json = rules;
      tb::add_object_layer(db, lo);
    }
    return r;
  }();
  return s;
}

// The height of the drawn mesh at world (x, y): a scan of every drawn triangle in the world
// plane (NaN where none contains the point).
double mesh_height(const tb::DrawnMesh& m, double x, double y) {
  for (const auto& t : m.triangles) {
    const tp::Vec3 &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    if (x < std::min({a.x, b.x, c.x}) - 1e-6 || x > std::max({a.x, b.x, c.x}) + 1e-6 ||
        y < std::min({a.y, b.y, c.y}) - 1e-6 || y > std::max({a.y, b.y, c.y}) + 1e-6)
      continue;
    const double det = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (det == 0) continue;
    const double l1 = ((x - a.x) * (c.y - a.y) - (y - a.y) * (c.x - a.x)) / det;
    const double l2 = ((b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x)) / det;
    if (l1 >= -1e-9 && l2 >= -1e-9 && 1 - l1 - l2 >= -1e-9) return (1 - l1 - l2) * a.z + l1 * b.z + l2 * c.z;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

tp::Camera camera_at(const Scene& s, double col, double row, double above, double yaw, double pitch) {
  return tt::camera_over(s.hf, col, row, above, yaw, pitch);
}

TEST(ObjectPlacement, AnchorsFollowTheDrawnMeshAlongAFlightWithGeomorphsAndLoads) {
  const Scene& s = scene();
  const auto db = tb::BlockDatabase::open(s.db);
  tb::ObjectPlacer placer(db, {"points", "trail", "lake"});
  ASSERT_EQ(placer.objects().size(), std::size_t(kPoints + 3));
  for (const tb::MapObject& m : placer.objects()) {  // plan positions: the features' world coordinates
    const auto [col, row] = s.where.at(m.name);
    const auto [x, y] = s.hf.transform.to_world(col, row);
    EXPECT_NEAR(m.anchor.x, x, 1e-6) << m.name;
    EXPECT_NEAR(m.anchor.y, y, 1e-6) << m.name;
  }
  tb::RuntimeOptions ro;
  ro.morph_seconds = 0.5;
  tb::TerrainRuntime rt(s.db, ro);
  std::size_t placed_total = 0, outside_total = 0, morph_frames = 0, missing_frames = 0;
  for (int f = 0; f < 24; ++f) {
    // Low over the terrain, heading north-east then turning: blocks load and morph in.
    tp::Camera cam = camera_at(s, 15 + 3.5 * f, 110 - 3.0 * f, 250.0 + 20 * f, 45.0 + 4 * f, -20.0);
    rt.fit_camera(cam);
    const tp::View view(cam);
    const double t = f / 60.0;
    const tb::RuntimeFrameStats st = f % 3 == 2 ? rt.update(view, t) : rt.update_until_loaded(view, t);
    morph_frames += rt.stats().moving_vertices > 0;
    missing_frames += st.missing_in_view > 0;
    const bool points_on = f < 12 || f >= 16;
    placer.set_layer_visible("points", points_on);
    const std::vector<tb::PlacedObject>& placed = placer.place(rt, view);
    std::map<const tb::MapObject*, tp::Vec3> got;
    for (const tb::PlacedObject& p : placed) {
      EXPECT_TRUE(got.emplace(p.object, p.anchor).second) << "placed twice: " << p.object->name;
      EXPECT_EQ(p.anchor.x, p.object->anchor.x);
      EXPECT_EQ(p.anchor.y, p.object->anchor.y);
      if (!points_on) {
        EXPECT_NE(p.object->layer, 0u) << "hidden layer placed: " << p.object->name;
      }
    }
    for (const tb::MapObject& m : placer.objects()) {
      const double h = mesh_height(rt.drawn_mesh(), m.anchor.x, m.anchor.y);
      const bool in =
          !std::isnan(h) && view.contains({m.anchor.x, m.anchor.y, h}) && (points_on || m.layer != 0);
      const auto g = got.find(&m);
      ASSERT_EQ(g != got.end(), in) << "frame " << f << ", " << m.name << " (drawn height " << h << ")";
      if (in) {
        EXPECT_NEAR(g->second.z, h, 1e-6) << "frame " << f << ", " << m.name;
      }
      outside_total += !in;
    }
    EXPECT_EQ(placer.stats().objects_placed, placed.size());
    EXPECT_LE(placer.stats().objects_tested, placer.objects().size());
    placed_total += placed.size();
  }
  EXPECT_GT(placed_total, 100u);
  EXPECT_GT(outside_total, 100u);
  EXPECT_GT(morph_frames, 0u) << "the flight must exercise geomorphs";
  EXPECT_GT(missing_frames, 0u) << "the flight must draw blocks still loading";
}

TEST(ObjectPlacement, ObjectsOutsideTheFrustumAreNotTested) {
  const Scene& s = scene();
  const auto db = tb::BlockDatabase::open(s.db);
  tb::ObjectPlacer placer(db, {"points"});
  tb::TerrainRuntime rt(s.db);
  // Looking out of the terrain from its west edge: nothing is in view.
  tp::Camera cam = camera_at(s, 0, 64, 300.0, 270.0, 0.0);
  rt.fit_camera(cam);
  rt.update_until_loaded(tp::View(cam), 0.0);
  EXPECT_TRUE(placer.place(rt, tp::View(cam)).empty());
  EXPECT_EQ(placer.stats().objects_tested, 0u);
  EXPECT_GE(placer.stats().regions_culled, 1u);
}

TEST(ObjectPlacement, PickReturnsTheObjectUnderThePixelElseTheDrawnGround) {
  const Scene& s = scene();
  const auto db = tb::BlockDatabase::open(s.db);
  tb::ObjectPlacer placer(db, {"points", "lake"});
  tb::TerrainRuntime rt(s.db);
  // Above the Summit, looking steeply down from the south.
  tp::Camera cam = camera_at(s, 64.5, 80, 900.0, 0.0, -60.0);
  rt.fit_camera(cam);
  const tp::View view(cam);
  rt.update_until_loaded(view, 0.0);
  placer.place(rt, view);
  const tb::PlacedObject* summit = nullptr;
  for (const tb::PlacedObject& p : placer.placed())
    if (p.object->name == "Summit") summit = &p;
  ASSERT_NE(summit, nullptr);
  double px = 0, py = 0;
  ASSERT_TRUE(view.project(summit->anchor, px, py));
  // Within the pick radius (8 px) of the Summit and nearer it than to any other object.
  for (const auto& [dx, dy] : {std::pair{0.0, 0.0}, std::pair{3.0, -2.0}}) {
    const auto hit = placer.pick_pixel(rt, px + dx, py + dy);
    ASSERT_TRUE(hit);
    ASSERT_NE(hit->object, nullptr);
    EXPECT_EQ(hit->object->name, "Summit");
    EXPECT_EQ(hit->object->feature.attribute("name")->value, "Summit");
    EXPECT_EQ(hit->point.z, summit->anchor.z);
  }
  // A pixel more than 8 px from every placed object: the ground, where the ray first meets
  // the drawn mesh (checked by the scan: on the mesh, and the ray above it before).
  double gx = -1, gy = -1;
  for (double y = 10; y < cam.height_px && gx < 0; y += 7)
    for (double x = 10; x < cam.width_px && gx < 0; x += 7) {
      bool clear = true;
      for (const tb::PlacedObject& p : placer.placed()) {
        double qx = 0, qy = 0;
        if (view.project(p.anchor, qx, qy) && std::hypot(qx - x, qy - y) < 12) clear = false;
      }
      if (clear) gx = x, gy = y;
    }
  ASSERT_GE(gx, 0);
  const auto ground = placer.pick_pixel(rt, gx, gy);
  ASSERT_TRUE(ground);
  EXPECT_EQ(ground->object, nullptr);
  const tp::Vec3 e = view.eye(), g = ground->point;
  EXPECT_NEAR(mesh_height(rt.drawn_mesh(), g.x, g.y), g.z, 1e-6);
  double gpx = 0, gpy = 0;
  ASSERT_TRUE(view.project(g, gpx, gpy));
  EXPECT_NEAR(gpx, gx, 1e-6);
  EXPECT_NEAR(gpy, gy, 1e-6);
  for (int k = 1; k < 200; ++k) {  // the ray before the ground point is above the drawn mesh
    const double a = k / 200.0;
    const tp::Vec3 q{e.x + a * (g.x - e.x), e.y + a * (g.y - e.y), e.z + a * (g.z - e.z)};
    const double h = mesh_height(rt.drawn_mesh(), q.x, q.y);
    if (!std::isnan(h)) {
      EXPECT_GT(q.z, h - 1e-6) << "the ray meets the mesh before " << a;
    }
  }
  // Rays aimed at the Summit from around it, low and high: it is picked exactly when the
  // segment up to it stays above the drawn mesh (scanned at 4 m steps) except within the pick
  // radius r before it; rays that dip below by less than 1 m, or near r, are not judged.
  const double r = 8.0 * view.depth(summit->anchor) / view.focal_px();
  int seen = 0, hidden = 0;
  for (int k = 0; k < 48; ++k) {
    const double az = k * 7.5 * std::numbers::pi / 180, el = (1.0 + (k % 6) * 4.0) * std::numbers::pi / 180;
    const tp::Vec3 a = summit->anchor;
    const double len = 2500;
    const tp::Vec3 o{a.x + len * std::cos(el) * std::cos(az), a.y + len * std::cos(el) * std::sin(az),
                     a.z + len * std::sin(el)};
    double deepest_before = 0;  // how far below the mesh the ray gets before t = len - 2 r
    bool near_r = false;
    for (double t = 2; t < len; t += 4) {
      const tp::Vec3 q{o.x + t / len * (a.x - o.x), o.y + t / len * (a.y - o.y), o.z + t / len * (a.z - o.z)};
      const double h = mesh_height(rt.drawn_mesh(), q.x, q.y);
      if (std::isnan(h) || q.z >= h) continue;
      if (t < len - 2 * r)
        deepest_before = std::max(deepest_before, h - q.z);
      else if (t < len - 0.5 * r)
        near_r = true;
    }
    if (near_r || (deepest_before > 0 && deepest_before < 1)) continue;
    const auto hit = placer.pick(rt, o, {a.x - o.x, a.y - o.y, a.z - o.z});
    if (deepest_before == 0) {
      ++seen;
      ASSERT_TRUE(hit && hit->object) << "ray " << k << " sees the Summit";
      EXPECT_LE(hit->distance, len + 1e-6) << "ray " << k;
    } else {
      ++hidden;
      EXPECT_FALSE(hit && hit->object == summit->object)
          << "ray " << k << ": the Summit is behind the terrain";
    }
  }
  EXPECT_GT(seen, 0);
  EXPECT_GT(hidden, 0);
  // Hidden layers are not picked: the Summit's pixel then gives the ground.
  placer.set_layer_visible("points", false);
  placer.place(rt, view);
  const auto under = placer.pick_pixel(rt, px, py);
  ASSERT_TRUE(under);
  EXPECT_EQ(under->object, nullptr);
  EXPECT_NEAR(under->point.z, summit->anchor.z, 1.0);
  // A ray into the sky meets nothing.
  EXPECT_FALSE(placer.pick(rt, e, {0, 0, 1}));
}

// Rules inside placement: exactly the objects drawn, in view and within their rules are placed,
// each as its range says (hand rules here, not choose()), and objects beyond the rules are not
// touched: every object tested lies within the rules' reach plus one grid cell's diagonal.
TEST(ObjectPlacement, RulesChooseTheDrawingAndObjectsBeyondThemCostNothing) {
  const Scene& s = scene();
  const auto db = tb::BlockDatabase::open(s.db);
  tb::ObjectPlacer placer(db, {"near", "sized"});
  ASSERT_EQ(placer.objects().size(), 2 * std::size_t(kPoints + 1));
  EXPECT_EQ(placer.rules(0).priority_field(), "name");
  EXPECT_EQ(placer.objects()[0].priority, 0.0);  // "p0" is no number: priority 0
  EXPECT_EQ(placer.objects()[kPoints + 1].extent_m, 30.0);
  // Every object, its ring and its attributes at least.
  EXPECT_GE(placer.memory_bytes(), placer.objects().size() * (sizeof(tb::MapObject) + sizeof(tb::WorldPoint) +
                                                              sizeof(tb::ObjectAttribute)));
  tb::TerrainRuntime rt(s.db);
  std::size_t icons = 0, labels = 0, beyond = 0, tested = 0;
  for (int f = 0; f < 6; ++f) {
    tp::Camera cam = camera_at(s, 10 + 20 * f, 120 - 18 * f, 150.0, 30.0 + 50 * f, -15.0);
    rt.fit_camera(cam);
    // Every other frame through a strong ground scale (singular values 0.82 and 1.28): the rules
    // take the distance the camera sees, which is ground metres on a continent-wide frame.
    if (f % 2) cam.ground = {1.25, 0.12, 0.85};
    const tp::View view(cam);
    rt.update_until_loaded(view, f);
    std::map<const tb::MapObject*, tb::Representation> got;
    for (const tb::PlacedObject& p : placer.place(rt, view)) got[p.object] = p.draw;
    const double focal = view.focal_px(), sized_reach = 30.0 * focal / 20.0;
    for (const tb::MapObject& m : placer.objects()) {
      const double h = mesh_height(rt.drawn_mesh(), m.anchor.x, m.anchor.y);
      const tp::Vec3 p{m.anchor.x, m.anchor.y, h};
      const double wx = p.x - cam.x, wy = p.y - cam.y;
      const double d = std::hypot(cam.ground.xx * wx + cam.ground.xy * wy,
                                  cam.ground.xy * wx + cam.ground.yy * wy, p.z - cam.z);
      tb::Representation want = tb::Representation::None;
      if (m.layer == 0)
        want = d <= 1000 ? tb::Representation::Icon : d <= 2000 ? tb::Representation::Label : want;
      if (m.layer == 1 && d <= sized_reach) want = tb::Representation::Icon;
      if (std::isnan(h) || !view.contains(p)) want = tb::Representation::None;
      const auto g = got.find(&m);
      ASSERT_EQ(g != got.end() ? g->second : tb::Representation::None, want)
          << "frame " << f << ", layer " << m.layer << ", " << m.name << " at " << d << " m";
      icons += want == tb::Representation::Icon, labels += want == tb::Representation::Label;
      beyond += !std::isnan(h) && view.contains(p) && want == tb::Representation::None;
    }
    // Nothing beyond the reach (2000 m, sized_reach, as seen: over the ground scale's smallest
    // singular value in world metres) plus a cell's diagonal is tested.
    const double cell = std::hypot(s.hf.width() * 30.0, s.hf.height() * 30.0) /
                        std::ceil(std::sqrt(placer.objects().size() / 8.0));
    std::size_t reachable = 0;
    for (const tb::MapObject& m : placer.objects())
      reachable += std::hypot(m.anchor.x - cam.x, m.anchor.y - cam.y) <=
                   (m.layer == 0 ? 2000 : sized_reach) / cam.ground.min_distance_scale() + cell;
    EXPECT_LE(placer.stats().objects_tested, reachable) << "frame " << f;
    tested += placer.stats().objects_tested;
  }
  std::printf("rules: %zu icons, %zu labels placed, %zu in view beyond the rules; %zu objects tested\n",
              icons, labels, beyond, tested);
  EXPECT_GT(icons, 10u);
  EXPECT_GT(labels, 10u);
  EXPECT_GT(beyond, 50u);
}

TEST(ObjectPlacement, AnchorsOfLinesAndPolygonsAndBadLayerNames) {
  const Scene& s = scene();
  const auto db = tb::BlockDatabase::open(s.db);
  tb::ObjectPlacer placer(db, {"trail", "lake"});
  ASSERT_EQ(placer.objects().size(), 2u);
  EXPECT_EQ(placer.objects()[0].name, "Trail");
  EXPECT_EQ(placer.objects()[0].kind, tb::ObjectKind::Line);
  EXPECT_EQ(placer.objects()[1].kind, tb::ObjectKind::Shape);
  try {
    tb::ObjectPlacer bad(db, {"trail", "nope"});
    ADD_FAILURE() << "a missing layer must be an error";
  } catch (const tb::DatabaseError& e) {
    EXPECT_NE(std::string(e.what()).find(s.db), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("nope"), std::string::npos) << e.what();
  }
  EXPECT_THROW(tb::ObjectPlacer(db, {"lake", "lake"}), std::invalid_argument);
  EXPECT_THROW(placer.set_layer_visible("points", false), std::invalid_argument);
}

}  // namespace
