// Camera conventions of terralod turned into view and projection matrices and pixel rays.
#include "terralod/render/camera.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>

namespace terralod::render {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

void check(const Camera& c) {
  assert(c.pitch_deg >= -90.0 && c.pitch_deg <= 90.0 && "Camera::pitch_deg must be in [-90, 90]");
  assert(c.fovy_deg > 0.0 && c.fovy_deg < 180.0 && "Camera::fovy_deg must be in (0, 180)");
  assert(c.near_m > 0.0 && c.far_m > c.near_m && "Camera needs 0 < near_m < far_m");
  assert(c.width_px >= 1 && c.height_px >= 1 && "Camera viewport must be at least 1 x 1");
  (void)c;
}

double aspect(const Camera& c) { return double(c.width_px) / double(c.height_px); }

/// The perspective projection of `c` with clip z = a z_e + b (the depth convention's part) and
/// w = -z_e.
glm::dmat4 perspective(const Camera& c, double a, double b) {
  const double t = 1.0 / std::tan(0.5 * c.fovy_deg * kDeg);
  glm::dmat4 p(0.0);
  p[0][0] = t / aspect(c);
  p[1][1] = t;
  p[2][2] = a;
  p[2][3] = -1.0;
  p[3][2] = b;
  return p;
}

}  // namespace

glm::dvec3 camera_forward(const Camera& c) {
  const double yaw = c.yaw_deg * kDeg, pitch = c.pitch_deg * kDeg;
  return {std::sin(yaw) * std::cos(pitch), std::cos(yaw) * std::cos(pitch), std::sin(pitch)};
}

glm::dvec3 camera_right(const Camera& c) {
  const double yaw = c.yaw_deg * kDeg;
  return {std::cos(yaw), -std::sin(yaw), 0.0};
}

glm::dvec3 camera_up(const Camera& c) { return glm::cross(camera_right(c), camera_forward(c)); }

glm::dmat4 view_matrix(const Camera& c) {
  check(c);
  // The seen space's axes pulled back through the ground scale (pm/view.hpp): rows G' r, G' u,
  // -G' f, so that the eye coordinates of p are those of eye + G' (p - eye).
  const glm::dvec3 r = c.ground.apply(camera_right(c)), u = c.ground.apply(camera_up(c)),
                   f = c.ground.apply(camera_forward(c)), p = camera_position(c);
  glm::dmat4 v(1.0);  // column-major: v[column][row]
  v[0][0] = r.x, v[1][0] = r.y, v[2][0] = r.z, v[3][0] = -glm::dot(r, p);
  v[0][1] = u.x, v[1][1] = u.y, v[2][1] = u.z, v[3][1] = -glm::dot(u, p);
  v[0][2] = -f.x, v[1][2] = -f.y, v[2][2] = -f.z, v[3][2] = glm::dot(f, p);
  return v;
}

glm::dmat4 projection_matrix(const Camera& c) {
  check(c);
  const double n = c.near_m, f = c.far_m;
  return perspective(c, (f + n) / (n - f), 2.0 * f * n / (n - f));
}

glm::dmat4 reverse_z_projection_matrix(const Camera& c) {
  check(c);
  // clip z = A z_e + B, w = -z_e; depth = z/w: 1 at z_e = -near, 0 at z_e = -far.
  const double n = c.near_m, f = c.far_m;
  return perspective(c, n / (f - n), n * f / (f - n));
}

double focal_length_pixels(const Camera& c) {
  check(c);
  return 0.5 * double(c.height_px) / std::tan(0.5 * c.fovy_deg * kDeg);
}

double max_pixels_per_radian(const Camera& c) {
  const double k = focal_length_pixels(c);
  const double r2 = 0.25 * (double(c.width_px) * c.width_px + double(c.height_px) * c.height_px);
  return k * (1.0 + r2 / (k * k));
}

glm::dvec3 pixel_ray(const Camera& c, double px, double py) {
  check(c);
  const double t = std::tan(0.5 * c.fovy_deg * kDeg);
  const double nx = 2.0 * px / c.width_px - 1.0, ny = 1.0 - 2.0 * py / c.height_px;
  return glm::normalize(c.ground.inverse_apply(camera_forward(c) + camera_right(c) * (nx * t * aspect(c)) +
                                               camera_up(c) * (ny * t)));
}

}  // namespace terralod::render
