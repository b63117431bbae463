// Tests of terralod::render: camera conventions, DrawMesh construction, and headless OSMesa
// frames checked against analytic terrains (depth), themselves (determinism), and each other
// (GPU vs CPU geomorphs); a GLFW window under a private Xvfb; GPU vs CPU geomorph timing.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

// AddressSanitizer builds: GCC defines __SANITIZE_ADDRESS__, clang has the feature test, and a
// TERRALOD_SANITIZE build, which compiles the tests themselves plain, defines TERRALOD_TEST_ASAN.
#if defined(TERRALOD_TEST_ASAN)
#elif defined(__SANITIZE_ADDRESS__)
#define TERRALOD_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define TERRALOD_TEST_ASAN 1
#endif
#endif
#ifdef TERRALOD_TEST_ASAN
#include <dlfcn.h>
#include <link.h>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

#include "full_mesh.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/render/camera.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/terrain_renderer.hpp"
#include "xvfb.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace render = terralod::render;
using render::Camera;
using render::DrawMesh;
using render::Image;

constexpr double kDeg = std::numbers::pi / 180.0;

// ---------------------------------------------------------------------------------------------
// Fixtures

/// UTM-sized world origin: float coordinates this large would be off by up to 0.5 m.
constexpr double kX0 = 500000.0, kY0 = 5000000.0;

/// North-up heightfield of n x n samples, `spacing` metres apart, first sample at
/// (kX0, kY0 + (n-1) spacing) so that it covers [kX0, kX0 + L] x [kY0, kY0 + L], heights f(x, y).
pm::Heightfield analytic_heightfield(int n, double spacing, const std::function<double(double, double)>& f) {
  pm::Heightfield hf(n, n);
  hf.transform = pm::GridTransform::north_up(kX0, kY0 + (n - 1) * spacing, spacing, spacing);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const auto [x, y] = hf.transform.to_world(c, r);
      hf.at(c, r) = f(x, y);
    }
  return hf;
}

using terralod::test::full_mesh;

/// A plane z = 300 + 0.08 (x - kX0) - 0.05 (y - kY0), 129 x 129 samples 4 m apart (512 m square).
struct Plane {
  double a = 0.08, b = -0.05, c = 300.0;
  double operator()(double x, double y) const { return c + a * (x - kX0) + b * (y - kY0); }
};

/// A camera south of the 512 m square, looking north and down at it; the top of the image is sky.
Camera plane_camera() {
  return Camera{.x = kX0 + 256.0,
                .y = kY0 - 150.0,
                .z = 420.0,
                .yaw_deg = 10.0,
                .pitch_deg = -18.0,
                .fovy_deg = 50.0,
                .width_px = 320,
                .height_px = 240,
                .near_m = 1.0,
                .far_m = 5000.0,
                .ground = {}};
}

/// A rough generated terrain (relief 300 m, 30 m spacing) at a UTM-sized origin.
pm::Heightfield rough_terrain(int n, std::uint64_t seed = 7) {
  pm::TerrainOptions o;
  o.width = o.height = n;
  o.seed = seed;
  o.relief = 300.0;
  pm::Heightfield hf = pm::generate_terrain(o);
  hf.transform = pm::GridTransform::north_up(kX0, kY0 + (n - 1) * 30.0, 30.0, 30.0);
  return hf;
}

/// A camera above the south-west corner of an n x n, 30 m terrain, looking north-east and down.
Camera terrain_camera(int n, int width = 320, int height = 240) {
  const double L = (n - 1) * 30.0;
  return Camera{.x = kX0 - 0.15 * L,
                .y = kY0 - 0.15 * L,
                .z = 0.45 * L + 400.0,
                .yaw_deg = 45.0,
                .pitch_deg = -28.0,
                .fovy_deg = 55.0,
                .width_px = width,
                .height_px = height,
                .near_m = 5.0,
                .far_m = 4.0 * L + 2000.0,
                .ground = {}};
}

/// Fraction of pixels that are not the sky colour.
double terrain_fraction(const Image& img, const render::RendererOptions& o = {}) {
  const std::uint8_t sky[3] = {std::uint8_t(std::lround(o.sky_color.r * 255.0f)),
                               std::uint8_t(std::lround(o.sky_color.g * 255.0f)),
                               std::uint8_t(std::lround(o.sky_color.b * 255.0f))};
  std::size_t n = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const std::uint8_t* p = img.pixel(x, y);
      if (std::abs(p[0] - sky[0]) > 1 || std::abs(p[1] - sky[1]) > 1 || std::abs(p[2] - sky[2]) > 1) ++n;
    }
  return double(n) / double(img.width * img.height);
}

struct ImageDiff {
  int max_channel = 0;     // largest |a - b| over all channels
  std::size_t pixels = 0;  // pixels that differ at all
};

ImageDiff diff(const Image& a, const Image& b) {
  ImageDiff d;
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  if (a.rgb.size() != b.rgb.size()) return {255, a.rgb.size() / 3};
  for (std::size_t p = 0; p < a.rgb.size() / 3; ++p) {
    int m = 0;
    for (int c = 0; c < 3; ++c) m = std::max(m, std::abs(int(a.rgb[3 * p + c]) - int(b.rgb[3 * p + c])));
    d.max_channel = std::max(d.max_channel, m);
    d.pixels += m > 0;
  }
  return d;
}

fs::path tmp_dir() {
  static const fs::path d = fs::path(TERRALOD_TEST_TMP) / ("render-" + std::to_string(getpid()));
  fs::create_directories(d);
  return d;
}

class RemoveTmpDir : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(tmp_dir(), ec);
  }
};
[[maybe_unused]] ::testing::Environment* const kRemoveTmpDir =
    ::testing::AddGlobalTestEnvironment(new RemoveTmpDir);

// ---------------------------------------------------------------------------------------------
// Camera conventions (no GL)

void expect_near(const glm::dvec3& a, const glm::dvec3& b, double tol, const char* what) {
  EXPECT_NEAR(a.x, b.x, tol) << what;
  EXPECT_NEAR(a.y, b.y, tol) << what;
  EXPECT_NEAR(a.z, b.z, tol) << what;
}

TEST(Camera, YawIsClockwiseFromNorthPitchIsAboveTheHorizon) {
  Camera c;
  expect_near(render::camera_forward(c), {0, 1, 0}, 1e-15, "yaw 0 looks north (+y)");
  c.yaw_deg = 90.0;
  expect_near(render::camera_forward(c), {1, 0, 0}, 1e-15, "yaw 90 looks east (+x)");
  expect_near(render::camera_right(c), {0, -1, 0}, 1e-15, "looking east, right is south");
  c.yaw_deg = -90.0;
  expect_near(render::camera_forward(c), {-1, 0, 0}, 1e-15, "yaw -90 looks west");
  c.yaw_deg = 0.0;
  c.pitch_deg = -90.0;
  expect_near(render::camera_forward(c), {0, 0, -1}, 1e-15, "pitch -90 looks straight down");
  expect_near(render::camera_up(c), {0, 1, 0}, 1e-15, "looking down with yaw 0, image up is north");
  c.pitch_deg = 30.0;
  expect_near(render::camera_forward(c), {0, std::cos(30 * kDeg), 0.5}, 1e-15, "pitch 30 looks up");
  expect_near(render::camera_up(c), {0, -0.5, std::cos(30 * kDeg)}, 1e-15, "image up tilts back");
}

TEST(Camera, ViewMatrixPutsTheCameraAtTheOriginLookingDownMinusZ) {
  Camera c;
  c.x = kX0 + 12.5, c.y = kY0 - 7.0, c.z = 830.0;
  c.yaw_deg = 37.0;
  c.pitch_deg = -21.0;
  const glm::dmat4 v = render::view_matrix(c);
  expect_near(glm::dvec3(v * glm::dvec4(terralod::render::camera_position(c), 1.0)), {0, 0, 0}, 1e-9,
              "camera position -> eye origin");
  expect_near(
      glm::dvec3(v *
                 glm::dvec4(terralod::render::camera_position(c) + 10.0 * render::camera_forward(c), 1.0)),
      {0, 0, -10}, 1e-9, "10 m ahead -> z_eye = -10");
  expect_near(glm::dvec3(v * glm::dvec4(terralod::render::camera_position(c) + render::camera_right(c), 1.0)),
              {1, 0, 0}, 1e-9, "right -> +x_eye");
  expect_near(glm::dvec3(v * glm::dvec4(terralod::render::camera_position(c) + render::camera_up(c), 1.0)),
              {0, 1, 0}, 1e-9, "up -> +y_eye");
}

/// An oblique 640 x 360 camera over the test grid's corner, looking south-west and down.
Camera oblique_camera(const pm::GroundScale& ground = {}) {
  return Camera{.x = kX0,
                .y = kY0,
                .z = 500.0,
                .yaw_deg = 200.0,
                .pitch_deg = -40.0,
                .fovy_deg = 45.0,
                .width_px = 640,
                .height_px = 360,
                .near_m = 2.0,
                .far_m = 3000.0,
                .ground = ground};
}

TEST(Camera, ProjectionAndPixelRaysAgree) {
  const Camera c = oblique_camera();
  const glm::dmat4 pv = render::projection_matrix(c) * render::view_matrix(c);
  const glm::dmat4 rpv = render::reverse_z_projection_matrix(c) * render::view_matrix(c);
  // The centre ray is the view direction.
  expect_near(render::pixel_ray(c, 320.0, 180.0), render::camera_forward(c), 1e-12, "centre ray");
  // A point along the ray through image point (px, py) projects back to it, top-left origin.
  for (const auto& [px, py] :
       std::vector<std::pair<double, double>>{{0, 0}, {639.5, 0.5}, {100.25, 300.75}}) {
    const glm::dvec3 p = terralod::render::camera_position(c) + 123.0 * render::pixel_ray(c, px, py);
    glm::dvec4 clip = pv * glm::dvec4(p, 1.0);
    const glm::dvec3 ndc = glm::dvec3(clip) / clip.w;
    EXPECT_NEAR((ndc.x + 1.0) * 0.5 * c.width_px, px, 1e-6);
    EXPECT_NEAR((1.0 - ndc.y) * 0.5 * c.height_px, py, 1e-6);
    const glm::dvec4 rclip = rpv * glm::dvec4(p, 1.0);
    EXPECT_NEAR(rclip.x / rclip.w, ndc.x, 1e-12);
  }
  // Depth ranges: standard near -> -1, far -> +1; reverse-Z near -> 1, far -> 0.
  for (const auto& [d, ndc_std, ndc_rev] :
       std::vector<std::tuple<double, double, double>>{{2.0, -1.0, 1.0}, {3000.0, 1.0, 0.0}}) {
    const glm::dvec4 p(terralod::render::camera_position(c) + d * render::camera_forward(c), 1.0);
    const glm::dvec4 a = pv * p, b = rpv * p;
    EXPECT_NEAR(a.z / a.w, ndc_std, 1e-9);
    EXPECT_NEAR(b.z / b.w, ndc_rev, 1e-9);
  }
  // K: a 1 m segment across the axis at 100 m covers K/100 pixels.
  const double k = render::focal_length_pixels(c);
  EXPECT_NEAR(k, 180.0 / std::tan(22.5 * kDeg), 1e-9);
  EXPECT_GE(render::max_pixels_per_radian(c), k);
}

// With a ground scale the GPU's matrices are pm::View's (the selection's), and a pixel's ray
// projects back onto the pixel.
TEST(Camera, GroundScaleMatricesAndRaysAreTheSelections) {
  const Camera c = oblique_camera({1.02, -0.015, 0.985});
  const pm::View v(c);
  const glm::dmat4 vm = render::view_matrix(c);
  const std::array<double, 16> pv = v.view_matrix();
  for (int col = 0; col < 4; ++col)
    for (int row = 0; row < 4; ++row) EXPECT_NEAR(vm[col][row], pv[std::size_t(col * 4 + row)], 1e-9);
  const glm::dmat4 m = render::projection_matrix(c) * vm;
  for (const auto& [px, py] :
       std::vector<std::pair<double, double>>{{0, 0}, {639.5, 0.5}, {100.25, 300.75}}) {
    const glm::dvec3 r = render::pixel_ray(c, px, py);
    const pm::Vec3 d = v.pixel_direction(px, py);
    expect_near(r, glm::dvec3(d.x, d.y, d.z), 1e-12, "ray");
    const glm::dvec4 clip = m * glm::dvec4(render::camera_position(c) + 123.0 * r, 1.0);
    EXPECT_NEAR((clip.x / clip.w + 1.0) * 0.5 * c.width_px, px, 1e-6);
    EXPECT_NEAR((1.0 - clip.y / clip.w) * 0.5 * c.height_px, py, 1e-6);
  }
}

TEST(Camera, MaxPixelsPerRadianBoundsTheProjectionEverywhere) {
  Camera c;
  c.yaw_deg = 30.0;
  c.pitch_deg = -10.0;
  c.fovy_deg = 70.0;
  c.width_px = 800;
  c.height_px = 400;
  const double bound = render::max_pixels_per_radian(c);
  // Pixels per radian between two nearby image points: the distance in pixels over the angle
  // between their rays. Never above the bound; at a corner, moving radially, nearly equal.
  auto ratio = [&](double px, double py, double dx, double dy) {
    const double angle = std::acos(
        std::min(1.0, glm::dot(render::pixel_ray(c, px, py), render::pixel_ray(c, px + dx, py + dy))));
    return std::hypot(dx, dy) / angle;
  };
  double worst = 0.0;
  for (double px : {0.0, 200.0, 400.0, 800.0})
    for (double py : {0.0, 100.0, 200.0, 400.0})
      for (const auto& [dx, dy] :
           std::vector<std::pair<double, double>>{{0.05, 0}, {0, 0.05}, {0.04, -0.03}}) {
        const double r = ratio(px, py, dx, dy);
        worst = std::max(worst, r);
        EXPECT_LE(r, bound * (1.0 + 1e-3)) << "at pixel " << px << "," << py;
      }
  EXPECT_LE(render::focal_length_pixels(c), ratio(400.0, 200.0, 0.05, 0.0) * (1.0 + 1e-3))
      << "K at the centre";
  const double corner = ratio(0.0, 0.0, 0.04, 0.02);  // (-400, -200) points radially along (2, 1)
  EXPECT_GT(corner, 0.99 * bound) << "the bound is reached at the corners";
  EXPECT_LE(corner, bound * (1.0 + 1e-3));
  EXPECT_GT(worst, render::focal_length_pixels(c));
}

// ---------------------------------------------------------------------------------------------
// DrawMesh (no GL)

TEST(DrawMesh, RelativeToTheGridCentreWithSampleNormalsAndUpwardWinding) {
  const Plane plane;
  const pm::Heightfield hf = analytic_heightfield(33, 4.0, plane);
  const DrawMesh d = render::make_draw_mesh(full_mesh(hf), hf);
  EXPECT_NO_THROW(render::validate(d));
  // Origin: grid centre (x0 + 64, y0 + 64) at the middle of the heights.
  EXPECT_DOUBLE_EQ(d.origin.x, kX0 + 64.0);
  EXPECT_DOUBLE_EQ(d.origin.y, kY0 + 64.0);
  EXPECT_DOUBLE_EQ(d.origin.z, plane(kX0 + 64.0, kY0 + 64.0));  // a plane's mid height is its centre's
  ASSERT_EQ(d.vertex_count(), 33u * 33u);
  ASSERT_EQ(d.triangle_count(), 2u * 32u * 32u);
  const glm::dvec3 n_exact = glm::normalize(glm::dvec3(-plane.a, -plane.b, 1.0));
  for (std::size_t v = 0; v < d.vertex_count(); ++v) {
    const int col = int(v % 33), row = int(v / 33);
    const auto [x, y] = hf.transform.to_world(col, row);
    EXPECT_NEAR(d.origin.x + d.xyz[3 * v], x, 1e-5);
    EXPECT_NEAR(d.origin.y + d.xyz[3 * v + 1], y, 1e-5);
    EXPECT_NEAR(d.origin.z + d.xyz[3 * v + 2], plane(x, y), 1e-5);
    const glm::dvec3 n(d.normals[3 * v], d.normals[3 * v + 1], d.normals[3 * v + 2]);
    expect_near(n, n_exact, 1e-6, "a plane's sample normals are its normal, border samples too");
  }
  // North-up rasters mirror (col,row) -> (x,y); the helper flips triangles to stay CCW from above.
  for (std::size_t t = 0; t < d.triangle_count(); ++t) {
    glm::dvec3 p[3];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t i = d.indices[3 * t + k];
      p[k] = {d.xyz[3 * i], d.xyz[3 * i + 1], d.xyz[3 * i + 2]};
    }
    ASSERT_GT(glm::cross(p[1] - p[0], p[2] - p[0]).z, 0.0) << "triangle " << t;
  }
}

TEST(DrawMesh, NormalsFollowARotatedTransform) {
  // Grid axes rotated by 30 degrees: col -> (cos, sin) * 2 m, row -> (-sin, cos) * 3 m.
  pm::Heightfield hf(9, 9);
  const double c30 = std::cos(30 * kDeg), s30 = std::sin(30 * kDeg);
  hf.transform = pm::GridTransform{100.0, 2.0 * c30, -3.0 * s30, 200.0, 2.0 * s30, 3.0 * c30};
  const double a = 0.3, b = -0.7;  // z = a x + b y
  for (int r = 0; r < 9; ++r)
    for (int c = 0; c < 9; ++c) {
      const auto [x, y] = hf.transform.to_world(c, r);
      hf.at(c, r) = a * x + b * y;
    }
  const glm::dvec3 n_exact = glm::normalize(glm::dvec3(-a, -b, 1.0));
  for (int r = 0; r < 9; ++r)
    for (int c = 0; c < 9; ++c)
      expect_near(render::heightfield_normal(hf, c, r), n_exact, 1e-12, "rotated plane");
}

TEST(DrawMesh, ValidateNamesTheProblem) {
  DrawMesh d;
  d.xyz = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  d.indices = {0, 1, 3};
  try {
    render::validate(d);
    FAIL() << "an index beyond the vertices must be refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("index 2 is 3"), std::string::npos) << e.what();
  }
  d.indices = {0, 1, 2};
  d.z_target = {1.0f};
  EXPECT_THROW(render::validate(d), std::invalid_argument);
  d.z_target.clear();
  d.xyz[4] = std::nanf("");
  EXPECT_THROW(render::validate(d), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Images (no GL)

TEST(Image, PngRoundTripAndErrorsNameTheFile) {
  Image img;
  img.width = 5;
  img.height = 3;
  for (int i = 0; i < 5 * 3 * 3; ++i) img.rgb.push_back(std::uint8_t(i * 17));
  const std::string path = (tmp_dir() / "tiny.png").string();
  render::write_png(img, path);
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  EXPECT_EQ(render::read_image(path), img);
  const std::string bad = (tmp_dir() / "no-such-folder" / "x.png").string();
  try {
    render::write_png(img, bad);
    FAIL() << "writing into a missing folder must fail";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(bad));
  EXPECT_THROW(render::read_image((tmp_dir() / "missing.png").string()), std::runtime_error);
}

// ---------------------------------------------------------------------------------------------
// Offscreen frames (OSMesa)

TEST(Offscreen, ContextIsCore33OrNewerAndNeedsNoDisplay) {
  // No X display may be used: hide any the environment has.
  const char* display = std::getenv("DISPLAY");
  const std::string saved = display ? display : "";
  unsetenv("DISPLAY");
  auto ctx = render::create_offscreen_context({/*width=*/64, /*height=*/32});
  if (!saved.empty()) setenv("DISPLAY", saved.c_str(), 1);
  const render::GlInfo& info = ctx->info();
  std::printf("offscreen context: %s | %s | GLSL %s | core %d | clip control %d\n", info.renderer.c_str(),
              info.version.c_str(), info.glsl_version.c_str(), int(info.core_profile),
              int(info.clip_control));
  EXPECT_EQ(info.backend, "osmesa");
  EXPECT_GE(info.major * 10 + info.minor, 33);
  EXPECT_EQ(ctx->framebuffer_width(), 64);
  EXPECT_EQ(ctx->framebuffer_height(), 32);
}

TEST(Offscreen, FrameOfATerrainIsNotBlank) {
  const pm::Heightfield hf = rough_terrain(65);
  auto ctx = render::create_offscreen_context();
  render::TerrainRenderer r(*ctx);
  const render::MeshId id = r.upload(render::make_draw_mesh(full_mesh(hf), hf));
  const render::FrameStats s = r.draw(terrain_camera(65), {{id, 0.0f}});
  EXPECT_EQ(s.triangles, 2u * 64u * 64u);
  EXPECT_EQ(s.meshes, 1u);
  const Image img = r.read_color();
  ASSERT_EQ(img.width, 320);
  ASSERT_EQ(img.height, 240);
  const double f = terrain_fraction(img);
  EXPECT_GT(f, 0.3) << "the terrain should fill a good part of the view";
  EXPECT_LT(f, 0.99) << "the sky should show at the top";
  // Top row is sky (the camera looks down at a terrain below the horizon line).
  const std::uint8_t* top = img.pixel(160, 0);
  EXPECT_EQ(top[2], std::uint8_t(std::lround(r.options().sky_color.b * 255.0f)));
  // Lighting varies: a lit terrain is not one flat colour.
  int lo = 255, hi = 0;
  for (int x = 0; x < img.width; ++x)
    lo = std::min<int>(lo, img.pixel(x, 200)[1]), hi = std::max<int>(hi, img.pixel(x, 200)[1]);
  EXPECT_GT(hi - lo, 20) << "shading should vary along a row of terrain";
}

/// Ray-casts the analytic plane through pixel centres and compares the renderer's depth.
void check_plane_depth(bool reverse_z, double rel_tol) {
  const Plane plane;
  const int n = 129;
  const double spacing = 4.0, L = (n - 1) * spacing;
  const pm::Heightfield hf = analytic_heightfield(n, spacing, plane);
  auto ctx = render::create_offscreen_context();
  render::RendererOptions opt;
  opt.reverse_z = reverse_z;
  render::TerrainRenderer r(*ctx, opt);
  const render::MeshId id = r.upload(render::make_draw_mesh(full_mesh(hf), hf));
  const Camera cam = plane_camera();
  r.draw(cam, {{id, 0.0f}});

  std::vector<glm::ivec2> pixels;
  for (int y = 0; y < cam.height_px; y += 7)
    for (int x = 0; x < cam.width_px; x += 9) pixels.push_back({x, y});
  const std::vector<render::DepthSample> got = r.read_depth(pixels);
  ASSERT_EQ(got.size(), pixels.size());
  int hits = 0, misses = 0;
  double worst = 0.0;
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const glm::dvec3 dir = render::pixel_ray(cam, pixels[i].x + 0.5, pixels[i].y + 0.5);
    const glm::dvec3 o = terralod::render::camera_position(cam);
    // z(o + t dir) = plane(x, y)  =>  t = (o.z - plane(o)) / (a dx + b dy - dz)
    const double t = (o.z - plane(o.x, o.y)) / (plane.a * dir.x + plane.b * dir.y - dir.z);
    const glm::dvec3 p = o + t * dir;
    const double margin = 2.0 * spacing;  // stay clear of the square's edges
    const bool inside =
        t > 0 && p.x > kX0 + margin && p.x < kX0 + L - margin && p.y > kY0 + margin && p.y < kY0 + L - margin;
    const bool outside = t <= 0 || p.x < kX0 - margin || p.x > kX0 + L + margin || p.y < kY0 - margin ||
                         p.y > kY0 + L + margin;
    const render::DepthSample& s = got[i];
    EXPECT_EQ(s.pixel, pixels[i]);
    if (inside) {
      ++hits;
      ASSERT_TRUE(s.hit) << "pixel " << pixels[i].x << "," << pixels[i].y << " should see the plane at " << t
                         << " m";
      const double err = std::abs(s.distance - t) / t;
      worst = std::max(worst, err);
      EXPECT_LE(err, rel_tol) << "pixel " << pixels[i].x << "," << pixels[i].y << ": " << s.distance
                              << " m vs " << t;
      EXPECT_NEAR(s.eye_depth, t * glm::dot(dir, render::camera_forward(cam)), rel_tol * t);
      EXPECT_NEAR(s.world.z, plane(s.world.x, s.world.y), rel_tol * t) << "the point lies on the plane";
      EXPECT_NEAR(glm::length(s.world - o), s.distance, 1e-6 * t);
    } else if (outside) {
      ++misses;
      EXPECT_FALSE(s.hit) << "pixel " << pixels[i].x << "," << pixels[i].y << " should see sky";
      EXPECT_TRUE(std::isinf(s.distance));
    }
  }
  std::printf("plane depth (%s): %d hits, %d misses, worst relative error %.3g\n",
              reverse_z ? "reverse-Z" : "standard", hits, misses, worst);
  EXPECT_GT(hits, 300);
  EXPECT_GT(misses, 50);
}

TEST(Offscreen, DepthMatchesARayCastPlaneReverseZ) { check_plane_depth(/*reverse_z=*/true, 2e-5); }
TEST(Offscreen, DepthMatchesARayCastPlaneStandardDepth) { check_plane_depth(/*reverse_z=*/false, 2e-4); }

TEST(Offscreen, TwoRunsGiveByteIdenticalPngPixels) {
  const pm::Heightfield hf = rough_terrain(97);
  const DrawMesh dm = render::make_draw_mesh(full_mesh(hf), hf);
  std::vector<Image> shots;
  for (int run = 0; run < 2; ++run) {  // fresh context and renderer each time
    auto ctx = render::create_offscreen_context();
    render::RendererOptions opt;
    opt.wireframe = true;  // lines too: the most rasteriser-sensitive part
    render::TerrainRenderer r(*ctx, opt);
    const render::MeshId id = r.upload(dm);
    r.draw(terrain_camera(97, 400, 300), {{id, 0.0f}});
    const std::string path = (tmp_dir() / ("run" + std::to_string(run) + ".png")).string();
    render::write_png(r.read_color(), path);
    shots.push_back(render::read_image(path));
    EXPECT_EQ(shots.back(), r.read_color()) << "PNG keeps every byte";
  }
  EXPECT_EQ(shots[0].width, 400);
  EXPECT_EQ(shots[0].height, 300);
  EXPECT_GT(terrain_fraction(shots[0]), 0.3);
  EXPECT_TRUE(shots[0].rgb == shots[1].rgb)
      << "two runs differ in " << diff(shots[0], shots[1]).pixels << " pixels";
}

/// A terrain with geomorph targets: z1 = a smoothed, shifted copy of z0.
DrawMesh morphing_mesh(const pm::Heightfield& hf) {
  DrawMesh d = render::make_draw_mesh(full_mesh(hf), hf);
  d.z_target.resize(d.vertex_count());
  for (std::size_t v = 0; v < d.vertex_count(); ++v)
    d.z_target[v] = 0.5f * d.xyz[3 * v + 2] + 20.0f * std::sin(0.01f * d.xyz[3 * v]) - 15.0f;
  return d;
}

TEST(Offscreen, GeomorphGpuAndCpuPathsAgreeAndEndpointsAreExact) {
  const int n = 97;
  const pm::Heightfield hf = rough_terrain(n, 11);
  const DrawMesh morph = morphing_mesh(hf);
  DrawMesh start = morph, end = morph;  // the two static meshes the morph runs between
  start.z_target.clear();
  end.z_target.clear();
  for (std::size_t v = 0; v < morph.vertex_count(); ++v) end.xyz[3 * v + 2] = morph.z_target[v];
  const Camera cam = terrain_camera(n, 400, 300);

  auto ctx = render::create_offscreen_context();
  render::RendererOptions opt;
  opt.ramp_low = morph.origin.z - 200.0;  // a fixed colour ramp for all meshes
  opt.ramp_high = morph.origin.z + 200.0;
  render::TerrainRenderer r(*ctx, opt);
  const render::MeshId m = r.upload(morph), s = r.upload(start), e = r.upload(end);
  auto shot = [&](render::MeshId id, float alpha, render::GeomorphPath path) {
    r.options().geomorph = path;
    r.draw(cam, {{id, alpha}});
    return r.read_color();
  };
  const Image start_img = shot(s, 0.0f, render::GeomorphPath::Gpu);
  const Image end_img = shot(e, 0.0f, render::GeomorphPath::Gpu);
  EXPECT_GT(diff(start_img, end_img).pixels, 1000u) << "the morph should visibly change the terrain";
  for (const float alpha : {0.0f, 0.25f, 0.5f, 0.8125f, 1.0f}) {
    const Image gpu = shot(m, alpha, render::GeomorphPath::Gpu);
    const Image cpu = shot(m, alpha, render::GeomorphPath::Cpu);
    const ImageDiff d = diff(gpu, cpu);
    std::printf("alpha %.4f: GPU vs CPU path differ in %zu pixels, by at most %d\n", alpha, d.pixels,
                d.max_channel);
    EXPECT_LE(d.max_channel, 1) << "alpha " << alpha;
    EXPECT_GT(terrain_fraction(gpu), 0.3);
  }
  // The CPU path uploads one float per vertex when alpha changes, nothing when it does not.
  r.options().geomorph = render::GeomorphPath::Cpu;
  EXPECT_EQ(r.draw(cam, {{m, 0.375f}}).bytes_uploaded, morph.vertex_count() * sizeof(float));
  EXPECT_EQ(r.draw(cam, {{m, 0.375f}}).bytes_uploaded, 0u);
  r.options().geomorph = render::GeomorphPath::Gpu;
  EXPECT_EQ(r.draw(cam, {{m, 0.625f}}).bytes_uploaded, 0u);
  // Exact endpoints: alpha 0 is the start mesh and alpha 1 the end mesh, bit for bit, both paths.
  for (const auto path : {render::GeomorphPath::Gpu, render::GeomorphPath::Cpu}) {
    EXPECT_TRUE(shot(m, 0.0f, path) == start_img) << "alpha 0 must draw z0 exactly";
    EXPECT_TRUE(shot(m, 1.0f, path) == end_img) << "alpha 1 must draw z_target exactly";
  }
}

TEST(Offscreen, IndexUpdatesChangeOnlyTheTriangleList) {
  const pm::Heightfield hf = rough_terrain(65);
  const DrawMesh dm = render::make_draw_mesh(full_mesh(hf), hf);
  auto ctx = render::create_offscreen_context();
  render::TerrainRenderer r(*ctx);
  const render::MeshId id = r.upload(dm);
  const Camera cam = terrain_camera(65);
  r.draw(cam, {{id, 0.0f}});
  const Image full = r.read_color();
  // Keep the first half of the triangles (the northern half of the grid's rows).
  const std::vector<std::uint32_t> half(dm.indices.begin(), dm.indices.begin() + dm.indices.size() / 2);
  r.update_indices(id, half);
  EXPECT_EQ(r.triangle_count(id), dm.triangle_count() / 2);
  const render::FrameStats s = r.draw(cam, {{id, 0.0f}});
  EXPECT_EQ(s.triangles, dm.triangle_count() / 2);
  const Image part = r.read_color();
  EXPECT_GT(diff(full, part).pixels, 1000u);
  EXPECT_LT(terrain_fraction(part), terrain_fraction(full));
  // Growing past the old list (capacity) and back to the original list.
  std::vector<std::uint32_t> twice = dm.indices;
  twice.insert(twice.end(), dm.indices.begin(), dm.indices.end());
  r.update_indices(id, twice);
  r.draw(cam, {{id, 0.0f}});
  EXPECT_TRUE(r.read_color() == full) << "drawing every triangle twice gives the same picture";
  r.update_indices(id, dm.indices);
  r.draw(cam, {{id, 0.0f}});
  EXPECT_TRUE(r.read_color() == full);
  // An index beyond the vertices is refused before anything reaches the GPU.
  std::vector<std::uint32_t> bad = {0, 1, std::uint32_t(dm.vertex_count())};
  EXPECT_THROW(r.update_indices(id, bad), std::invalid_argument);
  EXPECT_EQ(r.triangle_count(id), dm.triangle_count());
}

TEST(Offscreen, ManyMeshesShareAFrameAndCanBeRemoved) {
  // Two halves of one terrain uploaded as separate meshes with different origins draw the
  // same picture as the whole (up to the seam pixels that the halves' rounding may move).
  const pm::Heightfield hf = rough_terrain(65);
  const pm::TriangleMesh whole = full_mesh(hf);
  pm::TriangleMesh north = whole, south = whole;
  north.triangles.assign(whole.triangles.begin(), whole.triangles.begin() + whole.triangles.size() / 2);
  south.triangles.assign(whole.triangles.begin() + whole.triangles.size() / 2, whole.triangles.end());
  render::DrawMeshOptions o_south;
  o_south.origin = glm::dvec3(kX0 + 900.0, kY0 + 500.0, 100.0);
  auto ctx = render::create_offscreen_context();
  render::RendererOptions opt;
  opt.ramp_low = 0.0, opt.ramp_high = 400.0;
  render::TerrainRenderer r(*ctx, opt);
  const render::MeshId w = r.upload(render::make_draw_mesh(whole, hf));
  const render::MeshId a = r.upload(render::make_draw_mesh(north, hf));
  const render::MeshId b = r.upload(render::make_draw_mesh(south, hf, o_south));
  const Camera cam = terrain_camera(65);
  r.draw(cam, {{w, 0.0f}});
  const Image one = r.read_color();
  const render::FrameStats s = r.draw(cam, {{a, 0.0f}, {b, 0.0f}});
  EXPECT_EQ(s.meshes, 2u);
  EXPECT_EQ(s.triangles, whole.triangles.size());
  const ImageDiff d = diff(one, r.read_color());
  EXPECT_LE(d.pixels, 40u) << "only pixels on triangle edges may change with the origin";
  const std::size_t before = r.gpu_bytes();
  r.remove(a);
  EXPECT_LT(r.gpu_bytes(), before);
}

TEST(Offscreen, WireframeDrawsEdgesOverTheSurface) {
  const pm::Heightfield hf = rough_terrain(33);
  auto ctx = render::create_offscreen_context();
  render::TerrainRenderer r(*ctx);
  const render::MeshId id = r.upload(render::make_draw_mesh(full_mesh(hf), hf));
  const Camera cam = terrain_camera(33);
  r.draw(cam, {{id, 0.0f}});
  const Image plain = r.read_color();
  r.options().wireframe = true;
  r.draw(cam, {{id, 0.0f}});
  const Image wire = r.read_color();
  const glm::vec3 wc = r.options().wire_color;
  std::size_t wire_pixels = 0;
  for (std::size_t p = 0; p < wire.rgb.size() / 3; ++p)
    wire_pixels += wire.rgb[3 * p] == std::lround(wc.r * 255) &&
                   wire.rgb[3 * p + 1] == std::lround(wc.g * 255) &&
                   wire.rgb[3 * p + 2] == std::lround(wc.b * 255);
  EXPECT_GT(wire_pixels, 2000u);
  EXPECT_GT(diff(plain, wire).pixels, wire_pixels / 2);
  EXPECT_NEAR(terrain_fraction(plain), terrain_fraction(wire), 0.02) << "the outline of the terrain stays";
}

TEST(Offscreen, FrameSizeFollowsTheCamera) {
  const pm::Heightfield hf = rough_terrain(33);
  auto ctx = render::create_offscreen_context({/*width=*/16, /*height=*/16});
  render::TerrainRenderer r(*ctx);
  const render::MeshId id = r.upload(render::make_draw_mesh(full_mesh(hf), hf));
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{200, 100}, {64, 256}, {200, 100}}) {
    r.draw(terrain_camera(33, w, h), {{id, 0.0f}});
    const Image img = r.read_color();
    EXPECT_EQ(img.width, w);
    EXPECT_EQ(img.height, h);
    EXPECT_GT(terrain_fraction(img), 0.1);
  }
  // The default framebuffer keeps its size; the frame is scaled into it.
  const Image win = r.read_window_color();
  EXPECT_EQ(win.width, 16);
  EXPECT_EQ(win.height, 16);
}

// ---------------------------------------------------------------------------------------------
// GLFW window under a private Xvfb

/// Under AddressSanitizer: keeps the GL driver modules a window loaded (libGLX_mesa, the
/// *_dri.so driver) mapped until exit. Mesa's driver allocates a little once per process and
/// keeps it in a global; glfwTerminate unloads the driver, which turns that memory into a
/// "leak" LSan cannot even attribute (unknown module). Pinned, the memory stays reachable.
void pin_gl_driver_modules() {
#ifdef TERRALOD_TEST_ASAN
  std::vector<std::string> names;
  dl_iterate_phdr(
      [](dl_phdr_info* info, std::size_t, void* out) {
        const std::string name = info->dlpi_name ? info->dlpi_name : "";
        if (name.find("_dri.so") != std::string::npos || name.find("libGLX_mesa") != std::string::npos)
          static_cast<std::vector<std::string>*>(out)->push_back(name);
        return 0;
      },
      &names);
  for (const std::string& n : names) dlopen(n.c_str(), RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
#endif
}

TEST(Window, GlfwUnderXvfbDrawsAndReadsBackAFrame) {
  terralod::test::Xvfb xvfb;
  if (xvfb.display().empty()) GTEST_SKIP() << "Xvfb could not be started (is the xvfb package installed?)";
  setenv("DISPLAY", xvfb.display().c_str(), 1);
  std::unique_ptr<render::WindowContext> win;
  try {
    render::WindowOptions wo;
    wo.width = 320;
    wo.height = 240;
    wo.visible = false;
    wo.vsync = false;
    win = render::WindowContext::create(wo);
    pin_gl_driver_modules();
  } catch (const render::RenderError& e) {
    GTEST_SKIP() << "no GLFW window on " << xvfb.display() << ": " << e.what();
  }
  std::printf("window context on %s: %s | %s\n", xvfb.display().c_str(), win->info().renderer.c_str(),
              win->info().version.c_str());
  EXPECT_EQ(win->info().backend, "glfw");
  EXPECT_GE(win->info().major * 10 + win->info().minor, 33);
  {
    const pm::Heightfield hf = rough_terrain(65);
    render::TerrainRenderer r(*win);
    const render::MeshId id = r.upload(render::make_draw_mesh(full_mesh(hf), hf));
    Camera cam = terrain_camera(65, win->framebuffer_width(), win->framebuffer_height());
    r.draw(cam, {{id, 0.0f}});
    const Image frame = r.read_color();
    EXPECT_GT(terrain_fraction(frame), 0.3);
    const Image shown = r.read_window_color();  // blitted into the window's back buffer
    EXPECT_TRUE(shown == frame) << "the window holds the frame, differing in " << diff(shown, frame).pixels
                                << " pixels";
    r.present();
    win->poll_events();
    EXPECT_FALSE(win->should_close());
  }
  win.reset();
  unsetenv("DISPLAY");
}

// ---------------------------------------------------------------------------------------------
// GPU vs CPU geomorph cost on a 513 x 513 terrain reduced to about 200k triangles

TEST(Timing, GeomorphGpuVsCpuOn513Terrain) {
  const int n = 513;
  const pm::Heightfield hf = rough_terrain(n, 3);
  auto t0 = std::chrono::steady_clock::now();
  pm::BuildOptions bo;
  const pm::ProgressiveMesh pmesh = pm::ProgressiveMesh::build(hf, bo);
  const double build_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  // Each interior collapse removes two triangles: keep about 200k of the 524288.
  const std::size_t full_tris = 2u * (n - 1) * (n - 1);
  const std::size_t count = std::min(pmesh.vsplit_count(), (full_tris - 200000) / 2);
  const pm::TriangleMesh m = pmesh.extract_after(count);
  DrawMesh dm = render::make_draw_mesh(m, hf);
  dm.z_target.resize(dm.vertex_count());
  for (std::size_t v = 0; v < dm.vertex_count(); ++v) dm.z_target[v] = dm.xyz[3 * v + 2] + 10.0f;
  std::printf("terrain %d x %d: PM built in %.0f ms; mesh of %zu triangles, %zu vertices\n", n, n, build_ms,
              m.triangles.size(), dm.vertex_count());
  EXPECT_GT(m.triangles.size(), 150000u);
  EXPECT_LT(m.triangles.size(), 250000u);

  auto ctx = render::create_offscreen_context();
  render::TerrainRenderer r(*ctx);
  const render::MeshId id = r.upload(dm);
  // A full-size frame (rasterisation dominates) and a small one (per-vertex work shows more).
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{1024, 768}, {256, 192}}) {
    const Camera cam = terrain_camera(n, w, h);
    const int frames = 12;
    Image last[2];
    double upload[2] = {}, draw[2] = {};
    for (const auto path : {render::GeomorphPath::Gpu, render::GeomorphPath::Cpu}) {
      const int k = path == render::GeomorphPath::Cpu;
      r.options().geomorph = path;
      r.draw(cam, {{id, 0.0f}});  // warm-up
      for (int f = 0; f < frames; ++f) {
        const float alpha = float(f + 1) / float(frames);  // a new alpha every frame
        const render::FrameStats s = r.draw(cam, {{id, alpha}});
        upload[k] += s.upload_ms / frames;
        draw[k] += s.draw_ms / frames;
      }
      last[k] = r.read_color();
    }
    std::printf("%4d x %3d  GPU geomorph: %.3f ms blend+upload, %6.2f ms draw per frame (%s)\n", w, h,
                upload[0], draw[0], ctx->info().renderer.c_str());
    std::printf(
        "%4d x %3d  CPU geomorph: %.3f ms blend+upload, %6.2f ms draw per frame (%zu bytes per frame)\n", w,
        h, upload[1], draw[1], dm.vertex_count() * 4);
    const std::string tag = std::to_string(w) + "x" + std::to_string(h);
    RecordProperty("gpu_upload_ms_" + tag, std::to_string(upload[0]));
    RecordProperty("gpu_draw_ms_" + tag, std::to_string(draw[0]));
    RecordProperty("cpu_upload_ms_" + tag, std::to_string(upload[1]));
    RecordProperty("cpu_draw_ms_" + tag, std::to_string(draw[1]));
    EXPECT_LT(upload[0], upload[1]) << "the GPU path uploads nothing per frame";
    EXPECT_LE(diff(last[0], last[1]).max_channel, 1);
  }
}

}  // namespace
