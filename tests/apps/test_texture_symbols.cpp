// End-to-end tests of 'terralod texture symbols' (apps/texture_symbols.cpp): a 65 x 65 UTM terrain
// with a point layer whose rules draw an icon near, a symbol farther and nothing far away; every
// exported pyramid level holds the symbol exactly when its view distance d_k falls in the symbol
// range, at the anchor's texel, with the asked diameter and colour, and is transparent elsewhere;
// bad options fail clearly and leave the database unchanged.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "cli_utm_database.hpp"
#include "run_command.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/texture_store.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
using namespace terralod::render;
using terralod::test::quote;
using terralod::test::slurp;

const terralod::test::CliRunner cli{TERRALOD_CLI};
int run(const std::string& args, std::string* out = nullptr) { return cli.run(args, out); }

// The Hut (cs2cs: lon 15.0114513341, lat 45.1615781192 is E 500900, N 5000900 in UTM 33N).
const char* kPoints = R"({"type": "FeatureCollection", "features": [
  {"type": "Feature", "id": 1, "properties": {"name": "Hut"},
   "geometry": {"type": "Point", "coordinates": [15.0114513341, 45.1615781192]}}]})";

// Icon up to D1 = 30 km, symbol in (30 km, 100 km], nothing farther.
const char* kRules = R"({"ranges": [{"max_distance_m": 30000, "draw": "icon"},
  {"max_distance_m": 100000, "draw": "symbol"}, {"draw": "none"}]})";

// Terrain: 65 x 65 samples of 30 m, ASCII grid corner (500000, 5000000), so the layer's georef
// (sample extent padded by half a cell) is [500000, 501950] x [5000000, 5001950]. With
// --max-texture-size 4 the levels are 65, 32, 16, 8, 4 texels wide (and high); level k has
// texels of t_k = 2^k x 30 m and is shown at d_k = t_k x 623.5 = 18705, 37410, 74820, 149640,
// 299280 m: the symbol is in levels 1 and 2 only (d_k in (30000, 100000]). The Hut at level k
// (width w_k): u = 900 / 1950 x w_k, v = (5001950 - 5000900) / 1950 x w_k.
class SymbolsCli : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    suite_ = new terralod::test::TempDir("symbols-suite");
    const fs::path d = suite_->path();
    terralod::test::build_utm_cli_database(cli, d);
    std::ofstream(d / "points.geojson") << kPoints;
    std::ofstream(d / "rules.json") << kRules;
    const std::string db = quote((d / "t.db").string());
    ASSERT_EQ(run("objects add " + db + " --layer huts --input " + quote((d / "points.geojson").string()) +
                  " --rules " + quote((d / "rules.json").string())),
              0);
  }
  static void TearDownTestSuite() {
    delete suite_;
    suite_ = nullptr;
  }
  void SetUp() override {
    ASSERT_NE(suite_, nullptr);
    fs::copy_file(suite_->path() / "t.db", db());
  }
  std::string db() const { return (dir_.path() / "t.db").string(); }
  RgbaImage level(const std::string& layer, int k) const {
    const fs::path png = dir_.path() / (layer + std::to_string(k) + ".png");
    EXPECT_EQ(run("texture export " + quote(db()) + " --layer " + layer + " --level " + std::to_string(k) +
                  " --out " + quote(png.string())),
              0);
    const ImagePyramid p(png.string(), PyramidOptions{4096, 64, 8});
    return p.read({0, 0, 0, p.level(0).width, p.level(0).height});
  }

  static terralod::test::TempDir* suite_;
  terralod::test::TempDir dir_{"symbols"};
};
terralod::test::TempDir* SymbolsCli::suite_ = nullptr;

TEST_F(SymbolsCli, EachLevelShowsTheSymbolsItsViewDistanceDraws) {
  std::string out;
  ASSERT_EQ(run("texture symbols " + quote(db()) +
                    " --layer sym --objects huts --color 00ff00 --symbol-px 5 --max-texture-size 4",
                &out),
            0)
      << out;
  EXPECT_NE(out.find("level 1: 32 x 32 texels of 60 m, view distance 37410 m: 1 symbols"), std::string::npos)
      << out;
  const auto base = tb::BlockDatabase::open(db());
  const LayerRecord rec = read_layer_record(base, "sym");
  EXPECT_EQ(rec.kind, "symbols");
  EXPECT_NE(rec.parameters.find("\"objects\": \"huts\", \"color\": [0, 255, 0, 255], \"symbol_px\": 5"),
            std::string::npos)
      << rec.parameters;
  ASSERT_EQ(rec.levels.size(), 5u);
  EXPECT_EQ(rec.georef, (GeoRect{500000, 5000000, 501950, 5001950}));

  const double radius = 2.5;  // --symbol-px 5
  for (int k = 0; k < 5; ++k) {
    SCOPED_TRACE("level " + std::to_string(k));
    const RgbaImage img = level("sym", k);
    const int w = 65 >> k;
    ASSERT_EQ(img.width, w);
    ASSERT_EQ(img.height, w);
    const double u = 900.0 / 1950.0 * w, v = 1050.0 / 1950.0 * w;
    const bool symbol = k == 1 || k == 2;  // d_k in (30000, 100000]
    double sum = 0, su = 0, sv = 0;
    int stray = 0;
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) {
        const double a = img.get(x, y)[3] / 255.0;
        sum += a, su += a * (x + 0.5), sv += a * (y + 0.5);
        // Outside the disc's reach (radius + half a texel's diagonal) everything is transparent.
        if (a > 0 && (!symbol || std::hypot(x + 0.5 - u, y + 0.5 - v) > radius + 0.75)) ++stray;
      }
    EXPECT_EQ(stray, 0);
    if (!symbol) {
      EXPECT_EQ(sum, 0.0);
      continue;
    }
    // Centre within half a texel of the anchor; coverage = the disc's area pi r^2 = 19.6 texels.
    EXPECT_NEAR(su / sum, u, 0.5);
    EXPECT_NEAR(sv / sum, v, 0.5);
    EXPECT_NEAR(sum, M_PI * radius * radius, 0.1 * M_PI * radius * radius);
    // Diameter: texels at least half covered along the anchor's row and column, 5 +- 1.
    int row = 0, col = 0;
    for (int x = 0; x < img.width; ++x) row += img.get(x, int(v))[3] >= 128;
    for (int y = 0; y < img.height; ++y) col += img.get(int(u), y)[3] >= 128;
    EXPECT_NEAR(row, 5, 1);
    EXPECT_NEAR(col, 5, 1);
    // The fill colour at the anchor's texel, wholly covered (1.5 texels inside the outline).
    const auto c = img.get(int(u), int(v));
    EXPECT_EQ(c[1], 255);
    EXPECT_EQ(c[3], 255);
  }
}

TEST_F(SymbolsCli, BadOptionsAreRefusedAndLeaveTheDatabaseUnchanged) {
  const std::string before = slurp(db());
  struct Case {
    std::string args, message;
  };
  const Case cases[] = {
      {"--objects peaks", db() + ": no object layer 'peaks' (it has huts)"},
      {"--objects huts --color 12345", "option '--color' must be a colour RRGGBB or RRGGBBAA, not '12345'"},
      {"--objects huts --color red", "option '--color' must be a colour RRGGBB or RRGGBBAA, not 'red'"},
      {"--objects huts --symbol-px 0", "option '--symbol-px' needs an integer in [1, 1000], not '0'"},
      {"", "'texture symbols' needs --objects OBJLAYER"},
  };
  for (const Case& c : cases) {
    std::string out;
    EXPECT_EQ(run("texture symbols " + quote(db()) + " --layer sym " + c.args, &out), 2) << c.args;
    EXPECT_NE(out.find(c.message), std::string::npos) << c.args << "\n" << out;
    EXPECT_EQ(slurp(db()), before) << c.args;
  }
  std::string out;
  ASSERT_EQ(run("texture --help", &out), 0);
  EXPECT_NE(out.find("add|shade|thematic|symbols|export DB"), std::string::npos) << out;
  EXPECT_NE(out.find("--symbol-px N"), std::string::npos) << out;
  EXPECT_NE(out.find("d_k = t_k x 623.5 / sqrt(1)"), std::string::npos) << out;
}

}  // namespace
