// Tests of the view parameters: camera conventions, projection, frustum planes, and the bound on
// projected vertical segments, against hand-derived fixtures and the independent GLM projector.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "screen_error_checker.hpp"
#include "terralod/pm/view.hpp"

namespace pm = terralod::pm;
namespace tt = terralod::test;

namespace {

void expect_vec(const pm::Vec3& v, double x, double y, double z) {
  EXPECT_NEAR(v.x, x, 1e-12);
  EXPECT_NEAR(v.y, y, 1e-12);
  EXPECT_NEAR(v.z, z, 1e-12);
}

pm::Camera random_camera(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  pm::Camera c;
  c.x = (U(rng) - 0.5) * 2e4, c.y = (U(rng) - 0.5) * 2e4, c.z = U(rng) * 3000;
  c.yaw_deg = U(rng) * 720 - 360;
  c.pitch_deg = U(rng) * 180 - 90;
  c.fovy_deg = 10 + U(rng) * 150;
  c.width_px = 100 + int(U(rng) * 2000);
  c.height_px = 100 + int(U(rng) * 1200);
  c.near_m = 0.5 + U(rng) * 5;
  c.far_m = c.near_m + 1e3 + U(rng) * 1e5;
  // Every other camera has a ground scale, stretching far more than a map projection's.
  if (U(rng) < 0.5) c.ground = tt::random_ground_scale(rng);
  return c;
}

}  // namespace

// World frame x east, y north, z up; yaw clockwise from north; pitch above the horizon.
TEST(View, CameraConventions) {
  pm::Camera c;
  c.yaw_deg = 0, c.pitch_deg = 0;
  pm::View north(c);
  expect_vec(north.forward(), 0, 1, 0);
  expect_vec(north.right(), 1, 0, 0);
  expect_vec(north.up(), 0, 0, 1);
  c.yaw_deg = 90;
  pm::View east(c);
  expect_vec(east.forward(), 1, 0, 0);
  expect_vec(east.right(), 0, -1, 0);
  c.yaw_deg = 180, c.pitch_deg = -90;
  pm::View down(c);
  expect_vec(down.forward(), 0, 0, -1);
  expect_vec(down.right(), -1, 0, 0);
  expect_vec(down.up(), 0, -1, 0);  // looking down while facing south: the image's up is south
  c.yaw_deg = 0, c.pitch_deg = 30;
  pm::View upward(c);
  expect_vec(upward.forward(), 0, std::cos(M_PI / 6), 0.5);
}

// Fixture: eye at the origin looking north, fovy 90 (tan = 1), 1280 x 720, so K = 360 px.
//   (0, 100, 10): 10 m up at 100 m depth -> 360 * 10 / 100 = 36 px above the centre: (640, 324).
//   (50, 100, 0): 50 m east -> 360 * 0.5 = 180 px right: (820, 360).
TEST(View, ProjectionFixture) {
  pm::Camera c;
  c.x = c.y = c.z = 0;
  c.fovy_deg = 90;
  pm::View v(c);
  EXPECT_NEAR(v.focal_px(), 360.0, 1e-9);
  EXPECT_NEAR(v.tan_half_fovx(), 1280.0 / 720.0, 1e-12);
  double px, py;
  ASSERT_TRUE(v.project({0, 100, 10}, px, py));
  EXPECT_NEAR(px, 640, 1e-9);
  EXPECT_NEAR(py, 324, 1e-9);
  ASSERT_TRUE(v.project({50, 100, 0}, px, py));
  EXPECT_NEAR(px, 820, 1e-9);
  EXPECT_NEAR(py, 360, 1e-9);
  EXPECT_FALSE(v.project({0, -5, 0}, px, py));  // behind the eye
  EXPECT_NEAR(v.depth({3, 100, -7}), 100.0, 1e-12);
  // A vertical segment of 1 m at depth 100 on the axis: exactly K / 100 = 3.6 px, the bound.
  EXPECT_NEAR(v.vertical_factor(), 1.0, 1e-15);
  tt::ScreenProjector glm_cam(c);
  EXPECT_NEAR(glm_cam.vertical_segment_px(0, 100, -0.5, 0.5), 3.6, 1e-9);
  EXPECT_NEAR(v.vertical_error_px_at_depth(100, 1.0), 3.6, 1e-12);
}

// vertical_factor: 1 for a level camera; looking straight down, the radial streak of a vertical
// segment at the image corner: sqrt(tan^2(fovx/2) + tan^2(fovy/2)).
TEST(View, VerticalFactorFixture) {
  pm::Camera c;
  c.fovy_deg = 90, c.width_px = 1280, c.height_px = 720;
  c.pitch_deg = -90;
  const double tx = 1280.0 / 720.0;
  EXPECT_NEAR(pm::View(c).vertical_factor(), std::sqrt(tx * tx + 1.0), 1e-12);
  c.pitch_deg = -30;  // sqrt((0.5 tx)^2 + (cos 30 + 0.5 * 1)^2)
  EXPECT_NEAR(pm::View(c).vertical_factor(), std::hypot(0.5 * tx, std::cos(M_PI / 6) + 0.5), 1e-12);
}

TEST(View, MatricesMatchProjectAndGlm) {
  std::mt19937_64 rng(11);
  std::printf("seed 11\n");
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::size_t compared = 0;
  for (int k = 0; k < 200; ++k) {
    const pm::Camera c = random_camera(rng);
    const pm::View v(c);
    const tt::ScreenProjector g(c);
    const auto V = v.view_matrix(), P = v.projection_matrix();
    for (int i = 0; i < 20; ++i) {
      const pm::Vec3 p{c.x + U(rng) * 5000, c.y + U(rng) * 5000, c.z + U(rng) * 2000};
      double px, py, gx, gy;
      const bool ok = v.project(p, px, py);
      ASSERT_EQ(ok, g.project(p.x, p.y, p.z, gx, gy));
      if (!ok) continue;
      ++compared;
      double e[4] = {0, 0, 0, 0}, clip[4] = {0, 0, 0, 0};
      const double in[4] = {p.x, p.y, p.z, 1};
      for (int col = 0; col < 4; ++col)
        for (int row = 0; row < 4; ++row) e[row] += V[col * 4 + row] * in[col];
      for (int col = 0; col < 4; ++col)
        for (int row = 0; row < 4; ++row) clip[row] += P[col * 4 + row] * e[col];
      const double mx = (clip[0] / clip[3] + 1) * 0.5 * c.width_px,
                   my = (1 - clip[1] / clip[3]) * 0.5 * c.height_px;
      const double tol = 1e-7 * (1 + std::abs(px) + std::abs(py));
      EXPECT_NEAR(px, mx, tol);
      EXPECT_NEAR(py, my, tol);
      EXPECT_NEAR(px, gx, tol);
      EXPECT_NEAR(py, gy, tol);
    }
  }
  EXPECT_GT(compared, 1000u);
}

// contains() agrees with GLM's clip-space test; outside() never discards a point in the frustum.
TEST(View, FrustumPlanesAgreeWithClipSpace) {
  std::mt19937_64 rng(12);
  std::printf("seed 12\n");
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::size_t inside = 0, boxes_out = 0, spheres_out = 0;
  for (int k = 0; k < 200; ++k) {
    pm::Camera c = random_camera(rng);
    c.far_m = c.near_m + 3000;
    const pm::View v(c);
    const tt::ScreenProjector g(c);
    for (int i = 0; i < 200; ++i) {
      const pm::Vec3 p{c.x + (U(rng) - 0.5) * 8000, c.y + (U(rng) - 0.5) * 8000, c.z + (U(rng) - 0.5) * 8000};
      bool near_boundary = false;
      for (const pm::Plane& pl : v.planes()) near_boundary |= std::abs(pl.distance(p)) < 1e-6;
      if (near_boundary) continue;
      ASSERT_EQ(v.contains(p), g.inside(p.x, p.y, p.z));
      inside += v.contains(p);
    }
    for (int i = 0; i < 50; ++i) {
      const pm::Vec3 lo{c.x + (U(rng) - 0.5) * 8000, c.y + (U(rng) - 0.5) * 8000,
                        c.z + (U(rng) - 0.5) * 4000};
      const pm::Box b{lo, {lo.x + U(rng) * 800, lo.y + U(rng) * 800, lo.z + U(rng) * 300}};
      const pm::Sphere s{lo, U(rng) * 500};
      const bool bo = v.outside(b), so = v.outside(s);
      boxes_out += bo, spheres_out += so;
      for (int j = 0; j < 30; ++j) {
        const pm::Vec3 q{b.lo.x + U(rng) * (b.hi.x - b.lo.x), b.lo.y + U(rng) * (b.hi.y - b.lo.y),
                         b.lo.z + U(rng) * (b.hi.z - b.lo.z)};
        if (bo) {
          ASSERT_FALSE(g.inside(q.x, q.y, q.z));
        }
        const double r = s.radius * std::cbrt(U(rng));
        const double th = U(rng) * 2 * M_PI, ph = std::acos(2 * U(rng) - 1);
        const pm::Vec3 w{s.center.x + r * std::sin(ph) * std::cos(th),
                         s.center.y + r * std::sin(ph) * std::sin(th), s.center.z + r * std::cos(ph)};
        if (so) {
          ASSERT_FALSE(g.inside(w.x, w.y, w.z));
        }
      }
    }
  }
  EXPECT_GT(inside, 100u);
  EXPECT_GT(boxes_out, 100u);
  EXPECT_GT(spheres_out, 100u);
}

// The bound of view.cpp holds for every vertical segment in a box, measured by GLM with
// clipping; and it is tight for a level camera (segment at the box's nearest depth, on axis).
TEST(View, VerticalErrorBoundHolds) {
  std::mt19937_64 rng(13);
  std::printf("seed 13\n");
  std::uniform_real_distribution<double> U(0.0, 1.0);
  double worst_ratio = 0;
  std::size_t measured = 0;
  for (int k = 0; k < 300; ++k) {
    const pm::Camera c = random_camera(rng);
    const pm::View v(c);
    const tt::ScreenProjector g(c);
    for (int i = 0; i < 30; ++i) {
      // A box around a point in front of the camera (sometimes reaching behind the eye).
      const double d = std::exp(U(rng) * std::log(5000.0));
      const pm::Vec3 m{c.x + v.forward().x * d + (U(rng) - 0.5) * d,
                       c.y + v.forward().y * d + (U(rng) - 0.5) * d,
                       c.z + v.forward().z * d + (U(rng) - 0.5) * d};
      const double h = U(rng) * d * 0.5, e = U(rng) * 50;
      const pm::Box b{{m.x - h, m.y - h, m.z - h - e}, {m.x + h, m.y + h, m.z + h + e}};
      const pm::Sphere s{m, std::sqrt(3.0) * h + e};
      const double bound_b = v.vertical_error_px(b, e), bound_s = v.vertical_error_px(s, e);
      for (int j = 0; j < 20; ++j) {
        const double x = m.x + (U(rng) - 0.5) * 2 * h, y = m.y + (U(rng) - 0.5) * 2 * h;
        const double z0 = m.z - h + U(rng) * 2 * h, len = U(rng) * e;
        const double px = g.vertical_segment_px(x, y, z0, z0 + (U(rng) < 0.5 ? len : -len));
        if (px == 0) continue;
        ++measured;
        ASSERT_LE(px, bound_b * (1 + 1e-9) + 1e-12) << "box bound";
        ASSERT_LE(px, bound_s * (1 + 1e-9) + 1e-12) << "sphere bound";
        worst_ratio = std::max(worst_ratio, px / bound_b);
      }
    }
  }
  std::printf("vertical segments measured %zu, worst measured / bound %.4f\n", measured, worst_ratio);
  EXPECT_GT(measured, 10000u);
  // Tightness: level camera, a segment centred on the axis at the box's nearest depth.
  pm::Camera c;
  c.x = c.y = c.z = 0, c.fovy_deg = 50;
  const pm::View v(c);
  const pm::Box b{{-10, 300, -2}, {10, 320, 2}};
  EXPECT_NEAR(tt::ScreenProjector(c).vertical_segment_px(0, 300, -2, 2), v.vertical_error_px(b, 4.0), 1e-9);
}

// The ground scale: a world point p is seen at eye + G (p - eye). project() of p is the plain
// view's projection of that seen point; depth_gradient() gives the seen depth; the ray through a
// pixel, pixel_direction(), projects back onto that pixel; the singular values are G's.
TEST(View, GroundScaleShowsTheWorldStretchedAboutTheEye) {
  std::mt19937_64 rng(14);
  std::printf("seed 14\n");
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::size_t compared = 0;
  for (int k = 0; k < 100; ++k) {
    pm::Camera c = random_camera(rng);
    c.ground = {1.1 + 0.1 * U(rng), 0.1 * U(rng), 0.9 + 0.05 * U(rng)};
    pm::Camera plain = c;
    plain.ground = {};
    const pm::View v(c), p0(plain);
    for (int i = 0; i < 20; ++i) {
      const pm::Vec3 p{c.x + U(rng) * 5000, c.y + U(rng) * 5000, c.z + U(rng) * 2000};
      const pm::Vec3 seen{c.x + c.ground.xx * (p.x - c.x) + c.ground.xy * (p.y - c.y),
                          c.y + c.ground.xy * (p.x - c.x) + c.ground.yy * (p.y - c.y), p.z};
      EXPECT_NEAR(v.depth(p), p0.depth(seen), 1e-9 * (1 + std::abs(v.depth(p))));
      double px, py, sx, sy;
      const bool ok = v.project(p, px, py);
      ASSERT_EQ(ok, p0.project(seen, sx, sy));
      if (!ok) continue;
      ++compared;
      EXPECT_NEAR(px, sx, 1e-7 * (1 + std::abs(px)));
      EXPECT_NEAR(py, sy, 1e-7 * (1 + std::abs(py)));
      EXPECT_EQ(v.contains(p), p0.contains(seen));
    }
    // min_depth of a sphere and of a box: no point of it is shallower, and one reaches it.
    const pm::Vec3 m{c.x + U(rng) * 2000, c.y + U(rng) * 2000, c.z + U(rng) * 500};
    const pm::Sphere sphere{m, 300.0};
    const pm::Vec3& f = v.depth_gradient();
    const double lf = std::sqrt(pm::dot(f, f));
    EXPECT_NEAR(v.min_depth(sphere),
                v.depth({m.x - 300 * f.x / lf, m.y - 300 * f.y / lf, m.z - 300 * f.z / lf}),
                1e-9 * (1 + std::abs(v.min_depth(sphere))));
    const pm::Box box{{m.x - 200, m.y - 100, m.z - 50}, {m.x + 200, m.y + 100, m.z + 50}};
    double corner = 1e300;
    for (int j = 0; j < 8; ++j)
      corner = std::min(corner, v.depth({j & 1 ? box.hi.x : box.lo.x, j & 2 ? box.hi.y : box.lo.y,
                                         j & 4 ? box.hi.z : box.lo.z}));
    EXPECT_NEAR(v.min_depth(box), corner, 1e-9 * (1 + std::abs(corner)));
    const double qx = (0.5 + 0.4 * U(rng)) * c.width_px, qy = (0.5 + 0.4 * U(rng)) * c.height_px;
    const pm::Vec3 d = v.pixel_direction(qx, qy);
    EXPECT_NEAR(pm::dot(d, d), 1.0, 1e-12);
    double rx, ry;
    ASSERT_TRUE(v.project({c.x + 100 * d.x, c.y + 100 * d.y, c.z + 100 * d.z}, rx, ry));
    EXPECT_NEAR(rx, qx, 1e-6);
    EXPECT_NEAR(ry, qy, 1e-6);
  }
  EXPECT_GT(compared, 300u);
  const pm::GroundScale g{1.2, 0.1, 0.9};  // eigenvalues 1.05 +- sqrt(0.0325)
  EXPECT_NEAR(g.min_scale(), 1.05 - std::sqrt(0.0325), 1e-12);
  EXPECT_NEAR(g.max_scale(), 1.05 + std::sqrt(0.0325), 1e-12);
  EXPECT_EQ(g.min_distance_scale(), g.min_scale());  // under 1
  EXPECT_EQ(g.max_distance_scale(), g.max_scale());
  const pm::GroundScale up{1.2, 0.0, 1.1}, down{0.8, 0.0, 0.9};
  EXPECT_EQ(up.min_distance_scale(), 1.0);  // z is not scaled: a vertical offset keeps its length
  EXPECT_EQ(down.max_distance_scale(), 1.0);
}

// fit_clip_planes: every point of the box is seen (through the ground scale) between near and
// far, and the planes are tight: near is half the nearest seen distance (unless clamped), far
// about the farthest.
TEST(View, ClipPlanesHoldTheBoxAsSeen) {
  std::mt19937_64 rng(15);
  std::uniform_real_distribution<double> U(-1.0, 1.0), U01(0.0, 1.0);
  for (int k = 0; k < 200; ++k) {
    pm::Camera c = random_camera(rng);
    if (k % 2) c.ground = {1.0 + 0.3 * U(rng), 0.2 * U(rng), 1.0 + 0.3 * U(rng)};
    const pm::Vec3 m{c.x + U(rng) * 20000, c.y + U(rng) * 20000, c.z + U(rng) * 3000};
    const pm::Box box{{m.x - 3000 * U01(rng), m.y - 3000 * U01(rng), m.z - 500 * U01(rng)},
                      {m.x + 3000 * U01(rng), m.y + 3000 * U01(rng), m.z + 500 * U01(rng)}};
    pm::fit_clip_planes(c, box);
    ASSERT_NO_THROW(pm::View{c});
    const auto seen_distance = [&](const pm::Vec3& p) {
      const double dx = p.x - c.x, dy = p.y - c.y;
      return std::hypot(c.ground.xx * dx + c.ground.xy * dy, c.ground.xy * dx + c.ground.yy * dy, p.z - c.z);
    };
    double nearest = 1e300, farthest = 0.0;
    for (int i = 0; i < 4000; ++i) {
      // Corners, the point nearest the eye in world metres, and points all over the box.
      pm::Vec3 p{box.lo.x + (box.hi.x - box.lo.x) * U01(rng), box.lo.y + (box.hi.y - box.lo.y) * U01(rng),
                 box.lo.z + (box.hi.z - box.lo.z) * U01(rng)};
      if (i < 8) p = {i & 1 ? box.hi.x : box.lo.x, i & 2 ? box.hi.y : box.lo.y, i & 4 ? box.hi.z : box.lo.z};
      if (i == 8)
        p = {std::clamp(c.x, box.lo.x, box.hi.x), std::clamp(c.y, box.lo.y, box.hi.y),
             std::clamp(c.z, box.lo.z, box.hi.z)};
      const double d = seen_distance(p);
      nearest = std::min(nearest, d), farthest = std::max(farthest, d);
    }
    EXPECT_LE(c.near_m, std::max(0.05, 0.5 * nearest) * (1 + 1e-12)) << k;
    EXPECT_GE(c.far_m, farthest) << k;
    // Tight: within the ground scale's spread of the sampled extremes.
    const double spread = c.ground.max_distance_scale() / c.ground.min_distance_scale();
    if (0.5 * nearest > 0.05 && 0.5 * nearest < 1000.0) {
      EXPECT_GE(c.near_m, 0.5 * nearest / spread) << k;
    }
    EXPECT_LE(c.far_m, std::max(2.0 * c.near_m, 1.01 * farthest * spread + 1.0) * (1 + 1e-12)) << k;
  }
}

TEST(View, DistanceToBox) {
  const pm::Box b{{0, 0, 0}, {10, 20, 5}};
  EXPECT_EQ(pm::distance_to_box({5, 5, 1}, b), 0.0);
  EXPECT_DOUBLE_EQ(pm::distance_to_box({13, 24, 5}, b), 5.0);  // 3-4-5 off a vertical edge
  EXPECT_DOUBLE_EQ(pm::distance_to_box({5, 5, 105}, b), 100.0);
  EXPECT_DOUBLE_EQ(pm::max_distance_to_box({0, 0, 0}, b), std::sqrt(100.0 + 400.0 + 25.0));
}

TEST(View, ToleranceAsFractionOfScreenHeight) {
  EXPECT_DOUBLE_EQ(pm::tolerance_px_from_fraction(0.002, 720), 1.44);
  EXPECT_DOUBLE_EQ(pm::tolerance_px_from_fraction(1.0 / 1080, 1080), 1.0);
  EXPECT_THROW(pm::tolerance_px_from_fraction(0.0, 720), std::invalid_argument);
  EXPECT_THROW(pm::tolerance_px_from_fraction(0.01, 0), std::invalid_argument);
}

TEST(View, BadCameraIsRejectedWithTheFieldName) {
  auto msg = [](pm::Camera c) -> std::string {
    try {
      pm::View v(c);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  pm::Camera c;
  c.pitch_deg = 91;
  EXPECT_NE(msg(c).find("pitch_deg"), std::string::npos);
  c = {}, c.fovy_deg = 180;
  EXPECT_NE(msg(c).find("fovy_deg"), std::string::npos);
  c = {}, c.width_px = 0;
  EXPECT_NE(msg(c).find("width_px"), std::string::npos);
  c = {}, c.near_m = 0;
  EXPECT_NE(msg(c).find("near_m"), std::string::npos);
  c = {}, c.far_m = c.near_m;
  EXPECT_NE(msg(c).find("far_m"), std::string::npos);
  c = {}, c.x = NAN;
  EXPECT_NE(msg(c).find("position"), std::string::npos);
  c = {}, c.yaw_deg = INFINITY;
  EXPECT_NE(msg(c).find("yaw_deg"), std::string::npos);
  c = {}, c.ground = {3.0, 0.0, 1.0};
  EXPECT_NE(msg(c).find("ground scale"), std::string::npos);
  c = {}, c.ground = {1.0, 1.0, 1.0};  // singular
  EXPECT_NE(msg(c).find("ground scale"), std::string::npos);
  c = {}, c.ground = {1.0, NAN, 1.0};
  EXPECT_NE(msg(c).find("ground scale"), std::string::npos);
}
