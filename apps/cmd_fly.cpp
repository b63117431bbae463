// terralod fly: the headless flight runner. Replays a camera path over a block database
// through blocks::TerrainRuntime (the tree from its root, PM blocks, loading with prefetch,
// seams, geomorphs) without drawing, and writes per-frame statistics and, optionally, every
// frame's drawn mesh.
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "flight_log.hpp"
#include "flight_objects.hpp"
#include "flight_path.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/camera_path.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/timing.hpp"

namespace terralod::cli {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

}  // namespace

CommandSpec fly_spec() {
  CommandSpec s;
  s.name = "fly";
  s.summary = "Replay a camera path over a block database headlessly; per-frame statistics as CSV.";
  s.description =
      "Runs the terrain runtime (blocks::TerrainRuntime) without drawing, one frame per row of\n"
      "--path (60 frames per second): the approximation tree from its root over the whole terrain\n"
      "(frustum culling, coarse grid / TIN / non-regular-grid nodes where their error on screen\n"
      "meets tau), PM blocks below them refined view-dependently, background loading by priority\n"
      "with flight-path prefetch within --budget, watertight seams between all patches, geomorphs.\n"
      "The frame never waits for the disk: a block that has not arrived is drawn as its nearest\n"
      "ancestor in the tree and counted in missing_in_view. A block is read only down to the error\n"
      "its view needs (divided by 4): a far block holds the coarse end of its PM, and while a finer\n"
      "copy loads the coarse one is drawn, with its true bound, and counted in missing_in_view.\n\n"
      "What is guaranteed: bound_px bounds the screen-space error of the mesh exactly as drawn that\n"
      "frame (geomorphs included); in every frame with missing_in_view = 0 it is <= tau_px.\n\n"
      "PATH.csv: a header 'x,y,z,yaw,pitch,fovy', then one camera per frame in the conventions of\n"
      "'terralod view': world metres (x east, y north, z up), yaw degrees clockwise from north,\n"
      "pitch degrees above the horizon (-90..90), fovy the vertical field of view (0..180). The\n"
      "near and far planes follow the terrain: far beyond its farthest corner. So does the view's\n"
      "ground scale: over a database with a CRS, world offsets about the eye are stretched by the\n"
      "frame's scale there, so that they are ground metres near the camera however wide the\n"
      "frame (TerrainRuntime::fit_camera; the identity without a CRS).\n\n" +
      track_help() +
      "\n\n"
      "Writes DIR/frames.csv (only once the whole flight succeeded: a flight stopped by an error,\n"
      "such as a corrupt block, leaves none): frame, time_s, x, y, z, yaw, pitch, fovy, tau_px,\n"
      "triangles, bound_px, missing_in_view, update_ms, update_cpu_ms (thread CPU time of the\n"
      "update), resident_bytes, blocks_resident, blocks_loading, blocks_evicted (this frame),\n"
      "nodes_resident, nodes_loading, nodes_evicted (tree nodes: all stay resident), prefetch_misses\n"
      "(cumulative: blocks needed before they were resident), bytes_read (cumulative), nodes_visited,\n"
      "nodes_culled, coarse_nodes, pm_blocks, standin_blocks, fallback_nodes, moving_vertices, "
      "clamped_vertices,\n"
      "seam_triangles, standins_held (block stand-ins in memory: read when a frame first looks at\n"
      "their block, dropped 120 frames after its last look), standin_reads (cumulative), and the\n"
      "view's ground scale ground_xx, ground_xy, ground_yy (the symmetric matrix G: the view\n"
      "shows a world point p at eye + G (p - eye) in x, y, z unchanged; bound_px is of that view).\n"
      "--dump-meshes also writes each frame's drawn mesh as DIR/frame_NNNNN.ply\n"
      "(binary little-endian, double x y z in the world frame at the displayed heights, int faces,\n"
      "counter-clockwise seen from above).\n\n"
      "--objects NAME (an object layer of --db, from 'terralod objects add'; repeatable) places the\n"
      "layer's objects every frame on the terrain as drawn (geomorphs included): each anchor (a\n"
      "point, a line's midpoint by length, a polygon's area centroid) takes the drawn mesh's height\n"
      "under it; objects outside the frustum, over nothing drawn or beyond their layer's rules are\n"
      "left out (and cost nothing beyond their grid cell's test). The summary gives the objects placed per "
      "frame and\n"
      "the placement's thread CPU time. --dump-objects also writes DIR/objects_NNNNN.csv per frame:\n"
      "name,kind,x,y,z,ground_z (name: the layer's label field, else the attribute 'name', else the\n"
      "feature id; kind: what the layer's rules draw it as at its distance (icon, label, shape, line,\n"
      "symbol; objects the rules do not draw there are left out); x, y, z: the anchor as drawn,\n"
      "world frame; ground_z: the drawn terrain's height under the anchor, equal to z while anchors\n"
      "stand on the ground).\n\n"
      "--speed-factor K paces frame f to start no earlier than f / (60 K) seconds after the first\n"
      "(K = 1: real time, 2: twice as fast; 0: no pacing, as fast as the CPU goes). Loading runs in\n"
      "real time, so K decides how much time the loader gets per frame.";
  s.options = {
      {"--db", "FILE", "block database (from 'terralod build')", true},
      {"--path", "FILE", "camera path: PATH.csv, one row per frame at 60 fps, or a GPX/IGC flight track",
       true},
      {"--out", "DIR", "output folder (created if missing)", true},
      {"--size", "WxH", "viewport in pixels (default 1280x720, each 1..16384)"},
      {"--tau", "PIXELS", "screen-space error tolerance, pixels (> 0, default 1)"},
      {"--triangles", "N", "triangle-budget mode: regulate tau to hold about N triangles (default off)"},
      {"--dump-meshes", "", "also write every frame's drawn mesh as DIR/frame_NNNNN.ply"},
      objects_option_spec(),
      {"--dump-objects", "", "with --objects: write every frame's placed objects as DIR/objects_NNNNN.csv"},
      {"--no-prefetch", "", "no flight-path prediction (load what the view and the region need)"},
      {"--speed-factor", "K", "replay speed relative to real time, >= 0 (default 1; 0 = unpaced)"},
      {"--morph", "SECONDS", "geomorph duration, >= 0 (default 0.5; 0 pops)"},
      {"--theta", "DEGREES",
       "minimum visible angle of the region kept ready, b = a cot(theta), (0, 90) (default 20)"},
      {"--budget", "MB", "resident memory budget, megabytes (default 512): blocks, tree, summaries, mesh"},
  };
  s.options = concat(std::move(s.options), track_option_specs());
  return s;
}

int cmd_fly(const Args& a) {
  const auto t_start = Clock::now();
  const std::string db_path = a.get("--db"), path_csv = a.get("--path"), out = a.get("--out");
  const auto [width, height] = image_size_option(a, {1280, 720});
  const double tau = tau_option(a);
  const double speed = a.get_double("--speed-factor", 1.0);
  if (!(speed >= 0))
    throw UsageError("option '--speed-factor' must be >= 0, not '" + a.get("--speed-factor") + "'");
  const double morph = a.get_double("--morph", 0.5);
  if (!(morph >= 0))
    throw UsageError("option '--morph' must be >= 0 seconds, not '" + a.get("--morph") + "'");
  const double theta = a.get_double("--theta", 20.0);
  if (!(theta > 0 && theta < 90))
    throw UsageError("option '--theta' must be in (0, 90) degrees, not '" + a.get("--theta") + "'");
  const double budget_mb = a.get_double("--budget", 512.0);
  if (!(budget_mb > 0))
    throw UsageError("option '--budget' must be > 0 megabytes, not '" + a.get("--budget") + "'");
  const long long target = a.has("--triangles") ? a.get_int("--triangles", 0, 1, 1000000000) : 0;
  const bool dump = a.has("--dump-meshes"), dump_objects = a.has("--dump-objects");
  if (dump_objects && !a.has("--objects")) throw UsageError("--dump-objects needs --objects");

  pm::CameraPathOptions view;
  view.width_px = width, view.height_px = height;
  // The shared path reader (flight_path.hpp): a PATH.csv as every tool reads it, or a GPX/IGC track.
  const FlightPath flight = read_flight_path(a, "--path", db_path, view);
  const std::vector<pm::Camera>& path = flight.cameras;
  print_line(
      strf("read  %s: %zu frames (%.1f s at 60 fps)", path_csv.c_str(), path.size(), path.size() / 60.0));
  std::error_code ec;
  fs::create_directories(out, ec);
  if (!fs::is_directory(out)) throw std::runtime_error(out + ": cannot create the output folder");

  auto t = Clock::now();
  blocks::RuntimeOptions opt;
  opt.tolerance_px = tau;
  opt.target_triangles = std::size_t(target);
  opt.morph_seconds = morph;
  opt.region.theta_deg = theta;
  opt.budget_bytes = std::size_t(budget_mb * 1e6);
  opt.prefetch = !a.has("--no-prefetch");
  blocks::TerrainRuntime rt(db_path, opt);
  const blocks::BlockGrid& grid = rt.grid();
  print_line(strf("open  %s: %d x %d samples, %d x %d blocks of %d, tree of %zu nodes, in %s",
                  db_path.c_str(), grid.grid_width(), grid.grid_height(), grid.cols(), grid.rows(),
                  grid.block_size(), rt.tree().size(), format_duration(ms_since(t)).c_str()));

  std::optional<blocks::ObjectPlacer> objects = object_placer(a, db_path);
  std::vector<double> placed, place_cpu;
  if (objects)
    print_line(strf("read  %zu objects of %zu layers", objects->objects().size(), objects->layers().size()));

  FlightLog log(out, /*drawing=*/false);  // frames.csv appears only when the whole flight succeeded
  std::vector<double> ms, cpu, sel_ms, res_ms, ref_ms, seam_ms;
  ms.reserve(path.size());
  std::size_t complete = 0, over_tau = 0, lifted = 0;
  double worst_complete = 0;
  const bool flip = grid.transform().determinant() < 0;
  ProgressBar bar("fly");
  const auto t_fly = Clock::now();
  for (std::size_t f = 0; f < path.size(); ++f) {
    if (speed > 0)
      std::this_thread::sleep_until(t_fly + std::chrono::duration<double>(double(f) / (60.0 * speed)));
    pm::Camera cam = path[f];
    if (flight.clearance_m > 0) {  // a track's eye above the ground
      if (f == 0) {                // (the first frame is updated once beforehand, to have one)
        rt.fit_camera(cam);
        rt.update(pm::View(cam), 0.0);
      }
      lifted += keep_clear(cam, rt, flight.clearance_m);
    }
    rt.fit_camera(cam);
    const blocks::RuntimeFrameStats& s = rt.update(pm::View(cam), double(f) / 60.0);
    ms.push_back(s.update_ms);
    cpu.push_back(s.update_cpu_ms);
    sel_ms.push_back(s.select_ms), res_ms.push_back(s.residency_ms), ref_ms.push_back(s.refine_ms);
    seam_ms.push_back(s.seams_ms);
    if (s.missing_in_view == 0) {
      ++complete;
      worst_complete = std::max(worst_complete, s.bound_px / s.tolerance_px);
      over_tau += s.bound_px > s.tolerance_px;
    }
    log.row({f, s.time_s, cam, s});
    if (objects) {
      const double c0 = pm::thread_cpu_ms();
      objects->place(rt, pm::View(cam));
      place_cpu.push_back(pm::thread_cpu_ms() - c0);
      placed.push_back(double(objects->placed().size()));
      if (dump_objects)
        write_objects_csv(objects->placed(), rt, (fs::path(out) / strf("objects_%05zu.csv", f)).string());
    }
    if (dump) {
      const blocks::DrawnMesh& m = rt.drawn_mesh();
      pm::TriangleMeshData d;
      d.positions.reserve(m.positions.size());
      for (const pm::Vec3& p : m.positions) d.positions.push_back({p.x, p.y, p.z});
      d.triangles = m.triangles;
      if (flip)
        for (auto& tri : d.triangles) std::swap(tri[1], tri[2]);
      pm::write_mesh(d, (fs::path(out) / strf("frame_%05zu.ply", f)).string());
    }
    bar.update(double(f + 1) / double(path.size()));
  }
  bar.finish();
  log.commit();
  const blocks::RuntimeFrameStats& last = rt.stats();
  print_line(
      strf("fly   %zu frames in %s (speed factor %g%s): update median %.2f ms, p99 %.2f ms, worst %.2f ms; "
           "CPU median %.2f ms, p99 %.2f ms",
           path.size(), format_duration(ms_since(t_fly)).c_str(), speed,
           opt.prefetch ? ", prefetch" : ", no prefetch", pm::quantile(ms, 0.5), pm::quantile(ms, 0.99),
           pm::quantile(ms, 1.0), pm::quantile(cpu, 0.5), pm::quantile(cpu, 0.99)));
  print_line(strf(
      "steps median: selection %.3f ms, loader queue %.3f ms, refinement %.3f ms, seams and bound %.3f ms",
      pm::quantile(sel_ms, 0.5), pm::quantile(res_ms, 0.5), pm::quantile(ref_ms, 0.5),
      pm::quantile(seam_ms, 0.5)));
  print_line(strf(
      "load  %zu prefetch misses of %zu blocks needed, %s read, peak resident %s (budget %s), %zu evicted",
      last.prefetch_misses_total, last.prefetch_hits_total + last.prefetch_misses_total,
      format_bytes(last.bytes_read_total).c_str(), format_bytes(last.peak_resident_bytes).c_str(),
      format_bytes(opt.budget_bytes).c_str(), last.evicted_total));
  print_line(
      strf("bound %zu of %zu frames had nothing missing; in those the drawn bound was <= tau in %zu (largest "
           "bound / "
           "tau %.3f)",
           complete, path.size(), complete - over_tau, worst_complete));
  if (flight.clearance_m > 0)
    print_line(strf("track the eye was lifted to %g m above the ground in %zu of %zu frames",
                    flight.clearance_m, lifted, path.size()));
  if (objects)
    print_line(
        strf("objects placed per frame median %.0f, max %.0f; placement thread CPU median %.3f ms, p99 "
             "%.3f ms",
             pm::quantile(placed, 0.5), pm::quantile(placed, 1.0), pm::quantile(place_cpu, 0.5),
             pm::quantile(place_cpu, 0.99)));
  print_line(strf("write %s%s%s in %s", log.path().c_str(), dump ? " and the frame meshes" : "",
                  dump_objects ? " and the objects" : "", format_duration(ms_since(t_start)).c_str()));
  return 0;
}

}  // namespace terralod::cli
