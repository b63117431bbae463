// terralod-fly's window: a GLFW window with flight controls (mouse and keys, terrain following,
// recording and replay of a path, screenshots), texture-layer switches and a highlight lens, map
// objects placed on the drawn terrain (picked by a click, switched by O), and the heads-up
// display over every frame.
#include <GLFW/glfw3.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "flight_objects.hpp"
#include "flight_path.hpp"
#include "fly_cli.hpp"
#include "fly_hud.hpp"
#include "fly_modes.hpp"
#include "fly_pipeline.hpp"
#include "object_drawing.hpp"
#include "terralod/pm/camera_path.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/hud.hpp"
#include "terralod/render/image.hpp"

namespace terralod::fly {

using namespace terralod::cli;
using Clock = std::chrono::steady_clock;

namespace {

// The ground point seen through normalised screen position (sx, sy) in [-1,1]^2 (y up): march
// along the ray in steps of one grid spacing, then bisect; nullopt when it leaves the terrain's
// range or misses it within the far plane.
std::optional<std::array<double, 2>> ground_point(const LodSource& t, const pm::Camera& c, double sx,
                                                  double sy) {
  const double yr = c.yaw_deg * std::numbers::pi / 180, pr = c.pitch_deg * std::numbers::pi / 180;
  const glm::dvec3 f(std::sin(yr) * std::cos(pr), std::cos(yr) * std::cos(pr), std::sin(pr));
  const glm::dvec3 right(std::cos(yr), -std::sin(yr), 0.0);
  const glm::dvec3 up = glm::cross(right, f);
  const double th = std::tan(0.5 * c.fovy_deg * std::numbers::pi / 180);
  const glm::dvec3 d =
      glm::normalize(f + sx * th * double(c.width_px) / double(c.height_px) * right + sy * th * up);
  const glm::dvec3 o(c.x, c.y, c.z);
  const Extent& e = t.extent();
  const double step = std::max(1e-3, std::min(e.transform.spacing_x(), e.transform.spacing_y()));
  double a = 0;
  for (double s = step; s <= c.far_m; s += step) {
    const glm::dvec3 p = o + s * d;
    if (p.z <= t.ground(p.x, p.y)) {
      double lo = a, hi = s;
      for (int i = 0; i < 40; ++i) {
        const double m = 0.5 * (lo + hi);
        const glm::dvec3 q = o + m * d;
        (q.z <= t.ground(q.x, q.y) ? hi : lo) = m;
      }
      const glm::dvec3 q = o + hi * d;
      return std::array<double, 2>{q.x, q.y};
    }
    if (p.z < e.zmin - 1.0 || (d.z >= 0 && p.z > e.zmax + 1.0)) return std::nullopt;
    a = s;
  }
  return std::nullopt;
}

// Shows a LayeredRenderer frame in the window: its framebuffer is still bound after draw();
// blit it to the default framebuffer (GL 3.0 entry points through GLFW).
void present_layered(int w, int h) {
  using GetIntegerv = void (*)(GLenum, GLint*);
  using BindFramebuffer = void (*)(GLenum, GLuint);
  using BlitFramebuffer =
      void (*)(GLint, GLint, GLint, GLint, GLint, GLint, GLint, GLint, GLbitfield, GLenum);
  static const auto get = reinterpret_cast<GetIntegerv>(glfwGetProcAddress("glGetIntegerv"));
  static const auto bind = reinterpret_cast<BindFramebuffer>(glfwGetProcAddress("glBindFramebuffer"));
  static const auto blit = reinterpret_cast<BlitFramebuffer>(glfwGetProcAddress("glBlitFramebuffer"));
  if (!get || !bind || !blit) throw std::runtime_error("no glBlitFramebuffer in this OpenGL context");
  constexpr GLenum kFramebufferBinding = 0x8CA6, kRead = 0x8CA8, kDraw = 0x8CA9;
  GLint fbo = 0;
  get(kFramebufferBinding, &fbo);
  bind(kRead, GLuint(fbo));
  bind(kDraw, 0);
  blit(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
}

// The mouse cursor's position in the window as fractions of its size: (0, 0) top left, (1, 1)
// bottom right.
std::array<double, 2> cursor_in_window(GLFWwindow* gw) {
  double mx = 0, my = 0;
  int ww = 1, wh = 1;
  glfwGetCursorPos(gw, &mx, &my);
  glfwGetWindowSize(gw, &ww, &wh);
  return {mx / ww, my / wh};
}

struct Controls {
  double speed = 80.0;  // m/s along the view direction
  double climb = 0.0;   // m/s
  bool follow = true, recording = false;
};

}  // namespace

int run_window(const Args& a) {
  const auto [w, h] = parse_size(a);
  std::optional<LayerSetup> layers = layer_setup(a);  // usage errors before the terrain loads
  std::optional<blocks::ObjectPlacer> objects = fly_objects(a);
  const std::unique_ptr<LodSource> t = open_terrain(a);
  const Extent& ext = t->extent();
  std::vector<pm::Camera> replay;
  double replay_clearance = 0.0;  // a track's (flight_path.hpp)
  if (a.has("--replay")) {
    pm::CameraPathOptions po;
    po.width_px = w, po.height_px = h;
    FlightPath flight = read_flight_path(a, "--replay", a.get("--db"), po);
    replay = std::move(flight.cameras);
    replay_clearance = flight.clearance_m;
  }
  const long long max_frames =
      a.get_int("--frames", replay.empty() ? -1 : (long long)replay.size(), -1, 1LL << 40);
  const std::string record_path = a.get("--record", "flight.csv");
  const double clearance = a.get_double("--clearance", 30.0);
  const std::size_t budget = std::size_t(a.get_int("--budget", 50000, 100, 100000000));

  render::WindowOptions wo;
  wo.width = w, wo.height = h, wo.title = "terralod-fly";
  auto win = render::WindowContext::create(wo);
  Pipeline p(*t, *win);
  std::optional<ObjectDrawing> drawing;  // the objects' icons, labels, lines and shapes
  if (objects) drawing.emplace(*win, *objects);
  ObjectDrawStats drawn;
  p.wireframe = a.has("--wireframe");
  if (layers) {
    p.set_layers(*win, &*layers);
    if (layers->lens_radius() <= 0) {  // no --lens: H shows one of 4% of the terrain's width
      layers->set_lens_radius(0.04 * ext.side_x());
    }
  }
  render::Hud hud(*win);
  if (!hud.has_font())
    std::fprintf(stderr, "terralod-fly: no heads-up display: %s\n", hud.font_error().c_str());
  GLFWwindow* gw = win->glfw_window();

  // Start above the south-west quarter, heading north-east, looking slightly down.
  const auto [sx, sy] = ext.transform.to_world(ext.width * 0.25, ext.height * 0.75);
  pm::Camera cam;
  cam.x = sx, cam.y = sy, cam.z = t->ground(sx, sy) + 4 * clearance;
  cam.yaw_deg = 45, cam.pitch_deg = -12, cam.fovy_deg = 60;
  cam.width_px = w, cam.height_px = h;
  Controls ctl;
  std::vector<pm::Camera> recorded;
  std::vector<std::string> messages;
  bool prev_keys[GLFW_KEY_LAST + 1] = {};
  auto pressed = [&](int key) {  // edge-triggered
    const bool down = glfwGetKey(gw, key) == GLFW_PRESS;
    const bool edge = down && !prev_keys[key];
    prev_keys[key] = down;
    return edge;
  };

  // A click: the left button released within 0.25 s of its press picks at the release point.
  bool left_down = false, clicked = false;
  Clock::time_point pressed_at{};
  std::array<double, 2> click{0.0, 0.0};
  std::vector<std::string> picked;  // the last pick's HUD lines
  double fps = 0;
  long long frame = 0;
  bool screenshot_written = false;
  const auto start = Clock::now();
  auto last = start;
  FrameRecord r;
  while (!win->should_close() && (max_frames < 0 || frame < max_frames)) {
    win->poll_events();
    const auto now = Clock::now();
    const double dt = std::clamp(std::chrono::duration<double>(now - last).count(), 1e-4, 0.1);
    last = now;
    fps = fps == 0 ? 1.0 / dt : 0.95 * fps + 0.05 / dt;
    const double time_s = replay.empty() ? std::chrono::duration<double>(now - start).count() : frame / 60.0;

    if (glfwGetKey(gw, GLFW_KEY_ESCAPE) == GLFW_PRESS) break;
    pm::RefinementOptions o = t->options();
    bool options_changed = false;
    if (pressed(GLFW_KEY_T)) ctl.follow = !ctl.follow;
    if (pressed(GLFW_KEY_G)) o.morph_seconds = o.morph_seconds > 0 ? 0.0 : 0.3, options_changed = true;
    if (pressed(GLFW_KEY_X)) p.wireframe = !p.wireframe;
    if (pressed(GLFW_KEY_L)) p.frozen = !p.frozen;
    if (layers) {
      for (int k = 0; k < int(layers->styles().size()); ++k)
        if (pressed(GLFW_KEY_1 + k))
          layers->styles()[std::size_t(k)].enabled = !layers->styles()[std::size_t(k)].enabled;
      if (pressed(GLFW_KEY_H)) layers->lens().enabled = !layers->lens().enabled;
    }
    if (objects && pressed(GLFW_KEY_O)) {  // all object layers off when any is on, else all on
      bool any = false;
      for (const blocks::ObjectLayerInfo& l : objects->layers()) any |= objects->layer_visible(l.name);
      for (const blocks::ObjectLayerInfo& l : objects->layers()) objects->set_layer_visible(l.name, !any);
    }
    const bool left = glfwGetMouseButton(gw, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
    if (left && !left_down) pressed_at = now;
    if (!left && left_down && now - pressed_at < std::chrono::milliseconds(250))
      clicked = true, click = cursor_in_window(gw);
    left_down = left;
    if (pressed(GLFW_KEY_B))
      o.target_triangles = o.target_triangles ? 0 : t->budget_share(budget), options_changed = true;
    if (pressed(GLFW_KEY_LEFT_BRACKET))
      o.tolerance_px = std::max(0.05, o.tolerance_px / 1.25), options_changed = true;
    if (pressed(GLFW_KEY_RIGHT_BRACKET))
      o.tolerance_px = std::min(64.0, o.tolerance_px * 1.25), options_changed = true;
    if (options_changed) t->set_options(o);
    if (pressed(GLFW_KEY_C)) {
      ctl.recording = !ctl.recording;
      if (!ctl.recording && !recorded.empty()) {
        pm::write_camera_path(recorded, record_path);
        std::printf("recorded %zu frames to %s\n", recorded.size(), record_path.c_str());
        recorded.clear();
      }
    }
    const bool shot = pressed(GLFW_KEY_P);

    if (replay.empty()) {
      // Flight model: steer with the mouse (left button) or the arrow keys.
      double yaw_rate = 0, pitch_rate = 0;
      if (glfwGetMouseButton(gw, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS) {
        const std::array<double, 2> m = cursor_in_window(gw);
        yaw_rate = 90.0 * (m[0] - 0.5) * 2.0;
        pitch_rate = -60.0 * (m[1] - 0.5) * 2.0;
      }
      if (glfwGetKey(gw, GLFW_KEY_LEFT) == GLFW_PRESS) yaw_rate -= 45;
      if (glfwGetKey(gw, GLFW_KEY_RIGHT) == GLFW_PRESS) yaw_rate += 45;
      if (glfwGetKey(gw, GLFW_KEY_UP) == GLFW_PRESS) pitch_rate += 30;
      if (glfwGetKey(gw, GLFW_KEY_DOWN) == GLFW_PRESS) pitch_rate -= 30;
      if (glfwGetKey(gw, GLFW_KEY_W) == GLFW_PRESS) ctl.speed = std::min(5000.0, ctl.speed * std::exp(dt));
      if (glfwGetKey(gw, GLFW_KEY_S) == GLFW_PRESS) ctl.speed = std::max(1.0, ctl.speed * std::exp(-dt));
      ctl.climb = 0;
      if (glfwGetKey(gw, GLFW_KEY_R) == GLFW_PRESS) ctl.climb = std::max(20.0, 0.5 * ctl.speed);
      if (glfwGetKey(gw, GLFW_KEY_F) == GLFW_PRESS) ctl.climb = -std::max(20.0, 0.5 * ctl.speed);
      cam.yaw_deg = std::fmod(cam.yaw_deg + yaw_rate * dt + 360.0, 360.0);
      cam.pitch_deg = std::clamp(cam.pitch_deg + pitch_rate * dt, -89.0, 89.0);
      const double yr = cam.yaw_deg * std::numbers::pi / 180, pr = cam.pitch_deg * std::numbers::pi / 180;
      cam.x += ctl.speed * dt * std::sin(yr) * std::cos(pr);
      cam.y += ctl.speed * dt * std::cos(yr) * std::cos(pr);
      cam.z += ctl.speed * dt * std::sin(pr) + ctl.climb * dt;
      if (ctl.follow) cam.z = std::max(cam.z, t->ground(cam.x, cam.y) + clearance);
    } else {
      cam = replay[std::size_t(std::min<long long>(frame, (long long)replay.size() - 1))];
      if (t->runtime()) keep_clear(cam, *t->runtime(), replay_clearance);  // a track's eye above the ground
    }
    int fw = 1, fh = 1;
    glfwGetFramebufferSize(gw, &fw, &fh);
    cam.width_px = std::max(1, fw), cam.height_px = std::max(1, fh);
    t->fit_camera(cam);
    if (ctl.recording) recorded.push_back(cam);
    if (layers && layers->lens().enabled) {  // the lens follows the centre, or the mouse (right button)
      double sx = 0, sy = 0;
      if (glfwGetMouseButton(gw, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS) {
        const std::array<double, 2> m = cursor_in_window(gw);
        sx = 2.0 * m[0] - 1.0, sy = 1.0 - 2.0 * m[1];
      }
      if (const auto g = ground_point(*t, cam, sx, sy)) layers->move_lens((*g)[0], (*g)[1]);
    }

    r = p.frame(cam, time_s, /*wait=*/false);
    if (objects && t->runtime()) {
      objects->place(*t->runtime(), pm::View(cam));
      drawn = drawing->draw(p.frame_source(), *objects, *t->runtime(), pm::View(cam));
      if (clicked) {
        const auto hit =
            objects->pick_pixel(*t->runtime(), click[0] * cam.width_px, click[1] * cam.height_px);
        picked = pick_lines(hit, *objects);
        clicked = false;
      }
    }
    const pm::RefinementOptions now_o = t->options();
    std::vector<std::string> lines = lod_lines(r, now_o, /*timings=*/true);
    lines[0] = strf("%5.1f fps   ", fps) + lines[0];
    lines.insert(lines.end(), {strf("speed %.0f m/s   height %.0f m above ground%s", ctl.speed,
                                    cam.z - t->ground(cam.x, cam.y), ctl.follow ? " (following)" : ""),
                               strf("%s%s%s%s", now_o.morph_seconds > 0 ? "geomorphs" : "no geomorphs",
                                    p.wireframe ? "  wireframe" : "", p.frozen ? "  LOD FROZEN" : "",
                                    ctl.recording ? "  REC" : "")});
    if (layers) {
      std::string on = "layers";
      for (std::size_t k = 0; k < layers->styles().size(); ++k)
        on += strf("  %zu:%s%s", k + 1, layers->styles()[k].name.c_str(),
                   layers->styles()[k].enabled ? "" : "(off)");
      lines.push_back(on + (layers->lens().enabled ? "  lens" : ""));
    }
    if (objects) {
      lines.push_back(objects_line(*objects, /*timings=*/true));
      lines.push_back(drawn_line(drawn, /*timings=*/true));
      lines.insert(lines.end(), picked.begin(), picked.end());
    }
    hud.set_lines(lines);
    if (p.drew_layered())
      present_layered(cam.width_px, cam.height_px);
    else
      p.renderer().present(/*swap=*/false);
    hud.draw();
    const bool last_frame = max_frames >= 0 && frame + 1 == max_frames;
    if (shot || (last_frame && a.has("--screenshot"))) {
      // The window's picture with its heads-up display, read before the swap.
      const std::string name = shot ? strf("screenshot_%05lld.png", frame) : a.get("--screenshot");
      render::write_png(p.renderer().read_window_color(/*blit=*/false), name);
      std::printf("wrote %s\n", name.c_str());
      screenshot_written |= !shot;
    }
    win->swap_buffers();
    ++frame;
  }
  if (ctl.recording && !recorded.empty()) {
    pm::write_camera_path(recorded, record_path);
    std::printf("recorded %zu frames to %s\n", recorded.size(), record_path.c_str());
  }
  if (a.has("--screenshot") && !screenshot_written) {
    render::write_png(p.read_color(), a.get("--screenshot"));
    std::printf("wrote %s\n", a.get("--screenshot").c_str());
  }
  std::printf("flew %lld frames, last: %zu triangles, drawn within %.3f px\n", frame, r.lod.triangles,
              r.lod.bound_px);
  return 0;
}

}  // namespace terralod::fly
