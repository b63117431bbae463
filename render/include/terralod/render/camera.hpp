// A terrain camera (position, yaw, pitch, field of view) and the matrices and rays it defines.
//
// Usage:
//   terralod::render::Camera cam;   // = terralod::pm::Camera (pm/view.hpp)
//   cam.x = 500000.0, cam.y = 4200000.0, cam.z = 1800.0;   // world metres (x east, y north, z up)
//   cam.yaw_deg = 90.0;      // looking east
//   cam.pitch_deg = -20.0;   // 20 degrees below the horizon
//   cam.fovy_deg = 60.0;  cam.width_px = 1280;  cam.height_px = 720;
//   glm::dmat4 v = terralod::render::view_matrix(cam);          // world -> eye
//   glm::dmat4 p = terralod::render::projection_matrix(cam);    // eye -> clip (GL, z in [-1,1])
//   glm::dvec3 ray = terralod::render::pixel_ray(cam, 640.0, 360.0);  // through the image centre
//   double k = terralod::render::focal_length_pixels(cam);      // pixels per metre at 1 m
//
// Conventions (shared with the CLI and the pm/ view-dependent runtime):
//   - World frame: x east, y north, z up, metres, doubles. Matrices are computed in doubles;
//     callers turn them into floats only after translating to a mesh origin (see
//     TerrainRenderer), never with absolute UTM-sized coordinates.
//   - yaw_deg: degrees clockwise from north; 0 looks along +y, 90 along +x. Any value.
//   - pitch_deg: degrees above the horizon, in [-90, 90]; negative looks down.
//   - fovy_deg: vertical field of view across the image height, in (0, 180).
//   - near_m, far_m: clip distances along the view axis, metres, 0 < near_m < far_m.
//   - width_px, height_px: the viewport in pixels, >= 1. Image coordinates (px, py) are pixels with
//     (0,0) the top-left corner of the image; pixel (i, j) has its centre at (i+0.5, j+0.5).
//   - The eye frame is OpenGL's: the camera looks along -z_eye, x_eye is image right, y_eye
//     image up. Roll is always zero: image right is horizontal (cos yaw, -sin yaw, 0).
// Violating a range is a programming error (assert); functions never clamp silently.
#pragma once

#include <glm/glm.hpp>

#include "terralod/pm/view.hpp"

namespace terralod::render {

/// The camera is pm::Camera (one camera type from the selection to the GPU): eye x, y, z,
/// yaw, pitch, fovy, width_px x height_px, near_m and far_m, as documented above.
using Camera = pm::Camera;

/// The eye position as a glm vector.
inline glm::dvec3 camera_position(const Camera& c) { return {c.x, c.y, c.z}; }

/// Unit view direction in the seen space (the world itself when c.ground is the identity; see
/// pm/view.hpp's ground scale): (sin yaw cos pitch, cos yaw cos pitch, sin pitch).
glm::dvec3 camera_forward(const Camera& c);
/// Unit image-right direction in the seen space: (cos yaw, -sin yaw, 0).
glm::dvec3 camera_right(const Camera& c);
/// Unit image-up direction in the seen space: right x forward.
glm::dvec3 camera_up(const Camera& c);

/// World -> eye (OpenGL convention, looking along -z), through the ground scale: the eye
/// coordinates of p are those of the seen point eye + G' (p - eye), as pm::View's.
glm::dmat4 view_matrix(const Camera& c);
/// Eye -> clip, OpenGL depth convention (near -> -1, far -> +1 in NDC).
glm::dmat4 projection_matrix(const Camera& c);
/// Eye -> clip for reverse-Z with glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE): near -> 1,
/// far -> 0. With a float depth buffer this keeps the relative depth error near 2^-24 at
/// every distance, where the standard mapping loses precision with distance squared.
glm::dmat4 reverse_z_projection_matrix(const Camera& c);

/// K = height / (2 tan(fovy/2)): pixels spanned by a 1 m segment at 1 m distance on the
/// optical axis, seen side-on.
double focal_length_pixels(const Camera& c);
/// An upper bound on the pixels per radian of the view anywhere in the image:
/// K (1 + r^2 / K^2), r = the half-diagonal of the image in pixels. A segment of length E at
/// distance d subtends at most E/d radians, so it covers at most E * this / d pixels anywhere
/// on screen (E * K / d is exact only at the image centre).
double max_pixels_per_radian(const Camera& c);

/// Unit world direction of the ray from the camera through image point (px, py) (pixels,
/// top-left origin; a pixel's centre is at +0.5): the seen ray pulled back through G'^-1.
glm::dvec3 pixel_ray(const Camera& c, double px, double py);

}  // namespace terralod::render
