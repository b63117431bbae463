// The camera of 'terralod view' and its clip planes (see view_camera.hpp).
#include "view_camera.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "terralod/render/camera.hpp"

namespace terralod::cli {

namespace {

std::vector<double> parse_numbers(const std::string& option, const std::string& text, std::size_t count) {
  std::vector<double> v;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = text.find(',', start);
    const std::string item =
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    char* end = nullptr;
    errno = 0;
    const double x = item.empty() ? NAN : std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || errno == ERANGE || !std::isfinite(x))
      throw UsageError("option '" + option + "' needs " + std::to_string(count) +
                       " comma-separated finite numbers, not '" + text + "'");
    v.push_back(x);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (v.size() != count)
    throw UsageError("option '" + option + "' needs " + std::to_string(count) +
                     " comma-separated numbers, not " + std::to_string(v.size()) + " ('" + text + "')");
  return v;
}

}  // namespace

pm::Camera camera_option(const Args& a, const std::string& option, const pm::Camera& like) {
  const std::vector<double> c = parse_numbers(option, a.get(option), 6);
  if (c[4] < -90.0 || c[4] > 90.0) throw UsageError(option + ": PITCH must be in [-90, 90] degrees");
  if (c[5] <= 0.0 || c[5] >= 180.0) throw UsageError(option + ": FOVY must be in (0, 180) degrees");
  pm::Camera cam = like;
  cam.x = c[0], cam.y = c[1], cam.z = c[2], cam.yaw_deg = c[3], cam.pitch_deg = c[4], cam.fovy_deg = c[5];
  return cam;
}

ViewCamera view_camera_options(const Args& a) {
  // --camera first, then --tau and --size (the order of the UsageErrors).
  const pm::Camera c = camera_option(a, "--camera", pm::Camera{});
  ViewCamera v;
  v.tau = tau_option(a);
  const auto [width, height] = image_size_option(a, {1024, 768});
  v.camera = c;
  v.camera.width_px = width, v.camera.height_px = height;
  return v;
}

pm::Camera interpolate_camera(const pm::Camera& a, const pm::Camera& b, double alpha) {
  if (alpha <= 0.0) return a;
  if (alpha >= 1.0) {
    pm::Camera c = b;
    c.width_px = a.width_px, c.height_px = a.height_px, c.near_m = a.near_m, c.far_m = a.far_m;
    return c;
  }
  pm::Camera c = a;
  c.x = std::lerp(a.x, b.x, alpha);
  c.y = std::lerp(a.y, b.y, alpha);
  c.z = std::lerp(a.z, b.z, alpha);
  c.pitch_deg = std::lerp(a.pitch_deg, b.pitch_deg, alpha);
  c.fovy_deg = std::lerp(a.fovy_deg, b.fovy_deg, alpha);
  // The turn from a's yaw to b's in (-180, 180]: the shorter way round.
  double turn = std::fmod(b.yaw_deg - a.yaw_deg, 360.0);
  if (turn > 180.0) turn -= 360.0;
  if (turn <= -180.0) turn += 360.0;
  c.yaw_deg = a.yaw_deg + alpha * turn;
  return c;
}

void fit_clip_to_box(pm::Camera& c, const glm::dvec3& lo, const glm::dvec3& hi) {
  pm::fit_clip_planes(c, pm::Box{{lo.x, lo.y, lo.z}, {hi.x, hi.y, hi.z}});
}

void write_view_json(JsonWriter& j, const pm::Camera& c, double tau) {
  j.begin_object("camera");
  for (const auto& [k, v] : {std::pair{"x", c.x},
                             {"y", c.y},
                             {"z", c.z},
                             {"yaw", c.yaw_deg},
                             {"pitch", c.pitch_deg},
                             {"fovy", c.fovy_deg},
                             {"near", c.near_m},
                             {"far", c.far_m},
                             {"ground_xx", c.ground.xx},
                             {"ground_xy", c.ground.xy},
                             {"ground_yy", c.ground.yy}})
    j.field(k, v);
  j.end_object();
  j.field("width", c.width_px);
  j.field("height", c.height_px);
  j.field("tau", tau);
}

}  // namespace terralod::cli
