// End-to-end tests of `terralod view`: runs the built binary on a .pm and a DEM it writes
// itself and checks the PNG (size, not blank); for the view-dependent selection (the default)
// the statistics JSON (bound_px <= tau, counts equal to the dumped mesh's) and the dumped mesh
// with the independent checkers (a valid plan-view triangulation of the domain; measured
// screen-space error <= bound_px); for --uniform the statistics against an independent
// recomputation of the conservative uniform error; and bad command lines.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>

#include "mesh_checker.hpp"
#include "run_command.hpp"
#include "screen_error_checker.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/render/image.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace render = terralod::render;

using CliResult = terralod::test::CommandResult;
using terralod::test::quote;
using terralod::test::slurp;

/// A folder of this process's own, removed when the process ends (tests/support/run_command.hpp).
const fs::path& tmp_dir() { return terralod::test::process_temp_dir("view-cli"); }

/// Runs `terralod <args>` (already quoted) with no X display, capturing both streams.
CliResult terralod(const std::string& args) {
  return terralod::test::run_tool(TERRALOD_CLI, args, {.no_display = true});
}

/// The number after "key": in a JSON text (NaN when absent).
double json_number(const std::string& json, const std::string& key) {
  const std::string tag = "\"" + key + "\": ";
  const std::size_t at = json.find(tag);
  if (at == std::string::npos) return std::nan("");
  const char* start = json.c_str() + at + tag.size();
  char* end = nullptr;
  const double v = std::strtod(start, &end);
  return end == start ? std::nan("") : v;
}

/// The dumped mesh (world units) as a mesh of samples of hf: each position rounded to its grid
/// index, which must be within 1e-6 of a sample whose height matches.
pm::TriangleMesh as_sample_mesh(const pm::TriangleMeshData& d, const pm::Heightfield& hf) {
  pm::TriangleMesh m;
  for (const auto& p : d.positions) {
    const auto [col, row] = terralod::test::world_to_index(hf, p[0], p[1]);
    const long c = std::lround(col), r = std::lround(row);
    EXPECT_NEAR(col, double(c), 1e-6);
    EXPECT_NEAR(row, double(r), 1e-6);
    if (c < 0 || r < 0 || c >= hf.width() || r >= hf.height()) {
      ADD_FAILURE() << "vertex outside the grid: " << col << ", " << row;
      continue;
    }
    const std::uint32_t s = std::uint32_t(r * hf.width() + c);
    EXPECT_NEAR(p[2], hf.samples()[s], 1e-6 * (1.0 + std::abs(p[2])));
    m.vertices.push_back(s);
  }
  m.triangles = d.triangles;
  if (hf.transform.determinant() < 0)  // World units flip the winding of north-up rasters
    for (auto& t : m.triangles) std::swap(t[1], t[2]);
  return m;
}

/// Fraction of pixels differing from the top-left one (the sky in these views).
double non_sky_fraction(const render::Image& img) {
  std::size_t n = 0;
  const std::uint8_t* sky = img.pixel(0, 0);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const std::uint8_t* p = img.pixel(x, y);
      n += p[0] != sky[0] || p[1] != sky[1] || p[2] != sky[2];
    }
  return double(n) / (double(img.width) * img.height);
}

/// A 129 x 129 generated terrain, 30 m spacing, x in [0, 3840], y in [0, 3840], as a .pm file.
struct PmFixture {
  pm::ProgressiveMesh mesh;
  fs::path path;
};

const PmFixture& pm_fixture() {
  static const PmFixture f = [] {
    pm::TerrainOptions o;
    o.width = o.height = 129;
    o.seed = 5;
    o.relief = 600.0;
    pm::Heightfield hf = pm::generate_terrain(o);
    hf.transform = pm::GridTransform::north_up(0.0, 128 * 30.0, 30.0, 30.0);
    PmFixture p{pm::ProgressiveMesh::build(hf), tmp_dir() / "terrain.pm"};
    pm::write_pm(p.mesh, p.path.string());
    return p;
  }();
  return f;
}

TEST(ViewCli, RendersAPmFileWithTheViewDependentSelection) {
  const PmFixture& f = pm_fixture();
  const pm::Heightfield& hf = f.mesh.heightfield();
  const fs::path png = tmp_dir() / "view.png", json = tmp_dir() / "view.json", ply = tmp_dir() / "view.ply";
  // South-west of the square, 1 km up, looking north-east (yaw 45) and 22 degrees down.
  const double tau = 1.5;
  const int w = 240, h = 160;
  const CliResult r =
      terralod("view --input " + quote(f.path.string()) + " --camera -300,-300,1000,45,-22,60 --tau 1.5" +
               " --size 240x160 --out " + quote(png.string()) + " --stats " + quote(json.string()) +
               " --dump-mesh " + quote(ply.string()));
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  EXPECT_NE(r.out.find("select tau=1.5 px (view-dependent)"), std::string::npos) << r.out;

  // The picture: right size, sky at the top, terrain below.
  ASSERT_TRUE(fs::exists(png));
  EXPECT_FALSE(fs::exists(png.string() + ".tmp"));
  const render::Image img = render::read_image(png.string());
  EXPECT_EQ(img.width, w);
  EXPECT_EQ(img.height, h);
  const double terrain = non_sky_fraction(img);
  EXPECT_GT(terrain, 0.3);
  EXPECT_LT(terrain, 0.95);

  // The statistics.
  const std::string s = slurp(json);
  EXPECT_NE(s.find("\"selection\": \"view-dependent\""), std::string::npos) << s;
  EXPECT_EQ(json_number(s, "tau"), tau);
  const double bound_px = json_number(s, "bound_px");
  EXPECT_GT(bound_px, 0.0);
  EXPECT_LE(bound_px, tau) << "the guarantee in pixels";
  EXPECT_GT(json_number(s, "vsplits"), 0.0) << "one update from the base mesh refines";
  EXPECT_EQ(json_number(s, "ecols"), 0.0);
  EXPECT_GE(json_number(s, "update_ms"), 0.0);
  for (const char* key : {"load", "dag", "update", "mesh", "upload", "draw", "write_png"})
    EXPECT_GE(json_number(s, key), 0.0) << key;
  const double triangles = json_number(s, "triangles");
  EXPECT_GT(triangles, 100.0);
  EXPECT_LT(triangles, 2.0 * 128 * 128) << "tau 1.5 at 0.5 km should simplify";

  // The dumped mesh is the rendered one, in world units, with the counts of the statistics.
  const pm::TriangleMeshData dumped = pm::read_ply(ply.string());
  EXPECT_EQ(double(dumped.triangles.size()), triangles);
  EXPECT_EQ(double(dumped.positions.size()), json_number(s, "active_vertices"));
  EXPECT_EQ(double(dumped.positions.size()), json_number(s, "vertices"));
  const pm::TriangleMesh sel = as_sample_mesh(dumped, hf);

  // A valid plan-view triangulation of the domain (independent checker).
  const terralod::test::MeshCheck check = terralod::test::check_mesh(hf, sel, {f.mesh.dropped_faces()});
  EXPECT_TRUE(check.topology_ok()) << check.describe();
  EXPECT_LE(check.max_continuous_error(), json_number(s, "error_bound") + check.tolerance)
      << check.describe();

  // Measured screen-space error of every in-frustum error segment <= bound_px (independent
  // projection, with the clip planes the command used).
  pm::Camera cam;
  cam.x = -300.0, cam.y = -300.0, cam.z = 1000.0;
  cam.yaw_deg = 45.0, cam.pitch_deg = -22.0, cam.fovy_deg = 60.0;
  cam.width_px = w, cam.height_px = h;
  cam.near_m = json_number(s, "near");
  cam.far_m = json_number(s, "far");
  const terralod::test::ScreenCheck screen =
      terralod::test::check_screen_error(hf, sel, terralod::test::ScreenProjector(cam));
  EXPECT_GT(screen.triangles_visible, 0u);
  EXPECT_LE(screen.max_error_px, bound_px + 1e-9) << screen.describe();

  // Coarser than the conservative uniform mesh for the same tau, which is still available.
  const fs::path ujson = tmp_dir() / "uniform.json";
  const CliResult ru =
      terralod("view --input " + quote(f.path.string()) + " --camera -300,-300,1000,45,-22,60 --tau 1.5" +
               " --size 240x160 --uniform --out " + quote((tmp_dir() / "uniform.png").string()) +
               " --stats " + quote(ujson.string()));
  ASSERT_EQ(ru.status, 0) << ru.err << ru.out;
  EXPECT_LT(triangles, json_number(slurp(ujson), "triangles"));

  // Wireframe draws something else on the same terrain.
  const fs::path wire = tmp_dir() / "wire.png";
  const CliResult rw =
      terralod("view --input " + quote(f.path.string()) +
               " --camera=-300,-300,1000,45,-22,60 --tau 1.5 --size 240x160 --wireframe --out " +
               quote(wire.string()));
  ASSERT_EQ(rw.status, 0) << rw.err;
  const render::Image wimg = render::read_image(wire.string());
  EXPECT_EQ(wimg.width, w);
  EXPECT_FALSE(wimg == img);
}

TEST(ViewCli, UniformRendersTheConservativeUniformExtraction) {
  const PmFixture& f = pm_fixture();
  const fs::path png = tmp_dir() / "uview.png", json = tmp_dir() / "uview.json",
                 ply = tmp_dir() / "uview.ply";
  // South-west of the square, 1 km up, looking north-east (yaw 45) and 22 degrees down.
  const double cx = -300.0, cy = -300.0, cz = 1000.0, fovy = 60.0, tau = 1.5;
  const int w = 240, h = 160;
  const CliResult r =
      terralod("view --input " + quote(f.path.string()) + " --camera -300,-300,1000,45,-22,60 --tau 1.5" +
               " --size 240x160 --uniform --out " + quote(png.string()) + " --stats " + quote(json.string()) +
               " --dump-mesh " + quote(ply.string()));
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  EXPECT_NE(r.out.find("select tau=1.5 px"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("uniform extraction, --uniform"), std::string::npos) << r.out;
  const render::Image img = render::read_image(png.string());
  EXPECT_EQ(img.width, w);
  EXPECT_EQ(img.height, h);
  EXPECT_GT(non_sky_fraction(img), 0.3);

  // The statistics, against an independent recomputation of the conservative uniform error.
  const std::string s = slurp(json);
  EXPECT_NE(s.find("\"selection\": \"uniform\""), std::string::npos) << s;
  const double kDeg = std::numbers::pi / 180.0;
  const double k = 0.5 * h / std::tan(0.5 * fovy * kDeg);
  const double r2 = 0.25 * (w * w + h * h);
  const double k_max = k * (1.0 + r2 / (k * k));
  double hmin = 1e300, hmax = -1e300;
  for (const double z : f.mesh.heightfield().samples()) hmin = std::min(hmin, z), hmax = std::max(hmax, z);
  const double dx = 0.0 - cx, dy = 0.0 - cy,
               dz = cz > hmax ? cz - hmax : 0.0;  // nearest box point: corner (0,0,hmax)
  const double d_min = std::sqrt(dx * dx + dy * dy + dz * dz);
  const double max_error = tau * d_min / k_max;
  EXPECT_NEAR(json_number(s, "k"), k, 1e-9 * k);
  EXPECT_NEAR(json_number(s, "k_max"), k_max, 1e-9 * k_max);
  EXPECT_NEAR(json_number(s, "nearest_distance"), d_min, 1e-9 * d_min);
  EXPECT_NEAR(json_number(s, "max_error"), max_error, 1e-9 * max_error);
  const pm::TriangleMesh expected = f.mesh.extract(max_error);
  EXPECT_EQ(json_number(s, "triangles"), double(expected.triangles.size()));
  EXPECT_EQ(json_number(s, "error_bound"), expected.error_bound);
  EXPECT_LE(json_number(s, "error_bound"), max_error);
  EXPECT_LE(json_number(s, "screen_error_bound"), tau) << "the guarantee in pixels";
  EXPECT_LE(json_number(s, "bound_px"), tau);
  EXPECT_GT(expected.triangles.size(), 100u);
  EXPECT_LT(expected.triangles.size(), 2u * 128u * 128u) << "tau 1.5 at 0.5 km should simplify";
  for (const char* key : {"load", "extract", "upload", "draw", "write_png"})
    EXPECT_GE(json_number(s, key), 0.0) << key;

  // The dumped mesh is the rendered one, in world units.
  const pm::TriangleMeshData dumped = pm::read_ply(ply.string());
  EXPECT_EQ(dumped.triangles.size(), expected.triangles.size());
  EXPECT_EQ(dumped.positions.size(), expected.vertices.size());
}

TEST(ViewCli, RendersADemFile) {
  // A 33 x 33 Esri ASCII grid of a tilted ridge, 10 m cells, lower-left corner at (1000, 2000).
  const fs::path asc = tmp_dir() / "ridge.asc", png = tmp_dir() / "ridge.png";
  {
    std::ofstream f(asc);
    f << "ncols 33\nnrows 33\nxllcorner 1000\nyllcorner 2000\ncellsize 10\nNODATA_value -9999\n";
    for (int r = 0; r < 33; ++r) {
      for (int c = 0; c < 33; ++c) f << (c ? " " : "") << 100.0 + 40.0 * std::sin(0.2 * c) + 2.0 * r;
      f << "\n";
    }
  }
  const CliResult r = terralod("view --input " + quote(asc.string()) +
                               " --camera 1165,1960,320,0,-40,60 --size 128x96 --out " + quote(png.string()));
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  const render::Image img = render::read_image(png.string());
  EXPECT_EQ(img.width, 128);
  EXPECT_EQ(img.height, 96);
  EXPECT_GT(non_sky_fraction(img), 0.2);
}

// A DEM with a CRS is seen through the frame's ground scale at the eye (pm/view.hpp), as a
// flight sees it; --stats gives it. A 33 x 33 geographic grid of 30 x 30 degrees (an Esri ASCII
// grid with a WGS 84 .prj) reads under --crs auto into an azimuthal frame about 1 % off at its
// edges; the ridge above, without a CRS, is seen as it is.
TEST(ViewCli, ADemWithACrsIsSeenThroughItsGroundScale) {
  const fs::path asc = tmp_dir() / "continent.asc", png = tmp_dir() / "continent.png",
                 json = tmp_dir() / "continent.json";
  {
    std::ofstream f(asc);
    f << "ncols 33\nnrows 33\nxllcorner 0\nyllcorner 30\ncellsize 0.9375\nNODATA_value -9999\n";
    for (int r = 0; r < 33; ++r) {
      for (int c = 0; c < 33; ++c)
        f << (c ? " " : "") << 500.0 + 300.0 * std::sin(0.3 * c) * std::cos(0.2 * r);
      f << "\n";
    }
    std::ofstream prj(tmp_dir() / "continent.prj");
    prj << "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],"
           "PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]]";
  }
  // 1200 km south of the frame's centre, 50 km up, looking north and down.
  const CliResult r = terralod("view --input " + quote(asc.string()) +
                               " --camera 0,-1200000,50000,0,-20,60 --size 128x96 --out " +
                               quote(png.string()) + " --stats " + quote(json.string()));
  ASSERT_EQ(r.status, 0) << r.err << r.out;
  const std::string stats = slurp(json);
  const double xx = json_number(stats, "ground_xx"), xy = json_number(stats, "ground_xy"),
               yy = json_number(stats, "ground_yy");
  std::printf("ground scale at the eye: %.6f %.6f %.6f\n", xx, xy, yy);
  EXPECT_GT(std::abs(xx - 1.0) + std::abs(yy - 1.0), 1e-3) << stats;
  EXPECT_LT(std::abs(xx - 1.0) + std::abs(xy) + std::abs(yy - 1.0), 0.05) << stats;
  EXPECT_LE(json_number(stats, "screen_error_bound"), 1.0) << stats;
  EXPECT_GT(non_sky_fraction(render::read_image(png.string())), 0.2);

  const fs::path ridge = tmp_dir() / "ridge_plain.asc", rjson = tmp_dir() / "ridge_plain.json";
  {
    std::ofstream f(ridge);
    f << "ncols 9\nnrows 9\nxllcorner 1000\nyllcorner 2000\ncellsize 10\nNODATA_value -9999\n";
    for (int k = 0; k < 81; ++k) f << 100.0 + 3.0 * (k % 9) << (k % 9 == 8 ? "\n" : " ");
  }
  const CliResult p = terralod(
      "view --input " + quote(ridge.string()) + " --camera 1040,1900,200,0,-30,60 --size 64x48 --out " +
      quote((tmp_dir() / "ridge_plain.png").string()) + " --stats " + quote(rjson.string()));
  ASSERT_EQ(p.status, 0) << p.err << p.out;
  const std::string plain = slurp(rjson);
  EXPECT_EQ(json_number(plain, "ground_xx"), 1.0) << plain;
  EXPECT_EQ(json_number(plain, "ground_xy"), 0.0) << plain;
  EXPECT_EQ(json_number(plain, "ground_yy"), 1.0) << plain;
}

TEST(ViewCli, BadCommandLinesAreRefusedWithExitCode2) {
  const std::string in = quote(pm_fixture().path.string()), out = quote((tmp_dir() / "bad.png").string());
  struct Case {
    std::string args, message;
  };
  for (const Case& c : std::vector<Case>{
           {"--camera 1,2,3,4,5 --out " + out, "--camera"},
           {"--camera 1,2,3,4,x,6 --out " + out, "--camera"},
           {"--camera 1,2,3,0,-95,60 --out " + out, "PITCH"},
           {"--camera 1,2,3,0,-10,180 --out " + out, "FOVY"},
           {"--camera 1,2,3,0,-10,60 --tau 0 --out " + out, "--tau"},
           {"--camera 1,2,3,0,-10,60 --size 0x10 --out " + out, "--size"},
           {"--camera 1,2,3,0,-10,60 --size 10x10x --out " + out, "--size"},
           {"--camera 1,2,3,0,-10,60 --out " + quote((tmp_dir() / "bad.jpg").string()), ".png"},
           {"--camera 1,2,3,0,-10,60 --out " + out + " --dump-mesh x.stl", "--dump-mesh"},
       }) {
    const CliResult r = terralod("view --input " + in + " " + c.args);
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << "\n" << r.err;
  }
  EXPECT_FALSE(fs::exists(tmp_dir() / "bad.png"));
  // A missing input is bad data: exit 1, the file named.
  const std::string missing = (tmp_dir() / "missing.pm").string();
  const CliResult r = terralod("view --input " + quote(missing) + " --camera 1,2,3,0,-10,60 --out " + out);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(missing), std::string::npos) << r.err;
  // --help documents both selections.
  const CliResult h = terralod("view --help");
  EXPECT_EQ(h.status, 0);
  EXPECT_NE(h.out.find("VIEW-DEPENDENT selection"), std::string::npos);
  EXPECT_NE(h.out.find("--uniform"), std::string::npos);
  EXPECT_NE(h.out.find("UNIFORM extraction"), std::string::npos);
  EXPECT_NE(h.out.find("YAW degrees clockwise from north"), std::string::npos);
}

}  // namespace
