// End-to-end test of `terralod hybrid` (which stores the hybrid approximation tree) and
// `terralod view --db`: a small Esri ASCII grid and a TIN (binary PLY, ascii PLY, OBJ) written
// here; near the TIN the finest hybrid level and the TIN are drawn, far away only grid nodes;
// the dumped mesh is consistently oriented with every directed edge used once.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include "run_command.hpp"
#include "terralod/pm/mesh_io.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;

/// A folder of this process's own, removed when the process ends (tests/support/run_command.hpp).
const fs::path& tmp_dir() { return terralod::test::process_temp_dir("cmd-hybrid-view"); }

using CliResult = terralod::test::CommandResult;

CliResult run_cli(const std::string& args) { return terralod::test::run_tool(TERRALOD_CLI, args); }

// 65 x 65 samples, cellsize 10, lower-left corner (1000, 2000): x = 1005 + 10 col,
// y = 2005 + 10 (64 - row). Grid step 4, 2 levels: 8 x 8 coarsest cells of 8 samples.
constexpr int kN = 65;
double height(double c, double r) {
  return 100.0 + c + 2.0 * r + 8.0 * std::sin(c / 3.0) * std::cos(r / 4.0);
}
std::array<double, 2> world(double c, double r) { return {1005.0 + 10.0 * c, 2005.0 + 10.0 * (kN - 1 - r)}; }

void write_inputs() {
  std::ofstream f(tmp_dir() / "dem.asc");
  f << "ncols " << kN << "\nnrows " << kN
    << "\nxllcorner 1000\nyllcorner 2000\ncellsize 10\nNODATA_value -9999\n";
  for (int r = 0; r < kN; ++r)
    for (int c = 0; c < kN; ++c) f << height(c, r) << (c + 1 < kN ? " " : "\n");
  f.close();
  // The TIN: 11 x 9 squares of 2.5 samples from (13.5, 17.25), across several coarsest cells.
  pm::TriangleMeshData tin;
  for (int j = 0; j <= 9; ++j)
    for (int i = 0; i <= 11; ++i) {
      const double c = 13.5 + 2.5 * i, r = 17.25 + 2.5 * j;
      const auto w = world(c, r);
      tin.positions.push_back({w[0], w[1], height(c, r)});
    }
  for (std::uint32_t j = 0; j < 9; ++j)
    for (std::uint32_t i = 0; i < 11; ++i) {
      const std::uint32_t a = j * 12 + i;
      tin.triangles.push_back({a, a + 1, a + 13});
      tin.triangles.push_back({a, a + 13, a + 12});
    }
  pm::write_mesh(tin, (tmp_dir() / "tin.ply").string());
  // The same TIN as other tools write it: ascii PLY (float coordinates would round, so %.17g)
  // and Wavefront OBJ with v//vn corners and each square as one quad (a fan of the same two
  // triangles: (a, a+1, a+13) and (a, a+13, a+12)).
  char buf[96];
  std::ofstream ply(tmp_dir() / "tin_ascii.ply");
  ply << "ply\nformat ascii 1.0\nelement vertex " << tin.positions.size()
      << "\nproperty double x\nproperty double y\nproperty double z\nelement face " << tin.triangles.size()
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const auto& p : tin.positions) {
    std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g\n", p[0], p[1], p[2]);
    ply << buf;
  }
  for (const auto& t : tin.triangles) ply << "3 " << t[0] << " " << t[1] << " " << t[2] << "\n";
  std::ofstream obj(tmp_dir() / "tin.obj");
  obj << "# the TIN by hand\nvn 0 0 1\n";
  for (const auto& p : tin.positions) {
    std::snprintf(buf, sizeof buf, "v %.17g %.17g %.17g\n", p[0], p[1], p[2]);
    obj << buf;
  }
  for (std::uint32_t j = 0; j < 9; ++j)
    for (std::uint32_t i = 0; i < 11; ++i) {
      const std::uint32_t a = j * 12 + i + 1;  // 1-based
      obj << "f " << a << "//1 " << a + 1 << "//1 " << a + 13 << "//1 " << a + 12 << "//1\n";
    }
}

std::size_t count_after(const std::string& text, const std::string& key) {
  const auto at = text.find(key);
  if (at == std::string::npos) {
    ADD_FAILURE() << "'" << key << "' not in the output:\n" << text;
    return 0;
  }
  return std::size_t(std::strtoull(text.c_str() + at + key.size(), nullptr, 10));
}

/// `terralod info DB` without its "file" line.
std::string info_without_file(const std::string& db) {
  const CliResult r = run_cli("info " + db);
  EXPECT_EQ(r.status, 0) << r.err;
  std::string out;
  for (const std::string& l : terralod::test::lines_of(r.out))
    if (l.find("\"file\":") == std::string::npos) out += l + "\n";
  return out;
}

}  // namespace

TEST(CmdHybridView, TinNearGridFar) {
  write_inputs();
  const std::string d = tmp_dir().string();
  const CliResult b = run_cli("hybrid --grid " + d + "/dem.asc --grid-step 4 --levels 2 --tin " + d +
                              "/tin.ply --out " + d + "/h.db");
  ASSERT_EQ(b.status, 0) << b.err << b.out;
  EXPECT_NE(b.out.find("hybrid tree: "), std::string::npos) << b.out;

  // 150 m north of the TIN's centre (col 27, row 28.5), looking south and down.
  const auto c = world(27, 28.5);
  const std::string cam = std::to_string(c[0]) + "," + std::to_string(c[1] + 150) + ",420,180,-45,60";
  const CliResult n = run_cli("view --db " + d + "/h.db --camera " + cam + " --tau 1 --size 160x120 --out " +
                              d + "/near.png --dump-mesh " + d + "/near.ply");
  ASSERT_EQ(n.status, 0) << n.err << n.out;
  EXPECT_GT(count_after(n.out, "hybrid level 0 "), 0u) << n.out;
  EXPECT_GT(count_after(n.out, "triangles ("), 0u) << n.out;  // "(N TIN, ..."
  EXPECT_GT(fs::file_size(d + "/near.png"), 100u);
  const pm::TriangleMeshData m = pm::read_ply(d + "/near.ply");
  std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
  for (const auto& t : m.triangles) {
    const auto &p = m.positions[t[0]], &q = m.positions[t[1]], &r = m.positions[t[2]];
    EXPECT_GT((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]), 0) << "not CCW seen from above";
    for (int k = 0; k < 3; ++k)
      EXPECT_TRUE(edges.insert({t[k], t[(k + 1) % 3]}).second) << "directed edge twice";
  }

  const std::string far = std::to_string(c[0]) + "," + std::to_string(c[1] + 2e5) + ",30000,180,-8,40";
  const CliResult f =
      run_cli("view --db " + d + "/h.db --camera " + far + " --tau 1 --size 160x120 --out " + d + "/far.png");
  ASSERT_EQ(f.status, 0) << f.err << f.out;
  EXPECT_NE(f.out.find("(0 hybrid,"), std::string::npos) << f.out;
  EXPECT_EQ(count_after(f.out, "triangles ("), 0u) << "no TIN triangle far away: " << f.out;

  const CliResult both = run_cli("view --db " + d + "/h.db --input " + d + "/dem.asc --camera " + cam +
                                 " --out " + d + "/x.png");
  EXPECT_NE(both.status, 0);
  EXPECT_NE(both.err.find("exactly one of '--input' and '--db'"), std::string::npos) << both.err;
}

// The TIN read from an ascii PLY and from an OBJ of quads gives the database the binary PLY
// gives (the same vertices and triangles: info's storage figures equal), and the hybrid mesh
// extracts to glTF.
TEST(CmdHybridView, TinFromAsciiPlyAndObj) {
  write_inputs();
  const std::string d = tmp_dir().string();
  std::string reference;
  for (const std::string tin : {"tin.ply", "tin_ascii.ply", "tin.obj"}) {
    SCOPED_TRACE(tin);
    const std::string db = d + "/from_" + tin + ".db";
    fs::remove(db);
    const CliResult b = run_cli("hybrid --grid " + d + "/dem.asc --grid-step 4 --levels 2 --tin " + d + "/" +
                                tin + " --out " + db);
    ASSERT_EQ(b.status, 0) << b.err << b.out;
    EXPECT_NE(b.out.find("read " + d + "/" + tin + ": 120 vertices, 198 triangles"), std::string::npos)
        << b.out;
    const std::string info = info_without_file(db);
    if (reference.empty())
      reference = info;
    else
      EXPECT_EQ(info, reference);
  }
  const CliResult e =
      run_cli("extract --db " + d + "/from_tin.obj.db --grid-level 0 --out " + d + "/hybrid.glb");
  ASSERT_EQ(e.status, 0) << e.err << e.out;
  EXPECT_EQ(terralod::test::slurp(d + "/hybrid.glb").substr(0, 4), "glTF");

  // A broken TIN names the file and the line.
  std::ofstream(d + "/broken.obj") << "v 0 0 0\nv 1 0 0\nf 1 2 3\n";
  const CliResult bad =
      run_cli("hybrid --grid " + d + "/dem.asc --tin " + d + "/broken.obj --out " + d + "/broken.db");
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find(d + "/broken.obj: line 3: face corner '3'"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(d + "/broken.db"));
}
