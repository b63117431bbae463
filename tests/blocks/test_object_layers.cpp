// Object layers (blocks/object_layers.hpp): GeoJSON, Shapefile and GeoPackage files written here
// (the last two through OGR) are added to real block databases (SQLite files) and read back:
// coordinates against hand-known UTM values and the geographic frame's formula, the block index
// against a brute-force overlap test, attributes, and every bad input leaving the file unchanged.
//
// The terrain of every test: 65 x 65 samples, 33-sample blocks, so 2 x 2 blocks of 32 sample
// steps (block (c, r) covers columns [32c, 32c + 32] and rows [32r, 32r + 32]):
//
//   col 0          32          64
//   row 0  +-------+-------+
//          | (0,0) | (1,0) |
//      32  +-------+-------+
//          | (0,1) | (1,1) |
//      64  +-------+-------+
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>
#include <sqlite3.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/object_layers.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
using terralod::pm::GridTransform;

constexpr int kSize = 65, kBlock = 33;
// UTM zone 33N terrain: sample (col, row) at easting 500015 + 30 col, northing 5001935 - 30 row.
const GridTransform kUtm = GridTransform::north_up(500015.0, 5001935.0, 30.0, 30.0);

struct TempDir {
  fs::path dir;
  TempDir() {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    dir = fs::temp_directory_path() / (std::string("terralod_objects_") + info->name());
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~TempDir() { fs::remove_all(dir); }
  std::string operator/(const std::string& name) const { return (dir / name).string(); }
};

std::string wkt_of_epsg(int epsg) {
  OGRSpatialReference srs;
  EXPECT_EQ(srs.importFromEPSG(epsg), OGRERR_NONE);
  char* text = nullptr;
  srs.exportToWkt(&text);
  std::string s = text;
  CPLFree(text);
  return s;
}

// A database with no blocks but the metadata of a built terrain: the world frame `world`,
// the CRS `epsg` and the georeference `crs` (what 'terralod build' records).
void make_db(const std::string& path, int epsg, const GridTransform& crs, const GridTransform& world) {
  tb::DatabaseInfo info;
  info.grid_width = info.grid_height = kSize;
  info.block_size = kBlock;
  info.transform = world;
  info.crs_wkt = wkt_of_epsg(epsg);
  info.source = "test";
  auto db = tb::BlockDatabase::create(path, info);
  db.put_georeference({crs, ""});
}

// Options naming the layer and the file; `kind`, fields and rules as given ("" = none).
tb::ObjectLayerOptions opts(const std::string& name, const std::string& input,
                            std::optional<tb::ObjectKind> kind = {}, const std::string& label = "",
                            const std::string& height = "", std::optional<std::string> rules = {}) {
  tb::ObjectLayerOptions o;
  o.name = name;
  o.input = input;
  o.kind = kind;
  o.label_field = label;
  o.height_field = height;
  o.rules_json = std::move(rules);
  o.rules_source = "r.json";
  return o;
}

/// `o` taking only the parts of geometry `g`.
tb::ObjectLayerOptions only(tb::ObjectLayerOptions o, tb::GeometryType g) {
  o.geometry = g;
  return o;
}

void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

std::string bytes_of(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

struct VectorFeature {
  std::string wkt, name;
  double height = 0.0;
};

// Writes `features` with OGR: fields name (string) and height (real), in EPSG `epsg` (0: no CRS).
void write_vector(const std::string& path, const char* driver, int epsg,
                  const std::vector<VectorFeature>& features) {
  GDALAllRegister();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName(driver);
  ASSERT_NE(drv, nullptr) << driver;
  GDALDatasetUniquePtr ds(drv->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  ASSERT_TRUE(ds) << path;
  OGRSpatialReference srs;
  if (epsg) srs.importFromEPSG(epsg);
  OGRLayer* layer = ds->CreateLayer("objects", epsg ? &srs : nullptr, wkbUnknown, nullptr);
  ASSERT_NE(layer, nullptr);
  OGRFieldDefn name("name", OFTString), height("height", OFTReal);
  ASSERT_EQ(layer->CreateField(&name), OGRERR_NONE);
  ASSERT_EQ(layer->CreateField(&height), OGRERR_NONE);
  for (const VectorFeature& v : features) {
    OGRFeatureUniquePtr f(OGRFeature::CreateFeature(layer->GetLayerDefn()));
    f->SetField("name", v.name.c_str());
    f->SetField("height", v.height);
    OGRGeometry* g = nullptr;
    ASSERT_EQ(OGRGeometryFactory::createFromWkt(v.wkt.c_str(), nullptr, &g), OGRERR_NONE) << v.wkt;
    f->SetGeometryDirectly(g);
    ASSERT_EQ(layer->CreateFeature(f.get()), OGRERR_NONE);
  }
}

// Easting/northing of sample (col, row) as WKT coordinates.
std::string at(double col, double row) {
  const auto [x, y] = kUtm.to_world(col, row);
  return std::to_string(x) + " " + std::to_string(y);
}

// Design rules (object_rules.hpp): icons up to 5 km, labels farther, ranked by "h".
const char* const kRules =
    R"({"ranges": [{"max_distance_m": 5000, "draw": "icon"}, {"draw": "label"}], "priority_field": "h"})";

TEST(ObjectLayers, GeoJsonInWgs84IsProjectedToUtmWithItsAttributes) {
  TempDir t;
  const std::string db_path = t / "t.db", json = t / "p.geojson";
  make_db(db_path, 32633, kUtm, kUtm);  // a projected DEM: the world frame is the UTM coordinates
  // cs2cs EPSG:4326 -> EPSG:32633: lat 45.1615781192, lon 15.0114513341 -> E 500900, N 5000900.
  write_text(json, R"({"type": "FeatureCollection", "features": [
    {"type": "Feature", "id": 7, "properties": {"name": "A", "h": 12.5, "n": 3, "empty": null},
     "geometry": {"type": "Point", "coordinates": [15.0114513341, 45.1615781192]}},
    {"type": "Feature", "id": 8, "properties": {"name": "no geometry"}, "geometry": null},
    {"type": "Feature", "id": 9, "properties": {"name": "B", "h": 0.1, "n": -4},
     "geometry": {"type": "MultiPoint", "coordinates": [[15.005, 45.155], [15.01, 45.16]]}}]})");
  auto db = tb::BlockDatabase::open(db_path, tb::BlockDatabase::Mode::ReadWrite);
  tb::ObjectLayerOptions o;
  o.name = "peaks";
  o.input = json;
  o.label_field = "name";
  o.height_field = "h";
  o.rules_json = kRules;
  std::vector<double> progress;
  o.progress = [&](double f) { progress.push_back(f); };
  const tb::ObjectLayerReport r = tb::add_object_layer(db, o);
  EXPECT_EQ(r.source_features, 3);
  EXPECT_EQ(r.layer.skipped, 1);
  EXPECT_EQ(r.layer.feature_count, 3);  // the point and the multipoint's two parts
  ASSERT_FALSE(progress.empty());
  EXPECT_EQ(progress.back(), 1.0);

  const std::vector<tb::ObjectLayerInfo> layers = tb::object_layers(db);
  ASSERT_EQ(layers.size(), 1u);
  EXPECT_EQ(layers[0].name, "peaks");
  EXPECT_EQ(layers[0].kind, tb::ObjectKind::Icon);  // points default to icons
  EXPECT_EQ(layers[0].geometry, tb::GeometryType::Point);
  EXPECT_EQ(layers[0].source, json);
  EXPECT_NE(layers[0].crs_wkt.find("WGS 84"), std::string::npos);
  EXPECT_EQ(layers[0].label_field, "name");
  EXPECT_EQ(layers[0].height_field, "h");
  EXPECT_EQ(layers[0].rules_json, std::optional<std::string>(kRules));  // as given

  const std::vector<tb::ObjectFeature> f = tb::object_features(db, "peaks");
  ASSERT_EQ(f.size(), 3u);
  EXPECT_EQ(f[0].source_fid, 7);
  ASSERT_EQ(f[0].rings.size(), 1u);
  ASSERT_EQ(f[0].rings[0].size(), 1u);
  EXPECT_NEAR(f[0].rings[0][0].x, 500900.0, 1e-3);
  EXPECT_NEAR(f[0].rings[0][0].y, 5000900.0, 1e-3);
  EXPECT_EQ(f[0].attributes, (std::vector<tb::ObjectAttribute>{{"name", tb::AttributeType::String, "A"},
                                                               {"h", tb::AttributeType::Real, "12.5"},
                                                               {"n", tb::AttributeType::Integer, "3"},
                                                               {"empty", tb::AttributeType::Null, ""}}));
  EXPECT_EQ(f[2].attribute("h")->value, "0.1");  // the shortest text that reads back as the double
  // The multipoint's parts, each transformed independently by OGR/PROJ here.
  OGRSpatialReference wgs84, utm;
  wgs84.SetWellKnownGeogCS("WGS84");
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  utm.importFromEPSG(32633);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&wgs84, &utm));
  ASSERT_TRUE(ct);
  const double lon[2] = {15.005, 15.01}, lat[2] = {45.155, 45.16};
  for (int k = 0; k < 2; ++k) {
    double x = lon[k], y = lat[k];
    ASSERT_TRUE(ct->Transform(1, &x, &y));
    const tb::ObjectFeature& part = f[std::size_t(1 + k)];
    EXPECT_EQ(part.source_fid, 9);
    EXPECT_EQ(part.part, k);
    EXPECT_NEAR(part.rings[0][0].x, x, 1e-6);
    EXPECT_NEAR(part.rings[0][0].y, y, 1e-6);
    EXPECT_EQ(part.attribute("name")->value, "B");
  }
  const tb::BlockDatabase::IntegrityReport ir = db.check_integrity();
  EXPECT_TRUE(ir.ok);
  EXPECT_GE(ir.items_checked, 3u);
}

TEST(ObjectLayers, DatesAndTimesKeepTheirIso8601Form) {
  // OGR's own string for a date is 2024/05/01; the file (and a user's label) says 2024-05-01.
  TempDir t;
  const std::string db_path = t / "t.db", json = t / "d.geojson";
  make_db(db_path, 32633, kUtm, kUtm);
  write_text(json, R"({"type": "FeatureCollection", "features": [
    {"type": "Feature", "properties": {"day": "2024-05-01", "at": "13:05:09",
     "utc": "2024-05-01T13:05:09.250Z", "east": "2024-05-01T13:05:09+05:30"},
     "geometry": {"type": "Point", "coordinates": [15.0114513341, 45.1615781192]}}]})");
  auto db = tb::BlockDatabase::open(db_path, tb::BlockDatabase::Mode::ReadWrite);
  tb::ObjectLayerOptions o;
  o.name = "dates";
  o.input = json;
  tb::add_object_layer(db, o);
  const std::vector<tb::ObjectFeature> f = tb::object_features(db, "dates");
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].attributes, (std::vector<tb::ObjectAttribute>{
                                 {"day", tb::AttributeType::Date, "2024-05-01"},
                                 {"at", tb::AttributeType::Time, "13:05:09"},
                                 {"utc", tb::AttributeType::DateTime, "2024-05-01T13:05:09.250Z"},
                                 {"east", tb::AttributeType::DateTime, "2024-05-01T13:05:09+05:30"}}));
}

TEST(ObjectLayers, GeographicTerrainUsesTheLocalEquirectangularFrame) {
  TempDir t;
  const std::string db_path = t / "g.db", json = t / "p.geojson";
  // A geographic DEM as dem_reader.hpp maps it: 1/1200 degree samples, north-west sample at
  // (-72, 44.1); world x = R cos(phi_c) (lon - lon0) pi/180, y = R (lat - lat0) pi/180 with
  // (lon0, lat0) the south-west sample and phi_c the centre latitude.
  const double step = 1.0 / 1200.0, lon0 = -72.0, lat_top = 44.1, lat0 = lat_top - 64 * step;
  const double phi_c = (lat_top + lat0) / 2, R = 6371008.8, k = std::numbers::pi / 180.0;
  const GridTransform crs = GridTransform::north_up(lon0, lat_top, step, step);
  const GridTransform world = GridTransform::north_up(0.0, R * (lat_top - lat0) * k,
                                                      R * std::cos(phi_c * k) * step * k, R * step * k);
  make_db(db_path, 4326, crs, world);
  write_text(json, R"({"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {},
    "geometry": {"type": "LineString", "coordinates": [[-71.99, 44.08], [-71.975, 44.09]]}}]})");
  auto db = tb::BlockDatabase::open(db_path, tb::BlockDatabase::Mode::ReadWrite);
  tb::add_object_layer(db, opts("road", json));
  EXPECT_EQ(tb::object_layers(db)[0].kind, tb::ObjectKind::Line);
  const auto f = tb::object_features(db, "road");
  ASSERT_EQ(f.size(), 1u);
  ASSERT_EQ(f[0].rings[0].size(), 2u);
  const double lons[2] = {-71.99, -71.975}, lats[2] = {44.08, 44.09};
  for (int i = 0; i < 2; ++i) {
    EXPECT_NEAR(f[0].rings[0][std::size_t(i)].x, R * std::cos(phi_c * k) * (lons[i] - lon0) * k, 1e-6);
    EXPECT_NEAR(f[0].rings[0][std::size_t(i)].y, R * (lats[i] - lat0) * k, 1e-6);
  }
}

// Blocks whose sample rectangle the box [c0, c1] x [r0, r1] meets (closed intervals).
std::set<std::pair<int, int>> touched(double c0, double r0, double c1, double r1) {
  std::set<std::pair<int, int>> s;
  for (int bc = 0; bc < 2; ++bc)
    for (int br = 0; br < 2; ++br)
      if (c1 >= 32 * bc && c0 <= 32 * bc + 32 && r1 >= 32 * br && r0 <= 32 * br + 32) s.insert({bc, br});
  return s;
}

TEST(ObjectLayers, ShapefileFeaturesAreIndexedUnderEveryBlockTheirBoxTouches) {
  TempDir t;
  const std::string db_path = t / "t.db", shp = t / "p.shp";
  make_db(db_path, 32633, kUtm, kUtm);
  // Points inside one block, on the shared border column 32, on the four-block corner (32, 32),
  // on the terrain's last sample and at fractional samples.
  const std::vector<std::pair<double, double>> pts = {{10, 10}, {40, 50}, {32, 5},
                                                      {32, 32}, {64, 64}, {5.5, 60.25}};
  std::vector<VectorFeature> v;
  for (std::size_t i = 0; i < pts.size(); ++i)
    // (std::string("p"): GCC 12 warns -Wrestrict, wrongly, on "p" + std::to_string(i) here)
    v.push_back(
        {"POINT (" + at(pts[i].first, pts[i].second) + ")", std::string("p") + std::to_string(i), double(i)});
  write_vector(shp, "ESRI Shapefile", 32633, v);
  auto db = tb::BlockDatabase::open(db_path, tb::BlockDatabase::Mode::ReadWrite);
  tb::add_object_layer(db, opts("pts", shp, tb::ObjectKind::Label, "name"));
  const auto all = tb::object_features(db, "pts");
  ASSERT_EQ(all.size(), pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {  // the same CRS: coordinates pass unchanged
    const auto [x, y] = kUtm.to_world(pts[i].first, pts[i].second);
    EXPECT_NEAR(all[i].rings[0][0].x, x, 1e-6);
    EXPECT_NEAR(all[i].rings[0][0].y, y, 1e-6);
    EXPECT_EQ(all[i].attribute("height")->value, std::to_string(i));
  }
  std::map<std::pair<int, int>, std::set<std::int64_t>> expected;
  for (std::size_t i = 0; i < pts.size(); ++i)
    for (const auto& b : touched(pts[i].first, pts[i].second, pts[i].first, pts[i].second))
      expected[b].insert(std::int64_t(i));
  EXPECT_EQ(expected[std::pair(0, 0)], (std::set<std::int64_t>{0, 2, 3}));  // by hand, from the drawing above
  EXPECT_EQ(expected[std::pair(1, 1)], (std::set<std::int64_t>{1, 3, 4}));
  for (int c = 0; c < 2; ++c)
    for (int r = 0; r < 2; ++r) {
      std::set<std::int64_t> got;
      for (const auto& f : tb::block_object_features(db, "pts", {c, r})) got.insert(f.id);
      EXPECT_EQ(got, expected[std::pair(c, r)]) << "block " << c << "," << r;
    }
  EXPECT_TRUE(tb::block_object_features(db, "pts", {5, 5}).empty());
}

TEST(ObjectLayers, AnUnblockedTerrainIndexesEverythingUnderBlockZeroAndATerrainWithoutCrsRefuses) {
  TempDir t;
  const std::string shp = t / "p.shp";
  write_vector(shp, "ESRI Shapefile", 32633,
               {{"POINT (" + at(10, 10) + ")", "a", 1}, {"POINT (" + at(60, 60) + ")", "b", 2}});
  {
    tb::DatabaseInfo info;  // block_size 0: one block, (0, 0)
    info.grid_width = info.grid_height = kSize;
    info.transform = kUtm;
    info.crs_wkt = wkt_of_epsg(32633);
    auto db = tb::BlockDatabase::create(t / "u.db", info);
    db.put_georeference({kUtm, ""});
    tb::add_object_layer(db, opts("p", shp));
    EXPECT_EQ(tb::block_object_features(db, "p", {0, 0}).size(), 2u);
    EXPECT_TRUE(tb::block_object_features(db, "p", {1, 1}).empty());
  }
  for (const bool crs : {false, true}) {  // no CRS at all; a CRS but no georeference
    tb::DatabaseInfo info;
    info.grid_width = info.grid_height = kSize;
    info.block_size = kBlock;
    info.transform = kUtm;
    if (crs) info.crs_wkt = wkt_of_epsg(32633);
    const std::string path = t / (crs ? "nogeo.db" : "nocrs.db");
    tb::BlockDatabase::create(path, info);
    const std::string before = bytes_of(path);
    {
      auto db = tb::BlockDatabase::open(path, tb::BlockDatabase::Mode::ReadWrite);
      try {
        tb::add_object_layer(db, opts("p", shp));
        ADD_FAILURE() << path << ": accepted";
      } catch (const tb::ObjectLayerError& e) {
        EXPECT_NE(std::string(e.what()).find(crs ? "has no georeference" : "has no CRS"), std::string::npos)
            << e.what();
      }
    }
    EXPECT_EQ(bytes_of(path), before);
  }
}

TEST(ObjectLayers, GeoPackagePolygonsKeepHolesAndSplitMultiPolygons) {
  TempDir t;
  const std::string db_path = t / "t.db", gpkg = t / "b.gpkg";
  make_db(db_path, 32633, kUtm, kUtm);
  write_vector(
      gpkg, "GPKG", 32633,
      {{"POLYGON ((" + at(2, 2) + ", " + at(8, 2) + ", " + at(8, 8) + ", " + at(2, 2) + "), (" + at(5, 3) +
            ", " + at(6, 3) + ", " + at(6, 4) + ", " + at(5, 3) + "))",
        "house", 9.5},
       {"MULTIPOLYGON (((" + at(30, 40) + ", " + at(36, 40) + ", " + at(36, 44) + ", " + at(30, 40) +
            ")), ((" + at(50, 10) + ", " + at(52, 10) + ", " + at(52, 12) + ", " + at(50, 10) + ")))",
        "farm", 4}});
  auto db = tb::BlockDatabase::open(db_path, tb::BlockDatabase::Mode::ReadWrite);
  const auto r = tb::add_object_layer(db, opts("b", gpkg, {}, "", "height"));
  EXPECT_EQ(r.layer.kind, tb::ObjectKind::Shape);
  const auto f = tb::object_features(db, "b");
  ASSERT_EQ(f.size(), 3u);
  EXPECT_EQ(f[0].rings.size(), 2u);  // exterior and hole
  EXPECT_EQ(f[0].rings[1][1], (tb::WorldPoint{kUtm.to_world(6, 3).first, kUtm.to_world(6, 3).second}));
  EXPECT_EQ(f[1].source_fid, f[2].source_fid);
  EXPECT_EQ(f[2].part, 1);
  EXPECT_EQ(f[2].attribute("name")->value, "farm");
  EXPECT_EQ(f[1].min, (tb::WorldPoint{kUtm.to_world(30, 44).first, kUtm.to_world(30, 44).second}));
  // The first part of the farm spans columns 30..36, rows 40..44: blocks (0,1) and (1,1).
  std::set<std::int64_t> b01, b11;
  for (const auto& x : tb::block_object_features(db, "b", {0, 1})) b01.insert(x.id);
  for (const auto& x : tb::block_object_features(db, "b", {1, 1})) b11.insert(x.id);
  EXPECT_EQ(b01, std::set<std::int64_t>{1});
  EXPECT_EQ(b11, std::set<std::int64_t>{1});
}

TEST(ObjectLayers, EveryBadInputLeavesTheDatabaseByteIdentical) {
  TempDir t;
  const std::string db_path = t / "t.db";
  make_db(db_path, 32633, kUtm, kUtm);
  const std::string good = t / "good.geojson";
  write_text(good,
             R"({"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {"name": "x"},
    "geometry": {"type": "Point", "coordinates": [15.0114513341, 45.1615781192]}}]})");
  {
    auto db = tb::BlockDatabase::open(db_path, tb::BlockDatabase::Mode::ReadWrite);
    tb::add_object_layer(db, opts("taken", good));
  }
  write_text(t / "garbage.geojson", "{ this is not json");
  write_text(t / "outside.geojson",
             R"({"type": "FeatureCollection", "features": [{"type": "Feature", "id": 41,
    "properties": {}, "geometry": {"type": "Point", "coordinates": [16.5, 45.1]}}]})");
  write_text(t / "mixed.geojson", R"({"type": "FeatureCollection", "features": [
    {"type": "Feature", "id": 4, "properties": {}, "geometry": {"type": "Point",
     "coordinates": [15.0114513341, 45.1615781192]}},
    {"type": "Feature", "id": 5, "properties": {}, "geometry": {"type": "LineString",
     "coordinates": [[15.0114, 45.16], [15.0115, 45.1616]]}}]})");
  write_vector(t / "nocrs.shp", "ESRI Shapefile", 0, {{"POINT (" + at(3, 3) + ")", "a", 1}});
  write_vector(t / "badcrs.shp", "ESRI Shapefile", 32633, {{"POINT (" + at(3, 3) + ")", "a", 1}});
  write_text(t / "badcrs.prj", "PROJCS[\"nonsense\", UNKNOWN[1,2]]");
  struct Case {
    std::string what;
    tb::ObjectLayerOptions options;
    std::string expect;  // in the message
    bool database_error = false;
  };
  const std::vector<Case> cases = {
      {"missing file", opts("a", t / "missing.geojson"), "missing.geojson: no such file"},
      {"unreadable file", opts("a", t / "garbage.geojson"), "garbage.geojson: not a readable"},
      {"no CRS", opts("a", t / "nocrs.shp"), "nocrs.shp: unknown CRS"},
      {"unknown CRS", opts("a", t / "badcrs.shp"), "badcrs.shp: unknown CRS"},
      {"outside", opts("a", t / "outside.geojson"), "outside.geojson: feature 41: lies wholly outside"},
      {"mixed", opts("a", t / "mixed.geojson"),
       "mixed.geojson: feature 5: a line in a layer of points (an object layer holds one geometry type: take "
       "one with --geometry"},
      {"none of the geometry taken", only(opts("a", t / "mixed.geojson"), tb::GeometryType::Polygon),
       "mixed.geojson: has no polygon (2 parts of other types)"},
      {"layer exists", opts("taken", good), "object layer 'taken' already exists", true},
      {"kind", opts("a", good, tb::ObjectKind::Shape), "kind shape does not fit"},
      {"label field", opts("a", good, {}, "nope"), "label field 'nope' is not a field"},
      {"height field", opts("a", good, {}, "", "name"), "height field 'name' is not numeric"},
      {"rules", opts("a", good, {}, "", "", "{\"a\": "), "r.json: line 1, column 7"},
      {"shape rule on points", opts("a", good, {}, "", "", R"({"ranges": [{"draw": "shape"}]})"),
       "r.json: draws \"shape\", which points of"},
      {"line rule on points",
       opts("a", good, {}, "", "",
            R"({"ranges": [{"max_distance_m": 9, "draw": "icon"}, {"draw": "line"}]})"),
       "r.json: draws \"line\""},
      {"priority field",
       opts("a", good, {}, "", "", R"({"ranges": [{"draw": "label"}], "priority_field": "pop"})"),
       "r.json: priority_field 'pop' is not a field"},
  };
  const std::string before = bytes_of(db_path);
  ASSERT_FALSE(before.empty());
  for (const Case& c : cases) {
    {
      auto db = tb::BlockDatabase::open(db_path, tb::BlockDatabase::Mode::ReadWrite);
      try {
        tb::add_object_layer(db, c.options);
        ADD_FAILURE() << c.what << ": accepted";
      } catch (const tb::DatabaseError& e) {
        EXPECT_TRUE(c.database_error) << c.what << ": " << e.what();
        EXPECT_NE(std::string(e.what()).find(c.expect), std::string::npos) << c.what << ": " << e.what();
      } catch (const tb::ObjectLayerError& e) {
        EXPECT_FALSE(c.database_error) << c.what << ": " << e.what();
        EXPECT_NE(std::string(e.what()).find(c.expect), std::string::npos) << c.what << ": " << e.what();
      }
    }
    EXPECT_EQ(bytes_of(db_path), before) << c.what;
    EXPECT_FALSE(fs::exists(db_path + "-wal") && fs::file_size(db_path + "-wal") > 0) << c.what;
  }
  const auto db = tb::BlockDatabase::open(db_path);
  ASSERT_EQ(tb::object_layers(db).size(), 1u);
}

// An OpenStreetMap extract's GeoJSON mixes points, lines and polygons in one collection: a layer
// holds one type, so the whole file was refused. ObjectLayerOptions::geometry takes the parts of
// one type and counts the others; each type goes in a layer of its own.
TEST(ObjectLayers, AMixedFileGivesOneGeometryTypePerLayer) {
  TempDir t;
  const std::string db_path = t / "t.db";
  make_db(db_path, 32633, kUtm, kUtm);
  const std::string mixed = t / "osm.geojson";
  write_text(mixed, R"({"type": "FeatureCollection", "features": [
    {"type": "Feature", "id": 1, "properties": {"name": "hut"}, "geometry": {"type": "Point",
     "coordinates": [15.0114513341, 45.1615781192]}},
    {"type": "Feature", "id": 2, "properties": {"name": "path"}, "geometry": {"type": "LineString",
     "coordinates": [[15.0114, 45.16], [15.0115, 45.1616]]}},
    {"type": "Feature", "id": 3, "properties": {"name": "lake"}, "geometry": {"type": "Polygon",
     "coordinates": [[[15.0114, 45.16], [15.0116, 45.16], [15.0116, 45.1612], [15.0114, 45.16]]]}},
    {"type": "Feature", "id": 4, "properties": {"name": "two huts"}, "geometry": {"type": "MultiPoint",
     "coordinates": [[15.0114, 45.1601], [15.0115, 45.1602]]}},
    {"type": "Feature", "id": 5, "properties": {"name": "mixed"}, "geometry": {"type": "GeometryCollection",
     "geometries": [{"type": "Point", "coordinates": [15.0114, 45.1603]},
                    {"type": "LineString", "coordinates": [[15.0114, 45.16], [15.0116, 45.1604]]}]}}]})");
  auto db = tb::BlockDatabase::open(db_path, tb::BlockDatabase::Mode::ReadWrite);
  EXPECT_THROW(tb::add_object_layer(db, opts("all", mixed)), tb::ObjectLayerError);
  const tb::ObjectLayerReport points =
      tb::add_object_layer(db, only(opts("points", mixed), tb::GeometryType::Point));
  const tb::ObjectLayerReport lines =
      tb::add_object_layer(db, only(opts("lines", mixed), tb::GeometryType::Line));
  const tb::ObjectLayerReport polygons =
      tb::add_object_layer(db, only(opts("polygons", mixed), tb::GeometryType::Polygon));
  // Parts: points 1, 4 (two) and 5's point; lines 2 and 5's line; polygon 3.
  EXPECT_EQ(points.layer.feature_count, 4);
  EXPECT_EQ(points.other_geometry, 3);
  EXPECT_EQ(points.layer.kind, tb::ObjectKind::Icon);
  EXPECT_EQ(lines.layer.feature_count, 2);
  EXPECT_EQ(lines.other_geometry, 5);
  EXPECT_EQ(lines.layer.kind, tb::ObjectKind::Line);
  EXPECT_EQ(polygons.layer.feature_count, 1);
  EXPECT_EQ(polygons.other_geometry, 6);
  EXPECT_EQ(polygons.layer.kind, tb::ObjectKind::Shape);
  std::vector<std::string> names;
  for (const tb::ObjectFeature& f : tb::object_features(db, "points")) {
    EXPECT_EQ(f.geometry, tb::GeometryType::Point);
    names.push_back(f.attributes[0].value + "/" + std::to_string(f.source_fid) + "." +
                    std::to_string(f.part));
  }
  EXPECT_EQ(names, (std::vector<std::string>{"hut/1.0", "two huts/4.0", "two huts/4.1", "mixed/5.0"}));
  const std::vector<tb::ObjectFeature> line_parts = tb::object_features(db, "lines");
  ASSERT_EQ(line_parts.size(), 2u);
  EXPECT_EQ(line_parts[1].source_fid, 5);
  EXPECT_EQ(line_parts[1].part, 1);  // the collection's second part
  EXPECT_EQ(tb::parse_geometry("line"), tb::GeometryType::Line);
  EXPECT_THROW(tb::parse_geometry("lines"), std::invalid_argument);
}

// A GPX file, what a GPS or a hiking app writes, has five layers (waypoints, routes, tracks and
// the tracks' and routes' points again): it was refused for not having exactly one. The only
// layer with features of its own is read; with two (waypoints and a track) the error lists
// them and --source-layer picks one.
TEST(ObjectLayers, AGpxFileGivesItsTrackOrTheLayerNamed) {
  TempDir t;
  const std::string db_path = t / "t.db";
  make_db(db_path, 32633, kUtm, kUtm);
  const std::string track = R"(<trk><name>Ridge</name><trkseg>
      <trkpt lat="45.1600" lon="15.0114"><ele>300</ele></trkpt>
      <trkpt lat="45.1608" lon="15.0118"><ele>320</ele></trkpt>
      <trkpt lat="45.1616" lon="15.0115"><ele>340</ele></trkpt></trkseg></trk>)";
  const std::string head =
      R"(<?xml version="1.0"?><gpx version="1.1" creator="t" xmlns="http://www.topografix.com/GPX/1/1">)";
  write_text(t / "track.gpx", head + track + "</gpx>");
  write_text(t / "both.gpx", head + R"(<wpt lat="45.1615781192" lon="15.0114513341"><name>Hut</name></wpt>)" +
                                 track + "</gpx>");
  auto db = tb::BlockDatabase::open(db_path, tb::BlockDatabase::Mode::ReadWrite);
  const tb::ObjectLayerReport only = tb::add_object_layer(db, opts("track", t / "track.gpx"));
  EXPECT_EQ(only.layer.geometry, tb::GeometryType::Line);
  EXPECT_EQ(only.layer.feature_count, 1);
  EXPECT_EQ(only.layer.source, t / "track.gpx" + " (layer tracks)");
  try {
    tb::add_object_layer(db, opts("both", t / "both.gpx"));
    ADD_FAILURE() << "a GPX file with waypoints and a track was read without a choice";
  } catch (const tb::ObjectLayerError& e) {
    EXPECT_NE(
        std::string(e.what()).find("2 with features: waypoints (1 Point), tracks (1 Multi Line String); "
                                   "name one with --source-layer"),
        std::string::npos)
        << e.what();
  }
  tb::ObjectLayerOptions huts = opts("huts", t / "both.gpx", {}, "name");
  huts.source_layer = "waypoints";
  const tb::ObjectLayerReport named = tb::add_object_layer(db, huts);
  EXPECT_EQ(named.layer.geometry, tb::GeometryType::Point);
  ASSERT_EQ(tb::object_features(db, "huts").size(), 1u);
  huts.name = "none", huts.source_layer = "peaks";
  try {
    tb::add_object_layer(db, huts);
    ADD_FAILURE() << "a layer the file does not hold was read";
  } catch (const tb::ObjectLayerError& e) {
    EXPECT_EQ(e.cause(), tb::ObjectLayerError::Cause::Option);
    EXPECT_NE(std::string(e.what()).find("has no layer 'peaks'; its layers: waypoints (1 Point), routes"),
              std::string::npos)
        << e.what();
  }
}

// An IGC flight log (which GDAL does not read) gives its ground track as one line named after
// the file, on the same world points as the same fixes in a GPX track read through GDAL.
TEST(ObjectLayers, AnIgcLogGivesItsGroundTrackAsOneLine) {
  TempDir t;
  const std::string db_path = t / "t.db";
  make_db(db_path, 32633, kUtm, kUtm);
  write_text(t / "ridge.gpx",
             R"(<?xml version="1.0"?><gpx version="1.1" creator="t" xmlns="http://www.topografix.com/GPX/1/1">
      <trk><trkseg><trkpt lat="45.1600" lon="15.0114"><ele>300</ele></trkpt>
      <trkpt lat="45.1608" lon="15.0118"><ele>320</ele></trkpt>
      <trkpt lat="45.1616" lon="15.0115"><ele>340</ele></trkpt></trkseg></trk></gpx>)");
  // The same fixes in IGC's degrees and thousandths of minutes: 45 09.600 N 015 00.684 E, ...
  write_text(t / "ridge.igc",
             "AXXX001\r\nHFDTE010726\r\nB1200004509600N01500684EA0030000300\r\n"
             "B1200014509648N01500708EA0032000320\r\nB1200024509696N01500690EA0034000340\r\n");
  auto db = tb::BlockDatabase::open(db_path, tb::BlockDatabase::Mode::ReadWrite);
  tb::add_object_layer(db, opts("gpx", t / "ridge.gpx"));
  const tb::ObjectLayerReport igc = tb::add_object_layer(db, opts("igc", t / "ridge.igc"));
  EXPECT_EQ(igc.layer.geometry, tb::GeometryType::Line);
  EXPECT_EQ(igc.layer.feature_count, 1);
  const std::vector<tb::ObjectFeature> a = tb::object_features(db, "gpx"), b = tb::object_features(db, "igc");
  ASSERT_EQ(a.size(), 1u);
  ASSERT_EQ(b.size(), 1u);
  ASSERT_EQ(b[0].rings.size(), 1u);
  ASSERT_EQ(b[0].rings[0].size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(b[0].rings[0][i].x, a[0].rings[0][i].x, 1e-6) << i;
    EXPECT_NEAR(b[0].rings[0][i].y, a[0].rings[0][i].y, 1e-6) << i;
  }
  ASSERT_NE(b[0].attribute("name"), nullptr);
  EXPECT_EQ(b[0].attribute("name")->value, "ridge");
  write_text(t / "bad.igc", "HFDTE010726\nB1200004509600X01500684EA0030000300\n");
  try {
    tb::add_object_layer(db, opts("bad", t / "bad.igc"));
    ADD_FAILURE() << "a malformed log was read";
  } catch (const tb::ObjectLayerError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.igc: line 2: bad latitude"), std::string::npos) << e.what();
  }
}

TEST(ObjectLayers, ADatabaseWithoutObjectTablesHasNoLayersAndCorruptFeaturesAreReported) {
  TempDir t;
  const std::string db_path = t / "t.db", json = t / "p.geojson";
  make_db(db_path, 32633, kUtm, kUtm);
  {
    const auto db = tb::BlockDatabase::open(db_path);
    EXPECT_TRUE(tb::object_layers(db).empty());
    EXPECT_TRUE(db.check_integrity().ok);
    EXPECT_THROW(tb::object_features(db, "none"), tb::DatabaseError);
  }
  write_text(json, R"({"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {},
    "geometry": {"type": "Point", "coordinates": [15.0114513341, 45.1615781192]}}]})");
  {
    auto db = tb::BlockDatabase::open(db_path, tb::BlockDatabase::Mode::ReadWrite);
    tb::add_object_layer(db, opts("p", json));
  }
  sqlite3* s = nullptr;
  ASSERT_EQ(sqlite3_open(db_path.c_str(), &s), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(s, "UPDATE object_features SET data = zeroblob(size)", nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(s);
  const auto db = tb::BlockDatabase::open(db_path);
  try {
    tb::object_features(db, "p");
    ADD_FAILURE() << "a corrupt feature was read";
  } catch (const tb::DatabaseError& e) {
    EXPECT_NE(std::string(e.what()).find("object layer 'p': feature 0: checksum mismatch"), std::string::npos)
        << e.what();
  }
  const auto report = db.check_integrity();
  EXPECT_FALSE(report.ok);
  ASSERT_EQ(report.problems.size(), 1u);
  EXPECT_NE(report.problems[0].find("object layer 'p': feature 0"), std::string::npos) << report.problems[0];
  // A feature row gone: the layer's count and the block index no longer agree with the features.
  ASSERT_EQ(sqlite3_open(db_path.c_str(), &s), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(s, "DELETE FROM object_features", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(s);
  const auto gone = tb::BlockDatabase::open(db_path).check_integrity();
  ASSERT_EQ(gone.problems.size(), 2u);
  EXPECT_NE(gone.problems[0].find("object layer 'p': 1 features recorded, 0 stored"), std::string::npos)
      << gone.problems[0];
  EXPECT_NE(gone.problems[1].find("lists feature 0, which is not stored"), std::string::npos)
      << gone.problems[1];
}

}  // namespace
