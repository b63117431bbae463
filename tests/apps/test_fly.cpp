// End-to-end tests of the flight demo terralod-fly: its window mode under a private Xvfb (a
// few hundred frames of a replayed path, no GL error, a screenshot that is not blank), and its
// headless mode (deterministic: the same path gives the same statistics apart from times,
// identical images and identical meshes).
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
#include "terralod/pm/camera_path.hpp"
#include "terralod/render/image.hpp"
#include "xvfb.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace rd = terralod::render;

// This process's own folder (ctest runs the test cases as parallel processes), removed at exit.
const fs::path kTmp = terralod::test::process_temp_dir("fly");

// Runs a shell command line; returns its exit status (-1 if it did not exit normally).
int run(const std::string& cmd) {
  const int s = std::system(cmd.c_str());
  return WIFEXITED(s) ? WEXITSTATUS(s) : -1;
}

using terralod::test::slurp;

// A 4-second low flight over the 129 x 129 built-in terrain (30 m spacing, 3.84 km square),
// turning gently, with a dive so that geomorphs run.
fs::path write_path(int frames) {
  fs::create_directories(kTmp);
  std::vector<pm::Camera> path;
  for (int k = 0; k < frames; ++k) {
    pm::Camera c;
    c.x = 600.0 + 8.0 * k;
    c.y = 600.0 + 6.0 * k;
    c.z = 1500.0 - 2.0 * k;
    c.yaw_deg = 50.0 + 0.1 * k, c.pitch_deg = -20.0, c.fovy_deg = 60.0;
    path.push_back(c);
  }
  const fs::path p = kTmp / ("path_" + std::to_string(frames) + ".csv");
  pm::write_camera_path(path, p.string());
  return p;
}

// The comma-separated fields of a line of frames.csv.
std::vector<std::string> fields(const std::string& line) {
  std::vector<std::string> f;
  std::stringstream ss(line);
  for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
  return f;
}

// frames.csv without the columns that hold wall times.
std::vector<std::string> stats_without_times(const fs::path& csv) {
  std::ifstream in(csv);
  std::string line;
  std::vector<std::string> rows;
  std::vector<int> keep;
  bool header = true;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = fields(line);
    if (header) {
      for (int i = 0; i < int(f.size()); ++i)
        if (f[std::size_t(i)].find("_ms") == std::string::npos) keep.push_back(i);
      header = false;
    }
    std::string r;
    for (int i : keep) r += (i < int(f.size()) ? f[std::size_t(i)] : "<missing>") + ",";
    rows.push_back(r);
  }
  return rows;
}

}  // namespace

TEST(FlyHeadless, IsDeterministicAndWritesEveryOutput) {
  const fs::path path = write_path(40);
  std::vector<fs::path> outs = {kTmp / "headless_a", kTmp / "headless_b"};
  for (const fs::path& o : outs) {
    fs::remove_all(o);
    const std::string cmd = std::string(TERRALOD_FLY) + " --headless --terrain-size 129 --path " +
                            path.string() + " --size 320x200 --tau 1 --out " + o.string() +
                            " --dump-meshes > " + (o.string() + ".log") + " 2>&1";
    ASSERT_EQ(run(cmd), 0) << cmd << "\n" << slurp(o.string() + ".log");
  }
  const auto a = stats_without_times(outs[0] / "frames.csv");
  const auto b = stats_without_times(outs[1] / "frames.csv");
  ASSERT_EQ(a.size(), 41u) << "header + 40 frames";
  EXPECT_EQ(a, b) << "the statistics of two runs differ";
  EXPECT_NE(a[0].find("bound_px"), std::string::npos);
  EXPECT_NE(a[0].find("triangles"), std::string::npos);
  for (int k = 0; k < 40; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d", k);
    const rd::Image ia = rd::read_image((outs[0] / (std::string(name) + ".png")).string());
    const rd::Image ib = rd::read_image((outs[1] / (std::string(name) + ".png")).string());
    EXPECT_EQ(ia.width, 320);
    EXPECT_EQ(ia.height, 200);
    EXPECT_TRUE(ia == ib) << name << ".png differs between runs";
    EXPECT_EQ(slurp(outs[0] / (std::string(name) + ".ply")), slurp(outs[1] / (std::string(name) + ".ply")))
        << name << ".ply differs between runs";
  }
  // Every frame kept its guarantee: bound_px <= tau_px.
  std::ifstream in(outs[0] / "frames.csv");
  std::string line;
  std::getline(in, line);
  // The columns: those of 'terralod fly' (the runtime's statistics), then the drawing's.
  EXPECT_EQ(
      line,
      "frame,time_s,x,y,z,yaw,pitch,fovy,tau_px,triangles,bound_px,missing_in_view,update_ms,update_cpu_ms,"
      "resident_bytes,blocks_resident,blocks_loading,blocks_evicted,nodes_resident,nodes_loading,nodes_"
      "evicted,"
      "prefetch_misses,bytes_read,nodes_visited,nodes_culled,coarse_nodes,pm_blocks,standin_blocks,fallback_"
      "nodes,"
      "moving_vertices,clamped_vertices,seam_triangles,standins_held,standin_reads,vertices,draw_ms,upload_"
      "ms,wait_ms,texture_bytes,"
      "texture_patches,textures_from_parent,ground_xx,ground_xy,ground_yy");
  int rows = 0;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = fields(line);
    ASSERT_EQ(f.size(), 44u) << line;
    EXPECT_LE(std::stod(f[10]), std::stod(f[8])) << "frame " << f[0] << ": bound above tau";
    EXPECT_GT(std::stoul(f[9]), 0u) << "frame " << f[0] << ": no triangles";
    // One PM: one block resident, none loading or missing; no evictions, misses or reads.
    EXPECT_EQ(f[11], "0") << line;
    EXPECT_EQ(f[15] + "," + f[16] + "," + f[17], "1,0,0") << line;
    EXPECT_EQ(f[21] + "," + f[22], "0,0") << line;
    EXPECT_EQ(f[26], "1") << line;
    EXPECT_EQ(f[32] + "," + f[33], "0,0") << line;                  // no stand-ins held or read
    EXPECT_EQ(f[41] + "," + f[42] + "," + f[43], "1,0,1") << line;  // no CRS: no ground scale
    EXPECT_EQ(std::stod(f[37]), 0.0) << "frame " << f[0] << ": a single PM never waits";  // wait_ms
    ++rows;
  }
  EXPECT_EQ(rows, 40);
}

// Without --path, the built-in flight circles where the land is: over a coastal terrain (sea at
// 0 m, an island in the south-west quarter, away from the circle around the centre), most of
// its frames are above the island.
TEST(FlyHeadless, BuiltInFlightFliesOverTheLand) {
  fs::create_directories(kTmp);
  const fs::path dem = kTmp / "coast.asc", out = kTmp / "coast_out", log = kTmp / "coast.log";
  {
    std::ofstream f(dem);
    f << "ncols 129\nnrows 129\nxllcorner 0\nyllcorner 0\ncellsize 30\n";
    for (int r = 0; r < 129; ++r) {  // row 0 is the north edge
      for (int c = 0; c < 129; ++c) {
        const double d2 = (c - 25.0) * (c - 25.0) + (r - 100.0) * (r - 100.0);
        const double h = 400.0 * std::exp(-d2 / 288.0);
        f << (c ? " " : "") << (h < 1.0 ? 0.0 : std::round(h));
      }
      f << "\n";
    }
    ASSERT_TRUE(f.good()) << dem;
  }
  fs::remove_all(out);
  const std::string cmd = std::string(TERRALOD_FLY) + " --headless --input " + dem.string() +
                          " --frames 240 --size 160x100 --out " + out.string() + " > " + log.string() +
                          " 2>&1";
  ASSERT_EQ(run(cmd), 0) << cmd << "\n" << slurp(log);
  std::ifstream in(out / "frames.csv");
  std::string line;
  std::getline(in, line);
  int frames = 0, over_land = 0;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = fields(line);
    ASSERT_GT(f.size(), 4u) << line;
    ++frames;
    over_land += std::stod(f[4]) > 201.0;  // z: 200 m above the ground under the camera
  }
  EXPECT_EQ(frames, 240);
  EXPECT_GE(over_land * 4, frames * 3) << over_land << " of " << frames << " frames above the island\n"
                                       << slurp(log);
}

TEST(FlyHeadless, BadPathIsAClearError) {
  fs::create_directories(kTmp);
  const fs::path bad = kTmp / "bad_path.csv";
  std::ofstream(bad) << "x,y,z,yaw,pitch,fovy\n1,2,3,4,5,60\nnot,a,row\n";
  const fs::path log = kTmp / "bad_path.log";
  const std::string cmd = std::string(TERRALOD_FLY) + " --headless --terrain-size 17 --path " + bad.string() +
                          " --out " + (kTmp / "bad_out").string() + " > " + log.string() + " 2>&1";
  EXPECT_EQ(run(cmd), 1);
  EXPECT_NE(slurp(log).find(bad.string() + ": line 3: expected 6 comma-separated numbers"), std::string::npos)
      << slurp(log);
  EXPECT_EQ(run(std::string(TERRALOD_FLY) + " --headless --size 0x0 > /dev/null 2>&1"), 2);
  EXPECT_EQ(run(std::string(TERRALOD_FLY) + " --help > /dev/null 2>&1"), 0);
}

TEST(FlyWindow, ReplaysAPathUnderXvfbAndWritesAScreenshot) {
  terralod::test::Xvfb xvfb;
  if (xvfb.display().empty()) GTEST_SKIP() << "Xvfb could not be started (is the xvfb package installed?)";
  const fs::path path = write_path(300);
  const fs::path shot = kTmp / "window_shot.png", log = kTmp / "window.log";
  fs::remove(shot);
  const std::string cmd = "DISPLAY=" + xvfb.display() + " " + TERRALOD_FLY + " --terrain-size 129 --replay " +
                          path.string() + " --frames 300 --size 320x240 --screenshot " + shot.string() +
                          " > " + log.string() + " 2>&1";
  ASSERT_EQ(run(cmd), 0) << cmd << "\n" << slurp(log);
  EXPECT_NE(slurp(log).find("flew 300 frames"), std::string::npos) << slurp(log);
  const rd::Image img = rd::read_image(shot.string());
  ASSERT_EQ(img.width, 320);
  ASSERT_EQ(img.height, 240);
  // Not blank: many colours, and both sky (top right) and shaded terrain (bottom).
  std::set<std::uint32_t> colours;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const std::uint8_t* p = img.pixel(x, y);
      colours.insert(std::uint32_t(p[0]) << 16 | std::uint32_t(p[1]) << 8 | p[2]);
    }
  EXPECT_GT(colours.size(), 100u) << "the screenshot looks blank";
  const std::uint8_t* top = img.pixel(img.width - 2, 1);
  const std::uint8_t* bottom = img.pixel(img.width / 2, img.height - 2);
  EXPECT_NE(std::vector<int>(top, top + 3), std::vector<int>(bottom, bottom + 3));
}
