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

ViewCamera view_camera_options(const Args& a) {
  const std::vector<double> c = parse_numbers("--camera", a.get("--camera"), 6);
  if (c[4] < -90.0 || c[4] > 90.0) throw UsageError("--camera: PITCH must be in [-90, 90] degrees");
  if (c[5] <= 0.0 || c[5] >= 180.0) throw UsageError("--camera: FOVY must be in (0, 180) degrees");
  ViewCamera v;
  v.tau = tau_option(a);
  const auto [width, height] = image_size_option(a, {1024, 768});
  v.camera = pm::Camera{c[0], c[1], c[2], c[3], c[4], c[5], width, height};
  return v;
}

void fit_clip_to_box(pm::Camera& c, const glm::dvec3& lo, const glm::dvec3& hi) {
  c.near_m = std::clamp(0.5 * render::distance_to_box(render::camera_position(c), lo, hi), 0.05, 1000.0);
  c.far_m =
      std::max(c.near_m * 2.0, 1.01 * render::max_distance_to_box(render::camera_position(c), lo, hi) + 1.0);
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
                             {"far", c.far_m}})
    j.field(k, v);
  j.end_object();
  j.field("width", c.width_px);
  j.field("height", c.height_px);
  j.field("tau", tau);
}

}  // namespace terralod::cli
