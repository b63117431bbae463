// Tests of texture layers in the block database: the tile format (round trip, corrupt bytes),
// storing a layer (exact level 0, patch tiles equal to the pyramid's sub-images, metadata),
// on-demand loading from the database, and `terralod texture add|shade|export` end to end.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "cli_texture_database.hpp"
#include "run_command.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/texture_store.hpp"
#include "terralod/render/thematic_texture.hpp"
#include "terralod/render/topographic_texture.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
namespace pm = terralod::pm;
using namespace terralod::render;

/// A folder of this process's own, removed when the process ends (tests/support/run_command.hpp).
const fs::path& tmp_dir() { return terralod::test::process_temp_dir("texture-store"); }

RgbaImage pattern(int w, int h) {
  RgbaImage img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.set(
          x, y,
          {std::uint8_t(x * 7 + y), std::uint8_t(y * 3), std::uint8_t((x ^ y) & 255), std::uint8_t(255 - x)});
  return img;
}

TEST(TextureStore, TilesRoundTripAndCorruptTilesAreNamed) {
  const RgbaImage img = pattern(37, 11);
  std::vector<std::uint8_t> b = encode_texture_tile(img);
  ASSERT_GE(b.size(), 16u);
  EXPECT_EQ(std::string(b.begin(), b.begin() + 4), "TLTX");
  EXPECT_EQ(b[8], 37);  // u32 width, little-endian
  EXPECT_EQ(b[12], 11);
  EXPECT_EQ(decode_texture_tile(b, "t"), img);
  auto fails = [](std::vector<std::uint8_t> bytes, const std::string& what) {
    try {
      decode_texture_tile(bytes, "tile 7");
      ADD_FAILURE() << "no exception for " << what;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("tile 7: "), std::string::npos) << e.what();
    }
  };
  fails({b.begin(), b.begin() + 10}, "truncated header");
  fails({b.begin(), b.end() - 5}, "truncated pixels");
  std::vector<std::uint8_t> bad = b;
  bad[0] = 'X';
  fails(bad, "magic");
  bad = b;
  bad[10] = 0xff;  // claims 37 + 0xff0000 columns: refused before allocating
  fails(bad, "size");
}

TEST(TextureStore, GridGeorefPadsTheSampleExtentByHalfACell) {
  // North-up, first sample centre (100, 900), 10 m spacing, 5 x 3 samples: x from 95 to
  // 100 + 40 + 5 = 145, y from 900 - 20 - 5 = 875 to 905.
  EXPECT_EQ(grid_georef(pm::GridTransform::north_up(100, 900, 10, 10), 5, 3), (GeoRect{95, 875, 145, 905}));
}

TEST(TextureStore, StoredLayerReadsBackExactlyAndLoadsOnDemand) {
  // A 64 x 64 terrain grid, image 100 x 100 over it, max texture size 32: levels 100, 50, 25.
  const fs::path dbp = tmp_dir() / "store.db";
  tb::DatabaseInfo info;
  info.grid_width = info.grid_height = 64;
  info.transform = pm::GridTransform::identity();
  auto db = tb::BlockDatabase::create(dbp.string(), info);
  const RgbaImage src = pattern(100, 100);
  const fs::path tx = tmp_dir() / "store.tx";
  PyramidOptions po;
  po.max_texture_size = 32;
  ImagePyramid::convert(src, tx.string(), po);
  const ImagePyramid pyr(tx.string(), po);
  // Domains: root [0,100]^2 with four quadrant children (world = texel units here).
  std::vector<PatchDomain> doms(5);
  for (int i = 0; i < 5; ++i) doms[i].id = i, doms[i].parent = i ? 0 : -1;
  doms[0].children = {1, 2, 3, 4};
  doms[0].bbox = pm::Box{{0, 0, 0}, {100, 100, 0}};
  for (int q = 0; q < 4; ++q) {
    const double x = 50.0 * (q % 2), y = 50.0 * (q / 2);
    doms[q + 1].bbox = pm::Box{{x, y, 0}, {x + 50, y + 50, 0}};
  }
  LayerRecord rec;
  rec.name = "pattern";
  rec.georef = GeoRect{0, 0, 100, 100};
  rec.tile_size = 16;
  rec.constraints.max_texture_size = 32;
  rec.parameters = "{\"note\": \"a, b\"}";
  int calls = 0;
  store_texture_layer(db, rec, pyr, doms, [&](double) { ++calls; });
  EXPECT_GT(calls, 0);
  ASSERT_EQ(rec.levels.size(), 3u);
  // Root: 100 and 50 texels too many: level 2 (25 x 25). Quadrants: 50 at level 0 > 32, so
  // level 1, 25 x 25.
  EXPECT_EQ(rec.patches, 5u);
  EXPECT_EQ(stored_layers(db), std::vector<std::string>{"pattern"});
  const LayerRecord back = read_layer_record(db, "pattern");
  EXPECT_EQ(back.levels, rec.levels);
  EXPECT_EQ(back.georef, rec.georef);
  EXPECT_EQ(back.tile_size, 16);
  EXPECT_EQ(back.patches, 5u);
  EXPECT_EQ(back.parameters, rec.parameters);
  // The record's bytes, as every version so far has written them (pm::json_quote for strings).
  EXPECT_EQ(
      db.get_meta("texture_layer:pattern"),
      "{\"format\": 1, \"name\": \"pattern\", \"kind\": \"image\", \"source\": \"\", \"georef\": [0, 0, 100, "
      "100], \"levels\": [[100, 100], [50, 50], [25, 25]], \"tile_size\": 16, \"max_texture_size\": 32, "
      "\"power_of_two\": false, \"patches\": 5, \"parameters\": {\"note\": \"a, b\"}}");
  EXPECT_EQ(read_layer_level(db, back, 0), src);  // exact, across 7 x 7 tiles of 16
  EXPECT_EQ(read_layer_level(db, back, 1), pyr.read({1, 0, 0, 50, 50}));
  const auto tree = std::make_shared<TextureTree>(doms, back.levels, back.georef, back.constraints);
  EXPECT_EQ(tree->patch(0).rect, (PixelRect{2, 0, 0, 25, 25}));
  EXPECT_EQ(tree->patch(4).rect, (PixelRect{1, 25, 0, 25, 25}));  // north-east quadrant: top rows
  for (std::int64_t n = 0; n < 5; ++n)
    EXPECT_EQ(read_layer_patch(db, "pattern", n, tree->patch(n).rect.level), pyr.read(tree->patch(n).rect))
        << n;
  EXPECT_TRUE(db.check_integrity().ok);
  // On demand through the cache, from another thread with its own connection.
  TextureCache cache(database_tile_loader(dbp.string(), "pattern", tree));
  cache.request({0, 3});
  ASSERT_TRUE(cache.wait_idle(10000));
  const auto px = cache.request({0, 3});
  ASSERT_NE(px, nullptr);
  EXPECT_EQ(*px, pyr.read(tree->patch(3).rect));
  // Missing layer: the error names the database and the layers there are.
  try {
    read_layer_record(db, "nope");
    FAIL();
  } catch (const tb::DatabaseError& e) {
    EXPECT_NE(std::string(e.what()).find("no texture layer 'nope' (layers: pattern)"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find(dbp.string()), std::string::npos);
  }
  // Exported files are exact (PNG and TIFF), written whole or from the tiles a row of tiles at
  // a time (7 rows of 16, the last of 4).
  for (const char* ext : {".png", ".tif"}) {
    const fs::path out = tmp_dir() / (std::string("level0") + ext);
    write_layer_image(src, out.string());
    const ImagePyramid again(out.string(), PyramidOptions{128, 64, 8});
    EXPECT_EQ(again.read({0, 0, 0, 100, 100}), src) << ext;
    const fs::path rows = tmp_dir() / (std::string("rows0") + ext);
    double shown = 0;
    export_layer_level(db, back, 0, rows.string(), [&](double f) {
      EXPECT_GT(f, shown);
      shown = f;
    });
    EXPECT_EQ(shown, 1.0);
    EXPECT_EQ(ImagePyramid(rows.string(), PyramidOptions{128, 64, 8}).read({0, 0, 0, 100, 100}), src) << ext;
  }
  EXPECT_THROW(write_layer_image(src, (tmp_dir() / "x.jpg").string()), std::runtime_error);
}

TEST(TextureStore, RecordsOfEarlierVersionsStayReadable) {
  const fs::path dbp = tmp_dir() / "records.db";
  tb::DatabaseInfo info;
  info.grid_width = info.grid_height = 9;
  info.transform = pm::GridTransform::identity();
  auto db = tb::BlockDatabase::create(dbp.string(), info);
  // As the first writer wrote it: control characters as \u00xx, other bytes (UTF-8) as they
  // are, a quote and a backslash escaped, "parameters" any JSON object.
  db.set_meta("texture_layer:old",
              "{\"format\": 1, \"name\": \"old\", \"kind\": \"thematic\", \"source\": "
              "\"a\\u0001\\u000a\\\"q\\\\ \xC3\xA9.tif\", "
              "\"georef\": [-0.5, -0.5, 8.5, 8.5], \"levels\": [[9, 9], [5, 5]], \"tile_size\": 512, "
              "\"max_texture_size\": 2048, \"power_of_two\": true, \"patches\": 0, \"parameters\": "
              "{\"attribute\": \"slope\", \"stops\": [[0, 255, 255, 255, 255], [45, 160, 0, 0, 255]]}}");
  // Keys in another order, a key of a later version, no parameters.
  db.set_meta("texture_layer:later",
              "{\"levels\": [[4, 2]], \"format\": 1, \"name\": \"later\", \"future\": {\"x\": [1, 2]}, "
              "\"georef\": [0, 0, 4, 2], \"tile_size\": 2, \"max_texture_size\": 4}");
  db.set_meta("texture_layer:broken", "{\"format\": 1, \"name\": \"broken\",\n \"georef\": [0, 0, 4, 2],}");
  db.set_meta("texture_layer:format2",
              "{\"format\": 2, \"georef\": [0, 0, 4, 2], \"levels\": [[4, 2]], \"tile_size\": 2}");
  db.set_meta("texture_layer:kinds", "{\"format\": 1, \"name\": 7}");

  const LayerRecord old = read_layer_record(db, "old");
  EXPECT_EQ(old.kind, "thematic");
  EXPECT_EQ(old.source, "a\x01\n\"q\\ \xC3\xA9.tif");  // every escape decoded
  EXPECT_EQ(old.georef, (GeoRect{-0.5, -0.5, 8.5, 8.5}));
  EXPECT_EQ(old.levels, (std::vector<LevelSize>{{9, 9}, {5, 5}}));
  EXPECT_TRUE(old.constraints.power_of_two);
  EXPECT_EQ(old.parameters,
            "{\"attribute\": \"slope\", \"stops\": [[0, 255, 255, 255, 255], [45, 160, 0, 0, 255]]}");
  const LayerRecord later = read_layer_record(db, "later");
  EXPECT_EQ(later.levels, (std::vector<LevelSize>{{4, 2}}));
  EXPECT_EQ(later.tile_size, 2);
  EXPECT_EQ(later.parameters, "{}");

  const auto error = [&](const std::string& name) -> std::string {
    try {
      (void)read_layer_record(db, name);
    } catch (const tb::DatabaseError& e) {
      return e.what();
    }
    return "(read)";
  };
  // Malformed JSON and wrong kinds: by line and column (the trailing comma's '}' is on line 2,
  // column 25); bad contents by what is wrong. Each names the database.
  for (const auto& [name, what] :
       {std::pair<std::string, std::string>{"broken",
                                            "texture layer 'broken': line 2, column 25: expected a key"},
        {"kinds", "texture layer 'kinds': line 1, column 23: \"name\" must be a string, not a number"},
        {"format2",
         "texture layer 'format2': malformed layer metadata: format 2 (this build reads format 1)"}}) {
    const std::string e = error(name);
    EXPECT_NE(e.find(what), std::string::npos) << e;
    EXPECT_NE(e.find(dbp.string()), std::string::npos) << e;
  }
}

#ifdef TERRALOD_CLI
using terralod::test::quote;

const terralod::test::CliRunner cli{TERRALOD_CLI};
int run(const std::string& args, std::string* out = nullptr) { return cli.run(args, out); }
void build_cli_database(const fs::path& asc, const fs::path& db) {
  terralod::test::build_cli_database(cli, asc, db);
}

TEST(TextureCli, ShadeAddAndExportEndToEnd) {
  const fs::path asc = tmp_dir() / "dem.asc", dbp = tmp_dir() / "cli.db";
  build_cli_database(asc, dbp);
  if (HasFatalFailure()) return;
  std::string text;
  ASSERT_EQ(run("texture shade " + quote(dbp.string()) + " --layer hill --light 315,45 --max-texture-size 32",
                &text),
            0);
  EXPECT_NE(text.find("store layer 'hill'"), std::string::npos) << text;
  const fs::path png = tmp_dir() / "hill.png";
  ASSERT_EQ(run("texture export " + quote(dbp.string()) + " --layer hill --out " + quote(png.string())), 0);
  // One texel per DEM sample, equal to the CPU hillshade of the DEM itself.
  const pm::Heightfield hf = tb::read_dem(asc.string());
  ShadingOptions so;
  const RgbaImage want = shading_texture(hf, so);
  const ImagePyramid got(png.string(), PyramidOptions{256, 64, 8});
  ASSERT_EQ(got.level(0), (LevelSize{65, 65}));
  EXPECT_EQ(got.read({0, 0, 0, 65, 65}), want);
  // With shadows at a low sun: the same as shading the DEM itself, though the database is read
  // window by window; relative height takes no shadows, said before any work.
  ASSERT_EQ(run("texture shade " + quote(dbp.string()) + " --layer low --shadows --light 200,12", &text), 0);
  ASSERT_EQ(run("texture export " + quote(dbp.string()) + " --layer low --out " + quote(png.string())), 0);
  so.shadows = true, so.azimuth_deg = 200, so.altitude_deg = 12;
  EXPECT_EQ(ImagePyramid(png.string(), PyramidOptions{256, 64, 8}).read({0, 0, 0, 65, 65}),
            shading_texture(hf, so));
  EXPECT_EQ(run("texture shade " + quote(dbp.string()) + " --layer r --method relative --shadows", &text), 2);
  EXPECT_NE(text.find("option '--shadows' applies to lit methods only"), std::string::npos) << text;
  EXPECT_EQ(text.find("terrain "), std::string::npos) << text;
  // Coarser level: 65 -> 32 (fits 32).
  ASSERT_EQ(run("texture export " + quote(dbp.string()) + " --layer hill --level 1 --out " +
                quote((tmp_dir() / "l1.tif").string())),
            0);
  EXPECT_EQ(ImagePyramid((tmp_dir() / "l1.tif").string(), PyramidOptions{256, 64, 8}).level(0),
            (LevelSize{32, 32}));
  // add: an image over the terrain, exported back unchanged.
  const fs::path img = tmp_dir() / "overlay.png";
  write_layer_image(pattern(90, 70), img.string());
  ASSERT_EQ(run("texture add " + quote(dbp.string()) + " --layer overlay --image " + quote(img.string()) +
                " --georef 0,0,1950,1950 --max-texture-size 32"),
            0);
  const fs::path back = tmp_dir() / "overlay_back.png";
  ASSERT_EQ(run("texture export " + quote(dbp.string()) + " --layer overlay --out " + quote(back.string())),
            0);
  EXPECT_EQ(ImagePyramid(back.string(), PyramidOptions{256, 64, 8}).read({0, 0, 0, 90, 70}), pattern(90, 70));
  // Errors: unknown layer, bad level, bad georef.
  EXPECT_NE(run("texture export " + quote(dbp.string()) + " --layer nope --out x.png", &text), 0);
  EXPECT_NE(text.find("no texture layer 'nope'"), std::string::npos) << text;
  EXPECT_EQ(run("texture export " + quote(dbp.string()) + " --layer hill --level 9 --out x.png", &text), 2);
  EXPECT_EQ(run("texture add " + quote(dbp.string()) + " --layer o2 --image " + quote(img.string()) +
                " --georef 1,2,3"),
            2);
}
// terralod texture thematic: a slope layer through a given ramp is the library's slope through
// that ramp, texel for texel; elevation bands are checked against the DEM's heights by hand;
// the default aspect ramp has its five compass stops; bad ramps and attributes are usage errors.
TEST(TextureCli, ThematicLayersEndToEnd) {
  const fs::path asc = tmp_dir() / "dem_thematic.asc", dbp = tmp_dir() / "thematic.db";
  build_cli_database(asc, dbp);
  if (HasFatalFailure()) return;
  const pm::Heightfield hf = tb::read_dem(asc.string());
  std::string text;
  ASSERT_EQ(run("texture thematic " + quote(dbp.string()) +
                    " --layer slope --attribute slope --ramp 0:000000,90:ff0000 --max-texture-size 32",
                &text),
            0);
  EXPECT_NE(text.find("thematic slope, 2 ramp stops: 65 x 65 texels"), std::string::npos) << text;
  const fs::path slope_png = tmp_dir() / "slope.png";
  ASSERT_EQ(
      run("texture export " + quote(dbp.string()) + " --layer slope --out " + quote(slope_png.string())), 0);
  const ColorRamp ramp({{0.0f, {0, 0, 0, 255}}, {90.0f, {255, 0, 0, 255}}});
  EXPECT_EQ(ImagePyramid(slope_png.string(), PyramidOptions{256, 64, 8}).read({0, 0, 0, 65, 65}),
            apply_mapper(terrain_attribute(hf, TerrainAttribute::SlopeDegrees), ramp));

  // Two bands split at the middle height: blue below, green at and above.
  double lo = 1e300, hi = -1e300;
  for (int r = 0; r < 65; ++r)
    for (int c = 0; c < 65; ++c) lo = std::min(lo, hf.at(c, r)), hi = std::max(hi, hf.at(c, r));
  ASSERT_GE(lo, 0.0) << "the first band starts at 0 m";
  const double split = std::round((lo + hi) / 2);
  ASSERT_EQ(run("texture thematic " + quote(dbp.string()) +
                " --layer bands --attribute elevation --bands --ramp 0:0000ff," + std::to_string(int(split)) +
                ":00ff00,100000:000000"),
            0);
  const fs::path bands_png = tmp_dir() / "bands.png";
  ASSERT_EQ(
      run("texture export " + quote(dbp.string()) + " --layer bands --out " + quote(bands_png.string())), 0);
  const RgbaImage bands =
      ImagePyramid(bands_png.string(), PyramidOptions{256, 64, 8}).read({0, 0, 0, 65, 65});
  int below = 0, above = 0;
  for (int r = 0; r < 65; ++r)
    for (int c = 0; c < 65; ++c) {
      const std::uint8_t* px = &bands.rgba[4 * (std::size_t(r) * 65 + std::size_t(c))];
      const bool high = hf.at(c, r) >= split;
      (high ? above : below)++;
      ASSERT_EQ(px[0], 0) << c << "," << r;
      ASSERT_EQ(px[1], high ? 255 : 0) << c << "," << r << " at " << hf.at(c, r) << " m";
      ASSERT_EQ(px[2], high ? 0 : 255) << c << "," << r << " at " << hf.at(c, r) << " m";
      ASSERT_EQ(px[3], 255);
    }
  std::printf("elevation bands: %d texels below %.0f m, %d above\n", below, split, above);
  EXPECT_GT(below, 0);
  EXPECT_GT(above, 0);

  ASSERT_EQ(run("texture thematic " + quote(dbp.string()) + " --layer aspect --attribute aspect", &text), 0);
  EXPECT_NE(text.find("thematic aspect, 5 ramp stops"), std::string::npos) << text;

  EXPECT_EQ(run("texture thematic " + quote(dbp.string()) + " --layer x --ramp 5:ff0000,1:00ff00", &text), 2);
  EXPECT_NE(text.find("not strictly increasing"), std::string::npos) << text;
  EXPECT_EQ(run("texture thematic " + quote(dbp.string()) + " --layer x --ramp 0:zz0000", &text), 2);
  EXPECT_NE(text.find("'zz0000' is not a colour"), std::string::npos) << text;
  // Beyond the float range: the stop would be stored as inf, which no JSON reader accepts.
  EXPECT_EQ(run("texture thematic " + quote(dbp.string()) + " --layer x --ramp 0:ff0000,1e39:00ff00", &text),
            2);
  EXPECT_NE(text.find("'1e39' is not a number"), std::string::npos) << text;
  EXPECT_EQ(run("texture thematic " + quote(dbp.string()) + " --layer x --attribute height", &text), 2);
}
#endif

}  // namespace
