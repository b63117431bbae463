// End-to-end tests of the terralod command-line tool: runs the built binary on a small Esri
// ASCII grid it writes itself and checks exit codes, messages, JSON fields and output meshes.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "mesh_checker.hpp"
#include "run_command.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;

// ---------------------------------------------------------------------------------------------
// Running the tool (tests/support/run_command.hpp)

using CliResult = terralod::test::CommandResult;
using terralod::test::lines_of;
using terralod::test::quote;
using terralod::test::slurp;

/// A folder of this process's own (ctest may run the tests of this file in parallel
/// processes), removed when the process ends.
const fs::path& tmp_dir() { return terralod::test::process_temp_dir("cli"); }

/// Runs `terralod <args>` (args already shell-quoted where needed), capturing both streams.
CliResult terralod(const std::string& args) { return terralod::test::run_tool(TERRALOD_CLI, args); }

/// The number after `"key": ` (first occurrence) in a JSON text; NaN when absent.
double json_number(const std::string& json, const std::string& key) {
  const std::string k = "\"" + key + "\": ";
  const std::size_t at = json.find(k);
  if (at == std::string::npos) return NAN;
  char* end = nullptr;
  const double v = std::strtod(json.c_str() + at + k.size(), &end);
  return end == json.c_str() + at + k.size() ? NAN : v;
}

/// The number after `word ` in a line such as "extract E=2 m: 10 triangles, bound 1.5 m".
double number_after(const std::string& line, const std::string& word) {
  const std::size_t at = line.find(word);
  if (at == std::string::npos) return NAN;
  return std::strtod(line.c_str() + at + word.size(), nullptr);
}

// ---------------------------------------------------------------------------------------------
// The test DEM
//
// A 33 x 25 Esri ASCII grid, cellsize 10, lower-left corner (1000, 2000), no CRS: the reader
// takes the units as metres and maps sample centres, so (by hand)
//   x = 1005 + 10 * col                 x0 = 1005, xc = 10, range [1005, 1325]
//   y = 2000 + 5 + 10 * (24 - row)      y0 = 2245, yr = -10, range [2005, 2245]
// Heights are multiples of 0.25 m, written exactly, so read-back heights compare with ==.

constexpr int kW = 33, kH = 25;

double height_at(int col, int row) {
  const double smooth = 80.0 * std::sin(col * 0.21) * std::cos(row * 0.17) + 3.0 * col - 2.0 * row;
  const int rough = int((unsigned(col) * 7919u + unsigned(row) * 104729u) % 13u);
  return std::round(smooth * 4.0) / 4.0 + 0.25 * rough + 500.0;
}

pm::Heightfield test_heightfield() {
  pm::Heightfield hf(kW, kH);
  for (int r = 0; r < kH; ++r)
    for (int c = 0; c < kW; ++c) hf.at(c, r) = height_at(c, r);
  hf.transform = pm::GridTransform::north_up(1005.0, 2245.0, 10.0, 10.0);
  return hf;
}

/// Writes the test grid; `void_at` >= 0 turns that sample index into NODATA.
void write_asc(const fs::path& path, int void_at = -1) {
  std::ofstream f(path);
  f << "ncols " << kW << "\nnrows " << kH
    << "\nxllcorner 1000\nyllcorner 2000\ncellsize 10\nNODATA_value -9999\n";
  char buf[64];
  for (int r = 0; r < kH; ++r) {
    for (int c = 0; c < kW; ++c) {
      const bool is_void = r * kW + c == void_at;
      std::snprintf(buf, sizeof buf, "%s%.2f", c ? " " : "", is_void ? -9999.0 : height_at(c, r));
      f << buf;
    }
    f << "\n";
  }
  ASSERT_TRUE(f.good()) << path;
}

// ---------------------------------------------------------------------------------------------
// Help and command-line errors

TEST(cli_help, EveryCommandHasHelp) {
  const CliResult top = terralod("--help");
  EXPECT_EQ(top.status, 0) << top.err;
  EXPECT_NE(top.out.find("usage: terralod"), std::string::npos) << top.out;
  for (const std::string cmd : {"pm", "extract", "info", "demo"}) {
    SCOPED_TRACE(cmd);
    EXPECT_NE(top.out.find("  " + cmd + " "), std::string::npos) << "not listed by --help:\n" << top.out;
    const CliResult r = terralod(cmd + " --help");
    EXPECT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(r.out.rfind("usage: terralod " + cmd, 0), 0u) << r.out;
    EXPECT_NE(r.out.find("--help"), std::string::npos) << r.out;
    EXPECT_TRUE(r.err.empty()) << r.err;
  }
  EXPECT_EQ(terralod("").status, 2);  // no command: usage on stderr, exit 2
}

TEST(cli_errors, BadOptionsExitTwoNamingTheOption) {
  const std::string dem = quote((tmp_dir() / "unused.asc").string());
  struct Case {
    std::string args, must_name;
  };
  const std::vector<Case> cases = {
      {"pm --input " + dem + " --out x.pm --frobnicate", "--frobnicate"},
      {"pm --input " + dem + " --out x.pm --metric exact", "--metric"},
      {"pm --input " + dem + " --out x.pm --threads two", "--threads"},
      {"pm --out x.pm", "--input"},
      {"extract --input " + dem + " --out x.ply --max-error", "--max-error"},
      {"extract --input " + dem + " --out x.ply --max-error -1", "--max-error"},
      {"extract --input " + dem + " --out x.ply --max-error nan", "--max-error"},
      {"extract --input " + dem + " --out x.ply --max-error inf", "--max-error"},
      {"extract --input " + dem + " --out x.ply --max-error 2m", "--max-error"},
      {"extract --input " + dem + " --out x.ply --max-error 1 --units feet", "--units"},
      {"extract --input " + dem + " --out x.stl --max-error 1", "--out"},
      {"extract --input " + dem + " --out x.stl --max-error 1", "must name a .ply, .obj, .glb or .gltf file"},
      {"extract --db " + dem + " --grid-level 0 --out x.stl", "--out"},
      {"info " + dem + " --bogus=1", "--bogus"},
      {"demo --size 1", "--size"},
      {"demo --sizes 65", "--sizes"},
      {"--frobnicate", "--frobnicate"},
      {"frobnicate", "frobnicate"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.args);
    const CliResult r = terralod(c.args);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find(c.must_name), std::string::npos) << r.err;
    EXPECT_EQ(lines_of(r.err).size(), 1u) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
  }
}

TEST(cli_errors, MissingInputExitsOneNamingTheFile) {
  const fs::path missing = tmp_dir() / "does_not_exist.asc";
  const fs::path out = tmp_dir() / "never_written.pm";
  fs::remove(out);
  for (const std::string& args : {"pm --input " + quote(missing.string()) + " --out " + quote(out.string()),
                                  "info " + quote(missing.string()),
                                  "extract --input " + quote(missing.string()) + " --max-error 1 --out " +
                                      quote((tmp_dir() / "n.ply").string()),
                                  "info " + quote((tmp_dir() / "does_not_exist.pm").string())}) {
    SCOPED_TRACE(args);
    const CliResult r = terralod(args);
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_EQ(r.err.rfind("terralod: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find("does_not_exist."), std::string::npos) << r.err;
    EXPECT_EQ(lines_of(r.err).size(), 1u) << r.err;
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(cli_errors, MissingOutputFolderExitsOneNamingThePath) {
  const fs::path dem = tmp_dir() / "folder_test.asc";
  write_asc(dem);
  const fs::path out = tmp_dir() / "no_such_folder" / "t.pm";
  const CliResult r = terralod("pm --input " + quote(dem.string()) + " --out " + quote(out.string()));
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find(out.string()), std::string::npos) << r.err;
}

// ---------------------------------------------------------------------------------------------
// pm -> info -> extract on the test grid

class cli_pipeline : public ::testing::Test {
 protected:
  static fs::path dem() { return tmp_dir() / "grid.asc"; }
  static fs::path pm_file() { return tmp_dir() / "grid.pm"; }

  static void SetUpTestSuite() {
    write_asc(dem());
    fs::remove(pm_file());
    pm_run_ = new CliResult(
        terralod("pm --threads 1 --input " + quote(dem().string()) + " --out " + quote(pm_file().string())));
  }
  static void TearDownTestSuite() {
    delete pm_run_;
    pm_run_ = nullptr;
  }

  /// Runs extract and returns its stdout lines (asserting success).
  static CliResult extract(const std::string& input, double e, const fs::path& out,
                           const std::string& units) {
    std::ostringstream a;
    a << "extract --threads 1 --input " << quote(input) << " --max-error " << e << " --out "
      << quote(out.string()) << " --units " << units;
    return terralod(a.str());
  }

  static CliResult* pm_run_;
};
CliResult* cli_pipeline::pm_run_ = nullptr;

TEST_F(cli_pipeline, PmPrintsOneLinePerStageAndWritesTheFile) {
  ASSERT_EQ(pm_run_->status, 0) << pm_run_->err;
  const std::vector<std::string> l = lines_of(pm_run_->out);
  ASSERT_EQ(l.size(), 3u) << pm_run_->out;
  EXPECT_EQ(l[0].rfind("read  ", 0), 0u) << l[0];
  EXPECT_NE(l[0].find("33 x 25 samples"), std::string::npos) << l[0];
  EXPECT_EQ(l[1].rfind("build 825 vertices -> ", 0), 0u) << l[1];
  EXPECT_EQ(l[2].rfind("write ", 0), 0u) << l[2];
  EXPECT_NE(l[2].find("bytes/vertex"), std::string::npos) << l[2];
  EXPECT_TRUE(fs::is_regular_file(pm_file()));
  // stderr is not a TTY here: the progress goes out as "build: N%" lines, ending at 100 %.
  EXPECT_NE(pm_run_->err.find("build: 100%"), std::string::npos) << pm_run_->err;
}

TEST_F(cli_pipeline, InfoReportsGridTransformAndHierarchy) {
  ASSERT_EQ(pm_run_->status, 0) << pm_run_->err;
  const CliResult r = terralod("info " + quote(pm_file().string()));
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string& j = r.out;
  EXPECT_NE(j.find("\"kind\": \"pm\""), std::string::npos) << j;
  EXPECT_EQ(json_number(j, "width"), kW) << j;
  EXPECT_EQ(json_number(j, "height"), kH) << j;  // the first "height" is the grid's
  EXPECT_EQ(json_number(j, "x0"), 1005.0) << j;
  EXPECT_EQ(json_number(j, "xc"), 10.0) << j;
  EXPECT_EQ(json_number(j, "xr"), 0.0) << j;
  EXPECT_EQ(json_number(j, "y0"), 2245.0) << j;
  EXPECT_EQ(json_number(j, "yc"), 0.0) << j;
  EXPECT_EQ(json_number(j, "yr"), -10.0) << j;
  // A full grid without holes: every sample is a vertex; vsplits + base vertices = vertices.
  const double vertices = json_number(j, "vertices"), vsplits = json_number(j, "vsplits");
  const double base = json_number(j, "base_vertices");
  EXPECT_EQ(vertices, kW * kH) << j;
  EXPECT_GT(vsplits, 0.0) << j;
  EXPECT_EQ(vsplits + base, vertices) << j;
  EXPECT_GE(base, 4.0) << j;  // the four grid corners never collapse
  EXPECT_EQ(json_number(j, "bytes"), double(fs::file_size(pm_file()))) << j;
  EXPECT_GE(json_number(j, "max_error"), 0.0) << j;
  EXPECT_NE(j.find("\"metric\": \"continuous\""), std::string::npos) << j;
  EXPECT_NE(j.find("\"formula\": \"x = x0 + col*xc + row*xr; y = y0 + col*yc + row*yr\""), std::string::npos)
      << j;

  // The same DEM read directly gives the same grid and transform, and no PM fields.
  const CliResult d = terralod("info " + quote(dem().string()));
  ASSERT_EQ(d.status, 0) << d.err;
  EXPECT_NE(d.out.find("\"kind\": \"dem\""), std::string::npos) << d.out;
  EXPECT_EQ(json_number(d.out, "width"), kW);
  EXPECT_EQ(json_number(d.out, "x0"), 1005.0);
  EXPECT_EQ(json_number(d.out, "found"), 0.0);
  EXPECT_EQ(d.out.find("\"vsplits\""), std::string::npos) << d.out;
}

TEST_F(cli_pipeline, ExtractSamplesAndWorldMeshesHoldTheirBound) {
  ASSERT_EQ(pm_run_->status, 0) << pm_run_->err;
  const pm::Heightfield hf = test_heightfield();
  for (const double e : {0.0, 2.0, 10.0}) {
    SCOPED_TRACE("E = " + std::to_string(e));
    const fs::path samples_ply = tmp_dir() / "grid_samples.ply", world_ply = tmp_dir() / "grid_world.ply";
    const CliResult s = extract(pm_file().string(), e, samples_ply, "samples");
    ASSERT_EQ(s.status, 0) << s.err;
    const CliResult w = extract(pm_file().string(), e, world_ply, "world");
    ASSERT_EQ(w.status, 0) << w.err;

    // "extract E=2 m: T triangles, V vertices, bound B m, ..." on the second line.
    const std::vector<std::string> l = lines_of(s.out);
    ASSERT_EQ(l.size(), 3u) << s.out;
    ASSERT_EQ(l[1].rfind("extract E=", 0), 0u) << l[1];
    const double triangles = number_after(l[1], " m: "), vertices = number_after(l[1], "triangles, ");
    const double bound = number_after(l[1], "bound ");
    EXPECT_LE(bound, e) << l[1];

    const pm::TriangleMeshData ms = pm::read_ply(samples_ply.string());
    const pm::TriangleMeshData mw = pm::read_ply(world_ply.string());
    ASSERT_GT(ms.positions.size(), 0u);
    EXPECT_EQ(double(ms.positions.size()), vertices);
    EXPECT_EQ(double(ms.triangles.size()), triangles);
    ASSERT_EQ(mw.positions.size(), ms.positions.size());
    ASSERT_EQ(mw.triangles.size(), ms.triangles.size());
    // Zero-error collapses (coplanar neighbourhoods) may already apply at E = 0.
    EXPECT_LE(ms.triangles.size(), std::size_t(2 * (kW - 1) * (kH - 1)));

    // Samples units: integer (col,row) with z the sample's height; world units: the same
    // vertices mapped by the transform worked out above.
    pm::TriangleMesh mesh;
    double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
    for (std::size_t i = 0; i < ms.positions.size(); ++i) {
      const auto [x, y, z] = ms.positions[i];
      ASSERT_TRUE(x == std::floor(x) && y == std::floor(y) && x >= 0 && x < kW && y >= 0 && y < kH)
          << x << " " << y;
      const int col = int(x), row = int(y);
      ASSERT_EQ(z, height_at(col, row)) << col << " " << row;
      mesh.vertices.push_back(std::uint32_t(row * kW + col));
      const auto [wx, wy, wz] = mw.positions[i];
      EXPECT_EQ(wx, 1005.0 + 10.0 * col);
      EXPECT_EQ(wy, 2245.0 - 10.0 * row);
      EXPECT_EQ(wz, z);
      xmin = std::min(xmin, wx), xmax = std::max(xmax, wx), ymin = std::min(ymin, wy),
      ymax = std::max(ymax, wy);
    }
    EXPECT_EQ(xmin, 1005.0);
    EXPECT_EQ(xmax, 1325.0);
    EXPECT_EQ(ymin, 2005.0);
    EXPECT_EQ(ymax, 2245.0);
    mesh.triangles = ms.triangles;
    mesh.error_bound = bound;

    // Independent check of the samples mesh: exact cover, watertight, error <= reported bound.
    const terralod::test::MeshCheck c = terralod::test::check_mesh(hf, mesh);
    EXPECT_TRUE(c.ok(bound)) << c.describe();
  }
}

// .glb and .gltf outputs: the glTF containers by their first bytes here; their content is
// checked by tests/pm/test_gltf_writer.cpp and by the official validator in
// tests/apps/test_gltf_validator.cpp.
TEST_F(cli_pipeline, ExtractWritesGlbAndGltf) {
  ASSERT_EQ(pm_run_->status, 0) << pm_run_->err;
  const fs::path glb = tmp_dir() / "grid.glb", gltf = tmp_dir() / "grid.GLTF";
  for (const fs::path& out : {glb, gltf}) {
    const CliResult r = extract(pm_file().string(), 2.0, out, "world");
    ASSERT_EQ(r.status, 0) << r.err;
    const std::vector<std::string> l = lines_of(r.out);
    ASSERT_EQ(l.size(), 3u) << r.out;
    EXPECT_EQ(l[2].rfind("write " + out.string() + ": ", 0), 0u) << l[2];
    EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
  }
  const std::string b = slurp(glb), t = slurp(gltf);
  ASSERT_GE(b.size(), 12u);
  EXPECT_EQ(b.substr(0, 4), "glTF");
  std::uint32_t length = 0;
  std::memcpy(&length, b.data() + 8, 4);
  EXPECT_EQ(length, b.size());
  EXPECT_EQ(t.rfind("{\"asset\":{\"version\":\"2.0\"", 0), 0u) << t.substr(0, 80);
  EXPECT_NE(t.find("data:application/octet-stream;base64,"), std::string::npos);
}

TEST_F(cli_pipeline, ExtractFromTheDemEqualsExtractFromThePm) {
  ASSERT_EQ(pm_run_->status, 0) << pm_run_->err;
  const fs::path a = tmp_dir() / "from_pm.obj", b = tmp_dir() / "from_dem.obj";
  const CliResult ra = extract(pm_file().string(), 3.0, a, "world");
  ASSERT_EQ(ra.status, 0) << ra.err;
  const CliResult rb = extract(dem().string(), 3.0, b, "world");
  ASSERT_EQ(rb.status, 0) << rb.err;
  // A DEM input prints read, build, extract, write; a .pm input read, extract, write.
  EXPECT_EQ(lines_of(ra.out).size(), 3u) << ra.out;
  EXPECT_EQ(lines_of(rb.out).size(), 4u) << rb.out;
  const std::string oa = slurp(a), ob = slurp(b);
  EXPECT_FALSE(oa.empty());
  EXPECT_EQ(oa, ob) << "the .pm round trip changed the extracted mesh";
  EXPECT_NE(oa.find("\nf "), std::string::npos) << "no faces in the OBJ";
}

TEST(cli_voids, VoidsAreReportedFilledOrKept) {
  const fs::path dem = tmp_dir() / "void.asc";
  write_asc(dem, /*void_at=*/10 * kW + 12);
  const CliResult filled = terralod("info " + quote(dem.string()));
  ASSERT_EQ(filled.status, 0) << filled.err;
  EXPECT_EQ(json_number(filled.out, "found"), 1.0) << filled.out;
  EXPECT_EQ(json_number(filled.out, "filled"), 1.0) << filled.out;
  const CliResult kept = terralod("info --keep-voids " + quote(dem.string()));
  ASSERT_EQ(kept.status, 0) << kept.err;
  EXPECT_EQ(json_number(kept.out, "found"), 1.0) << kept.out;
  EXPECT_EQ(json_number(kept.out, "filled"), 0.0) << kept.out;

  // A PM with a hole: the hole's sample is no vertex.
  const fs::path out = tmp_dir() / "void.pm";
  const CliResult p =
      terralod("pm --keep-voids --input " + quote(dem.string()) + " --out " + quote(out.string()));
  ASSERT_EQ(p.status, 0) << p.err;
  EXPECT_NE(p.out.find("1 voids (0 filled, 1 kept as holes)"), std::string::npos) << p.out;
  const CliResult i = terralod("info " + quote(out.string()));
  ASSERT_EQ(i.status, 0) << i.err;
  EXPECT_EQ(json_number(i.out, "vertices"), double(kW * kH - 1)) << i.out;
}

// A void region of 2^20 samples or more takes a second or so to fill: every command reading the
// DEM says so on stderr before and after, with where it is; a small one is filled silently.
TEST(cli_voids, AWideGapIsToldWhileItIsFilled) {
  const int w = 1100, h = 1060;
  const fs::path dem = tmp_dir() / "wide_gap.asc";
  {
    std::ofstream f(dem);
    f << "ncols " << w << "\nnrows " << h << "\nxllcorner 0\nyllcorner 0\ncellsize 30\nNODATA_value -9999\n";
    char buf[32];
    for (int r = 0; r < h; ++r) {
      for (int c = 0; c < w; ++c) {
        // 1023 x 1026 void samples (just over 2^20), and a 10 x 10 one
        const bool wide = r >= 20 && r <= 1045 && c >= 30 && c <= 1052, small = r < 10 && c < 10;
        std::snprintf(buf, sizeof buf, "%s%.0f", c ? " " : "",
                      wide || small ? -9999.0 : 100.0 + (c + 2 * r) % 50);
        f << buf;
      }
      f << "\n";
    }
    ASSERT_TRUE(f.good()) << dem;
  }
  const CliResult r = terralod("info " + quote(dem.string()));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("voids filling a region of 1049598 samples (input cols 30-1052, rows 20-1045)...\n"
                       "voids filled the region at input cols 30-1052, rows 20-1045 in "),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("voids filling a region of 100 samples"), std::string::npos) << r.err;
  EXPECT_EQ(json_number(r.out, "filled"), double(1023 * 1026 + 100)) << r.out;
}

// ---------------------------------------------------------------------------------------------
// --crs: the world frame of geographic DEMs

/// A geographic (WGS 84, .prj sidecar) ASCII grid of n x n samples `step` degrees apart, south-west
/// sample centre at (lon0, lat0), heights 100 + col + row.
fs::path write_geographic_asc(
    const std::string& name, double lon0, double lat0, int n, double step,
    const std::function<double(int, int)>& height = [](int c, int r) { return 100.0 + c + r; }) {
  const fs::path path = tmp_dir() / (name + ".asc");
  std::ofstream f(path);
  f.precision(17);
  f << "ncols " << n << "\nnrows " << n << "\nxllcenter " << lon0 << "\nyllcenter " << lat0 << "\ncellsize "
    << step << "\n";
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) f << (c ? " " : "") << height(c, r);
    f << "\n";
  }
  std::ofstream(tmp_dir() / (name + ".prj"))
      << "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],"
         "PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433],AUTHORITY[\"EPSG\",\"4326\"]]";
  return path;
}

TEST(cli_crs, InfoReportsTheFrameItsScaleErrorAndTheVerticalDatum) {
  const std::string dem = quote(write_geographic_asc("deg1", -70.0, 44.0, 41, 0.025).string());
  const CliResult a = terralod("info " + dem);  // --crs auto by default
  ASSERT_EQ(a.status, 0) << a.err;
  EXPECT_NE(a.out.find("\"frame\": \"azimuthal equidistant (auto)"), std::string::npos) << a.out;
  EXPECT_NE(a.out.find("scale error within +-0.001 %"), std::string::npos) << a.out;
  EXPECT_LT(json_number(a.out, "scale_error"), 2e-5) << a.out;
  EXPECT_NE(a.out.find("\"vertical_datum\": \"\""), std::string::npos) << a.out;  // an .asc states none
  // Heights and voids are the file's own, whatever the frame: 100 .. 180, none void (the warped
  // frame's cells outside the footprint were counted as voids, its bilinear heights as the range).
  EXPECT_EQ(json_number(a.out, "min"), 100.0) << a.out;
  EXPECT_EQ(json_number(a.out, "max"), 180.0) << a.out;
  EXPECT_EQ(json_number(a.out, "found"), 0.0) << a.out;
  // A folder of tiles is described as the mosaic build reads (it was "not a regular file").
  const fs::path folder = tmp_dir() / "info_tiles";
  fs::create_directories(folder);
  for (const auto& [name, lon] : {std::pair{"west", -70.0}, std::pair{"east", -70.0 + 41 * 0.025}}) {
    const fs::path asc = write_geographic_asc(name, lon, 44.0, 41, 0.025);
    fs::copy_file(asc, folder / asc.filename(), fs::copy_options::overwrite_existing);
    fs::copy_file(fs::path(asc).replace_extension(".prj"), folder / (std::string(name) + ".prj"),
                  fs::copy_options::overwrite_existing);
  }
  const CliResult m = terralod("info --crs native " + quote(folder.string()));
  ASSERT_EQ(m.status, 0) << m.err;
  EXPECT_EQ(json_number(m.out, "width"), 82.0) << m.out;
  EXPECT_EQ(json_number(m.out, "height"), 41.0) << m.out;
  EXPECT_NE(m.out.find("mosaic of 2 files"), std::string::npos) << m.out;
  const CliResult n = terralod("info --crs native " + dem);
  ASSERT_EQ(n.status, 0) << n.err;
  EXPECT_NE(n.out.find("\"frame\": \"local equirectangular"), std::string::npos) << n.out;
  EXPECT_GT(json_number(n.out, "scale_error"), 0.006) << n.out;
  const CliResult u = terralod("info --crs EPSG:32619 " + dem);
  ASSERT_EQ(u.status, 0) << u.err;
  EXPECT_NE(u.out.find("UTM zone 19N"), std::string::npos) << u.out;
  EXPECT_GT(json_number(u.out, "x0"), 300000.0) << u.out;  // UTM eastings
  const CliResult bad = terralod("info --crs EPSG:999999 " + dem);
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find("deg1.asc"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("'EPSG:999999'"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("--crs"), std::string::npos) << bad.err;
  // A DEM without a CRS cannot be warped to one, and says so.
  const fs::path plain = tmp_dir() / "plain.asc";
  write_asc(plain);
  const CliResult none = terralod("info --crs EPSG:32619 " + quote(plain.string()));
  EXPECT_EQ(none.status, 1);
  EXPECT_NE(none.err.find("has no CRS"), std::string::npos) << none.err;
  for (const std::string cmd : {"pm", "extract", "info", "view", "build", "tin", "hybrid"}) {
    const CliResult h = terralod(cmd + " --help");
    EXPECT_NE(h.out.find("--crs CRS"), std::string::npos) << cmd << ":\n" << h.out;
  }
}

TEST(cli_crs, InfoOfADatabaseReportsTheFrameItWasBuiltIn) {
  const std::string dem = quote(write_geographic_asc("deg1db", -70.0, 44.0, 41, 0.025).string());
  const fs::path db = tmp_dir() / "deg1.db";
  const CliResult b =
      terralod("build --threads 1 --block-size 17 --input " + dem + " --out " + quote(db.string()));
  ASSERT_EQ(b.status, 0) << b.err;
  const CliResult i = terralod("info " + quote(db.string()));
  ASSERT_EQ(i.status, 0) << i.err;
  EXPECT_NE(i.out.find("\"frame\": {\"description\": \"azimuthal equidistant (auto)"), std::string::npos)
      << i.out;
  EXPECT_NE(i.out.find("scale error within +-0.001 %"), std::string::npos) << i.out;
  EXPECT_LT(json_number(i.out, "scale_error"), 2e-5) << i.out;
  EXPECT_GT(json_number(i.out, "scale_error"), 0.0) << i.out;
  EXPECT_NE(i.out.find("\"vertical_datum\": \"\"}"), std::string::npos) << i.out;  // an .asc states none
  // Built with --crs native: its frame and its (larger) error.
  const fs::path ndb = tmp_dir() / "deg1_native.db";
  ASSERT_EQ(terralod("build --threads 1 --block-size 17 --crs native --input " + dem + " --out " +
                     quote(ndb.string()))
                .status,
            0);
  const CliResult n = terralod("info " + quote(ndb.string()));
  EXPECT_NE(n.out.find("\"frame\": {\"description\": \"local equirectangular"), std::string::npos) << n.out;
  EXPECT_GT(json_number(n.out, "scale_error"), 0.006) << n.out;
  // A database built before frames were recorded (its meta rows removed): info says so.
  sqlite3* s = nullptr;
  ASSERT_EQ(sqlite3_open(db.string().c_str(), &s), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(s, "DELETE FROM meta WHERE key IN ('frame', 'frame_scale_error')", nullptr, nullptr,
                         nullptr),
            SQLITE_OK)
      << sqlite3_errmsg(s);
  sqlite3_close(s);
  const CliResult old = terralod("info " + quote(db.string()));
  ASSERT_EQ(old.status, 0) << old.err;
  EXPECT_NE(old.out.find("\"frame\": \"not recorded (built before"), std::string::npos) << old.out;
}

TEST(cli_crs, ADemTooLargeForTheAutoFrameIsWarnedAbout) {
  // 12 x 12 degrees on the equator: c_max = 8.5 degrees, scale error ~ c_max^2 / 12 = 0.18 %.
  const std::string dem = quote(write_geographic_asc("deg12", 0.0, -6.0, 25, 0.5).string());
  const fs::path out = tmp_dir() / "deg12.pm";
  const CliResult p = terralod("pm --input " + dem + " --out " + quote(out.string()));
  ASSERT_EQ(p.status, 0) << p.err;
  EXPECT_NE(p.err.find("warning: "), std::string::npos) << p.err;
  EXPECT_NE(p.err.find("over 0.1 %"), std::string::npos) << p.err;
  const CliResult small =
      terralod("pm --input " + quote(write_geographic_asc("deg2", 0.0, -1.0, 25, 0.08).string()) + " --out " +
               quote((tmp_dir() / "deg2.pm").string()));
  ASSERT_EQ(small.status, 0) << small.err;
  EXPECT_EQ(small.err.find("warning: "), std::string::npos) << small.err;
}

// An export whose level cannot meet its bound says which level and why, and exits with 1; one
// that meets every bound says nothing and exits with 0.
TEST(cli_export, ALevelThatCannotMeetItsBoundIsWarnedAboutWithItsReason) {
  const auto export_of = [](const std::string& name, const fs::path& asc, const std::string& options) {
    const fs::path db = tmp_dir() / (name + ".db");
    const CliResult b = terralod("build --threads 1 --block-size 17 --crs native --input " +
                                 quote(asc.string()) + " --out " + quote(db.string()));
    EXPECT_EQ(b.status, 0) << b.err;
    return terralod("export --threads 1 --db " + quote(db.string()) + " --out " +
                    quote((tmp_dir() / (name + "_tiles")).string()) + options);
  };
  // One sample 900 km high (below the 10,000 km read as a fill value): a tile's 32,767 height
  // steps are 32 m, and half of one is over the deepest level's 1 m.
  const CliResult spike =
      export_of("export_spike",
                write_geographic_asc("export_spike", -70.0, 44.0, 41, 0.025,
                                     [](int c, int r) { return c == 20 && r == 20 ? 9e5 : 100.0 + c + r; }),
                "");
  EXPECT_EQ(spike.status, 1) << spike.out << spike.err;
  EXPECT_NE(spike.out.find("is measured above its bound: half its height step (16 m)"), std::string::npos)
      << spike.out;
  // Rough samples 0.0005 degrees apart in the two 180-degree tiles of level 0 only: their 1 m is
  // measured on a lattice of 0.0055 degrees.
  const CliResult coarse =
      export_of("export_coarse",
                write_geographic_asc("export_coarse", -70.0, 44.0, 41, 0.0005,
                                     [](int c, int r) { return 100.0 + 50.0 * ((c * 7 + r * 13) % 5); }),
                " --max-level 0");
  EXPECT_EQ(coarse.status, 1) << coarse.out << coarse.err;
  EXPECT_NE(coarse.out.find("level 0 is measured above its bound: a tile places its vertices on a 32768"),
            std::string::npos)
      << coarse.out;
  const CliResult fine =
      export_of("export_fine", write_geographic_asc("export_fine", -70.0, 44.0, 41, 0.025), "");
  EXPECT_EQ(fine.status, 0) << fine.out << fine.err;
  EXPECT_EQ(fine.out.find("warning"), std::string::npos) << fine.out;
}

// ---------------------------------------------------------------------------------------------
// demo

TEST(cli_demo, PrintsEightLevelsWithinTheirBounds) {
  const CliResult r = terralod("demo --size 65 --seed 7");
  ASSERT_EQ(r.status, 0) << r.err;
  std::vector<std::string> levels;
  for (const std::string& l : lines_of(r.out))
    if (l.rfind("E=", 0) == 0) levels.push_back(l);
  ASSERT_EQ(levels.size(), 8u) << r.out;
  const double expected_e[] = {0, 0.5, 1, 2, 5, 10, 20, 50};
  double previous = 1e300;
  for (std::size_t k = 0; k < levels.size(); ++k) {
    SCOPED_TRACE(levels[k]);
    EXPECT_EQ(number_after(levels[k], "E="), expected_e[k]);
    const double triangles = number_after(levels[k], " m: ");
    EXPECT_LE(number_after(levels[k], "bound "), expected_e[k]);
    EXPECT_LE(triangles, previous);  // a larger error never needs more triangles
    EXPECT_GT(triangles, 0.0);
    previous = triangles;
  }
  EXPECT_LE(number_after(levels[0], " m: "), 2.0 * 64 * 64);  // at most the full grid
  EXPECT_EQ(number_after(levels[0], "bound "), 0.0);
  EXPECT_NE(r.out.find("\nbuild 4225 vertices"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("bytes/vertex"), std::string::npos) << r.out;
}

}  // namespace
