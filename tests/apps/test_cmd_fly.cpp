// End-to-end test of `terralod fly` (issue 5, point 6): `terralod build` of a small DEM written
// here, a PATH.csv, then the headless flight runner; checks frames.csv (every documented column
// present and filled, the cameras and tau echoed exactly, triangle counts equal to the dumped
// meshes'), every dumped PLY (binary little-endian, double x y z in the world frame, int faces;
// with the independent frame checker: watertight, the whole view covered, measured screen-space
// error of the mesh as drawn, geomorphs included, <= the frame's bound), --no-prefetch and
// --speed-factor.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "drawn_frame_checker.hpp"
#include "run_command.hpp"
#include "screen_error_checker.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/camera_path.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace tb = terralod::blocks;
namespace tt = terralod::test;

const fs::path& tmp_dir() { return tt::process_temp_dir("cmd-fly"); }

tt::CommandResult terralod(const std::string& args) { return tt::run_tool(TERRALOD_CLI, args); }

// The terrain: 65 x 65 generated samples (whole metres), cellsize 30, lower-left corner (0, 0):
// sample centres x = 15 + 30 col, y = 15 + 30 (64 - row); built in blocks of 17 samples, so
// 4 x 4 blocks of 480 m. The flight: 40 frames at 500 m above the highest sample, from the
// south-west corner towards the north-east, looking ahead and down 35 degrees.
constexpr int kN = 65, kBlock = 17, kFrames = 40;

struct Fixture {
  fs::path asc, db, path_csv;
  pm::Heightfield hf;
  std::vector<pm::Camera> path;
  std::string build_error;
};

const Fixture& fixture() {
  static const Fixture f = [] {
    Fixture x;
    x.asc = tmp_dir() / "dem.asc";
    x.db = tmp_dir() / "terrain.db";
    x.path_csv = tmp_dir() / "path.csv";
    pm::TerrainOptions to;
    to.width = to.height = kN;
    to.seed = 23;
    to.relief = 500;
    to.quantize_to_metres = true;
    const pm::Heightfield gen = pm::generate_terrain(to);
    {
      std::ofstream f(x.asc);
      f << "ncols " << kN << "\nnrows " << kN
        << "\nxllcorner 0\nyllcorner 0\ncellsize 30\nNODATA_value -9999\n";
      for (int r = 0; r < kN; ++r)
        for (int c = 0; c < kN; ++c) f << gen.at(c, r) << (c + 1 < kN ? " " : "\n");
    }
    x.hf = tb::read_dem(x.asc.string());
    double top = -1e300;
    for (const double z : x.hf.samples()) top = std::max(top, z);
    for (int f = 0; f < kFrames; ++f) {
      pm::Camera c;
      c.x = 100.0 + 25.0 * f;
      c.y = 100.0 + 20.0 * f;
      c.z = top + 500.0 - 2.0 * f;
      c.yaw_deg = 51.0 + 0.5 * f;
      c.pitch_deg = -35.0;
      c.fovy_deg = 55.0;
      x.path.push_back(c);
    }
    pm::write_camera_path(x.path, x.path_csv.string());
    const tt::CommandResult b = terralod("build --threads 1 --block-size 17 --input " +
                                         tt::quote(x.asc.string()) + " --out " + tt::quote(x.db.string()));
    if (b.status != 0) x.build_error = "terralod build failed: " + b.err;
    return x;
  }();
  return f;
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> v;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, sep);) v.push_back(item);
  if (!s.empty() && s.back() == sep) v.emplace_back();
  return v;
}

const std::vector<std::string> kColumns = {"frame",
                                           "time_s",
                                           "x",
                                           "y",
                                           "z",
                                           "yaw",
                                           "pitch",
                                           "fovy",
                                           "tau_px",
                                           "triangles",
                                           "bound_px",
                                           "missing_in_view",
                                           "update_ms",
                                           "update_cpu_ms",
                                           "resident_bytes",
                                           "blocks_resident",
                                           "blocks_loading",
                                           "blocks_evicted",
                                           "nodes_resident",
                                           "nodes_loading",
                                           "nodes_evicted",
                                           "prefetch_misses",
                                           "bytes_read",
                                           "nodes_visited",
                                           "nodes_culled",
                                           "coarse_nodes",
                                           "pm_blocks",
                                           "standin_blocks",
                                           "fallback_nodes",
                                           "moving_vertices",
                                           "clamped_vertices",
                                           "seam_triangles",
                                           "standins_held",
                                           "standin_reads",
                                           "ground_xx",
                                           "ground_xy",
                                           "ground_yy"};

/// frames.csv as rows of numbers, asserting the header and that every field is a finite number.
std::vector<std::vector<double>> read_frames(const fs::path& csv) {
  const std::vector<std::string> lines = tt::lines_of(tt::slurp(csv));
  std::vector<std::vector<double>> rows;
  EXPECT_FALSE(lines.empty()) << csv;
  if (lines.empty()) return rows;
  EXPECT_EQ(split(lines[0], ','), kColumns) << lines[0];
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const std::vector<std::string> fields = split(lines[i], ',');
    EXPECT_EQ(fields.size(), kColumns.size()) << "line " << i + 1 << ": " << lines[i];
    std::vector<double> row;
    for (std::size_t k = 0; k < fields.size(); ++k) {
      char* end = nullptr;
      const double v = std::strtod(fields[k].c_str(), &end);
      EXPECT_TRUE(!fields[k].empty() && *end == '\0' && std::isfinite(v))
          << "line " << i + 1 << " column " << (k < kColumns.size() ? kColumns[k] : "?") << ": '" << fields[k]
          << "'";
      row.push_back(v);
    }
    rows.push_back(row);
  }
  return rows;
}

double col(const std::vector<double>& row, const std::string& name) {
  for (std::size_t k = 0; k < kColumns.size() && k < row.size(); ++k)
    if (kColumns[k] == name) return row[k];
  ADD_FAILURE() << "no column " << name;
  return NAN;
}

/// DIR/frame_NNNNN.ply of frame i.
std::string frame_ply(int i) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%05d.ply", i);
  return name;
}

std::string fly_args(const fs::path& out, const std::string& extra) {
  const Fixture& f = fixture();
  return "fly --db " + tt::quote(f.db.string()) + " --path " + tt::quote(f.path_csv.string()) +
         " --size 320x240 --tau 2 --out " + tt::quote(out.string()) + " " + extra;
}

TEST(CmdFly, FramesCsvAndDumpedMeshesAreCompleteWatertightAndWithinTheBound) {
  const Fixture& f = fixture();
  ASSERT_TRUE(f.build_error.empty()) << f.build_error;
  const fs::path out = tmp_dir() / "run";
  // Geomorphs on (the default): the bound is for the mesh as drawn, morphs included.
  const tt::CommandResult r = terralod(fly_args(out, "--dump-meshes --speed-factor 0"));
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  EXPECT_NE(r.out.find("read  " + f.path_csv.string() + ": 40 frames"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(", prefetch)"), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("fly: 100%"), std::string::npos) << r.err;  // progress, not a TTY

  const std::vector<std::vector<double>> rows = read_frames(out / "frames.csv");
  ASSERT_EQ(rows.size(), std::size_t(kFrames));
  double last_bytes = 0, last_misses = 0, last_standin_reads = 0, worst_ratio = 0;
  for (int i = 0; i < kFrames; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    const std::vector<double>& row = rows[std::size_t(i)];
    const pm::Camera& c = f.path[std::size_t(i)];
    EXPECT_EQ(col(row, "frame"), i);
    EXPECT_NEAR(col(row, "time_s"), i / 60.0, 1e-6);
    // The cameras and tau, echoed with 17 digits: bit-identical to the path.
    EXPECT_EQ(col(row, "x"), c.x);
    EXPECT_EQ(col(row, "y"), c.y);
    EXPECT_EQ(col(row, "z"), c.z);
    EXPECT_EQ(col(row, "yaw"), c.yaw_deg);
    EXPECT_EQ(col(row, "pitch"), c.pitch_deg);
    EXPECT_EQ(col(row, "fovy"), c.fovy_deg);
    EXPECT_EQ(col(row, "tau_px"), 2.0);
    const double bound = col(row, "bound_px");
    EXPECT_GE(bound, 0.0);
    if (col(row, "missing_in_view") == 0) {
      EXPECT_LE(bound, 2.0);
    }
    EXPECT_GE(col(row, "update_ms"), 0.0);
    EXPECT_GE(col(row, "update_cpu_ms"), 0.0);
    // Cumulative counters never decrease; 16 blocks at most in any count of blocks.
    EXPECT_GE(col(row, "bytes_read"), last_bytes);
    EXPECT_GE(col(row, "prefetch_misses"), last_misses);
    EXPECT_GE(col(row, "standin_reads"), last_standin_reads);
    last_bytes = col(row, "bytes_read");
    last_misses = col(row, "prefetch_misses");
    last_standin_reads = col(row, "standin_reads");
    // A stand-in drawn this frame was read and is held; every one held was read.
    EXPECT_LE(col(row, "standin_blocks"), col(row, "standins_held"));
    EXPECT_LE(col(row, "standins_held"), col(row, "standin_reads"));
    for (const char* k :
         {"blocks_resident", "blocks_loading", "missing_in_view", "pm_blocks", "standins_held"}) {
      EXPECT_GE(col(row, k), 0.0) << k;
      EXPECT_LE(col(row, k), 16.0) << k;
    }
    EXPECT_GT(col(row, "nodes_resident"), 16.0);
    EXPECT_LE(col(row, "resident_bytes"), 512e6);

    // The PLY: header as documented, then the mesh.
    const fs::path ply = out / frame_ply(i);
    const std::string bytes = tt::slurp(ply);
    ASSERT_EQ(bytes.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u) << ply;
    for (const char* line : {"property double x\n", "property double y\n", "property double z\n",
                             "property list uchar int vertex_indices\n"})
      EXPECT_NE(bytes.find(line), std::string::npos) << line;
    const pm::TriangleMeshData d = pm::read_ply(ply.string());
    EXPECT_EQ(double(d.triangles.size()), col(row, "triangles"));
    ASSERT_FALSE(d.triangles.empty());

    // Back to samples: every vertex stands over a sample (heights are the displayed ones).
    tt::DrawnFrame m;
    bool on_samples = true;
    for (const auto& p : d.positions) {
      const auto [fc, fr] = tt::world_to_index(f.hf, p[0], p[1]);
      const long ic = std::lround(fc), ir = std::lround(fr);
      if (std::abs(fc - double(ic)) > 1e-9 || std::abs(fr - double(ir)) > 1e-9 || ic < 0 || ir < 0 ||
          ic >= kN || ir >= kN) {
        on_samples = false;
        ADD_FAILURE() << "vertex (" << p[0] << ", " << p[1] << ", " << p[2] << ") is not over a sample";
        break;
      }
      m.samples.push_back(std::uint64_t(ir) * kN + std::uint64_t(ic));
      m.z.push_back(p[2]);
    }
    if (!on_samples) continue;
    // The PLY is counter-clockwise seen from above in the world; the checker wants CCW in
    // (col,row), which a north-up raster (determinant < 0) mirrors.
    m.triangles = d.triangles;
    for (auto& t : m.triangles) std::swap(t[1], t[2]);

    // The independent checker: measured error of what is drawn <= the bound, the whole view
    // covered, watertight. The runner's clip planes: far beyond the terrain, near from the
    // distance to its box; the eye is far above it, so near 0.5 m clips nothing more.
    // The ground scale as logged (this DEM has no CRS: the identity) is the view's.
    pm::Camera cam = c;
    cam.ground = {col(row, "ground_xx"), col(row, "ground_xy"), col(row, "ground_yy")};
    EXPECT_EQ(cam.ground, pm::GroundScale{});
    cam.width_px = 320;
    cam.height_px = 240;
    cam.near_m = 0.5;
    cam.far_m = 1e6;
    const tt::FrameCheck k = tt::check_drawn_frame(f.hf, m, cam);
    EXPECT_LE(k.max_error_px, bound * (1 + 1e-9) + 1e-9) << k.describe();
    EXPECT_TRUE(k.watertight()) << k.describe();
    EXPECT_EQ(k.uncovered_in_view, 0u) << k.describe();
    if (bound > 0) worst_ratio = std::max(worst_ratio, k.max_error_px / bound);
  }
  EXPECT_GT(last_bytes, 0.0);
  EXPECT_FALSE(fs::exists(out / frame_ply(kFrames)));
  std::printf("terralod fly: %d frames, worst measured / guaranteed screen error %.3f\n", kFrames,
              worst_ratio);
}

TEST(CmdFly, NoPrefetchAndSpeedFactor) {
  const Fixture& f = fixture();
  ASSERT_TRUE(f.build_error.empty()) << f.build_error;
  // --speed-factor K paces frame i to start no earlier than i / (60 K) s after the first:
  // 40 frames at K = 0.5 take at least 39 / 30 = 1.3 s; no PLYs without --dump-meshes.
  const fs::path out = tmp_dir() / "paced";
  const auto t0 = std::chrono::steady_clock::now();
  const tt::CommandResult r = terralod(fly_args(out, "--no-prefetch --speed-factor 0.5"));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  EXPECT_GE(seconds, 39.0 / 30.0);
  EXPECT_NE(r.out.find("(speed factor 0.5, no prefetch)"), std::string::npos) << r.out;
  const std::vector<std::vector<double>> rows = read_frames(out / "frames.csv");
  ASSERT_EQ(rows.size(), std::size_t(kFrames));
  for (const auto& e : fs::directory_iterator(out)) EXPECT_EQ(e.path().filename(), "frames.csv") << e.path();
  // 16 blocks fit the default 512 MB budget: nothing is ever evicted.
  EXPECT_EQ(col(rows.back(), "blocks_evicted"), 0.0);
  std::printf("terralod fly --no-prefetch --speed-factor 0.5: %.2f s for %d frames, %g prefetch misses\n",
              seconds, kFrames, col(rows.back(), "prefetch_misses"));

  // Bad values of both options are command-line errors (exit 2) naming the option.
  for (const std::string bad : {"--speed-factor -1", "--speed-factor nan", "--tau 0", "--size 0x10"}) {
    SCOPED_TRACE(bad);
    const tt::CommandResult e = terralod(fly_args(tmp_dir() / "bad", bad));
    EXPECT_EQ(e.status, 2) << e.err;
    EXPECT_NE(e.err.find(bad.substr(0, bad.find(' '))), std::string::npos) << e.err;
    EXPECT_FALSE(fs::exists(tmp_dir() / "bad" / "frames.csv"));
  }
}

}  // namespace
