// terralod objects add|list end to end: a 65 x 65 UTM terrain built by 'terralod build', GeoJSON
// layers added and listed, and each bad input refused with a message naming the file, the exit
// status of other commands, and the database file unchanged.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "cli_utm_database.hpp"
#include "run_command.hpp"
#include "xvfb.hpp"

namespace {

namespace fs = std::filesystem;
using terralod::test::CliRunner;
using terralod::test::quote;

std::string bytes_of(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

// Points in WGS 84 inside the terrain (cs2cs: lon 15.0114513341, lat 45.1615781192 is
// E 500900, N 5000900 in UTM 33N), one without geometry.
const char* kPoints = R"({"type": "FeatureCollection", "features": [
  {"type": "Feature", "id": 1, "properties": {"name": "Hut", "ele": 1200},
   "geometry": {"type": "Point", "coordinates": [15.0114513341, 45.1615781192]}},
  {"type": "Feature", "id": 2, "properties": {"name": "Spring", "ele": 900},
   "geometry": {"type": "Point", "coordinates": [15.005, 45.155]}},
  {"type": "Feature", "id": 3, "properties": {"name": "lost"}, "geometry": null}]})";

/// A camera path of `frames` frames south of the terrain, 1.5 km up, looking north and 40 degrees
/// down at it, moving 20 m east a frame.
void write_south_path(const std::string& path, int frames) {
  std::ofstream f(path);
  f << "x,y,z,yaw,pitch,fovy\n";
  for (int k = 0; k < frames; ++k) f << 500960 + 20 * k << ",4999000,1500,0,-40,60\n";
}

// The terrain, built once for the suite (each 'terralod' run costs about half a second):
// 65 x 65 samples of 30 m in UTM zone 33N, lower-left corner (500000, 5000000).
class ObjectsCli : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    suite_dir_ = new terralod::test::TempDir("objects-suite");
    terralod::test::build_utm_cli_database(CliRunner{TERRALOD_CLI}, suite_dir_->path());
  }
  static void TearDownTestSuite() {
    delete suite_dir_;
    suite_dir_ = nullptr;
  }
  void SetUp() override {
    ASSERT_NE(suite_dir_, nullptr);
    ASSERT_TRUE(fs::exists(suite_dir_->path() / "t.db"));
    fs::copy_file(suite_dir_->path() / "t.db", db());
    std::ofstream(dir_.path() / "points.geojson") << kPoints;
  }
  std::string db() const { return (dir_.path() / "t.db").string(); }
  std::string file(const std::string& name) const { return (dir_.path() / name).string(); }

  static terralod::test::TempDir* suite_dir_;
  terralod::test::TempDir dir_{"objects"};
  CliRunner cli_{TERRALOD_CLI};
};
terralod::test::TempDir* ObjectsCli::suite_dir_ = nullptr;

TEST_F(ObjectsCli, AddThenListShowsTheLayer) {
  std::string out;
  ASSERT_EQ(cli_.run("objects add " + quote(db()) + " --layer huts --input " + quote(file("points.geojson")) +
                         " --kind label --label-field name --height-field ele",
                     &out),
            0);
  EXPECT_NE(out.find("3 features (1 without geometry, skipped) in WGS 84 -> 2 point parts"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("store object layer 'huts' (label): 2 features"), std::string::npos) << out;
  ASSERT_EQ(cli_.run("objects add " + quote(db()) + " --layer pts --geometry point --input " +
                         quote(file("points.geojson")),
                     &out),
            0);
  EXPECT_NE(
      out.find("(1 without geometry, skipped, 0 parts of other types left out) in WGS 84 -> 2 point parts"),
      std::string::npos)
      << out;
  ASSERT_EQ(
      cli_.run("objects add " + quote(db()) + " --layer more --input " + quote(file("points.geojson")), &out),
      0);
  ASSERT_EQ(cli_.run("objects list " + quote(db()), &out), 0);
  EXPECT_NE(
      out.find("huts\tkind label\t2 features (points)\tsource " + file("points.geojson") + "\tCRS WGS 84"),
      std::string::npos)
      << out;
  EXPECT_NE(out.find("more\tkind icon\t2 features"), std::string::npos) << out;  // points default to icons
  EXPECT_NE(out.find("pts\tkind icon\t2 features"), std::string::npos) << out;
  EXPECT_LT(out.find("huts"), out.find("more"));  // sorted by name
  ASSERT_EQ(cli_.run("objects --help", &out), 0);
  EXPECT_NE(out.find("add|list DB"), std::string::npos) << out;
  EXPECT_NE(out.find("--rules FILE"), std::string::npos) << out;
  EXPECT_NE(out.find("design rules by level of detail"), std::string::npos) << out;
}

TEST_F(ObjectsCli, BadInputsAreRefusedAndLeaveTheDatabaseUnchanged) {
  std::ofstream(file("outside.geojson")) << R"({"type": "FeatureCollection", "features": [{"type": "Feature",
    "id": 12, "properties": {}, "geometry": {"type": "Point", "coordinates": [16.5, 45.1]}}]})";
  std::ofstream(file("bad.json")) << "{\"rules\": [";
  std::ofstream(file("sprite.json"))
      << "{\"ranges\": [\n  {\"max_distance_m\": 900, \"draw\": \"sprite\"},\n  {\"draw\": \"none\"}]}";
  std::ofstream(file("order.json"))
      << "{\"ranges\": [{\"max_distance_m\": 900, \"draw\": \"icon\"},\n"
         "  {\"max_distance_m\": 90, \"draw\": \"label\"}, {\"draw\": \"none\"}]}";
  std::ofstream(file("garbage.geojson")) << "not a vector file";
  ASSERT_EQ(
      cli_.run("objects add " + quote(db()) + " --layer taken --input " + quote(file("points.geojson"))), 0);
  const std::string before = bytes_of(db());
  struct Case {
    std::string args, message;
    int status;
  };
  const std::string add = "objects add " + quote(db()) + " --layer x --input ";
  const Case cases[] = {
      {add + quote(file("missing.geojson")), file("missing.geojson") + ": no such file", 1},
      {add + quote(file("garbage.geojson")), file("garbage.geojson") + ": not a readable vector file", 1},
      {add + quote(file("outside.geojson")), file("outside.geojson") + ": feature 12: lies wholly outside",
       1},
      {"objects add " + quote(db()) + " --layer taken --input " + quote(file("points.geojson")),
       db() + ": object layer 'taken' already exists", 1},
      {add + quote(file("points.geojson")) + " --kind line", "kind line does not fit its points", 2},
      {add + quote(file("points.geojson")) + " --label-field title", "label field 'title' is not a field", 2},
      {add + quote(file("points.geojson")) + " --rules " + quote(file("bad.json")),
       file("bad.json") + ": line 1, column 12", 2},
      {add + quote(file("points.geojson")) + " --rules " + quote(file("sprite.json")),
       file("sprite.json") + ": line 2, column 35: ranges[0].draw: unknown representation 'sprite'", 2},
      {add + quote(file("points.geojson")) + " --rules " + quote(file("order.json")),
       file("order.json") + ": line 2, column 22: ranges[1].max_distance_m must be larger than the range "
                            "before's 900",
       2},
      {add + quote(file("points.geojson")) + " --rules " + quote(file("none.json")),
       "option '--rules': " + file("none.json") + ": cannot be read", 2},
      {add + quote(file("points.geojson")) + " --geometry polygon",
       file("points.geojson") + ": has no polygon (2 parts of other types)", 1},
      {add + quote(file("points.geojson")) + " --geometry lines", "'--geometry'", 2},
  };
  for (const Case& c : cases) {
    std::string out;
    EXPECT_EQ(cli_.run(c.args, &out), c.status) << c.args;
    EXPECT_NE(out.find(c.message), std::string::npos) << c.args << "\n" << out;
    EXPECT_EQ(bytes_of(db()), before) << c.args;
  }
  std::string out;
  ASSERT_EQ(cli_.run("objects list " + quote(db()), &out), 0);
  EXPECT_EQ(out.find("\nx\t"), std::string::npos) << out;
}

// terralod fly --objects --dump-objects: one objects_NNNNN.csv per frame with the header, the
// anchors where the layer put them (the Hut at E 500900, N 5000900: the terrain's world frame
// is its UTM frame) and z equal to the drawn ground under them; a missing layer names the
// database; --dump-objects without --objects is a usage error.
TEST_F(ObjectsCli, FlyDumpsThePlacedObjectsOfEveryFrame) {
  ASSERT_EQ(cli_.run("objects add " + quote(db()) + " --layer huts --input " + quote(file("points.geojson"))),
            0);
  write_south_path(file("path.csv"), 5);
  const std::string fly = "fly --db " + quote(db()) + " --path " + quote(file("path.csv")) + " --out " +
                          quote(file("out")) + " --speed-factor 0 --size 320x240";
  std::string out;
  ASSERT_EQ(cli_.run(fly + " --objects huts --dump-objects", &out), 0);
  EXPECT_NE(out.find("read  2 objects of 1 layers"), std::string::npos) << out;
  EXPECT_NE(out.find("objects placed per frame median 2"), std::string::npos) << out;
  for (int k = 0; k < 5; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "objects_%05d.csv", k);
    const std::vector<std::string> lines =
        terralod::test::lines_of(terralod::test::slurp(file("out/") + name));
    ASSERT_EQ(lines.size(), 3u) << name;
    EXPECT_EQ(lines[0], "name,kind,x,y,z,ground_z");
    bool hut = false;
    for (std::size_t i = 1; i < lines.size(); ++i) {
      char label[64] = {}, kind[16] = {};
      double x = 0, y = 0, z = 0, ground = 0;
      ASSERT_EQ(
          std::sscanf(lines[i].c_str(), "%63[^,],%15[^,],%lf,%lf,%lf,%lf", label, kind, &x, &y, &z, &ground),
          6)
          << lines[i];
      EXPECT_EQ(std::string(kind), "icon");
      EXPECT_EQ(z, ground) << lines[i];
      EXPECT_GT(z, 90.0) << lines[i];  // on the terrain (heights 100..149 m, drawn within them)
      if (std::string(label) == "Hut") {
        hut = true;
        EXPECT_NEAR(x, 500900.0, 1e-3);
        EXPECT_NEAR(y, 5000900.0, 1e-3);
      }
    }
    EXPECT_TRUE(hut) << name;
  }
  EXPECT_EQ(cli_.run(fly + " --objects nope", &out), 1);
  EXPECT_NE(out.find(db() + ": object layer 'nope': not in the database"), std::string::npos) << out;
  EXPECT_EQ(cli_.run(fly + " --dump-objects", &out), 2);
  EXPECT_NE(out.find("--dump-objects needs --objects"), std::string::npos) << out;
  ASSERT_EQ(cli_.run("fly --help", &out), 0);
  EXPECT_NE(out.find("--objects NAME"), std::string::npos) << out;
  EXPECT_NE(out.find("name,kind,x,y,z,ground_z"), std::string::npos) << out;
}

// terralod-fly --headless --hud promises identical images for the same path, apart from the
// HUD's memory figure: its object lines (placed, drawn) carry no timings there (they did, in
// milliseconds, so two runs differed).
TEST_F(ObjectsCli, HeadlessHudObjectLinesAreTheSameInEveryRun) {
  ASSERT_EQ(cli_.run("objects add " + quote(db()) + " --layer huts --input " + quote(file("points.geojson"))),
            0);
  write_south_path(file("path.csv"), 2);
  const CliRunner fly{TERRALOD_FLY};
  auto rows = [&](const std::string& dir) {
    std::string out;
    EXPECT_EQ(fly.run("--headless --db " + quote(db()) + " --size 640x240 --path " + quote(file("path.csv")) +
                          " --out " + quote(file(dir)) + " --hud --objects huts",
                      &out),
              0)
        << out;
    auto in = OIIO::ImageInput::open(file(dir) + "/frame_00001.png");
    EXPECT_TRUE(in) << OIIO::geterror();
    if (!in) return std::vector<unsigned char>();
    const OIIO::ImageSpec& spec = in->spec();
    std::vector<unsigned char> px(std::size_t(spec.width) * spec.height * 3);
    EXPECT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, px.data()));
    // The HUD's lines 6 and 7 (objects, drawn): 16 px text, 20 px apart, 8 px margin, 5 px pad.
    const std::size_t row = std::size_t(spec.width) * 3;
    return std::vector<unsigned char>(px.begin() + std::ptrdiff_t((8 + 5 + 5 * 20) * row),
                                      px.begin() + std::ptrdiff_t((8 + 5 + 7 * 20) * row));
  };
  const std::vector<unsigned char> a = rows("hud1"), b = rows("hud2");
  ASSERT_FALSE(a.empty());
  EXPECT_TRUE(a == b) << "the HUD's object lines differ between two runs of the same path";
}

// A label layer whose label field is empty or missing for some features labels the others only:
// an unnamed feature is not labelled with its id (it still counts as placed, and is picked by it).
TEST_F(ObjectsCli, UnnamedFeaturesGetNoLabel) {
  std::ofstream(file("peaks.geojson")) << R"({"type": "FeatureCollection", "features": [
  {"type": "Feature", "id": 1, "properties": {"peak": "Hut"},
   "geometry": {"type": "Point", "coordinates": [15.0114513341, 45.1615781192]}},
  {"type": "Feature", "id": 2, "properties": {"peak": ""},
   "geometry": {"type": "Point", "coordinates": [15.005, 45.155]}},
  {"type": "Feature", "id": 3, "properties": {"peak": null},
   "geometry": {"type": "Point", "coordinates": [15.008, 45.158]}}]})";
  ASSERT_EQ(
      cli_.run("objects add " + quote(db()) + " --layer peaks --kind label --label-field peak --input " +
               quote(file("peaks.geojson"))),
      0);
  write_south_path(file("path.csv"), 3);
  const CliRunner fly{TERRALOD_FLY};
  std::string out;
  ASSERT_EQ(fly.run("--headless --db " + quote(db()) + " --size 320x240 --path " + quote(file("path.csv")) +
                        " --out " + quote(file("h")) + " --objects peaks",
                    &out),
            0);
  EXPECT_NE(out.find("headless: objects in view median 3, max 3 (of 3)"), std::string::npos) << out;
  EXPECT_NE(out.find("0 icons, 1 of 1 labels (decluttered)"), std::string::npos) << out;
}

// terralod view --db --objects: the frame with the objects drawn (the summary line counts them,
// the PNG differs from the same view without them, --stats records them); --objects needs --db.
TEST_F(ObjectsCli, ViewDrawsObjectLayers) {
  ASSERT_EQ(cli_.run("objects add " + quote(db()) + " --layer huts --input " + quote(file("points.geojson"))),
            0);
  const std::string view =
      "view --db " + quote(db()) + " --camera 500900,4999900,700,0,-30,60 --size 320x240";
  std::string out;
  ASSERT_EQ(cli_.run(view + " --objects huts --out " + quote(file("with.png")) + " --stats " +
                         quote(file("with.json")),
                     &out),
            0);
  EXPECT_NE(out.find("objects 1 in view"), std::string::npos) << out;
  EXPECT_NE(out.find("drawn: 1 icons"), std::string::npos) << out;
  const std::string stats = terralod::test::slurp(file("with.json"));
  EXPECT_NE(stats.find("\"placed\": 1,"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"icons\": 1,"), std::string::npos) << stats;
  ASSERT_EQ(cli_.run(view + " --out " + quote(file("without.png")), &out), 0);
  EXPECT_NE(bytes_of(file("with.png")), bytes_of(file("without.png")));
  EXPECT_EQ(
      cli_.run("view --input x.hgt --camera 0,0,0,0,0,60 --out " + quote(file("x.png")) + " --objects huts",
               &out),
      2);
  EXPECT_NE(out.find("--objects needs --db"), std::string::npos) << out;
}

#ifdef TERRALOD_FLY
// A building (a 47 m x 44 m square, 40 m high) north-east of the Hut, and a road across the
// terrain, in WGS 84.
const char* kBuilding = R"({"type": "FeatureCollection", "features": [
  {"type": "Feature", "properties": {"name": "Hall", "height": 40}, "geometry": {"type": "Polygon",
   "coordinates": [[[15.0120, 45.1620], [15.0126, 45.1620], [15.0126, 45.1624], [15.0120, 45.1624],
                    [15.0120, 45.1620]]]}}]})";
const char* kRoad = R"({"type": "FeatureCollection", "features": [
  {"type": "Feature", "properties": {"name": "Road"}, "geometry": {"type": "LineString",
   "coordinates": [[15.005, 45.158], [15.010, 45.161], [15.015, 45.163]]}}]})";

// terralod-fly --objects: placed and drawn in every headless frame (the summary counts the
// icons, labels, line and shape triangles; the frames differ from the same flight without
// objects), in the window under Xvfb (flies and exits cleanly); usage and missing layers are
// clear errors.
TEST_F(ObjectsCli, FlyDemoPlacesObjects) {
  ASSERT_EQ(cli_.run("objects add " + quote(db()) + " --layer huts --input " + quote(file("points.geojson"))),
            0);
  std::ofstream(file("building.geojson")) << kBuilding;
  std::ofstream(file("road.geojson")) << kRoad;
  // In view: the Hut (the Spring is off to the west), the hall and the road.
  ASSERT_EQ(cli_.run("objects add " + quote(db()) + " --layer halls --height-field height --input " +
                     quote(file("building.geojson"))),
            0);
  ASSERT_EQ(cli_.run("objects add " + quote(db()) + " --layer roads --input " + quote(file("road.geojson"))),
            0);
  {
    std::ofstream f(file("low.csv"));
    f << "x,y,z,yaw,pitch,fovy\n";
    for (int k = 0; k < 2; ++k) f << 500900 + 10 * k << ",4999900,700,0,-30,60\n";
  }
  const CliRunner demo{TERRALOD_FLY};
  const std::string low =
      "--headless --db " + quote(db()) + " --size 320x240 --path " + quote(file("low.csv"));
  std::string drawn;
  ASSERT_EQ(
      demo.run(low + " --out " + quote(file("with")) + " --objects huts --objects halls --objects roads",
               &drawn),
      0);
  EXPECT_NE(drawn.find("objects drawn per frame (median): 1 icons, 0 of 0 labels (decluttered), "),
            std::string::npos)
      << drawn;
  int line_tris = 0, shape_tris = 0;
  const std::size_t at = drawn.find("labels (decluttered), ");
  ASSERT_NE(at, std::string::npos) << drawn;
  ASSERT_EQ(std::sscanf(drawn.c_str() + at, "labels (decluttered), %d line and %d shape triangles",
                        &line_tris, &shape_tris),
            2)
      << drawn;
  EXPECT_GT(line_tris, 4) << drawn;               // the road, split at the drawn triangles' edges
  EXPECT_EQ(shape_tris, 4 * 2 + 2 * 2) << drawn;  // 4 walls, a roof and a floor of 2 triangles
  ASSERT_EQ(demo.run(low + " --out " + quote(file("without")), &drawn), 0);
  EXPECT_NE(bytes_of(file("with/frame_00000.png")), bytes_of(file("without/frame_00000.png")))
      << "the objects must show in the frame";
  write_south_path(file("path.csv"), 3);
  const CliRunner fly{TERRALOD_FLY};
  const std::string base = "--db " + quote(db()) + " --size 160x120 ";
  std::string out;
  ASSERT_EQ(fly.run("--headless " + base + "--path " + quote(file("path.csv")) + " --out " +
                        quote(file("h")) + " --hud --objects huts",
                    &out),
            0);
  EXPECT_NE(out.find("headless: objects in view median 2, max 2 (of 2)"), std::string::npos) << out;
  EXPECT_EQ(fly.run("--headless --path " + quote(file("path.csv")) + " --objects huts", &out), 2);
  EXPECT_NE(out.find("--objects needs --db"), std::string::npos) << out;
  EXPECT_EQ(fly.run("--headless " + base + "--path " + quote(file("path.csv")) + " --objects nope", &out), 1);
  EXPECT_NE(out.find(db() + ": object layer 'nope': not in the database"), std::string::npos) << out;
  ASSERT_EQ(fly.run("--help", &out), 0);
  EXPECT_NE(out.find("O switches the object layers on/off"), std::string::npos) << out;
  terralod::test::Xvfb xvfb;
  if (xvfb.display().empty()) GTEST_SKIP() << "Xvfb could not be started (is the xvfb package installed?)";
  const terralod::test::CommandResult r =
      terralod::test::run_command("DISPLAY=" + xvfb.display() + " " + quote(TERRALOD_FLY) + " " + base +
                                  "--objects huts --replay " + quote(file("path.csv")) + " --frames 3");
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("flew 3 frames"), std::string::npos) << r.out << r.err;
}
#endif

}  // namespace
