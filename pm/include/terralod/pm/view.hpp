// View parameters (camera pose, lens, viewport), frustum planes, and conservative bounds on the
// projected size, in pixels, of vertical error segments inside a bounding volume.
//
// Usage:
//   terralod::pm::Camera cam;                   // world frame: x east, y north, z up, metres
//   cam.x = 5000; cam.y = 2000; cam.z = 1800;   // eye position
//   cam.yaw_deg = 90;                           // clockwise from north: looks along +x
//   cam.pitch_deg = -20;                        // 20 degrees below the horizon
//   cam.fovy_deg = 60; cam.width_px = 1280; cam.height_px = 720;
//   terralod::pm::View view(cam);               // throws std::invalid_argument on bad values
//   double tau = terralod::pm::tolerance_px_from_fraction(/*fraction=*/0.002, cam.height_px);
//   terralod::pm::Box b{{0, 0, 100}, {30, 30, 140}};
//   if (!view.outside(b) && view.vertical_error_px(b, /*error_m=*/2.0) > tau) { /* refine */ }
//
// Conventions (the `terralod view` command uses them too):
//   - World frame: x east, y north, z up, metres (the frame of Heightfield::transform).
//   - yaw_deg: degrees clockwise from north; 0 looks along +y, 90 along +x. Any finite value.
//   - pitch_deg: degrees above the horizon, in [-90, 90]; negative looks down.
//   - No roll: the image's horizontal axis is always level. forward = (sin yaw cos pitch,
//     cos yaw cos pitch, sin pitch), right = (cos yaw, -sin yaw, 0), up = right x forward.
//   - fovy_deg: vertical field of view across the image height, in (0, 180). Pixels are
//     square, so tan(fovx / 2) = tan(fovy / 2) * width / height.
//   - Image coordinates: pixel x grows to the right from 0 at the left edge, pixel y grows
//     downwards from 0 at the top edge; the optical axis hits (width / 2, height / 2). A point
//     at depth z (distance along forward) and offsets (r, u) along right and up projects to
//     (width / 2 + K r / z, height / 2 - K u / z), K = focal_px() = height / (2 tan(fovy / 2)).
//   - The view frustum is the set of points with near_m <= depth <= far_m that project inside
//     the image rectangle (borders included).
//   - Screen-space tolerance tau is in pixels; the PM paper's tolerance, a fraction of the
//     screen height, converts with tolerance_px_from_fraction().
//
// The error bound (vertical_error_px), derived in view.cpp: a vertical segment of length e
// whose part inside the frustum lies in a volume V with smallest depth z_V projects to at most
//     e * K * vertical_factor() / max(z_V, near_m)   pixels,
// where vertical_factor() = max over the image corners of sqrt((sin p X)^2 + (cos p - sin p Y)^2)
// (X, Y the corner's tangent coordinates, p the pitch): 1 for a level camera, at most
// sqrt(1 + tan^2(fovx/2) + tan^2(fovy/2)) in general.
//
// Ground scale (Camera::ground, identity by default): a symmetric 2 x 2 map G of horizontal
// offsets about the eye, applied before the view. The camera sees a world point p at
//     eye + G' (p - eye),   G' = [G 0; 0 1]  (x, y mapped by G, z unchanged),
// and every member below (depth, projection, planes, matrices, the bound) is of that seen
// point. A runtime sets G to its frame's ground scale at the eye (blocks::TerrainRuntime::
// fit_camera): a map projection's x, y are metres only at its true-scale points, and G makes
// offsets near the eye ground metres again, so a continent-wide frame looks true where the
// camera is. G is positive definite, so the seen world is the world stretched by at most its
// singular values about the eye; the bound's derivation holds unchanged in the seen space
// (vertical segments stay vertical and keep their length, as G' leaves z alone).
//
// Memory: View is about 500 bytes; nothing is allocated.
#pragma once

#include <array>
#include <cstdint>

namespace terralod::pm {

/// The ground scale of a camera (see above): the symmetric matrix [xx xy; xy yy], positive
/// definite with singular values in [0.5, 2] (View refuses others). Identity by default.
struct GroundScale {
  double xx = 1.0, xy = 0.0, yy = 1.0;
  bool operator==(const GroundScale&) const = default;
  /// G' v: (xx x + xy y, xy x + yy y, z).
  template <class V>
  V apply(const V& v) const {
    return V{xx * v.x + xy * v.y, xy * v.x + yy * v.y, v.z};
  }
  /// G'^-1 v.
  template <class V>
  V inverse_apply(const V& v) const {
    const double det = xx * yy - xy * xy;
    return V{(yy * v.x - xy * v.y) / det, (xx * v.y - xy * v.x) / det, v.z};
  }
  /// Smallest and largest singular value of G (its eigenvalues: G is symmetric).
  double min_scale() const;
  double max_scale() const;
  /// A seen distance is the world distance times a factor in [min_distance_scale(),
  /// max_distance_scale()]: G' scales horizontal offsets by G's singular values and leaves z
  /// alone, so these are min(1, min_scale()) and max(1, max_scale()).
  double min_distance_scale() const;
  double max_distance_scale() const;
};

/// Camera pose and lens; see the conventions above. Defaults are a valid 1280 x 720 view.
struct Camera {
  double x = 0.0, y = 0.0, z = 1000.0;  ///< eye position, world metres (finite)
  double yaw_deg = 0.0;                 ///< clockwise from north (finite)
  double pitch_deg = 0.0;               ///< above the horizon, [-90, 90]
  double fovy_deg = 60.0;               ///< vertical field of view, (0, 180)
  int width_px = 1280;                  ///< viewport width, >= 1
  int height_px = 720;                  ///< viewport height, >= 1
  double near_m = 1.0;                  ///< near clip depth, > 0
  double far_m = 1.0e6;                 ///< far clip depth, > near_m
  GroundScale ground;                   ///< identity unless a runtime fits it (see above)
};

struct Vec3 {
  double x = 0.0, y = 0.0, z = 0.0;
};
inline double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 sub(const Vec3& a, const Vec3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

/// Axis-aligned box in world metres; lo <= hi componentwise.
struct Box {
  Vec3 lo, hi;
};

/// Sphere in world metres; radius >= 0.
struct Sphere {
  Vec3 center;
  double radius = 0.0;
};

/// Plane n . p + d = 0 with unit normal n pointing into the frustum.
struct Plane {
  Vec3 n;
  double d = 0.0;
  double distance(const Vec3& p) const { return dot(n, p) + d; }
};

/// Euclidean distance from p to the nearest point of the box (0 inside), and to its farthest
/// point (a corner). lo <= hi per axis.
double distance_to_box(const Vec3& p, const Box& b);
double max_distance_to_box(const Vec3& p, const Box& b);

/// Sets camera.near_m and far_m so that the whole box (the terrain's, world metres) lies between
/// them as seen through camera.ground: near is half the smallest seen distance from the eye to
/// the box, clamped to [0.05, 1000] m, far 1.01 times the largest (to its farthest corner) plus
/// 1 m, and at least twice near. A runtime calls it with the ground scale already set
/// (blocks::TerrainRuntime::fit_camera).
void fit_clip_planes(Camera& camera, const Box& box);

/// Converts the PM paper's tolerance (a fraction of the screen height, > 0) to pixels.
double tolerance_px_from_fraction(double fraction, int height_px);

class View {
 public:
  /// Validates the camera (std::invalid_argument naming the bad field) and derives the frame.
  explicit View(const Camera& camera);

  const Camera& camera() const { return cam_; }
  const Vec3& eye() const { return eye_; }
  /// The camera's axes in the seen space (unit): the view direction, the image's right
  /// (horizontal) and its up (right x forward).
  const Vec3& forward() const { return fwd_; }
  const Vec3& right() const { return right_; }
  const Vec3& up() const { return up_; }
  /// depth(p) = dot(p - eye, depth_gradient()): G' forward, forward itself when the ground
  /// scale is the identity.
  const Vec3& depth_gradient() const { return dfwd_; }
  /// Unit world direction of the ray from the eye through pixel (px, py) (image coordinates
  /// as above: a pixel's centre is at +0.5): G'^-1 of the seen ray.
  Vec3 pixel_direction(double px, double py) const;
  /// K: pixels per unit of tangent, height / (2 tan(fovy / 2)).
  double focal_px() const { return focal_; }
  double tan_half_fovx() const { return tanx_; }
  double tan_half_fovy() const { return tany_; }
  /// Largest image-plane speed factor of a vertical direction inside the frustum (see above).
  double vertical_factor() const { return vfactor_; }

  /// The six frustum planes: near, far, left, right, bottom, top (inward unit normals).
  const std::array<Plane, 6>& planes() const { return planes_; }

  /// Distance of p along forward from the eye (negative behind the eye).
  double depth(const Vec3& p) const { return dot(p, dfwd_) - dot(eye_, dfwd_); }
  /// Pixel coordinates of p (conventions above); false when depth(p) <= 0.
  bool project(const Vec3& p, double& px, double& py) const;
  /// True when p is inside the closed frustum.
  bool contains(const Vec3& p) const;

  /// True when the whole box (sphere) lies strictly outside one frustum plane.
  bool outside(const Box& b) const;
  bool outside(const Sphere& s) const;
  /// Smallest depth of any point of the box (sphere).
  double min_depth(const Box& b) const;
  double min_depth(const Sphere& s) const;
  /// Upper bound, in pixels, of the image length of the part inside the frustum of any vertical
  /// segment of length <= error_m (>= 0) that lies in the box (sphere). Finite for every input:
  /// a box that reaches the eye gets the bound at the near plane.
  double vertical_error_px(const Box& b, double error_m) const;
  double vertical_error_px(const Sphere& s, double error_m) const;
  /// Same bound for a volume whose smallest depth is known.
  double vertical_error_px_at_depth(double min_depth_m, double error_m) const;

  /// Column-major 4x4 matrices in OpenGL conventions (camera looks down -z; clip space
  /// -w <= x, y, z <= w), so that clip = projection * view * (x, y, z, 1) and the pixel of a
  /// point is ((ndc.x + 1) / 2 * width, (1 - ndc.y) / 2 * height), equal to project().
  std::array<double, 16> view_matrix() const;
  std::array<double, 16> projection_matrix() const;

 private:
  Camera cam_;
  Vec3 eye_, fwd_, right_, up_;
  Vec3 dfwd_, dright_, dup_;  // G' of the axes: camera coordinates of p are dot(p - eye, .)
  double focal_ = 0, tanx_ = 0, tany_ = 0, vfactor_ = 1;
  std::array<Plane, 6> planes_{};
};

}  // namespace terralod::pm
