// End-to-end tests of terralod-fly over a block database (--db, streamed through
// blocks::TerrainRuntime): a database built by the real `terralod build` from a generated DEM,
// a headless replayed flight (deterministic statistics and images, every CSV column filled,
// several blocks resident, loads adding up), texture layers from the same database, the window
// mode under a private Xvfb, and bad databases (clear errors naming the file, no crash).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "run_command.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/camera_path.hpp"
#include "terralod/pm/height_query.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/render/image.hpp"
#include "xvfb.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace rd = terralod::render;

// This process's own folder (ctest runs the test cases as parallel processes), removed at exit.
const fs::path& tmp() { return terralod::test::process_temp_dir("fly_db"); }

// Runs a shell command line; returns its exit status (-1 if it did not exit normally).
int run(const std::string& cmd) {
  const int s = std::system(cmd.c_str());
  return WIFEXITED(s) ? WEXITSTATUS(s) : -1;
}

using terralod::test::slurp;

// The terrain: the generated 129 x 129 terrain of seed 7 (30 m cells, about 3.8 km square),
// written as an Esri ASCII grid, built by `terralod build` into blocks of 33 samples: a 4 x 4
// block grid (each block 960 m square). Built once per process.
struct Terrain {
  fs::path dem, db;
  pm::Heightfield hf;  // as read_dem reads the DEM: the database's world frame
};
const Terrain& terrain() {
  static const Terrain t = [] {
    Terrain r;
    r.dem = tmp() / "gen.asc";
    r.db = tmp() / "gen.db";
    pm::TerrainOptions o;
    o.width = o.height = 129;
    o.seed = 7;
    o.roughness = 0.42;
    o.height_quantum = 1.0 / 16.0;
    const pm::Heightfield g = pm::generate_terrain(o);
    {
      std::ofstream f(r.dem);
      f << "ncols 129\nnrows 129\nxllcorner 0\nyllcorner 0\ncellsize 30\n";
      for (int row = 0; row < 129; ++row) {
        for (int c = 0; c < 129; ++c) f << (c ? " " : "") << g.at(c, row);
        f << "\n";
      }
    }
    const fs::path log = tmp() / "build.log";
    const std::string cmd = std::string(TERRALOD_CLI) + " build --input " + r.dem.string() + " --out " +
                            r.db.string() + " --block-size 33 --threads 1 > " + log.string() + " 2>&1";
    if (run(cmd) != 0) ADD_FAILURE() << cmd << "\n" << slurp(log);
    r.hf = terralod::blocks::read_dem(r.dem.string());
    return r;
  }();
  return t;
}

// A low flight across the blocks: 3 km in `frames` frames from the south-west (sample 20,108)
// towards the north-east, 150 m above the ground under the camera, looking 20 degrees down.
fs::path write_path(int frames) {
  const Terrain& t = terrain();
  std::vector<pm::Camera> path;
  const double step = 3000.0 / frames;
  for (int k = 0; k < frames; ++k) {
    const auto [x0, y0] = t.hf.transform.to_world(20, 108);  // south-west
    pm::Camera c;
    c.x = x0 + step * k * 0.8, c.y = y0 + step * k * 0.6;
    c.z = pm::bilinear_height(t.hf, c.x, c.y) + 150.0;
    c.yaw_deg = 53.13, c.pitch_deg = -20.0, c.fovy_deg = 60.0;
    path.push_back(c);
  }
  const fs::path p = tmp() / ("path_" + std::to_string(frames) + ".csv");
  pm::write_camera_path(path, p.string());
  return p;
}

struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  int col(const std::string& name) const {
    for (int i = 0; i < int(header.size()); ++i)
      if (header[std::size_t(i)] == name) return i;
    ADD_FAILURE() << "no column " << name;
    return 0;
  }
  // Every row without the columns holding wall times (*_ms) and resident_bytes: the runtime
  // counts the capacities its buffers hold, which keep the largest size any update gave them,
  // and a frame's inner updates (waiting for its loads) differ with the moment each block
  // arrives.
  std::vector<std::string> without_times() const {
    std::vector<std::string> out;
    for (const auto& r : rows) {
      std::string s;
      for (std::size_t i = 0; i < r.size(); ++i)
        if (i >= header.size() ||
            (header[i].find("_ms") == std::string::npos && header[i] != "resident_bytes"))
          s += r[i] + ",";
      out.push_back(s);
    }
    return out;
  }
};
Csv read_csv(const fs::path& p) {
  std::ifstream in(p);
  Csv c;
  std::string line;
  bool header = true;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    if (!line.empty() && line.back() == ',') f.push_back("");
    (header ? c.header : c.rows.emplace_back()) = f;
    header = false;
  }
  return c;
}

// Distinct colours, and whether the top-right (sky) and bottom-centre (terrain) pixels differ.
bool looks_drawn(const rd::Image& img) {
  std::set<std::uint32_t> colours;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const std::uint8_t* p = img.pixel(x, y);
      colours.insert(std::uint32_t(p[0]) << 16 | std::uint32_t(p[1]) << 8 | p[2]);
    }
  const std::uint8_t* top = img.pixel(img.width - 2, 1);
  const std::uint8_t* bottom = img.pixel(img.width / 2, img.height - 2);
  return colours.size() > 50 && std::vector<int>(top, top + 3) != std::vector<int>(bottom, bottom + 3);
}

std::string png_name(int k) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%05d", k);
  return name;
}

}  // namespace

TEST(FlyDb, HeadlessIsDeterministicAndFillsTheBlockColumns) {
  const Terrain& t = terrain();
  ASSERT_TRUE(fs::exists(t.db));
  const int frames = 30;
  const fs::path path = write_path(frames);
  const std::vector<fs::path> outs = {tmp() / "a", tmp() / "b"};
  for (const fs::path& o : outs) {
    const std::string cmd = std::string(TERRALOD_FLY) + " --headless --db " + t.db.string() + " --path " +
                            path.string() + " --size 240x160 --tau 1 --out " + o.string() +
                            " --dump-meshes > " + o.string() + ".log 2>&1";
    ASSERT_EQ(run(cmd), 0) << cmd << "\n" << slurp(o.string() + ".log");
  }
  const Csv a = read_csv(outs[0] / "frames.csv"), b = read_csv(outs[1] / "frames.csv");
  ASSERT_EQ(a.rows.size(), std::size_t(frames));
  EXPECT_EQ(a.without_times(), b.without_times()) << "the statistics of two runs differ";

  // Every column is filled in every row (the block columns too, with --db).
  for (const auto& r : a.rows) {
    ASSERT_EQ(r.size(), a.header.size()) << "row " << r[0];
    for (std::size_t i = 0; i < r.size(); ++i)
      EXPECT_FALSE(r[i].empty()) << "frame " << r[0] << ", " << a.header[i];
  }
  const int tri = a.col("triangles"), vert = a.col("vertices"), tau = a.col("tau_px"),
            bound = a.col("bound_px");
  const int pms = a.col("pm_blocks"), coarse = a.col("coarse_nodes"), res = a.col("blocks_resident"),
            missing = a.col("missing_in_view");
  const int evicted = a.col("blocks_evicted"), misses = a.col("prefetch_misses"), bytes = a.col("bytes_read");
  std::size_t max_resident = 0;
  unsigned long long last_bytes = 0, last_misses = 0;
  for (const auto& r : a.rows) {
    const std::string at = "frame " + r[0];
    EXPECT_GT(std::stoul(r[std::size_t(tri)]), 0u) << at;
    EXPECT_EQ(std::stod(r[std::size_t(tau)]), 1.0) << at;
    EXPECT_GE(std::stod(r[std::size_t(bound)]), 0.0) << at;
    // Headless frames wait for their loads: nothing needed is missing, so the bound holds.
    EXPECT_EQ(r[std::size_t(missing)], "0") << at;
    EXPECT_LE(std::stod(r[std::size_t(bound)]), 1.0) << at;
    // 4 x 4 blocks under the tree: between 1 and 16 PM blocks, and some node drawn.
    EXPECT_LE(std::stoul(r[std::size_t(pms)]), 16u) << at;
    EXPECT_GE(std::stoul(r[std::size_t(pms)]) + std::stoul(r[std::size_t(coarse)]), 1u) << at;
    max_resident = std::max<std::size_t>(max_resident, std::stoul(r[std::size_t(res)]));
    // Cumulative counters never decrease.
    EXPECT_GE(std::stoull(r[std::size_t(bytes)]), last_bytes) << at;
    EXPECT_GE(std::stoull(r[std::size_t(misses)]), last_misses) << at;
    last_bytes = std::stoull(r[std::size_t(bytes)]), last_misses = std::stoull(r[std::size_t(misses)]);
    // The frame's PLY has the vertices the CSV reports.
    const std::string ply = slurp(outs[0] / (png_name(std::stoi(r[0])) + ".ply"));
    EXPECT_NE(ply.find("element vertex " + r[std::size_t(vert)] + "\n"), std::string::npos) << at;
  }
  EXPECT_GT(max_resident, 1u) << "the flight should have several blocks resident";
  EXPECT_GT(last_bytes, 0u);
  // 16 blocks fit the default memory budget: nothing is evicted.
  EXPECT_EQ(a.rows.back()[std::size_t(evicted)], "0");

  for (int k = 0; k < frames; ++k) {
    const std::string name = png_name(k);
    const rd::Image ia = rd::read_image((outs[0] / (name + ".png")).string());
    const rd::Image ib = rd::read_image((outs[1] / (name + ".png")).string());
    ASSERT_EQ(ia.width, 240);
    ASSERT_EQ(ia.height, 160);
    EXPECT_TRUE(ia == ib) << name << ".png differs between runs";
    EXPECT_TRUE(looks_drawn(ia)) << name << ".png looks blank";
    EXPECT_EQ(slurp(outs[0] / (name + ".ply")), slurp(outs[1] / (name + ".ply"))) << name << ".ply differs";
  }
}

// A copy of the database with a shading layer 'hill' ('terralod texture shade'), made once,
// in patches of at most 64 x 64 texels (16 KiB): the tree's nodes get textures of their own.
const fs::path& shaded_db() {
  static const fs::path db = [] {
    const fs::path d = tmp() / "shaded.db", log = tmp() / "shade.log";
    fs::copy_file(terrain().db, d, fs::copy_options::overwrite_existing);
    const std::string cmd = std::string(TERRALOD_CLI) + " texture --layer hill --max-texture-size 64 shade " +
                            d.string() + " > " + log.string() + " 2>&1";
    if (run(cmd) != 0) ADD_FAILURE() << cmd << "\n" << slurp(log);
    return d;
  }();
  return db;
}

TEST(FlyDb, TextureLayersComeFromTheSameDatabase) {
  const fs::path& db = shaded_db();
  const fs::path log = tmp() / "shade.log";
  const fs::path path = write_path(6);
  const std::string base = std::string(TERRALOD_FLY) + " --headless --db " + db.string() + " --path " +
                           path.string() + " --size 200x120";
  const fs::path plain = tmp() / "plain", layered = tmp() / "layered";
  ASSERT_EQ(run(base + " --out " + plain.string() + " > " + log.string() + " 2>&1"), 0) << slurp(log);
  // No --texture-db: the layer comes from --db.
  ASSERT_EQ(run(base + " --layer hill --out " + layered.string() + " > " + log.string() + " 2>&1"), 0)
      << slurp(log);
  // Textures per drawn patch by gamma: several patches, every wanted one loaded (headless
  // frames wait), within the default budget.
  const Csv c = read_csv(layered / "frames.csv");
  ASSERT_EQ(c.rows.size(), 6u);
  std::size_t most_patches = 0;
  for (const auto& r : c.rows) {
    EXPECT_GT(std::stoul(r[std::size_t(c.col("texture_bytes"))]), 0u) << "frame " << r[0];
    EXPECT_LE(std::stoul(r[std::size_t(c.col("texture_bytes"))]), 536870912u) << "frame " << r[0];
    EXPECT_EQ(r[std::size_t(c.col("textures_from_parent"))], "0") << "frame " << r[0];
    most_patches = std::max<std::size_t>(most_patches, std::stoul(r[std::size_t(c.col("texture_patches"))]));
  }
  EXPECT_GT(most_patches, 2u) << "near terrain should want finer patches than the root's";
  // A budget of two patches: gamma is raised until two fit, and the cache holds no more.
  const fs::path tight = tmp() / "tight";
  ASSERT_EQ(run(base + " --layer hill --texture-memory 0.032768 --out " + tight.string() + " > " +
                log.string() + " 2>&1"),
            0)
      << slurp(log);
  const Csv ct = read_csv(tight / "frames.csv");
  ASSERT_EQ(ct.rows.size(), 6u);
  for (const auto& r : ct.rows) {
    EXPECT_LE(std::stoul(r[std::size_t(ct.col("texture_patches"))]), 2u) << "frame " << r[0];
    EXPECT_GE(std::stoul(r[std::size_t(ct.col("texture_patches"))]), 1u) << "frame " << r[0];
    EXPECT_LE(std::stoul(r[std::size_t(ct.col("texture_bytes"))]), 32768u) << "frame " << r[0];
  }
  for (int k = 0; k < 6; ++k) {
    const rd::Image ip = rd::read_image((plain / (png_name(k) + ".png")).string());
    const rd::Image il = rd::read_image((layered / (png_name(k) + ".png")).string());
    std::size_t differ = 0;
    for (int y = 0; y < ip.height; ++y)
      for (int x = 0; x < ip.width; ++x) {
        const std::uint8_t *p = ip.pixel(x, y), *q = il.pixel(x, y);
        differ += p[0] != q[0] || p[1] != q[1] || p[2] != q[2];
      }
    EXPECT_GT(differ, std::size_t(ip.width * ip.height / 4))
        << png_name(k) << ": the layer changed too little";
  }
  // A layer the database does not hold: a clear error.
  EXPECT_EQ(run(base + " --layer nothere --out " + (tmp() / "x").string() + " > " + log.string() + " 2>&1"),
            1);
  EXPECT_NE(slurp(log).find("nothere"), std::string::npos) << slurp(log);
}

// A number field of a flat JSON text ("key": value), NaN when missing.
double json_number(const std::string& json, const std::string& key) {
  const std::size_t at = json.find("\"" + key + "\":");
  return at == std::string::npos ? NAN : std::strtod(json.c_str() + at + key.size() + 3, nullptr);
}

// `terralod view --db` draws one frame of the same runtime: the first frame of terralod-fly
// from the same camera (no geomorphs) has the same triangles, and the bound holds.
TEST(FlyDb, ViewDrawsOneFrameOfTheRuntime) {
  const Terrain& t = terrain();
  const auto [x0, y0] = t.hf.transform.to_world(20, 108);
  const double z = pm::bilinear_height(t.hf, x0, y0) + 150.0;
  const std::string cam =
      std::to_string(x0) + "," + std::to_string(y0) + "," + std::to_string(z) + ",53.13,-20,60";
  const fs::path log = tmp() / "view.log", stats = tmp() / "view.json", png = tmp() / "view.png";
  const std::string cmd = std::string(TERRALOD_CLI) + " view --db " + t.db.string() + " --camera " + cam +
                          " --size 200x120 --out " + png.string() + " --stats " + stats.string() + " > " +
                          log.string() + " 2>&1";
  ASSERT_EQ(run(cmd), 0) << cmd << "\n" << slurp(log);
  const std::string j = slurp(stats);
  EXPECT_NE(j.find("\"selection\": \"runtime\""), std::string::npos) << j;
  EXPECT_EQ(json_number(j, "missing_in_view"), 0.0) << j;
  EXPECT_LE(json_number(j, "bound_px"), 1.0) << j;
  EXPECT_GT(json_number(j, "pm_blocks"), 0.0) << j;
  EXPECT_TRUE(looks_drawn(rd::read_image(png.string())));

  const fs::path path = tmp() / "one.csv", out = tmp() / "one";
  {
    std::ofstream f(path);
    f << "x,y,z,yaw,pitch,fovy\n" << cam << "\n";
  }
  ASSERT_EQ(run(std::string(TERRALOD_FLY) + " --headless --db " + t.db.string() + " --path " + path.string() +
                " --size 200x120 --morph 0 --out " + out.string() + " > " + log.string() + " 2>&1"),
            0)
      << slurp(log);
  const Csv c = read_csv(out / "frames.csv");
  ASSERT_EQ(c.rows.size(), 1u);
  EXPECT_EQ(std::stod(c.rows[0][std::size_t(c.col("triangles"))]), json_number(j, "triangles"));
  EXPECT_EQ(std::stod(c.rows[0][std::size_t(c.col("bound_px"))]), json_number(j, "bound_px"));
}

TEST(FlyDb, WindowStreamsBlocksUnderXvfb) {
  terralod::test::Xvfb xvfb;
  if (xvfb.display().empty()) GTEST_SKIP() << "Xvfb could not be started (is the xvfb package installed?)";
  const Terrain& t = terrain();
  const fs::path path = write_path(300);
  const fs::path shot = tmp() / "window_shot.png", log = tmp() / "window.log";
  const std::string cmd = "DISPLAY=" + xvfb.display() + " " + TERRALOD_FLY + " --db " + t.db.string() +
                          " --replay " + path.string() + " --frames 300 --size 320x240 --screenshot " +
                          shot.string() + " > " + log.string() + " 2>&1";
  ASSERT_EQ(run(cmd), 0) << cmd << "\n" << slurp(log);  // a GL error would throw: exit status 1
  EXPECT_NE(slurp(log).find("flew 300 frames"), std::string::npos) << slurp(log);
  const rd::Image img = rd::read_image(shot.string());
  ASSERT_EQ(img.width, 320);
  ASSERT_EQ(img.height, 240);
  EXPECT_TRUE(looks_drawn(img)) << "the screenshot looks blank";
}

// The window draws per-patch textures without waiting for them (the parent's texture while
// a patch loads): a flight with a layer under Xvfb draws and exits cleanly.
TEST(FlyDb, WindowDrawsTexturesPerPatchUnderXvfb) {
  terralod::test::Xvfb xvfb;
  if (xvfb.display().empty()) GTEST_SKIP() << "Xvfb could not be started (is the xvfb package installed?)";
  const fs::path path = write_path(90);
  const fs::path shot = tmp() / "window_layer.png", log = tmp() / "window_layer.log";
  const std::string cmd = "DISPLAY=" + xvfb.display() + " " + TERRALOD_FLY + " --db " + shaded_db().string() +
                          " --layer hill --replay " + path.string() +
                          " --frames 90 --size 320x240 --screenshot " + shot.string() + " > " + log.string() +
                          " 2>&1";
  ASSERT_EQ(run(cmd), 0) << cmd << "\n" << slurp(log);
  EXPECT_NE(slurp(log).find("flew 90 frames"), std::string::npos) << slurp(log);
  EXPECT_TRUE(looks_drawn(rd::read_image(shot.string()))) << "the screenshot looks blank";
}

TEST(FlyDb, BadDatabasesAreClearErrors) {
  const Terrain& t = terrain();
  const fs::path path = write_path(4);
  const std::string fly = std::string(TERRALOD_FLY) + " --headless --size 64x48 --path " + path.string() +
                          " --out " + (tmp() / "bad_out").string();
  const fs::path log = tmp() / "bad.log";
  // Not a database at all.
  const fs::path text = tmp() / "not_a.db";
  std::ofstream(text) << "this is not an SQLite file\n";
  EXPECT_EQ(run(fly + " --db " + text.string() + " > " + log.string() + " 2>&1"), 1) << slurp(log);
  EXPECT_NE(slurp(log).find(text.string()), std::string::npos) << slurp(log);
  // A missing file.
  const fs::path missing = tmp() / "missing.db";
  EXPECT_EQ(run(fly + " --db " + missing.string() + " > " + log.string() + " 2>&1"), 1) << slurp(log);
  EXPECT_NE(slurp(log).find(missing.string()), std::string::npos) << slurp(log);
  // Truncated: the first half of a good database (its header survives; pages are missing).
  const fs::path cut = tmp() / "truncated.db";
  fs::copy_file(t.db, cut, fs::copy_options::overwrite_existing);
  fs::resize_file(cut, fs::file_size(t.db) / 2);
  const int status = run(fly + " --db " + cut.string() + " > " + log.string() + " 2>&1");
  EXPECT_EQ(status, 1) << "a truncated database must be an error (not a crash): " << slurp(log);
  EXPECT_NE(slurp(log).find(cut.string()), std::string::npos) << slurp(log);
  // Misuse: --db and --input together, streaming options without --db, a bad theta.
  EXPECT_EQ(
      run(fly + " --db " + t.db.string() + " --input " + t.dem.string() + " > " + log.string() + " 2>&1"), 2);
  EXPECT_EQ(run(fly + " --memory 64 --terrain-size 17 > " + log.string() + " 2>&1"), 2);
  EXPECT_EQ(run(fly + " --db " + t.db.string() + " --theta 90 > " + log.string() + " 2>&1"), 2);
}
