// terralod-fly --headless: the frames of a camera path (--path, or a built-in circular flight)
// rendered offscreen through OSMesa, each waiting for its loads (reproducible), written as PNGs
// (optionally with the HUD, and the drawn meshes as PLY) and frames.csv, with a summary of the
// run's times and of the guarantee as measured.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "flight_log.hpp"
#include "flight_objects.hpp"
#include "flight_path.hpp"
#include "fly_cli.hpp"
#include "fly_hud.hpp"
#include "fly_modes.hpp"
#include "fly_pipeline.hpp"
#include "object_drawing.hpp"
#include "terralod/pm/camera_path.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/timing.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/hud.hpp"
#include "terralod/render/image.hpp"

namespace terralod::fly {

namespace fs = std::filesystem;
using namespace terralod::cli;

namespace {

// The built-in flight's circle, in world metres, flown counter-clockwise from its east point,
// one lap in 20 s (1200 frames at 60 fps) or slower, so that the speed is at most 500 m/s (large
// terrains).
struct Circle {
  double cx = 0, cy = 0, radius = 0;
  // Height above the ground: 200 m, or a quarter of the radius on a terrain so small that from
  // 200 m, looking 15 degrees down, it would lie below the view (a 100 m patch of lidar).
  double clearance() const { return std::min(200.0, 0.25 * radius); }
  double angle(double frame) const {
    return 2.0 * std::numbers::pi * frame / std::max(1200.0, 60.0 * 2.0 * std::numbers::pi * radius / 500.0);
  }
};

// The height bin of `ceiling()` heights: 1 m, or 1/1000 of the terrain's height range when larger.
long long height_bin(const LodSource& t, double z) {
  const Extent& e = t.extent();
  return std::llround(z / std::max(1.0, 1e-3 * (e.zmax - e.zmin)));
}

// Flat ground, as LodSource::ceiling sees it without loading anything: the height bin that holds
// the most of a 32 x 32 lattice of points over the terrain, when it holds a quarter of them or
// more: the sea of a coastal tile (Kauai fills a tenth of N22W160), a lake, a filled void.
// nullopt when there is none.
std::optional<long long> flat_bin(const LodSource& t) {
  const Extent& e = t.extent();
  std::map<long long, int> count;
  for (int j = 0; j < 32; ++j)
    for (int i = 0; i < 32; ++i) {
      const auto [x, y] =
          e.transform.to_world((e.width - 1) * (i + 0.5) / 32.0, (e.height - 1) * (j + 0.5) / 32.0);
      ++count[height_bin(t, t.ceiling(x, y))];
    }
  const auto mode = std::max_element(count.begin(), count.end(),
                                     [](const auto& a, const auto& b) { return a.second < b.second; });
  if (mode->second * 4 < 32 * 32) return std::nullopt;
  return mode->first;
}

// Share of the flight's `frames` frames along the circle over the flat ground of bin `flat`
// (flat_bin), judged at 64 of them.
double flat_share(const LodSource& t, const Circle& c, int frames, long long flat) {
  int n = 0;
  for (int k = 0; k < 64; ++k) {
    const double a = c.angle(frames * k / 64.0);
    n += height_bin(t, t.ceiling(c.cx + c.radius * std::cos(a), c.cy + c.radius * std::sin(a))) == flat;
  }
  return n / 64.0;
}

// The circle of radius 30% of the extent around the terrain's centre, unless more than a quarter
// of the flight's `frames` frames along it are over flat ground (flat_bin). Then the circle of
// radius 30%, 20% or 10% of the extent, centred on a 9 x 9 lattice of the places where it fits
// in the terrain, with the smallest share of flat ground (ties: the larger circle, then the
// earlier centre): a demo flight shows the land. With --db, ceiling() knows the highest sample of
// each block only, so a block that holds some land counts as land.
Circle default_circle(const LodSource& t, int frames) {
  const Extent& e = t.extent();
  const double side = std::min(e.side_x(), e.side_y());
  const auto [cx, cy] = e.centre();
  Circle best{cx, cy, 0.3 * side};
  const std::optional<long long> flat = flat_bin(t);
  if (!flat) return best;
  double best_flat = flat_share(t, best, frames, *flat);
  if (best_flat <= 0.25) return best;
  for (const double f : {0.3, 0.2, 0.1}) {
    const double r = f * side;
    // Centres from r to side - r in from the terrain's edges, in grid units along each axis.
    const double mx = r / e.transform.spacing_x(), my = r / e.transform.spacing_y();
    for (int j = 0; j <= 8; ++j)
      for (int i = 0; i <= 8; ++i) {
        const auto [x, y] = e.transform.to_world(mx + (e.width - 1 - 2.0 * mx) * i / 8.0,
                                                 my + (e.height - 1 - 2.0 * my) * j / 8.0);
        const Circle c{x, y, r};
        if (const double share = flat_share(t, c, frames, *flat); share < best_flat)
          best = c, best_flat = share;
      }
  }
  return best;
}

// The flight used when no --path is given: `frames` frames along `circle` (default_circle()),
// circle.clearance() above the ground under the camera (with --db: above the highest sample of
// the block under it, as no block is loaded yet), looking along the path and 15 degrees down.
std::vector<pm::Camera> default_flight(const LodSource& t, const Circle& circle, int frames, int w, int h) {
  const auto [cx, cy, radius] = circle;
  std::vector<pm::Camera> path;
  for (int k = 0; k < frames; ++k) {
    const double a = circle.angle(k);
    pm::Camera c;
    c.x = cx + radius * std::cos(a), c.y = cy + radius * std::sin(a);
    c.z = t.ceiling(c.x, c.y) + circle.clearance();
    // Moving counter-clockwise: the direction of motion is (-sin a, cos a); yaw from north.
    c.yaw_deg = std::atan2(-std::sin(a), std::cos(a)) * 180.0 / std::numbers::pi;
    c.pitch_deg = -15.0, c.fovy_deg = 60.0, c.width_px = w, c.height_px = h;
    path.push_back(c);
  }
  return path;
}

}  // namespace

int run_headless(const Args& a) {
  const auto [w, h] = parse_size(a);
  const std::string out = a.get("--out", "fly_out");
  pm::CameraPathOptions po;
  po.width_px = w, po.height_px = h;
  std::vector<pm::Camera> path;
  double clearance = 0.0;  // a track's (flight_path.hpp)
  if (a.has("--path")) {
    FlightPath flight = read_flight_path(a, "--path", a.get("--db"), po);
    path = std::move(flight.cameras);
    clearance = flight.clearance_m;
  }
  const bool dump = a.has("--dump-meshes"), hud = a.has("--hud");
  std::optional<render::TextRasterizer> hud_text;  // opened at the first frame with the HUD
  std::optional<LayerSetup> layers = layer_setup(a);
  std::optional<blocks::ObjectPlacer> objects = fly_objects(a);
  const std::unique_ptr<LodSource> t = open_terrain(a);
  if (path.empty()) {
    const int frames = int(a.get_int("--frames", 240, 1, 1000000));
    const Circle circle = default_circle(*t, frames);
    path = default_flight(*t, circle, frames, w, h);
    std::printf(
        "path: built-in flight, %zu frames (a circle of radius %.0f m around x %.0f, y %.0f, %.3g m "
        "above the ground, with --db above its block's highest sample, looking 15 degrees down)\n",
        path.size(), circle.radius, circle.cx, circle.cy, circle.clearance());
  }
  const long long frames = a.get_int("--frames", (long long)path.size(), 1, (long long)path.size());
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec || !fs::is_directory(out)) throw std::runtime_error(out + ": cannot create the output folder");
  auto ctx = render::create_offscreen_context({w, h});
  Pipeline p(*t, *ctx);
  std::optional<ObjectDrawing> drawing;  // the objects' icons, labels, lines and shapes
  if (objects) drawing.emplace(*ctx, *objects);
  ObjectDrawStats drawn;
  p.wireframe = a.has("--wireframe");
  if (layers) {
    layers->wait_loaded(/*timeout_ms=*/600000);  // every frame sees every layer: deterministic
    p.set_layers(*ctx, &*layers);
  }
  FlightLog log(out, /*drawing=*/true);  // the columns of 'terralod fly', then the drawing's
  ProgressBar bar("render " + std::to_string(frames) + " frames");
  std::vector<double> update_ms, update_cpu_ms, frame_ms, triangles, resident, placed;
  std::array<std::vector<double>, 5> drawn_per_frame;  // the ObjectDrawStats counts, per frame
  double worst_bound = 0, wait_ms = 0;                 // worst bound / tau of the frames with nothing missing
  std::size_t complete = 0, lifted = 0;
  for (long long k = 0; k < frames; ++k) {
    pm::Camera c = path[std::size_t(k)];
    if (clearance > 0 && t->runtime()) {  // a track's eye above the ground (tracks need --db)
      if (k == 0) {                       // (the first frame is drawn once beforehand, to have one)
        t->fit_camera(c);
        p.frame(c, 0.0, /*wait=*/true);
      }
      lifted += keep_clear(c, *t->runtime(), clearance);
    }
    t->fit_camera(c);
    const FrameRecord r = p.frame(c, double(k) / 60.0, /*wait=*/true);
    if (objects && t->runtime()) {
      objects->place(*t->runtime(), pm::View(c));
      placed.push_back(double(objects->placed().size()));
      drawn = drawing->draw(p.frame_source(), *objects, *t->runtime(), pm::View(c));
      for (std::size_t i = 0; i < 5; ++i)
        drawn_per_frame[i].push_back(
            double(std::array{drawn.icons, drawn.labels_shown, drawn.label_candidates, drawn.line_triangles,
                              drawn.shape_triangles}[i]));
    }
    update_ms.push_back(r.lod.update_ms);
    update_cpu_ms.push_back(r.lod.update_cpu_ms);
    frame_ms.push_back(r.lod.update_ms + r.upload_ms + r.draw_ms);
    triangles.push_back(double(r.lod.triangles));
    if (r.streamed) resident.push_back(double(r.lod.blocks_resident));
    if (r.lod.missing_in_view == 0) {
      ++complete;
      worst_bound = std::max(worst_bound, r.lod.bound_px / r.lod.tolerance_px);
    }
    wait_ms += r.wait_ms;
    FlightRow row{std::size_t(k), double(k) / 60.0, r.camera, r.lod};
    row.vertices = r.vertices, row.draw_ms = r.draw_ms, row.upload_ms = r.upload_ms, row.wait_ms = r.wait_ms;
    row.texture_bytes = r.texture_bytes, row.texture_patches = r.texture_patches;
    row.textures_from_parent = r.textures_from_parent;
    log.row(row);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05lld", k);
    render::Image img = p.read_color();
    if (hud) {
      std::vector<std::string> lines = lod_lines(r, t->options(), /*timings=*/false);
      lines[0] = strf("frame %lld   ", k) + lines[0];
      if (objects)
        lines.insert(lines.end(),
                     {objects_line(*objects, /*timings=*/false), drawn_line(drawn, /*timings=*/false)});
      if (!hud_text) hud_text.emplace();
      overlay_text(img, hud_text->rasterize(lines), render::HudOptions{}.margin);
    }
    render::write_png(img, (fs::path(out) / (std::string(name) + ".png")).string());
    if (dump)
      pm::write_mesh(render::world_mesh(p.draw_mesh()),
                     (fs::path(out) / (std::string(name) + ".ply")).string());
    bar.update(double(k + 1) / double(frames));
  }
  bar.finish();
  log.commit();
  std::printf("headless: %lld frames %dx%d -> %s (PNG%s, frames.csv); tau %g px\n", frames, w, h, out.c_str(),
              dump ? ", PLY" : "", t->options().tolerance_px);
  std::printf(
      "headless: frame (update + upload + draw) median %.2f ms, p99 %.2f ms; update median %.3f ms, p99 %.3f "
      "ms (thread CPU: median %.3f ms, p99 %.3f ms); triangles median %.0f, max %.0f\n",
      pm::quantile(frame_ms, 0.5), pm::quantile(frame_ms, 0.99), pm::quantile(update_ms, 0.5),
      pm::quantile(update_ms, 0.99), pm::quantile(update_cpu_ms, 0.5), pm::quantile(update_cpu_ms, 0.99),
      pm::quantile(triangles, 0.5), pm::quantile(triangles, 1.0));
  if (!placed.empty())
    std::printf("headless: objects in view median %.0f, max %.0f (of %zu)\n", pm::quantile(placed, 0.5),
                pm::quantile(placed, 1.0), objects->objects().size());
  if (!placed.empty()) {
    const auto& d = drawn_per_frame;
    std::printf(
        "headless: objects drawn per frame (median): %.0f icons, %.0f of %.0f labels (decluttered), %.0f "
        "line "
        "and %.0f shape triangles\n",
        pm::quantile(d[0], 0.5), pm::quantile(d[1], 0.5), pm::quantile(d[2], 0.5), pm::quantile(d[3], 0.5),
        pm::quantile(d[4], 0.5));
  }
  if (!resident.empty())
    std::printf("headless: blocks resident median %.0f, max %.0f; waited %s for block loads in all\n",
                pm::quantile(resident, 0.5), pm::quantile(resident, 1.0), format_duration(wait_ms).c_str());
  if (clearance > 0)
    std::printf("headless: the track's eye was lifted to %g m above the ground in %zu of %lld frames\n",
                clearance, lifted, frames);
  // The last line: the guarantee as measured on this run, and the update's cost.
  std::printf(
      "headless: guarantee: %zu of %lld frames had nothing missing, and in those the drawn mesh was within "
      "%.3f x tau (bound / tau <= 1 is the promise); update thread CPU median %.3f ms, p99 %.3f ms\n",
      complete, frames, worst_bound, pm::quantile(update_cpu_ms, 0.5), pm::quantile(update_cpu_ms, 0.99));
  return 0;
}

}  // namespace terralod::fly
