// View: camera frame, frustum planes, projection, and the bound on projected vertical segments.
//
// Derivation of the bound (used by selective refinement for its guarantee). Write a point in
// camera coordinates (r, u, z) = ((p - eye).right, (p - eye).up, (p - eye).forward) and its
// tangent coordinates X = r / z, Y = u / z; it projects to (W/2 + K X, H/2 - K Y). The world's
// vertical direction has camera coordinates (0, cos p, sin p) (no roll; p = pitch). Moving the
// point up by ds changes r by 0, u by cos p ds and z by sin p ds, so
//     dX = -X sin p ds / z,   dY = (cos p - Y sin p) ds / z,
// and its image moves by  K / z * sqrt((X sin p)^2 + (cos p - Y sin p)^2) ds.
// The square root is the norm of an affine function of (X, Y), hence convex; on the image
// rectangle |X| <= tan(fovx/2), |Y| <= tan(fovy/2) its maximum, vertical_factor(), is reached at
// a corner. Take a vertical segment of length e inside a volume whose depth is >= z_V. The part
// of it inside the frustum is one segment (the frustum is convex) of length <= e, every point
// of which has depth >= max(z_V, near) and lies inside the image rectangle. Integrating the
// speed along it, the image of that part is at most
//     e * K * vertical_factor() / max(z_V, near)    pixels.
// For a level camera the factor is exactly 1 and the bound is attained by a segment at depth
// z_V (a vertical segment is then parallel to the image plane); looking straight down it is
// the tangent of the half-diagonal of the image, the radial streak of a segment off the axis.
#include "terralod/pm/view.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace terralod::pm {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Vec3 add(const Vec3& a, const Vec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 mul(const Vec3& a, double s) { return {a.x * s, a.y * s, a.z * s}; }
Vec3 normalized(const Vec3& a) { return mul(a, 1.0 / std::sqrt(dot(a, a))); }
Vec3 absv(const Vec3& a) { return {std::abs(a.x), std::abs(a.y), std::abs(a.z)}; }

void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("view: ") + what);
}

}  // namespace

double GroundScale::min_scale() const {
  const double m = 0.5 * (xx + yy), r = std::hypot(0.5 * (xx - yy), xy);
  return m - r;
}

double GroundScale::max_scale() const {
  const double m = 0.5 * (xx + yy), r = std::hypot(0.5 * (xx - yy), xy);
  return m + r;
}

double GroundScale::min_distance_scale() const { return std::min(1.0, min_scale()); }

double GroundScale::max_distance_scale() const { return std::max(1.0, max_scale()); }

double distance_to_box(const Vec3& p, const Box& b) {
  assert(b.lo.x <= b.hi.x && b.lo.y <= b.hi.y && b.lo.z <= b.hi.z && "distance_to_box needs lo <= hi");
  const double dx = std::max({b.lo.x - p.x, 0.0, p.x - b.hi.x}),
               dy = std::max({b.lo.y - p.y, 0.0, p.y - b.hi.y}),
               dz = std::max({b.lo.z - p.z, 0.0, p.z - b.hi.z});
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

double max_distance_to_box(const Vec3& p, const Box& b) {
  const double fx = std::max(std::abs(p.x - b.lo.x), std::abs(p.x - b.hi.x)),
               fy = std::max(std::abs(p.y - b.lo.y), std::abs(p.y - b.hi.y)),
               fz = std::max(std::abs(p.z - b.lo.z), std::abs(p.z - b.hi.z));
  return std::sqrt(fx * fx + fy * fy + fz * fz);
}

void fit_clip_planes(Camera& c, const Box& b) {
  const Vec3 eye{c.x, c.y, c.z};
  const double nearest = c.ground.min_distance_scale() * distance_to_box(eye, b);
  const double farthest = c.ground.max_distance_scale() * max_distance_to_box(eye, b);
  c.near_m = std::clamp(0.5 * nearest, 0.05, 1000.0);
  c.far_m = std::max(c.near_m * 2.0, 1.01 * farthest + 1.0);
}

double tolerance_px_from_fraction(double fraction, int height_px) {
  if (!(fraction > 0.0) || !std::isfinite(fraction))
    throw std::invalid_argument("tolerance: the fraction of the screen height must be > 0");
  if (height_px < 1) throw std::invalid_argument("tolerance: height_px must be >= 1");
  return fraction * height_px;
}

View::View(const Camera& c) : cam_(c) {
  require(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z), "camera position must be finite");
  require(std::isfinite(c.yaw_deg), "yaw_deg must be finite");
  require(c.pitch_deg >= -90.0 && c.pitch_deg <= 90.0, "pitch_deg must be in [-90, 90]");
  require(c.fovy_deg > 0.0 && c.fovy_deg < 180.0, "fovy_deg must be in (0, 180)");
  require(c.width_px >= 1 && c.height_px >= 1, "width_px and height_px must be >= 1");
  require(c.near_m > 0.0 && std::isfinite(c.near_m), "near_m must be > 0");
  require(c.far_m > c.near_m && std::isfinite(c.far_m), "far_m must be finite and > near_m");
  const GroundScale& g = c.ground;
  require(std::isfinite(g.xx) && std::isfinite(g.xy) && std::isfinite(g.yy) && g.min_scale() >= 0.5 &&
              g.max_scale() <= 2.0,
          "the ground scale must be finite with singular values in [0.5, 2]");
  eye_ = {c.x, c.y, c.z};
  const double yaw = c.yaw_deg * kDeg, pitch = c.pitch_deg * kDeg;
  const double cp = std::cos(pitch), sp = std::sin(pitch);
  fwd_ = {std::sin(yaw) * cp, std::cos(yaw) * cp, sp};
  right_ = {std::cos(yaw), -std::sin(yaw), 0.0};
  up_ = cross(right_, fwd_);
  tany_ = std::tan(0.5 * c.fovy_deg * kDeg);
  tanx_ = tany_ * double(c.width_px) / double(c.height_px);
  focal_ = double(c.height_px) / (2.0 * tany_);
  // Camera coordinates of world up: (0, up.z, forward.z) = (0, cos p, sin p).
  const double cu = up_.z, cf = fwd_.z;
  vfactor_ = 0.0;
  for (double X : {-tanx_, tanx_})
    for (double Y : {-tany_, tany_}) vfactor_ = std::max(vfactor_, std::hypot(X * cf, cu - Y * cf));
  // Camera coordinates of p are dot(p - eye, G' axis): G' is symmetric. A plane of the seen
  // space with normal n has the world normal G' n, normalised here so that distance() is metres.
  dfwd_ = g.apply(fwd_), dright_ = g.apply(right_), dup_ = g.apply(up_);
  const double lf = std::sqrt(dot(dfwd_, dfwd_)), e = dot(eye_, dfwd_);
  planes_[0] = {mul(dfwd_, 1.0 / lf), (-e - c.near_m) / lf};
  planes_[1] = {mul(dfwd_, -1.0 / lf), (e + c.far_m) / lf};
  const Vec3 side[4] = {add(dright_, mul(dfwd_, tanx_)), add(mul(dright_, -1.0), mul(dfwd_, tanx_)),
                        add(dup_, mul(dfwd_, tany_)), add(mul(dup_, -1.0), mul(dfwd_, tany_))};
  for (int k = 0; k < 4; ++k) {
    const Vec3 n = normalized(side[k]);
    planes_[2 + k] = {n, -dot(n, eye_)};
  }
}

Vec3 View::pixel_direction(double px, double py) const {
  const double X = (px - 0.5 * cam_.width_px) / focal_, Y = (0.5 * cam_.height_px - py) / focal_;
  return normalized(cam_.ground.inverse_apply(add(fwd_, add(mul(right_, X), mul(up_, Y)))));
}

bool View::project(const Vec3& p, double& px, double& py) const {
  const Vec3 d = sub(p, eye_);
  const double z = dot(d, dfwd_);
  if (!(z > 0.0)) return false;
  px = 0.5 * cam_.width_px + focal_ * dot(d, dright_) / z;
  py = 0.5 * cam_.height_px - focal_ * dot(d, dup_) / z;
  return true;
}

bool View::contains(const Vec3& p) const {
  for (const Plane& pl : planes_)
    if (pl.distance(p) < 0.0) return false;
  return true;
}

bool View::outside(const Box& b) const {
  const Vec3 c = mul(add(b.lo, b.hi), 0.5), h = mul(sub(b.hi, b.lo), 0.5);
  for (const Plane& pl : planes_)
    if (pl.distance(c) + dot(absv(pl.n), h) < 0.0) return true;
  return false;
}

bool View::outside(const Sphere& s) const {
  for (const Plane& pl : planes_)
    if (pl.distance(s.center) + s.radius < 0.0) return true;
  return false;
}

double View::min_depth(const Box& b) const {
  const Vec3 c = mul(add(b.lo, b.hi), 0.5), h = mul(sub(b.hi, b.lo), 0.5);
  return dot(sub(c, eye_), dfwd_) - dot(absv(dfwd_), h);
}

double View::min_depth(const Sphere& s) const {
  return dot(sub(s.center, eye_), dfwd_) - s.radius * std::sqrt(dot(dfwd_, dfwd_));
}

double View::vertical_error_px_at_depth(double min_depth_m, double error_m) const {
  return error_m * focal_ * vfactor_ / std::max(min_depth_m, cam_.near_m);
}

double View::vertical_error_px(const Box& b, double error_m) const {
  return vertical_error_px_at_depth(min_depth(b), error_m);
}

double View::vertical_error_px(const Sphere& s, double error_m) const {
  return vertical_error_px_at_depth(min_depth(s), error_m);
}

std::array<double, 16> View::view_matrix() const {
  // Rows: G' right, G' up, -G' forward; translation -R eye. Column-major: m[col * 4 + row].
  const Vec3 r[3] = {dright_, dup_, mul(dfwd_, -1.0)};
  std::array<double, 16> m{};
  for (int row = 0; row < 3; ++row) {
    m[0 * 4 + row] = r[row].x;
    m[1 * 4 + row] = r[row].y;
    m[2 * 4 + row] = r[row].z;
    m[3 * 4 + row] = -dot(r[row], eye_);
  }
  m[15] = 1.0;
  return m;
}

std::array<double, 16> View::projection_matrix() const {
  const double n = cam_.near_m, f = cam_.far_m;
  std::array<double, 16> m{};
  m[0] = 1.0 / tanx_;
  m[5] = 1.0 / tany_;
  m[10] = (f + n) / (n - f);
  m[11] = -1.0;
  m[14] = 2.0 * f * n / (n - f);
  return m;
}

}  // namespace terralod::pm
