// Tests of ObjectRenderer (issue 19): label rectangles against the pixels drawn, a headless
// reference frame of icons, labels and buildings on a terrain (and that a changed label, a
// one-pixel shift or a changed rule fails it), icons hidden by a hill, draped ribbons, errors.
//
// The reference image is tests/render/data/objects_reference.png. After an intended change of
// the picture, regenerate it with
//   TERRALOD_UPDATE_REFERENCE=1 ./build/tests/render/test_object_render --gtest_filter='*Reference*'
// (it writes the PNG into the source tree; look at it before committing it).
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "full_mesh.hpp"
#include "terralod/blocks/object_mesh.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/render/camera.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/object_renderer.hpp"
#include "terralod/render/terrain_renderer.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace render = terralod::render;
namespace blocks = terralod::blocks;
using render::Camera;
using render::Image;

// ---------------------------------------------------------------------------------------------
// Fixtures

constexpr double kX0 = 500000.0, kY0 = 5000000.0;  // UTM-sized: floats would be off by 0.5 m
constexpr double kSpacing = 4.0;
constexpr int kN = 129;  // 512 m square

/// z = 300 + 0.03 (x - kX0) + a 120 m Gaussian hill (sigma 70 m) at the square's centre.
double ground(double x, double y) {
  const double dx = x - (kX0 + 256.0), dy = y - (kY0 + 256.0);
  return 300.0 + 0.03 * (x - kX0) + 120.0 * std::exp(-(dx * dx + dy * dy) / (2.0 * 70.0 * 70.0));
}

pm::Heightfield hill_heightfield() {
  pm::Heightfield hf(kN, kN);
  hf.transform = pm::GridTransform::north_up(kX0, kY0 + (kN - 1) * kSpacing, kSpacing, kSpacing);
  for (int r = 0; r < kN; ++r)
    for (int c = 0; c < kN; ++c) {
      const auto [x, y] = hf.transform.to_world(c, r);
      hf.at(c, r) = ground(x, y);
    }
  return hf;
}

using terralod::test::full_mesh;

/// South of the square looking north and down over the hill; 320 x 240.
Camera scene_camera() {
  return Camera{.x = kX0 + 256.0,
                .y = kY0 - 120.0,
                .z = 520.0,
                .yaw_deg = 0.0,
                .pitch_deg = -22.0,
                .fovy_deg = 50.0,
                .width_px = 320,
                .height_px = 240,
                .near_m = 1.0,
                .far_m = 5000.0,
                .ground = {}};
}

glm::dvec3 on_ground(double dx, double dy) { return {kX0 + dx, kY0 + dy, ground(kX0 + dx, kY0 + dy)}; }

/// An axis-aligned box on the ground at (dx, dy): footprint w x d metres, h high, its base at
/// the lowest ground height under the footprint's corners; triangles CCW from outside, with
/// per-face normals (or none).
blocks::ObjectMesh box_mesh(double dx, double dy, double w, double d, double h, bool normals) {
  const double x0 = kX0 + dx - w / 2, x1 = x0 + w, y0 = kY0 + dy - d / 2, y1 = y0 + d;
  const double z0 = std::min({ground(x0, y0), ground(x1, y0), ground(x0, y1), ground(x1, y1)}), z1 = z0 + h;
  blocks::ObjectMesh m;
  // Each face: 4 corners CCW seen from outside, and its outward normal.
  const auto face = [&](std::array<pm::Vec3, 4> c, pm::Vec3 n) {
    const auto base = std::uint32_t(m.positions.size());
    for (const pm::Vec3& p : c) {
      m.positions.push_back(p);
      if (normals) m.normals.push_back(n);
    }
    m.triangles.push_back({base, base + 1, base + 2});
    m.triangles.push_back({base, base + 2, base + 3});
    m.triangle_object.insert(m.triangle_object.end(), {0, 0});
  };
  face({{{x0, y0, z1}, {x1, y0, z1}, {x1, y1, z1}, {x0, y1, z1}}}, {0, 0, 1});   // roof
  face({{{x0, y0, z0}, {x1, y0, z0}, {x1, y0, z1}, {x0, y0, z1}}}, {0, -1, 0});  // south
  face({{{x1, y0, z0}, {x1, y1, z0}, {x1, y1, z1}, {x1, y0, z1}}}, {1, 0, 0});   // east
  face({{{x1, y1, z0}, {x0, y1, z0}, {x0, y1, z1}, {x1, y1, z1}}}, {0, 1, 0});   // north
  face({{{x0, y1, z0}, {x0, y0, z0}, {x0, y0, z1}, {x0, y1, z1}}}, {-1, 0, 0});  // west
  return m;
}

/// A 32 x 64 "tree" (green crown, brown trunk, transparent elsewhere) written as RGBA PNG.
std::string write_tree_png() {
  const fs::path dir = fs::path(TERRALOD_TEST_TMP) / ("objects-" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "tree.png").string();
  const int w = 32, h = 64;
  std::vector<std::uint8_t> px(std::size_t(w) * h * 4, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint8_t* p = &px[4 * (std::size_t(y) * w + x)];
      const double cx = std::abs(x + 0.5 - w / 2.0);
      if (y < 50 && cx < (y + 2) * 0.32)
        p[0] = 40, p[1] = 120, p[2] = 45, p[3] = 255;  // crown
      else if (y >= 50 && cx < 3)
        p[0] = 100, p[1] = 70, p[2] = 40, p[3] = 255;  // trunk
      else
        p[0] = 40, p[1] = 120, p[2] = 45;
    }
  auto out = OIIO::ImageOutput::create(path);
  EXPECT_TRUE(out && out->open(path, OIIO::ImageSpec(w, h, 4, OIIO::TypeDesc::UINT8)));
  EXPECT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data()));
  out->close();
  return path;
}

/// One context, terrain and object renderer for a test.
struct Stage {
  std::unique_ptr<render::GlContext> ctx = render::create_offscreen_context();
  render::TerrainRenderer terrain{*ctx};
  render::ObjectRenderer objects;
  render::MeshId hill;
  explicit Stage(const render::ObjectRendererOptions& o = {}) : objects(*ctx, o) {
    const pm::Heightfield hf = hill_heightfield();
    hill = terrain.upload(render::make_draw_mesh(full_mesh(hf), hf));
    terrain.options().ramp_low = 250.0, terrain.options().ramp_high = 450.0;
    terrain.options().light_direction = {-0.5, -0.5, 0.707};  // from the south-west: the lit side faces us
  }
};

/// The objects of the reference scene.
struct Scene {
  std::vector<render::IconInstance> icons;
  std::vector<render::LabelInstance> labels;
  std::vector<blocks::ObjectMesh> buildings;
};

Scene reference_scene(render::IconStyleId marker, render::IconStyleId tree) {
  Scene s;
  s.icons = {{on_ground(150, 130), marker, 30.0},
             {on_ground(380, 150), marker, 30.0},
             {on_ground(120, 230), tree, 40.0},
             {on_ground(140, 260), tree, 35.0},
             {on_ground(400, 270), tree, 40.0}};
  // Labels stand on the markers' tops and on the summit.
  const glm::dvec3 up(0.0, 0.0, 30.0);
  s.labels = {{s.icons[0].anchor + up, "Refuge", 14},
              {on_ground(256, 256), "Mont Blanc", 16},
              {s.icons[1].anchor + up, "Lac Blanc", 13}};
  s.buildings = {box_mesh(310, 95, 40, 25, 30, /*normals=*/true),
                 box_mesh(215, 140, 20, 30, 45, /*normals=*/false)};
  return s;
}

Image draw_scene(Stage& st, const Camera& cam, const Scene& s) {
  st.terrain.draw(cam, {{st.hill, 0.0f}});
  for (const blocks::ObjectMesh& b : s.buildings)
    st.objects.draw_mesh(st.terrain, b, {0.85f, 0.8f, 0.72f, 1.0f});
  st.objects.draw_icons(st.terrain, s.icons);
  st.objects.draw_labels(st.terrain, s.labels);
  return st.terrain.read_color();
}

/// How two frames differ: mean absolute difference per channel (levels of 255) and the share
/// of pixels where some channel differs by more than 16 levels.
struct Difference {
  double mean_abs = 0.0;
  double share_over_16 = 0.0;
};

Difference compare(const Image& a, const Image& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  if (a.rgb.size() != b.rgb.size()) return {255.0, 1.0};
  double sum = 0.0;
  std::size_t over = 0;
  for (std::size_t p = 0; p < a.rgb.size() / 3; ++p) {
    int m = 0;
    for (int c = 0; c < 3; ++c) {
      const int d = std::abs(int(a.rgb[3 * p + c]) - int(b.rgb[3 * p + c]));
      sum += d, m = std::max(m, d);
    }
    over += m > 16;
  }
  return {sum / double(a.rgb.size()), double(over) / double(a.rgb.size() / 3)};
}

// Tolerance of the reference comparison. llvmpipe gives byte-identical frames on one machine;
// another CPU or Mesa version may round shading differently (a level or two everywhere: the
// mean bound) and place an edge pixel differently (rasterisation is exact fixed-point, so only a
// few: the share bound, 0.05 % = 38 pixels of 320 x 240). Both bounds stay well below what a
// real change does: each variant below moves several hundred pixels by more than 16 levels.
constexpr double kMaxMeanAbs = 0.25, kMaxShareOver16 = 0.0005;
bool same_picture(const Difference& d) {
  return d.mean_abs <= kMaxMeanAbs && d.share_over_16 <= kMaxShareOver16;
}

/// Bounding box of the pixels that differ from black (any channel > 0).
render::PixelBox ink_box(const Image& img) {
  render::PixelBox b{img.width, img.height, 0, 0};
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const std::uint8_t* p = img.pixel(x, y);
      if (p[0] || p[1] || p[2])
        b.x0 = std::min(b.x0, x), b.y0 = std::min(b.y0, y), b.x1 = std::max(b.x1, x + 1),
        b.y1 = std::max(b.y1, y + 1);
    }
  return b;
}

// ---------------------------------------------------------------------------------------------
// Labels

/// A label alone on a black frame (no terrain): returns its label_rect and the frame.
std::pair<render::PixelBox, Image> lone_label(Stage& st, const std::string& text, int size_px) {
  const Camera cam = scene_camera();
  st.terrain.options().sky_color = {0.0f, 0.0f, 0.0f};
  st.terrain.draw(cam, std::span<const render::DrawItem>());
  const glm::dvec3 anchor = on_ground(256, 100);
  const auto p = render::project_point(cam, anchor);
  EXPECT_TRUE(p.has_value());
  const render::PixelBox r = st.objects.label_rect({p->x, p->y}, text, size_px);
  const glm::ivec2 size = st.objects.measure_label(text, size_px);
  EXPECT_EQ(size, glm::ivec2(r.width(), r.height())) << text;
  st.objects.draw_labels(st.terrain, {{anchor, text, size_px}});
  return {r, st.terrain.read_color()};
}

TEST(Labels, DrawnPixelsFillExactlyTheReportedRectangleWithABrightHalo) {
  // With an opaque grey halo every pixel of the halo is visible on black: the drawn pixels'
  // bounding box must be label_rect exactly (the halo of the outermost ink column/row reaches
  // the rectangle's edge, by construction of the dilation).
  Stage st({.halo_color = {0.5f, 0.5f, 0.5f, 1.0f}});
  for (const auto& [text, size] :
       {std::pair<std::string, int>{"Mont Blanc", 14}, {"Ågesund 9g", 20}, {"i", 9}}) {
    const auto [rect, img] = lone_label(st, text, size);
    EXPECT_FALSE(rect.empty());
    EXPECT_EQ(ink_box(img), rect) << text << " at " << size << " px";
  }
}

TEST(Labels, TextStaysInsideTheRectangleWithinTheHaloWidth) {
  // Default dark halo (5 % grey, 85 % opaque: levels of about 11 on black, so it shows too).
  // Stated tolerance: the drawn box lies inside label_rect and each edge is within halo_px of it.
  Stage st;
  const int halo = st.objects.options().halo_px;
  const auto [rect, img] = lone_label(st, "Lac Blanc", 14);
  const render::PixelBox ink = ink_box(img);
  EXPECT_GE(ink.x0, rect.x0);
  EXPECT_GE(ink.y0, rect.y0);
  EXPECT_LE(ink.x1, rect.x1);
  EXPECT_LE(ink.y1, rect.y1);
  EXPECT_LE(ink.x0 - rect.x0, halo);
  EXPECT_LE(ink.y0 - rect.y0, halo);
  EXPECT_LE(rect.x1 - ink.x1, halo);
  EXPECT_LE(rect.y1 - ink.y1, halo);
  // White text really is drawn (not only the halo).
  int white = 0;
  for (std::size_t i = 0; i < img.rgb.size(); i += 3) white += img.rgb[i] == 255 && img.rgb[i + 1] == 255;
  EXPECT_GT(white, 20);
}

TEST(Labels, MeasureGrowsWithTextAndSizeAndEmptyTextHasNoArea) {
  Stage st;
  const glm::ivec2 a = st.objects.measure_label("Lac", 14), b = st.objects.measure_label("Lac Blanc", 14);
  const glm::ivec2 c = st.objects.measure_label("Lac", 28);
  EXPECT_GT(b.x, a.x);
  EXPECT_GT(c.x, a.x);
  EXPECT_GT(c.y, a.y);
  EXPECT_EQ(st.objects.measure_label("", 14), glm::ivec2(0, 0));
  EXPECT_EQ(st.objects.measure_label("   ", 14), glm::ivec2(0, 0));
  EXPECT_TRUE(st.objects.label_rect({100.0, 100.0}, "", 14).empty());
  // The rectangle is centred on the anchor and its bottom is above it.
  const render::PixelBox r = st.objects.label_rect({100.0, 100.0}, "Lac", 14);
  EXPECT_LE(std::abs((r.x0 + r.x1) - 200), 1);
  EXPECT_LT(r.y1, 100);
}

// ---------------------------------------------------------------------------------------------
// The reference frame

TEST(Reference, FrameMatchesTheStoredReferenceAndChangesFailIt) {
  Stage st;
  const render::IconStyleId marker = st.objects.add_icon_style(render::default_marker_image(), 1);
  const std::string tree_png = write_tree_png();
  const render::IconStyleId tree = st.objects.load_icon_style(tree_png, 2);
  fs::remove_all(fs::path(tree_png).parent_path());
  const Camera cam = scene_camera();
  const Scene scene = reference_scene(marker, tree);
  const Image frame = draw_scene(st, cam, scene);

  const std::string ref_path = std::string(TERRALOD_RENDER_TEST_DATA) + "/objects_reference.png";
  const char* update = std::getenv("TERRALOD_UPDATE_REFERENCE");
  if (update && std::string(update) == "1") {
    render::write_png(frame, ref_path);
    std::printf("wrote %s\n", ref_path.c_str());
  }
  ASSERT_TRUE(fs::exists(ref_path)) << ref_path << " is missing: run with TERRALOD_UPDATE_REFERENCE=1";
  const Image ref = render::read_image(ref_path);
  const Difference d = compare(frame, ref);
  std::printf("reference: mean |diff| %.4f levels, %.4f %% of pixels > 16\n", d.mean_abs,
              100 * d.share_over_16);
  EXPECT_TRUE(same_picture(d)) << "the frame differs from " << ref_path;

  // The objects are in the picture: without them the frame is not the same picture.
  st.terrain.draw(cam, {{st.hill, 0.0f}});
  EXPECT_FALSE(same_picture(compare(st.terrain.read_color(), ref))) << "terrain alone";

  const auto expect_different = [&](const Scene& changed, const Camera& c, const char* what) {
    const Difference e = compare(draw_scene(st, c, changed), ref);
    std::printf("%s: mean |diff| %.4f levels, %.4f %% of pixels > 16\n", what, e.mean_abs,
                100 * e.share_over_16);
    EXPECT_FALSE(same_picture(e)) << what << " was not caught";
  };
  {  // One label's text changed.
    Scene s = scene;
    s.labels[2].text = "Lac Noir";
    expect_different(s, cam, "label text changed");
  }
  {  // Every object moved right by the world size of one pixel at its own distance.
    Scene s = scene;
    const glm::dvec3 right = render::camera_right(cam);
    const double k = render::focal_length_pixels(cam);
    const auto pixel_m = [&](const glm::dvec3& p) { return render::project_point(cam, p)->eye_depth / k; };
    for (auto& i : s.icons) i.anchor += right * pixel_m(i.anchor);
    for (auto& l : s.labels) l.anchor += right * pixel_m(l.anchor);
    for (auto& b : s.buildings) {
      const double m = pixel_m({b.positions[0].x, b.positions[0].y, b.positions[0].z});
      for (pm::Vec3& p : b.positions) p.x += right.x * m, p.y += right.y * m;
    }
    expect_different(s, cam, "objects shifted by one pixel");
  }
  {  // A changed rule: the last tree drawn as a label ("Pine") instead of an icon.
    Scene s = scene;
    s.labels.push_back({s.icons[4].anchor, "Pine", 14});
    s.icons.erase(s.icons.begin() + 4);
    expect_different(s, cam, "icon drawn as a label");
  }
}

// ---------------------------------------------------------------------------------------------
// Icon geometry

/// An icon alone on black, seen horizontally from 200 m at compass bearing `from_deg` (the camera
/// stands that way from the anchor and looks back at it): the drawn box, and the mean x of the
/// red and of the blue pixels.
struct IconView {
  render::PixelBox box;
  double red_x = 0.0, blue_x = 0.0;
};
IconView view_icon(Stage& st, render::IconStyleId style, double from_deg) {
  const double a = from_deg * std::acos(-1.0) / 180.0;
  const glm::dvec3 anchor(kX0 + 256.0, kY0 + 256.0, 400.0);
  const Camera cam{.x = anchor.x + 200.0 * std::sin(a),
                   .y = anchor.y + 200.0 * std::cos(a),
                   .z = anchor.z + 20.0,
                   .yaw_deg = from_deg + 180.0,
                   .pitch_deg = 0.0,
                   .fovy_deg = 50.0,
                   .width_px = 320,
                   .height_px = 240,
                   .near_m = 1.0,
                   .far_m = 5000.0,
                   .ground = {}};
  st.terrain.options().sky_color = {0.0f, 0.0f, 0.0f};
  st.terrain.draw(cam, std::span<const render::DrawItem>());
  st.objects.draw_icons(st.terrain, {{anchor, style, 40.0}});
  const Image img = st.terrain.read_color();
  IconView v{ink_box(img)};
  double rx = 0, rn = 0, bx = 0, bn = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      const std::uint8_t* p = img.pixel(x, y);
      if (p[0] > 128 && p[2] < 64) rx += x, rn += 1;
      if (p[2] > 128 && p[0] < 64) bx += x, bn += 1;
    }
  v.red_x = rn > 0 ? rx / rn : -1.0;
  v.blue_x = bn > 0 ? bx / bn : -1.0;
  return v;
}

TEST(Icons, OneQuadFacesTheCameraTwoQuadsAreFixedInTheWorld) {
  Stage st;
  render::RgbaImage half(32, 32);  // left half red, right half blue: shows a mirrored billboard
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x)
      half.set(
          x, y,
          x < 16 ? std::array<std::uint8_t, 4>{255, 0, 0, 255} : std::array<std::uint8_t, 4>{0, 0, 255, 255});
  const render::IconStyleId billboard = st.objects.add_icon_style(half, 1);
  const render::IconStyleId cross = st.objects.add_icon_style(half, 2);
  // A square 40 m icon at 200 m: about 40 * K / 200 = 51 pixels wide when seen face-on.
  const double k = 120.0 / std::tan(25.0 * std::acos(-1.0) / 180.0), face_on = 40.0 * k / 200.0;
  for (const double from : {180.0, 225.0, 300.0}) {
    const IconView v = view_icon(st, billboard, from);
    EXPECT_NEAR(v.box.width(), face_on, 2.0) << "billboard seen from " << from;
    EXPECT_LT(v.red_x, v.blue_x) << "the billboard's image must not be mirrored (seen from " << from << ")";
  }
  // The cross: quad 0 along world x, quad 1 along y. Seen from the south, quad 0 is face-on
  // (full width); from the south-west both quads are at 45 degrees: the widest points are the
  // two ends nearer the camera, 20 cos 45 m to either side and as much nearer than the anchor.
  const double c45 = std::sqrt(0.5);
  EXPECT_NEAR(view_icon(st, cross, 180.0).box.width(), face_on, 2.0);
  EXPECT_NEAR(view_icon(st, cross, 225.0).box.width(), face_on * c45 * 200.0 / (200.0 - 20.0 * c45), 2.0);
}

// ---------------------------------------------------------------------------------------------
// Cost

TEST(Cost, DrawCallsDoNotGrowWithTheNumberOfObjects) {
  Stage st;
  const render::IconStyleId marker = st.objects.add_icon_style(render::default_marker_image(), 1);
  const render::IconStyleId tree = st.objects.add_icon_style(render::default_marker_image(32), 3);
  std::vector<render::IconInstance> icons;
  std::vector<render::LabelInstance> labels;
  for (int i = 0; i < 2000; ++i) {  // a fixed scatter over the square
    const double dx = 8.0 + (i * 37 % 496), dy = 8.0 + (i * 101 % 496);
    icons.push_back({on_ground(dx, dy), i % 2 ? marker : tree, 15.0});
    if (i % 5 == 0) labels.push_back({on_ground(dx, dy), "Pt " + std::to_string(i), 12});
  }
  const blocks::ObjectMesh box = box_mesh(300, 200, 30, 30, 20, true);
  const Camera cam = scene_camera();
  st.terrain.draw(cam, {{st.hill, 0.0f}});
  const auto t0 = std::chrono::steady_clock::now();
  const render::ObjectDrawStats si = st.objects.draw_icons(st.terrain, icons);
  const render::ObjectDrawStats sl = st.objects.draw_labels(st.terrain, labels);
  const render::ObjectDrawStats sm = st.objects.draw_mesh(st.terrain, box, {1, 1, 1, 1});
  (void)st.terrain.read_color();  // waits for the GPU
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf(
      "%zu icons: %zu draw calls, %zu bytes; %zu labels: %zu draw calls, %zu bytes; mesh: %zu call; "
      "all drawn and read back in %.1f ms\n",
      si.objects, si.draw_calls, si.bytes_uploaded, sl.objects, sl.draw_calls, sl.bytes_uploaded,
      sm.draw_calls, ms);
  EXPECT_EQ(si.draw_calls, 2u);  // one per style
  EXPECT_EQ(si.bytes_uploaded, icons.size() * 16);
  EXPECT_EQ(sl.draw_calls, 2u);  // halo pass, text pass
  EXPECT_EQ(sm.draw_calls, 1u);
  EXPECT_EQ(sl.objects, labels.size());  // all are in front of the camera
}

// ---------------------------------------------------------------------------------------------
// Depth against the terrain

TEST(Depth, IconBehindTheHillIsHiddenByTheTerrain) {
  Stage st;
  const render::IconStyleId marker = st.objects.add_icon_style(render::default_marker_image(), 1);
  // A low camera south of the hill: the ground 170 m north of the hill's top is out of sight.
  const Camera cam{.x = kX0 + 256.0,
                   .y = kY0 - 150.0,
                   .z = 380.0,
                   .yaw_deg = 0.0,
                   .pitch_deg = -2.0,
                   .fovy_deg = 50.0,
                   .width_px = 320,
                   .height_px = 240,
                   .near_m = 1.0,
                   .far_m = 5000.0,
                   .ground = {}};
  const std::vector<render::IconInstance> hidden = {{on_ground(256, 426), marker, 60.0}};
  const auto changed_pixels = [&](bool terrain) {
    const std::vector<render::DrawItem> items = {{st.hill, 0.0f}};
    st.terrain.draw(cam,
                    terrain ? std::span<const render::DrawItem>(items) : std::span<const render::DrawItem>());
    const Image before = st.terrain.read_color();
    st.objects.draw_icons(st.terrain, hidden);
    const Image after = st.terrain.read_color();
    std::size_t n = 0;
    for (std::size_t i = 0; i < before.rgb.size(); i += 3)
      n += before.rgb[i] != after.rgb[i] || before.rgb[i + 1] != after.rgb[i + 1] ||
           before.rgb[i + 2] != after.rgb[i + 2];
    return n;
  };
  // Control: without the terrain the icon covers many pixels of the frame...
  EXPECT_GT(changed_pixels(/*terrain=*/false), 200u);
  // ... with it, every one of them keeps the terrain's colour.
  EXPECT_EQ(changed_pixels(/*terrain=*/true), 0u);

  // A label there too: its depth point (2 % of 590 m nearer) is still behind the hill.
  const auto label_pixels = [&](bool terrain) {
    const std::vector<render::DrawItem> items = {{st.hill, 0.0f}};
    st.terrain.draw(cam,
                    terrain ? std::span<const render::DrawItem>(items) : std::span<const render::DrawItem>());
    const Image before = st.terrain.read_color();
    st.objects.draw_labels(st.terrain, {{hidden[0].anchor, "Hidden Hut", 16}});
    const Image after = st.terrain.read_color();
    return compare(before, after).share_over_16 * before.width * before.height;
  };
  EXPECT_GT(label_pixels(/*terrain=*/false), 50.0);
  EXPECT_EQ(label_pixels(/*terrain=*/true), 0.0);
}

// ---------------------------------------------------------------------------------------------
// Draped ribbons

/// A ribbon draped exactly on the drawn terrain: the terrain's own cells (same sample positions,
/// same diagonals) of grid rows [row0, row0 + rows) and columns [col0, col1), no normals.
blocks::ObjectMesh draped_strip(const pm::Heightfield& hf, int row0, int rows, int col0, int col1) {
  blocks::ObjectMesh m;
  const int w = col1 - col0 + 1;
  for (int r = row0; r <= row0 + rows; ++r)
    for (int c = col0; c <= col1; ++c) {
      const auto [x, y] = hf.transform.to_world(c, r);
      m.positions.push_back({x, y, hf.at(c, r)});
    }
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < col1 - col0; ++i) {
      const auto a = std::uint32_t(j * w + i), b = a + 1, c = a + w + 1, d = a + w;
      // North-up rows run south: (a, c, b) and (a, d, c) are CCW seen from above.
      m.triangles.push_back({a, c, b});
      m.triangles.push_back({a, d, c});
      m.triangle_object.insert(m.triangle_object.end(), {0, 0});
    }
  return m;
}

TEST(Meshes, DrapedRibbonNeedsThePolygonOffsetAndThenShowsWhole) {
  Stage st;
  const pm::Heightfield hf = hill_heightfield();
  const blocks::ObjectMesh road = draped_strip(hf, 95, 3, 10, 118);  // 12 m wide, 432 m long, y 120..132 m
  const Camera cam = scene_camera();
  const auto ribbon_pixels = [&](bool terrain, bool offset) {
    const std::vector<render::DrawItem> items = {{st.hill, 0.0f}};
    st.terrain.draw(cam,
                    terrain ? std::span<const render::DrawItem>(items) : std::span<const render::DrawItem>());
    st.objects.draw_mesh(st.terrain, road, {1.0f, 0.0f, 1.0f, 1.0f}, {.on_terrain = offset});
    const Image img = st.terrain.read_color();
    std::size_t n = 0;  // magenta: blue well above green (the terrain is green to brown)
    for (std::size_t i = 0; i < img.rgb.size(); i += 3) n += int(img.rgb[i + 2]) > int(img.rgb[i + 1]) + 60;
    return n;
  };
  const std::size_t alone = ribbon_pixels(/*terrain=*/false, /*offset=*/false);
  const std::size_t fighting = ribbon_pixels(/*terrain=*/true, /*offset=*/false);
  const std::size_t offset = ribbon_pixels(/*terrain=*/true, /*offset=*/true);
  std::printf("ribbon pixels: alone %zu, on the terrain without offset %zu, with offset %zu\n", alone,
              fighting, offset);
  EXPECT_GT(alone, 500u);
  EXPECT_EQ(offset, alone) << "with the offset nothing of the ribbon may be lost to the terrain";
  EXPECT_LT(fighting, alone) << "without the offset the coplanar terrain should win some pixels (z-fighting)";
}

// ---------------------------------------------------------------------------------------------
// Errors name the file

TEST(Errors, MissingFontAndUnreadableIconNameTheFile) {
  auto ctx = render::create_offscreen_context();
  try {
    render::ObjectRenderer r(*ctx, {.font = "/nonexistent/NoSuchFont.ttf"});
    ADD_FAILURE() << "a missing font must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/NoSuchFont.ttf"), std::string::npos) << e.what();
  }
  render::ObjectRenderer r(*ctx);
  try {
    r.load_icon_style("/nonexistent/icon.png", 1);
    ADD_FAILURE() << "a missing icon must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/icon.png"), std::string::npos) << e.what();
  }
  EXPECT_THROW(r.add_icon_style(render::default_marker_image(), 4), std::invalid_argument);
  EXPECT_THROW(r.measure_label("x", 0), std::invalid_argument);
}

}  // namespace
