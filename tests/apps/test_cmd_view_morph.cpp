// End-to-end test of `terralod view --morph-to`: the static geomorph between the meshes selected
// for two cameras (pm/geomorph.hpp) drawn as --frames images. Runs the built binary on a small
// generated .pm written here, beside plain `terralod view` runs from each camera, and checks
// from the dumped meshes alone: the first and last frames are the plain views' meshes (as sets,
// heights bit-equal); every vertex of a frame between is at (1 - a) z_A + a z_B, z_A and z_B
// being the first and last frames' surfaces at its plan point (located here by brute force);
// its triangles keep their plan-view orientation and cover the domain exactly; the images exist
// and differ; the statistics (strict JSON, one array item per frame) agree; bad command lines
// write nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "run_command.hpp"
#include "terralod/pm/json.hpp"
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
using terralod::test::lines_of;
using terralod::test::quote;
using terralod::test::slurp;

const fs::path& tmp_dir() { return terralod::test::process_temp_dir("view-morph"); }

CliResult terralod(const std::string& args) {
  return terralod::test::run_tool(TERRALOD_CLI, args, {.no_display = true});
}

/// Member `key` of `v` as a number, looked up in v and its "camera" object (NaN when absent).
double number_of(const pm::JsonValue& v, const std::string& key) {
  const pm::JsonValue* m = v.find(key);
  if (!m && v.find("camera")) m = v.find("camera")->find(key);
  return m && m->kind == pm::JsonValue::Kind::Number ? m->number : std::nan("");
}

// A 65 x 65 generated terrain, 30 m spacing, north-up: x in [0, 1920], y in [0, 1920].
constexpr int kN = 65;
constexpr double kSpacing = 30.0, kExtent = (kN - 1) * kSpacing;

fs::path pm_file() {
  static const fs::path p = [] {
    pm::TerrainOptions o;
    o.width = o.height = kN;
    o.seed = 11;
    o.relief = 400.0;
    pm::Heightfield hf = pm::generate_terrain(o);
    hf.transform = pm::GridTransform::north_up(0.0, kExtent, kSpacing, kSpacing);
    const fs::path path = tmp_dir() / "terrain.pm";
    pm::write_pm(pm::ProgressiveMesh::build(hf), path.string());
    return path;
  }();
  return p;
}

// A: south-west of the square, looking north-north-east and down; B: east of it, looking
// west-north-west (yaw 300), lower and narrower. The shorter turn from 30 to 300 degrees is
// 90 degrees anticlockwise, through north: yaw 30 - 90 a.
const std::string kCamA = "-300,-300,900,30,-30,60", kCamB = "2300,1000,700,300,-20,50";
constexpr int kFrames = 5;
const std::string kCommon = " --tau 1.5 --size 160x120";

fs::path numbered(const std::string& stem, int k, const std::string& ext) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "_%05d", k);
  return tmp_dir() / (stem + buf + ext);
}

/// A triangle as its three positions, rotated to start at the smallest (winding kept).
using Tri = std::array<std::array<double, 3>, 3>;
std::multiset<Tri> triangle_set(const pm::TriangleMeshData& m) {
  std::multiset<Tri> s;
  for (const auto& t : m.triangles) {
    Tri x{m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]};
    std::rotate(x.begin(), std::min_element(x.begin(), x.end()), x.end());
    s.insert(x);
  }
  return s;
}

double cross(const std::array<double, 3>& a, const std::array<double, 3>& b, const std::array<double, 3>& c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/// Height of mesh m's surface at plan point (x, y): brute-force point location over its
/// triangles, barycentric interpolation in the first triangle containing it (NaN outside).
double surface_height(const pm::TriangleMeshData& m, double x, double y) {
  const std::array<double, 3> p{x, y, 0.0};
  for (const auto& t : m.triangles) {
    const auto &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    const double d = cross(a, b, c);
    if (d == 0.0) continue;
    const double la = cross(p, b, c) / d, lb = cross(a, p, c) / d, lc = cross(a, b, p) / d;
    constexpr double eps = -1e-9;
    if (la >= eps && lb >= eps && lc >= eps) return la * a[2] + lb * b[2] + lc * c[2];
  }
  return std::nan("");
}

class ViewMorph : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const std::string in = " --input " + quote(pm_file().string());
    morph_ = new CliResult(terralod(
        "view" + in + " --camera " + kCamA + " --morph-to " + kCamB + kCommon + " --frames " +
        std::to_string(kFrames) + " --out " + quote((tmp_dir() / "m.png").string()) + " --dump-mesh " +
        quote((tmp_dir() / "m.obj").string()) + " --stats " + quote((tmp_dir() / "m.json").string())));
    for (const auto& [cam, name] : {std::pair{kCamA, std::string("a")}, {kCamB, std::string("b")}})
      plain_.push_back(terralod("view" + in + " --camera " + cam + kCommon + " --out " +
                                quote((tmp_dir() / (name + ".png")).string()) + " --dump-mesh " +
                                quote((tmp_dir() / (name + ".obj")).string()) + " --stats " +
                                quote((tmp_dir() / (name + ".json")).string())));
  }
  static void TearDownTestSuite() {
    delete morph_;
    morph_ = nullptr;
    plain_.clear();
  }
  void SetUp() override {
    ASSERT_EQ(morph_->status, 0) << morph_->err << morph_->out;
    for (const CliResult& r : plain_) ASSERT_EQ(r.status, 0) << r.err << r.out;
  }
  static pm::TriangleMeshData frame_mesh(int k) { return pm::read_obj(numbered("m", k, ".obj").string()); }

  static CliResult* morph_;
  static std::vector<CliResult> plain_;
};
CliResult* ViewMorph::morph_ = nullptr;
std::vector<CliResult> ViewMorph::plain_;

TEST_F(ViewMorph, FirstAndLastFramesAreThePlainViews) {
  for (const auto& [k, name] : {std::pair{0, std::string("a")}, {kFrames - 1, std::string("b")}}) {
    SCOPED_TRACE("frame " + std::to_string(k) + " against the plain view " + name);
    const pm::TriangleMeshData f = frame_mesh(k), p = pm::read_obj((tmp_dir() / (name + ".obj")).string());
    ASSERT_GT(p.triangles.size(), 10u);
    const std::set<std::array<double, 3>> fv(f.positions.begin(), f.positions.end()),
        pv(p.positions.begin(), p.positions.end());
    EXPECT_EQ(fv.size(), f.positions.size());
    EXPECT_TRUE(fv == pv) << "vertices (heights compared bit for bit)";
    EXPECT_TRUE(triangle_set(f) == triangle_set(p)) << "triangles";
    // The same mesh from the same camera: the same picture.
    const render::Image fi = render::read_image(numbered("m", k, ".png").string());
    const render::Image pi = render::read_image((tmp_dir() / (name + ".png")).string());
    EXPECT_TRUE(fi == pi) << "the picture differs from the plain view's";
  }
  const pm::TriangleMeshData a = frame_mesh(0), b = frame_mesh(kFrames - 1);
  EXPECT_FALSE(triangle_set(a) == triangle_set(b)) << "the two cameras should select different meshes";
}

TEST_F(ViewMorph, FramesBetweenAreThePointwiseBlend) {
  const pm::TriangleMeshData a = frame_mesh(0), b = frame_mesh(kFrames - 1);
  for (int k = 1; k + 1 < kFrames; ++k) {
    const double alpha = double(k) / (kFrames - 1);
    SCOPED_TRACE("frame " + std::to_string(k) + ", alpha " + std::to_string(alpha));
    const pm::TriangleMeshData g = frame_mesh(k);
    // The overlay holds every vertex of both meshes, plus edge crossings.
    EXPECT_GT(g.positions.size(), std::max(a.positions.size(), b.positions.size()));
    double worst = 0.0, spread = 0.0;
    for (const auto& v : g.positions) {
      const double za = surface_height(a, v[0], v[1]), zb = surface_height(b, v[0], v[1]);
      ASSERT_FALSE(std::isnan(za) || std::isnan(zb)) << v[0] << ", " << v[1] << " outside a mesh";
      worst = std::max(worst, std::abs(v[2] - ((1.0 - alpha) * za + alpha * zb)));
      spread = std::max(spread, std::abs(zb - za));
    }
    EXPECT_LE(worst, 1e-6) << "a vertex is off the blend (1 - a) z_A + a z_B, metres";
    EXPECT_GT(spread, 1.0) << "M^A and M^B barely differ: the check above would not see a wrong alpha";
    // No triangle flips in plan view (world units of a north-up grid: CCW from above), and the
    // triangles cover the square exactly once.
    double area = 0.0;
    for (const auto& t : g.triangles) {
      const double d = cross(g.positions[t[0]], g.positions[t[1]], g.positions[t[2]]);
      EXPECT_GT(d, 0.0);
      area += 0.5 * d;
    }
    EXPECT_NEAR(area, kExtent * kExtent, 1e-6 * kExtent * kExtent);
  }
}

TEST_F(ViewMorph, WritesNDifferentImagesAndTheirStatistics) {
  std::vector<render::Image> images;
  for (int k = 0; k < kFrames; ++k) {
    ASSERT_TRUE(fs::is_regular_file(numbered("m", k, ".png"))) << k;
    images.push_back(render::read_image(numbered("m", k, ".png").string()));
    EXPECT_EQ(images.back().width, 160);
    EXPECT_EQ(images.back().height, 120);
    if (k > 0) {
      EXPECT_FALSE(images[std::size_t(k)] == images[std::size_t(k) - 1]) << k;
    }
  }
  EXPECT_FALSE(fs::exists(numbered("m", kFrames, ".png")));
  EXPECT_FALSE(fs::exists(tmp_dir() / "m.png"));

  // One progress line per frame.
  int frame_lines = 0;
  for (const std::string& l : lines_of(morph_->out)) frame_lines += l.rfind("frame ", 0) == 0;
  EXPECT_EQ(frame_lines, kFrames) << morph_->out;

  const std::string s = slurp(tmp_dir() / "m.json");
  // The statistics are strict JSON; the frames an array, item k for frame k.
  const pm::JsonValue stats = pm::parse_json(s, "m.json");
  EXPECT_NE(s.find("\"selection\": \"geomorph\""), std::string::npos) << s;
  EXPECT_EQ(number_of(stats, "frame_count"), kFrames);
  const double e_a = number_of(pm::parse_json(slurp(tmp_dir() / "a.json"), "a.json"), "error_bound");
  const double e_b = number_of(pm::parse_json(slurp(tmp_dir() / "b.json"), "b.json"), "error_bound");
  ASSERT_FALSE(std::isnan(e_a) || std::isnan(e_b));
  const pm::JsonValue* frames = stats.find("frames");
  ASSERT_NE(frames, nullptr) << s;
  ASSERT_EQ(frames->kind, pm::JsonValue::Kind::Array) << s;
  ASSERT_EQ(frames->items.size(), std::size_t(kFrames)) << s;
  for (int k = 0; k < kFrames; ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    const pm::JsonValue& f = frames->items[std::size_t(k)];
    ASSERT_EQ(f.kind, pm::JsonValue::Kind::Object) << s;
    const double alpha = double(k) / (kFrames - 1);
    EXPECT_EQ(number_of(f, "alpha"), alpha);
    EXPECT_NEAR(number_of(f, "x"), -300.0 + 2600.0 * alpha, 1e-9);
    EXPECT_NEAR(number_of(f, "y"), -300.0 + 1300.0 * alpha, 1e-9);
    EXPECT_NEAR(number_of(f, "z"), 900.0 - 200.0 * alpha, 1e-9);
    EXPECT_NEAR(number_of(f, "pitch"), -30.0 + 10.0 * alpha, 1e-9);
    EXPECT_NEAR(number_of(f, "fovy"), 60.0 - 10.0 * alpha, 1e-9);
    const double yaw = number_of(f, "yaw");  // 30 - 90 a, modulo 360
    EXPECT_NEAR(std::remainder(yaw - (30.0 - 90.0 * alpha), 360.0), 0.0, 1e-9) << yaw;
    const pm::TriangleMeshData m = frame_mesh(k);
    EXPECT_EQ(number_of(f, "triangles"), double(m.triangles.size()));
    EXPECT_EQ(number_of(f, "vertices"), double(m.positions.size()));
    EXPECT_EQ(number_of(f, "error_bound_from"), e_a);
    EXPECT_EQ(number_of(f, "error_bound_to"), e_b);
    EXPECT_NEAR(number_of(f, "error_bound"), (1.0 - alpha) * e_a + alpha * e_b, 1e-12 * (1.0 + e_a + e_b));
    const pm::JsonValue* mesh = f.find("mesh");
    ASSERT_NE(mesh, nullptr);
    EXPECT_EQ(mesh->string, k == 0 ? "from" : k == kFrames - 1 ? "to" : "geomorph");
  }
}

TEST(ViewMorphErrors, BadCommandLinesWriteNothing) {
  const terralod::test::TempDir dir("view-morph-bad");
  const std::string in = quote(pm_file().string());
  const std::string outs = " --out " + quote((dir / "x.png").string()) + " --dump-mesh " +
                           quote((dir / "x.obj").string()) + " --stats " + quote((dir / "x.json").string());
  struct Case {
    std::string args, message;
  };
  for (const Case& c : std::vector<Case>{
           {"--db " + quote((dir / "t.db").string()) + " --camera " + kCamA + " --morph-to " + kCamB,
            "--morph-to is for --input"},
           {"--input " + in + " --camera " + kCamA + " --morph-to " + kCamB + " --frames 1", "--frames"},
           {"--input " + in + " --camera " + kCamA + " --morph-to " + kCamB + " --frames 10001", "--frames"},
           {"--input " + in + " --camera " + kCamA + " --morph-to " + kCamB + " --frames two", "--frames"},
           {"--input " + in + " --camera " + kCamA + " --morph-to 1,2,3,4,5", "--morph-to"},
           {"--input " + in + " --camera " + kCamA + " --morph-to 1,2,3,4,x,60", "--morph-to"},
           {"--input " + in + " --camera " + kCamA + " --morph-to 1,2,3,4,-95,60", "--morph-to: PITCH"},
           {"--input " + in + " --camera " + kCamA + " --frames 3", "--frames needs --morph-to"},
           {"--input " + in + " --camera " + kCamA + " --morph-to " + kCamB + " --uniform", "--uniform"},
       }) {
    SCOPED_TRACE(c.args);
    const CliResult r = terralod("view " + c.args + kCommon + outs);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << r.err;
    EXPECT_EQ(lines_of(r.err).size(), 1u) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_TRUE(fs::is_empty(dir.path())) << "something was written";
  }
}

TEST(ViewMorphErrors, HelpListsTheOptions) {
  const CliResult h = terralod("view --help");
  ASSERT_EQ(h.status, 0) << h.err;
  EXPECT_NE(h.out.find("\n  --morph-to CAMERA "), std::string::npos) << h.out;
  EXPECT_NE(h.out.find("\n  --frames N "), std::string::npos) << h.out;
  EXPECT_NE(h.out.find("(1-a) e_A + a e_B <= max(e_A, e_B)"), std::string::npos) << h.out;
}

}  // namespace
