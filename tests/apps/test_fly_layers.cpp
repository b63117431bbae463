// End-to-end test of terralod-fly's texture layers (--texture-db, --layer, headless): a run
// with two layers from a block database is deterministic (identical images and statistics),
// differs from the run without layers, and reports the texture memory resident.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "run_command.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/pm/camera_path.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/texture_store.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace rd = terralod::render;
namespace tb = terralod::blocks;

// This process's own folder (ctest runs the test cases as parallel processes), removed at exit.
const fs::path kTmp = terralod::test::process_temp_dir("fly_layers");

int run(const std::string& cmd) {
  const int s = std::system(cmd.c_str());
  return WIFEXITED(s) ? WEXITSTATUS(s) : -1;
}

using terralod::test::slurp;

// Stores `img` as layer `name` of kind `kind` over `georef` (pyramid converted next to the db).
void add_layer(tb::BlockDatabase& db, const std::string& name, const std::string& kind,
               const rd::RgbaImage& img, const rd::GeoRect& georef) {
  const std::string tx = (kTmp / (name + ".tx")).string();
  rd::ImagePyramid::convert(img, tx);
  const rd::ImagePyramid pyr(tx);
  rd::LayerRecord rec;
  rec.name = name;
  rec.kind = kind;
  rec.source = "test";
  rec.georef = georef;
  rd::store_texture_layer(db, rec, pyr, {});
}

// Two layers over the built-in terrain (129 x 129 samples, 30 m): "shade" (kind shading, so
// decal mode), 64 x 64, a west-east ramp of grey 64..190; "bands", 32 x 32, stripes of 4 rows
// alternating red (255,60,60) and green (60,200,60), all opaque.
fs::path make_database() {
  fs::create_directories(kTmp);
  const fs::path path = kTmp / "layers.db";
  fs::remove(path);
  tb::DatabaseInfo info;
  info.grid_width = info.grid_height = 129;
  info.source = "test_fly_layers";
  tb::BlockDatabase db = tb::BlockDatabase::create(path.string(), info);
  const rd::GeoRect georef{-4000, -4000, 4000, 4000};
  rd::RgbaImage shade(64, 64), bands(32, 32);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) {
      std::uint8_t* p = shade.pixel(x, y);
      p[0] = p[1] = p[2] = std::uint8_t(64 + 2 * x), p[3] = 255;
    }
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x) {
      std::uint8_t* p = bands.pixel(x, y);
      const bool red = (y / 4) % 2 == 0;
      p[0] = red ? 255 : 60, p[1] = red ? 60 : 200, p[2] = 60, p[3] = 255;
    }
  add_layer(db, "shade", "shading", shade, georef);
  add_layer(db, "bands", "image", bands, georef);
  return path;
}

fs::path write_path(int frames) {
  std::vector<pm::Camera> path;
  for (int k = 0; k < frames; ++k) {
    pm::Camera c;
    c.x = 600.0 + 8.0 * k, c.y = 600.0 + 6.0 * k, c.z = 1500.0 - 2.0 * k;
    c.yaw_deg = 50.0 + 0.1 * k, c.pitch_deg = -20.0, c.fovy_deg = 60.0;
    path.push_back(c);
  }
  const fs::path p = kTmp / "path.csv";
  pm::write_camera_path(path, p.string());
  return p;
}

// Column `name` of every row of frames.csv, and the rows without the *_ms columns.
struct Csv {
  std::vector<std::string> rows_without_times;
  std::vector<std::string> texture_bytes;
};
Csv read_csv(const fs::path& csv) {
  std::ifstream in(csv);
  Csv out;
  std::string line;
  std::vector<int> keep;
  int tex = -1;
  bool header = true;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    if (header) {
      for (int i = 0; i < int(f.size()); ++i) {
        if (f[std::size_t(i)].find("_ms") == std::string::npos) keep.push_back(i);
        if (f[std::size_t(i)] == "texture_bytes") tex = i;
      }
      header = false;
      continue;
    }
    std::string r;
    for (int i : keep) r += (i < int(f.size()) ? f[std::size_t(i)] : "<missing>") + ",";
    out.rows_without_times.push_back(r);
    out.texture_bytes.push_back(tex >= 0 && tex < int(f.size()) ? f[std::size_t(tex)] : "<missing>");
  }
  return out;
}

}  // namespace

TEST(FlyLayers, TwoLayersAreDeterministicAndDifferFromNoLayers) {
  const fs::path db = make_database();
  const fs::path path = write_path(12);
  const std::string base = std::string(TERRALOD_FLY) + " --headless --terrain-size 129 --path " +
                           path.string() + " --size 240x160 --tau 1";
  const std::string layers = " --texture-db " + db.string() + " --layer shade --layer bands:multiply:0.8";
  const std::vector<std::pair<fs::path, std::string>> runs = {
      {kTmp / "layers_a", layers}, {kTmp / "layers_b", layers}, {kTmp / "plain", ""}};
  for (const auto& [out, extra] : runs) {
    fs::remove_all(out);
    const std::string cmd = base + extra + " --out " + out.string() + " > " + out.string() + ".log 2>&1";
    ASSERT_EQ(run(cmd), 0) << cmd << "\n" << slurp(out.string() + ".log");
  }
  const Csv a = read_csv(runs[0].first / "frames.csv"), b = read_csv(runs[1].first / "frames.csv");
  const Csv plain = read_csv(runs[2].first / "frames.csv");
  ASSERT_EQ(a.rows_without_times.size(), 12u);
  EXPECT_EQ(a.rows_without_times, b.rows_without_times);
  // Resident texture memory: both layers' level 0, 4 bytes per texel: 4 (64^2 + 32^2) = 20480.
  for (std::size_t k = 0; k < 12; ++k) {
    EXPECT_EQ(a.texture_bytes[k], "20480") << "frame " << k;
    EXPECT_EQ(plain.texture_bytes[k], "0") << "frame " << k;
  }
  for (int k = 0; k < 12; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d.png", k);
    const rd::Image ia = rd::read_image((runs[0].first / name).string());
    const rd::Image ib = rd::read_image((runs[1].first / name).string());
    const rd::Image ip = rd::read_image((runs[2].first / name).string());
    ASSERT_EQ(ia.width, 240);
    ASSERT_EQ(ia.height, 160);
    EXPECT_TRUE(ia == ib) << name << " differs between two runs with layers";
    // The layers change most terrain pixels: red/green bands, no lighting.
    std::size_t differ = 0, reddish = 0, greenish = 0;
    for (int y = 0; y < ia.height; ++y)
      for (int x = 0; x < ia.width; ++x) {
        const std::uint8_t* p = ia.pixel(x, y);
        const std::uint8_t* q = ip.pixel(x, y);
        differ += p[0] != q[0] || p[1] != q[1] || p[2] != q[2];
        reddish += p[0] > p[1] + 40;
        greenish += p[1] > p[0] + 40;
      }
    EXPECT_GT(differ, std::size_t(ia.width * ia.height / 4)) << name;
    EXPECT_GT(reddish, 100u) << name;
    EXPECT_GT(greenish, 100u) << name;
  }
}

TEST(FlyLayers, BadLayerOptionsAreClearErrors) {
  const fs::path db = make_database();
  const fs::path log = kTmp / "bad.log";
  const std::string fly = std::string(TERRALOD_FLY) + " --headless --terrain-size 17 --frames 1 --out " +
                          (kTmp / "bad_out").string();
  EXPECT_EQ(run(fly + " --layer shade > " + log.string() + " 2>&1"), 2) << "--layer without --texture-db";
  EXPECT_EQ(run(fly + " --texture-db " + db.string() + " --layer shade:divide > " + log.string() + " 2>&1"),
            2);
  EXPECT_NE(slurp(log).find("unknown operation 'divide'"), std::string::npos) << slurp(log);
  EXPECT_EQ(
      run(fly + " --texture-db " + db.string() + " --layer shade:blend:1.5 > " + log.string() + " 2>&1"), 2);
  EXPECT_EQ(run(fly + " --texture-db " + db.string() + " --layer nothere > " + log.string() + " 2>&1"), 1);
  EXPECT_NE(slurp(log).find("nothere"), std::string::npos) << slurp(log);
}

#ifdef TERRALOD_CLI
// `terralod view` with the same two layers over a 65 x 65 ESRI ASCII grid (100 m cells, centred
// on the origin, a gentle ramp): the layered frame shows the bands (red and green, no lighting)
// and differs from the plain frame; misuse of the options is a usage error (exit 2).
TEST(ViewLayers, DrawsTheLayersAndRejectsBadOptions) {
  const fs::path db = make_database();
  const fs::path dem = kTmp / "ramp.asc";
  {
    std::ofstream f(dem);
    f << "ncols 65\nnrows 65\nxllcorner -3250\nyllcorner -3250\ncellsize 100\n";
    for (int r = 0; r < 65; ++r) {
      for (int c = 0; c < 65; ++c) f << (c == 0 ? "" : " ") << 100 + 3 * c + 2 * r;
      f << "\n";
    }
  }
  const std::string view = std::string(TERRALOD_CLI) + " view --input " + dem.string() +
                           " --camera 0,-2500,2500,0,-40,60 --size 200x150";
  const fs::path plain = kTmp / "view_plain.png", layered = kTmp / "view_layered.png",
                 log = kTmp / "view.log";
  ASSERT_EQ(run(view + " --out " + plain.string() + " > " + log.string() + " 2>&1"), 0) << slurp(log);
  ASSERT_EQ(run(view + " --texture-db " + db.string() + " --layer shade --layer bands:multiply:0.8 --out " +
                layered.string() + " > " + log.string() + " 2>&1"),
            0)
      << slurp(log);
  const rd::Image ip = rd::read_image(plain.string()), il = rd::read_image(layered.string());
  ASSERT_EQ(il.width, 200);
  std::size_t differ = 0, reddish = 0, greenish = 0;
  for (int y = 0; y < il.height; ++y)
    for (int x = 0; x < il.width; ++x) {
      const std::uint8_t* p = il.pixel(x, y);
      const std::uint8_t* q = ip.pixel(x, y);
      differ += p[0] != q[0] || p[1] != q[1] || p[2] != q[2];
      reddish += p[0] > p[1] + 40;
      greenish += p[1] > p[0] + 40;
    }
  EXPECT_GT(differ, std::size_t(il.width * il.height / 4));
  EXPECT_GT(reddish, 100u);
  EXPECT_GT(greenish, 100u);
  const std::string out = " --out " + (kTmp / "view_bad.png").string() + " > " + log.string() + " 2>&1";
  EXPECT_EQ(run(view + " --layer shade" + out), 2) << "--layer without --texture-db";
  EXPECT_EQ(run(view + " --texture-db " + db.string() + " --layer shade --wireframe" + out), 2);
  EXPECT_EQ(run(view + " --texture-db " + db.string() + " --layer shade --lens 1,2" + out), 2);
  EXPECT_NE(slurp(log).find("X,Y,RADIUS"), std::string::npos) << slurp(log);
}
#endif
