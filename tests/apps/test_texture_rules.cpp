// End-to-end tests of 'terralod texture thematic --rules' (apps/texture_rules.cpp): every
// pyramid level of the stored layer is the look its texel size picks, drawn from the attribute
// generalised over 2^k x 2^k samples (computed here independently from the DEM), a changed
// threshold moves levels between looks, and bad rules files fail clearly without touching the
// database.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "cli_texture_database.hpp"
#include "run_command.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/texture_store.hpp"
#include "terralod/render/thematic_texture.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
namespace pm = terralod::pm;
using namespace terralod::render;
using terralod::test::quote;
using terralod::test::slurp;

const fs::path& tmp_dir() { return terralod::test::process_temp_dir("texture-rules"); }

const terralod::test::CliRunner cli{TERRALOD_CLI};
int run(const std::string& args, std::string* out = nullptr) { return cli.run(args, out); }
void build_database(const fs::path& asc, const fs::path& db) {
  terralod::test::build_cli_database(cli, asc, db);
}

void write_text(const fs::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

/// Level k of the layer, exported by the CLI and read back.
RgbaImage exported_level(const fs::path& db, const std::string& layer, int k) {
  const fs::path png = tmp_dir() / (layer + "_level" + std::to_string(k) + ".png");
  EXPECT_EQ(run("texture export " + quote(db.string()) + " --layer " + layer + " --level " +
                std::to_string(k) + " --out " + quote(png.string())),
            0);
  const ImagePyramid p(png.string(), PyramidOptions{4096, 64, 8});
  return p.read({0, 0, 0, p.level(0).width, p.level(0).height});
}

/// What level k should be, computed here: texel (i, j) = `ramp` of the mean of the valid values
/// of samples [i 2^k, (i+1) 2^k) x [j 2^k, (j+1) 2^k) (summed in double, row by row).
RgbaImage expected_level(const FloatRaster& v, int k, int w, int h, const ColorRamp& ramp) {
  const int step = 1 << k;
  RgbaImage img(w, h);
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      double sum = 0.0;
      int n = 0;
      for (int r = j * step; r < std::min((j + 1) * step, v.height); ++r)
        for (int c = i * step; c < std::min((i + 1) * step, v.width); ++c)
          if (!std::isnan(v.at(c, r))) sum += v.at(c, r), ++n;
      img.set(i, j, ramp.map(n ? float(sum / n) : std::numeric_limits<float>::quiet_NaN()));
    }
  return img;
}

// Near: slope bands every 10 degrees; far: a white-to-blue ramp. 30 m samples, max texture 8:
// levels 65, 32, 16, 8 texels of 30, 60, 120, 240 m.
const char* kNear = "0:ffffff,10:ffff00,20:ff8000,30:ff0000";
const char* kFar = "0:ffffff,45:0000ff";
std::string rules_json(double max_texel_m) {
  return "{\n  \"generalise\": \"mean\",\n  \"rules\": [\n    {\"max_texel_m\": " +
         std::to_string(max_texel_m) + ", \"ramp\": \"" + kNear + "\", \"bands\": true},\n    {\"ramp\": \"" +
         kFar + "\"}\n  ]\n}\n";
}

TEST(TextureRulesCli, EachLevelIsDrawnByTheRuleItsTexelSizePicks) {
  const fs::path asc = tmp_dir() / "dem.asc", dbp = tmp_dir() / "rules.db";
  build_database(asc, dbp);
  if (HasFatalFailure()) return;
  const FloatRaster slope = terrain_attribute(tb::read_dem(asc.string()), TerrainAttribute::SlopeDegrees);
  ASSERT_EQ(slope.width, 65);
  const ColorRamp near({{0.0f, {255, 255, 255, 255}},
                        {10.0f, {255, 255, 0, 255}},
                        {20.0f, {255, 128, 0, 255}},
                        {30.0f, {255, 0, 0, 255}}},
                       ColorRamp::Mode::Step);
  const ColorRamp far({{0.0f, {255, 255, 255, 255}}, {45.0f, {0, 0, 255, 255}}});
  const int sizes[] = {65, 32, 16, 8};

  // Threshold 60 m: levels 0 (30 m) and 1 (60 m) near, 2 and 3 far.
  const fs::path rules60 = tmp_dir() / "rules60.json", rules150 = tmp_dir() / "rules150.json";
  write_text(rules60, rules_json(60));
  std::string text;
  ASSERT_EQ(run("texture thematic " + quote(dbp.string()) + " --layer r60 --attribute slope --rules " +
                    quote(rules60.string()) + " --max-texture-size 8",
                &text),
            0);
  EXPECT_NE(text.find("level 1: 32 x 32 texels of 60 m, rule 0 (max_texel_m 60)"), std::string::npos) << text;
  EXPECT_NE(text.find("level 2: 16 x 16 texels of 120 m, rule 1 (far)"), std::string::npos) << text;
  std::vector<RgbaImage> r60;
  for (int k = 0; k < 4; ++k) {
    r60.push_back(exported_level(dbp, "r60", k));
    ASSERT_EQ(r60[k].width, sizes[k]);
    ASSERT_EQ(r60[k].height, sizes[k]);
    EXPECT_EQ(r60[k], expected_level(slope, k, sizes[k], sizes[k], k <= 1 ? near : far)) << "level " << k;
  }
  // Level 0 is the near bands of the full-resolution slope itself.
  EXPECT_EQ(r60[0], apply_mapper(slope, near));
  {
    const auto db = tb::BlockDatabase::open(dbp.string());
    const LayerRecord rec = read_layer_record(db, "r60");
    EXPECT_EQ(rec.levels.size(), 4u);
    EXPECT_NE(rec.parameters.find("\"generalise\": \"mean\""), std::string::npos) << rec.parameters;
    EXPECT_NE(rec.parameters.find("\"sample_size_m\": 30,"), std::string::npos) << rec.parameters;
    EXPECT_NE(rec.parameters.find("\"max_texel_m\": 60,"), std::string::npos) << rec.parameters;
    EXPECT_NE(rec.parameters.find("\"level_rules\": [0, 0, 1, 1]"), std::string::npos) << rec.parameters;
  }

  // Threshold 150 m: level 2 (120 m) moves to the near look; level 3 stays far.
  write_text(rules150, rules_json(150));
  ASSERT_EQ(run("texture thematic " + quote(dbp.string()) + " --layer r150 --attribute slope --rules " +
                quote(rules150.string()) + " --max-texture-size 8"),
            0);
  for (int k = 0; k < 4; ++k) {
    const RgbaImage got = exported_level(dbp, "r150", k);
    EXPECT_EQ(got, expected_level(slope, k, sizes[k], sizes[k], k <= 2 ? near : far)) << "level " << k;
    if (k == 2) {
      EXPECT_NE(got, r60[2]) << "the threshold did not change level 2's look";
    } else {
      EXPECT_EQ(got, r60[std::size_t(k)]) << "level " << k;
    }
  }
}

TEST(TextureRulesCli, BadRulesFailClearlyAndLeaveTheDatabaseUnchanged) {
  const fs::path asc = tmp_dir() / "dem_bad.asc", dbp = tmp_dir() / "bad.db";
  build_database(asc, dbp);
  if (HasFatalFailure()) return;
  const std::string bytes = slurp(dbp);
  const auto listing = [&] {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(tmp_dir())) names.insert(e.path().filename().string());
    return names;
  };
  const fs::path file = tmp_dir() / "bad.json";
  const auto fails = [&](const std::string& json, const std::string& options,
                         const std::vector<std::string>& words) {
    write_text(file, json);
    const std::set<std::string> before = listing();
    std::string text;
    EXPECT_EQ(run("texture thematic " + quote(dbp.string()) + " --layer bad --rules " + quote(file.string()) +
                      " " + options,
                  &text),
              2)
        << json;
    for (const std::string& w : words)
      EXPECT_NE(text.find(w), std::string::npos) << "'" << w << "' in:\n" << text;
    EXPECT_EQ(slurp(dbp), bytes) << "the database changed: " << json;
    EXPECT_EQ(listing(), before) << json;
  };
  const std::string ok_rule = "{\"ramp\": \"0:000000,90:ff0000\"}";
  // Malformed JSON: a trailing comma, named by file, line and column.
  fails("{\"rules\": [\n  " + ok_rule + ",\n]}", "", {file.string(), "line 3, column 1", "expected a value"});
  fails("{\"rules\": [" + ok_rule + "]", "", {file.string(), "expected '}'"});
  // Unknown generalisation, unknown key, wrong types.
  fails("{\"generalise\": \"median\", \"rules\": [" + ok_rule + "]}", "",
        {file.string(), "\"generalise\" must be nearest, majority or mean, not 'median'"});
  fails("{\"rules\": [{\"ramp\": \"0:000000,90:ff0000\", \"colour\": 1}]}", "",
        {"rules[0]: unknown key 'colour'"});
  fails("{\"rules\": [{\"max_texel_m\": \"60\"}, " + ok_rule + "]}", "",
        {"rules[0].max_texel_m must be a number, not a string"});
  fails("{\"rules\": []}", "", {"\"rules\" is empty"});
  fails("{}", "", {"no \"rules\""});
  // Rules that could never be used or never end.
  fails("{\"rules\": [" + ok_rule + ", " + ok_rule + "]}", "", {"rules[0] needs \"max_texel_m\""});
  fails("{\"rules\": [{\"max_texel_m\": 90}]}", "", {"rules[0] is the last rule", "takes no max_texel_m"});
  fails("{\"rules\": [{\"max_texel_m\": 90}, {\"max_texel_m\": 60}, " + ok_rule + "]}", "",
        {"rules[1].max_texel_m must be larger than the rule before's 90"});
  fails("{\"rules\": [{\"max_texel_m\": 0}, " + ok_rule + "]}", "", {"rules[0].max_texel_m must be > 0"});
  // A bad ramp inside the file names the rule.
  fails("{\"rules\": [{\"ramp\": \"5:ff0000,1:00ff00\"}]}", "",
        {file.string(), "rules[0].ramp", "not strictly increasing"});
  // Mean of aspect degrees is refused.
  fails("{\"generalise\": \"mean\", \"rules\": [" + ok_rule + "]}", "--attribute aspect",
        {"averages aspect degrees"});
  // --rules with --ramp or --bands.
  fails("{\"rules\": [" + ok_rule + "]}", "--ramp 0:000000,1:ffffff",
        {"'--rules' and '--ramp' cannot be combined"});
  fails("{\"rules\": [" + ok_rule + "]}", "--bands", {"'--rules' and '--bands' cannot be combined"});
  // A missing file.
  std::string text;
  EXPECT_EQ(run("texture thematic " + quote(dbp.string()) + " --layer bad --rules " +
                    quote((tmp_dir() / "missing.json").string()),
                &text),
            2);
  EXPECT_NE(text.find("cannot read " + (tmp_dir() / "missing.json").string()), std::string::npos) << text;
  EXPECT_EQ(slurp(dbp), bytes);
  const auto db = tb::BlockDatabase::open(dbp.string());
  EXPECT_THROW(read_layer_record(db, "bad"), std::runtime_error);
}

}  // namespace
