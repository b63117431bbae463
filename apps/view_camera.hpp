// The camera of 'terralod view' (of --input and of both kinds of --db): --camera, --tau and --size
// parsed into one pm::Camera, the clip planes that enclose a terrain's bounding box, the camera
// between two others (--morph-to), and the camera as --stats writes it.
//
// Usage:
//   ViewCamera v = view_camera_options(a);   // --camera X,Y,Z,YAW,PITCH,FOVY --tau T --size WxH
//   pm::Camera b = camera_option(a, "--morph-to", v.camera);  // same syntax, v's image size
//   pm::Camera c = interpolate_camera(v.camera, b, /*alpha=*/0.5);
//   fit_clip_to_box(v.camera, lo, hi);       // the terrain's box, world metres
//
// Contract: the conventions of render/camera.hpp (world metres, x east, y north, z up; yaw
// clockwise from north, pitch above the horizon). Bad values are UsageErrors naming the option.
#pragma once

#include <glm/glm.hpp>
#include <string>

#include "cli_common.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::cli {

/// What 'terralod view' is asked to see.
struct ViewCamera {
  pm::Camera camera;  ///< --camera and --size; near_m and far_m are pm::Camera's defaults
  double tau = 1.0;   ///< --tau, pixels
};

/// Parses --camera (six comma-separated finite numbers, PITCH in [-90, 90], FOVY in (0, 180)),
/// then --tau (tau_option) and --size (image_size_option, default 1024x768): the first bad one
/// in that order is the UsageError.
ViewCamera view_camera_options(const Args& a);

/// Parses the value of `option` with the syntax and checks of --camera (UsageErrors naming
/// `option`); image size and clip planes are those of `like`.
pm::Camera camera_option(const Args& a, const std::string& option, const pm::Camera& like);

/// The camera at `alpha` in [0, 1] between `a` (0) and `b` (1): position, PITCH and FOVY linear,
/// YAW linear the shorter way round (through north when that is shorter; ties go clockwise), so
/// it may leave [0, 360); exactly `a` at 0 and `b` at 1. Image size and clip planes are a's.
pm::Camera interpolate_camera(const pm::Camera& a, const pm::Camera& b, double alpha);

/// pm::fit_clip_planes(c, the box [lo, hi]): the clip planes of `c` around the box (world
/// metres) as `c` sees it through its ground scale (set c.ground first); near may be as close
/// as 0.05 m because reverse-Z keeps depth precise even so close.
void fit_clip_to_box(pm::Camera& c, const glm::dvec3& lo, const glm::dvec3& hi);

/// The fields of --stats about what was asked: "camera" {x, y, z, yaw, pitch, fovy, near, far, ground_xx,
/// ground_xy, ground_yy (the ground scale, pm/view.hpp)},
/// then "width", "height" (pixels) and "tau".
void write_view_json(JsonWriter& j, const pm::Camera& c, double tau);

}  // namespace terralod::cli
