// End-to-end tests of `terralod tin`: runs the built binary on a small Esri ASCII grid and a
// polygon CSV it writes itself, and checks exit codes, messages and the written TIN.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "run_command.hpp"
#include "terralod/pm/mesh_io.hpp"

namespace {

namespace fs = std::filesystem;

using CliResult = terralod::test::CommandResult;
using terralod::test::quote;

/// A folder of this process's own, removed when the process ends (tests/support/run_command.hpp).
const fs::path& tmp_dir() { return terralod::test::process_temp_dir("cmd-tin"); }

CliResult terralod(const std::string& args) { return terralod::test::run_tool(TERRALOD_CLI, args); }

// A 21 x 17 Esri ASCII grid, cellsize 10, lower-left corner (1000, 2000): sample centres are
//   x = 1005 + 10 col,   y = 2005 + 10 (16 - row) = 2165 - 10 row.
// Heights: the plane 100 + col + 2 row, plus a 50 m bump at (col 8, row 7).
constexpr int kW = 21, kH = 17, kBumpCol = 8, kBumpRow = 7;
double height(int col, int row) {
  return 100.0 + col + 2.0 * row + (col == kBumpCol && row == kBumpRow ? 50.0 : 0.0);
}
std::array<double, 2> world(int col, int row) { return {1005.0 + 10.0 * col, 2165.0 - 10.0 * row}; }

fs::path write_dem() {
  const fs::path p = tmp_dir() / "dem.asc";
  std::ofstream f(p);
  f << "ncols " << kW << "\nnrows " << kH
    << "\nxllcorner 1000\nyllcorner 2000\ncellsize 10\nNODATA_value -9999\n";
  for (int r = 0; r < kH; ++r) {
    for (int c = 0; c < kW; ++c) f << height(c, r) << (c + 1 < kW ? " " : "\n");
  }
  return p;
}

// The triangle (2,2), (18,3), (5,14) in samples (CCW in (col,row): orient2d = 16*12 - 1*3 = 189),
// given in world coordinates, with a comment line, CRLF endings and a UTF-8 byte order mark (as
// Excel's "CSV UTF-8" writes). The bump is inside.
fs::path write_polygon(const std::string& name = "area.csv") {
  const fs::path p = tmp_dir() / name;
  std::ofstream f(p, std::ios::binary);
  f << "\xEF\xBB\xBFx,y\r\n# a triangle\r\n";
  for (auto [c, r] : {std::array<int, 2>{2, 2}, {18, 3}, {5, 14}}) {
    const auto w = world(c, r);
    f << w[0] << "," << w[1] << "\r\n";
  }
  return p;
}

std::string args(const fs::path& dem, const fs::path& poly, const fs::path& out, const std::string& more) {
  return "tin --input " + quote(dem.string()) + " --polygon " + quote(poly.string()) + " --out " +
         quote(out.string()) + " " + more;
}

TEST(CmdTin, Help) {
  const CliResult r = terralod("tin --help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("--polygon AREA.csv"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--max-points"), std::string::npos) << r.out;
  const CliResult all = terralod("--help");
  EXPECT_NE(all.out.find("  tin "), std::string::npos) << all.out;
}

// The 3 polygon vertices span the plane exactly, so the bump (error 50 m, the only sample off
// the plane) is the 4th point; it splits the triangle into 3.
TEST(CmdTin, BumpIsTheFourthPoint) {
  const fs::path dem = write_dem(), poly = write_polygon(), out = tmp_dir() / "tin.ply";
  const CliResult r =
      terralod(args(dem, poly, out, "--max-error 0 --max-points 4 --metric samples --units samples"));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("3 polygon vertices, 4 points, 3 triangles"), std::string::npos) << r.out;
  const terralod::pm::TriangleMeshData m = terralod::pm::read_ply(out.string());
  ASSERT_EQ(m.positions.size(), 4u);
  EXPECT_EQ(m.triangles.size(), 3u);
  std::map<std::array<int, 2>, double> z;
  for (const auto& p : m.positions) z[{int(p[0]), int(p[1])}] = p[2];
  for (auto [c, r2] : {std::array<int, 2>{2, 2}, {18, 3}, {5, 14}, {kBumpCol, kBumpRow}}) {
    const std::array<int, 2> key{c, r2};
    ASSERT_TRUE(z.count(key)) << c << "," << r2;
    EXPECT_EQ(z.at(key), height(c, r2));
  }
  // Plan-view area (samples units, CCW in (col,row)) = the polygon's: |(16,1) x (3,12)| / 2 = 94.5.
  double area2 = 0;
  for (const auto& t : m.triangles) {
    const auto &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    const double o = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    EXPECT_GT(o, 0);
    area2 += o;
  }
  EXPECT_EQ(area2, 189.0);
}

// World units (the default): vertices at the samples' world positions and heights. With E = 0
// and the samples metric the TIN is exact: a plane off the bump's 8 neighbours needs them all.
TEST(CmdTin, WorldUnits) {
  const fs::path dem = write_dem(), poly = write_polygon(), out = tmp_dir() / "tin_world.obj";
  const CliResult r = terralod(args(dem, poly, out, "--max-error 0 --metric samples"));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("error 0 m"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("points"), std::string::npos);
  EXPECT_NE(r.out.find("triangles"), std::string::npos);
  EXPECT_NE(r.out.find(" ms"), std::string::npos);
  std::ifstream f(out);
  std::string tag;
  double x, y, zz;
  int vertices = 0;
  for (std::string line; std::getline(f, line);) {
    std::istringstream in(line);
    if (!(in >> tag) || tag != "v") continue;
    in >> x >> y >> zz;
    const double col = (x - 1005.0) / 10.0, row = (2165.0 - y) / 10.0;
    EXPECT_EQ(col, std::round(col));
    EXPECT_EQ(row, std::round(row));
    EXPECT_EQ(zz, height(int(col), int(row)));
    ++vertices;
  }
  EXPECT_GE(vertices, 4);
}

TEST(CmdTin, MaxPointsIsRespected) {
  const fs::path dem = write_dem(), poly = write_polygon(), out = tmp_dir() / "tin3.ply";
  const CliResult r = terralod(args(dem, poly, out, "--max-error 0 --max-points 3 --metric samples"));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("3 points, 1 triangles"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--max-points 3 reached"), std::string::npos) << r.out;
  EXPECT_EQ(terralod::pm::read_ply(out.string()).positions.size(), 3u);
  const CliResult low = terralod(args(dem, poly, out, "--max-error 0 --max-points 2"));
  EXPECT_EQ(low.status, 2) << low.err;
}

TEST(CmdTin, BadInputNamesTheFile) {
  const fs::path dem = write_dem(), out = tmp_dir() / "bad.ply";
  const CliResult missing = terralod(args(dem, tmp_dir() / "nope.csv", out, "--max-error 1"));
  EXPECT_EQ(missing.status, 1);
  EXPECT_NE(missing.err.find("nope.csv"), std::string::npos) << missing.err;

  const fs::path garbage = tmp_dir() / "garbage.csv";
  std::ofstream(garbage) << "x,y\n1010,2100\n1020,abc\n1100,2050\n";
  const CliResult bad = terralod(args(dem, garbage, out, "--max-error 1"));
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find("garbage.csv: line 3"), std::string::npos) << bad.err;

  const fs::path header = tmp_dir() / "header.csv";
  std::ofstream(header) << "lon;lat\n1,2\n";
  const CliResult nohdr = terralod(args(dem, header, out, "--max-error 1"));
  EXPECT_EQ(nohdr.status, 1);
  EXPECT_NE(nohdr.err.find("header.csv: line 1"), std::string::npos) << nohdr.err;

  const fs::path outside = tmp_dir() / "outside.csv";
  std::ofstream(outside) << "x,y\n1010,2100\n5000,2100\n1100,2050\n";
  const CliResult off = terralod(args(dem, outside, out, "--max-error 1"));
  EXPECT_EQ(off.status, 1);
  EXPECT_NE(off.err.find("outside.csv"), std::string::npos) << off.err;
  EXPECT_NE(off.err.find("outside"), std::string::npos) << off.err;
  EXPECT_FALSE(fs::exists(out));

  const CliResult noext = terralod(args(dem, write_polygon(), tmp_dir() / "tin.txt", "--max-error 1"));
  EXPECT_EQ(noext.status, 2);
  const CliResult nodem = terralod(args(tmp_dir() / "nodem.asc", write_polygon(), out, "--max-error 1"));
  EXPECT_EQ(nodem.status, 1);
  EXPECT_NE(nodem.err.find("nodem.asc"), std::string::npos) << nodem.err;
}

}  // namespace
