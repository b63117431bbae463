// End-to-end tests of `terralod pm --decimater`: the OpenMesh reference route writes a .pm that
// reads back, replays in CollapseDag and meets its bounds; the default is the fast builder, byte
// for byte; the build line names the decimater; bad names are usage errors; --help tells.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "mesh_checker.hpp"
#include "run_command.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace tt = terralod::test;

using CliResult = tt::CommandResult;
using tt::lines_of;
using tt::quote;

const fs::path& tmp_dir() { return tt::process_temp_dir("cmd-pm-decimater"); }

CliResult terralod(const std::string& args) { return tt::run_tool(TERRALOD_CLI, args); }

// A 29 x 23 Esri ASCII grid, cellsize 10, heights multiples of 0.25 m (written exactly);
// `void_at` >= 0 makes that sample NODATA (kept as a hole with --keep-voids).
constexpr int kW = 29, kH = 23;
double height_at(int col, int row) {
  const double z = 60.0 * std::sin(col * 0.23) * std::cos(row * 0.19) + 2.0 * col - 1.5 * row + 400.0;
  return std::round(z * 4.0) / 4.0 + 0.25 * double((col * 31 + row * 17) % 5);
}
fs::path write_asc(const std::string& name, int void_at = -1) {
  const fs::path path = tmp_dir() / name;
  std::ofstream f(path);
  f << "ncols " << kW << "\nnrows " << kH << "\nxllcorner 0\nyllcorner 0\ncellsize 10\nNODATA_value -9999\n";
  char buf[64];
  for (int r = 0; r < kH; ++r) {
    for (int c = 0; c < kW; ++c) {
      std::snprintf(buf, sizeof buf, "%s%.2f", c ? " " : "",
                    r * kW + c == void_at ? -9999.0 : height_at(c, r));
      f << buf;
    }
    f << "\n";
  }
  return path;
}

CliResult run_pm(const fs::path& dem, const fs::path& out, const std::string& extra) {
  return terralod("pm --threads 1 " + extra + " --input " + quote(dem.string()) + " --out " +
                  quote(out.string()));
}

// The written PM replays (CollapseDag throws otherwise) and extract(E) is within E everywhere.
void check_written_pm(const fs::path& file, const pm::Heightfield& hf_expected_size) {
  const pm::ProgressiveMesh p = pm::read_pm(file.string());
  EXPECT_EQ(p.heightfield().width(), hf_expected_size.width());
  EXPECT_GT(p.vsplit_count(), p.full_vertex_count() / 2);
  const pm::CollapseDag dag(p);
  EXPECT_EQ(dag.collapse_count(), p.vsplit_count());
  tt::CheckOptions opt;
  opt.excluded_faces = p.dropped_faces();
  for (double E : {0.5, 2.0, 8.0}) {
    const pm::TriangleMesh m = p.extract(E);
    const tt::MeshCheck c = tt::check_mesh(p.heightfield(), m, opt);
    EXPECT_TRUE(c.ok(E)) << "E = " << E << "\n" << c.describe();
  }
}

TEST(cmd_pm_decimater, OpenMeshWritesAPmThatReplaysAndMeetsItsBounds) {
  const fs::path dem = write_asc("grid.asc"), out = tmp_dir() / "openmesh.pm";
  const CliResult r = run_pm(dem, out, "--decimater openmesh");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> l = lines_of(r.out);
  ASSERT_EQ(l.size(), 3u) << r.out;
  EXPECT_EQ(l[1].rfind("build " + std::to_string(kW * kH) + " vertices -> ", 0), 0u) << l[1];
  EXPECT_TRUE(l[1].ends_with(", decimater openmesh")) << l[1];
  EXPECT_NE(r.err.find("build: 100%"), std::string::npos) << r.err;  // progress through the Observer
  check_written_pm(out, pm::Heightfield(kW, kH));
}

TEST(cmd_pm_decimater, OpenMeshWithAHoleKeptAsAVoid) {
  const fs::path dem = write_asc("void.asc", /*void_at=*/11 * kW + 14), out = tmp_dir() / "void.pm";
  const CliResult r = run_pm(dem, out, "--keep-voids --decimater openmesh");
  ASSERT_EQ(r.status, 0) << r.err;
  const pm::ProgressiveMesh p = pm::read_pm(out.string());
  EXPECT_TRUE(p.heightfield().has_holes());
  EXPECT_EQ(p.full_vertex_count(), std::size_t(kW * kH - 1));
  check_written_pm(out, pm::Heightfield(kW, kH));
}

TEST(cmd_pm_decimater, FastIsTheDefaultByteForByte) {
  const fs::path dem = write_asc("fast.asc"), plain = tmp_dir() / "plain.pm", fast = tmp_dir() / "fast.pm",
                 om = tmp_dir() / "om.pm";
  const CliResult a = run_pm(dem, plain, ""), b = run_pm(dem, fast, "--decimater fast"),
                  c = run_pm(dem, om, "--decimater openmesh");
  ASSERT_EQ(a.status, 0) << a.err;
  ASSERT_EQ(b.status, 0) << b.err;
  ASSERT_EQ(c.status, 0) << c.err;
  EXPECT_TRUE(lines_of(a.out).at(1).ends_with(", decimater fast")) << a.out;
  const std::string pa = tt::slurp(plain), pb = tt::slurp(fast), pc = tt::slurp(om);
  ASSERT_FALSE(pa.empty());
  EXPECT_EQ(pa, pb);
  EXPECT_NE(pa, pc) << "the openmesh route wrote the fast builder's PM: was it run at all?";
}

TEST(cmd_pm_decimater, BadNameIsAUsageErrorAndHelpTells) {
  const fs::path dem = write_asc("bad.asc");
  const CliResult r = run_pm(dem, tmp_dir() / "never.pm", "--decimater quadric");
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("--decimater"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp_dir() / "never.pm"));

  const CliResult h = terralod("pm --help");
  ASSERT_EQ(h.status, 0) << h.err;
  EXPECT_NE(h.out.find("  --decimater NAME"), std::string::npos) << h.out;
  EXPECT_NE(h.out.find("fast (the PM builder, default) or openmesh (a slow reference)"), std::string::npos)
      << h.out;
  EXPECT_NE(h.out.find("It is slow"), std::string::npos) << h.out;
}

}  // namespace
