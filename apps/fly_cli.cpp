// terralod-fly's command line (see fly_cli.hpp).
#include "fly_cli.hpp"

#include <string>
#include <vector>

#include "dem_options.hpp"
#include "flight_objects.hpp"
#include "flight_path.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/block_database.hpp"

namespace terralod::fly {

using namespace terralod::cli;

CommandSpec fly_spec() {
  CommandSpec s;
  s.name = "terralod-fly";
  s.summary = "fly over a terrain with view-dependent level of detail";
  s.description =
      "Opens a window and flies over the terrain: a block database (--db, from 'terralod build':\n"
      "the approximation tree from its root over the whole terrain, coarse nodes far away, PM\n"
      "blocks near, read by a background thread within --memory; a block that has not arrived is\n"
      "drawn as its ancestor in the tree), a DEM (built into one progressive mesh in memory), a .pm\n"
      "file, or, given neither, the built-in generated terrain. Every frame selects the mesh and\n"
      "draws it, with geomorphs. What is guaranteed: with --db, the HUD's 'drawn within B px'\n"
      "bounds the screen-space error of the mesh exactly as drawn that frame (geomorphs\n"
      "included), and B <= tau in every frame where no needed block is missing (the HUD says when\n"
      "some are). With one progressive mesh (a DEM, a .pm, the built-in terrain), 'selection\n"
      "within B px' bounds the selected mesh; while vertices geomorph the display lags it (the HUD\n"
      "says so; G turns geomorphs off).\n\n"
      "Controls: hold the left mouse button and move the mouse off the window's centre to steer\n"
      "(the farther, the faster the turn); W/S throttle up/down; R/F climb/descend; arrow keys\n"
      "turn and pitch; T terrain following (never below --clearance over the ground); G geomorphs\n"
      "on/off; X wireframe; L freeze the level of detail (fly around it to inspect it from\n"
      "outside); B triangle-budget mode (holds --budget triangles by regulating tau over the\n"
      "whole frame); [ and ] tau down/up; C start/stop recording the flight to --record; P\n"
      "screenshot; Esc quit; a click picks and O switches object layers (--objects, below). G, B, [\n"
      "and ] take effect at the next frame; nothing is read again.\n"
      "Texture layers (--layer NAME, from --texture-db, which defaults to --db): with --db each\n"
      "drawn patch gets its texture from the layer's texture tree, the coarsest whose texel covers\n"
      "at most --gamma pixels^2 on screen (the parent's texture while one loads; gamma is raised\n"
      "for a frame when the patches would not fit --texture-memory). Keys 1..9 switch\n"
      "layer 1..9 on/off; H switches the highlight lens, which follows the ground point at the\n"
      "screen's centre, or under the mouse while the right button is held (X shows the untextured\n"
      "wireframe).\n"
      "Map objects (--objects NAME, an object layer of --db from 'terralod objects add'; repeatable)\n"
      "are placed every frame on the terrain as drawn (each anchor at the drawn mesh's height, so\n"
      "objects never float or sink as the level of detail changes) and drawn as the layer's rules\n"
      "choose for their distance: icons (the rules' image, or a pin), labels (decluttered: none\n"
      "overlap, higher priority wins, no flicker), lines draped on the drawn triangles, and\n"
      "polygons extruded by their height field from the lowest drawn ground under them; objects\n"
      "beyond their rules cost nothing. The HUD counts those in view and drawn. A click (left button "
      "released within 0.25 s of its press) picks\n"
      "through the pixel: the HUD shows the nearest object within 8 pixels (name, kind, layer and\n"
      "attributes) or the ground point on the drawn terrain. O switches the object layers on/off.\n"
      "The heads-up display shows frames per second, tau, the bound of what is drawn, triangles,\n"
      "update and draw times, nodes drawn (PM blocks, blocks drawn as their stand-ins, coarse\n"
      "nodes, ancestors drawn for missing blocks), blocks resident/loading/evicted, prefetch misses, bytes "
      "read, resident memory and\n"
      "texture memory.\n\n"
      "--headless renders --frames frames of --path through OSMesa (no display needed) and\n"
      "writes DIR/frame_NNNNN.png, DIR/frames.csv and, with --dump-meshes, DIR/frame_NNNNN.ply\n"
      "(the drawn mesh, binary little-endian, double x y z in the world frame). Frame k is at time\n"
      "k/60 s. Every frame waits for its loads, so runs are reproducible; the window never waits.\n"
      "The same path gives the same statistics (apart from times and resident_bytes, which counts\n"
      "the capacity its buffers kept from whichever moment each block arrived at) and identical\n"
      "images (with --hud, apart from its memory figure).\n"
      "frames.csv has the columns of 'terralod fly' (see 'terralod fly --help': the runtime's\n"
      "statistics; a single PM fills them as one PM block), then vertices, draw_ms, upload_ms (the\n"
      "drawn mesh converted and sent to the GPU), wait_ms (the wait for loads), texture_bytes (resident\n"
      "in the texture cache), texture_patches (wanted this frame) and textures_from_parent (those\n"
      "drawn with an ancestor's texture while they load; headless frames wait for them), and last\n"
      "the view's ground scale, ground_xx, ground_xy and ground_yy, as 'terralod fly' writes them\n"
      "(1, 0, 1 without a CRS).\n"
      "PATH.csv: a header x,y,z,yaw,pitch,fovy and one row per frame (conventions of\n"
      "'terralod view': yaw clockwise from north, pitch above the horizon, degrees).\n" +
      cli::track_help();
  s.options = {
      {"--db", "FILE.db", "block database from 'terralod build' (streamed; excludes --input)"},
      {"--memory", "MB", "--db: resident memory budget, megabytes (default 537: 512 MiB)"},
      {"--theta", "DEGREES",
       "--db: the region kept ready around the eye, b = a cot(theta), (0, 90) (default 20)"},
      {"--input", "FILE", "a DEM or a .pm file (default: the built-in generated terrain)"},
      {"--terrain-size", "N", "samples per side of the built-in terrain (default 513, 2..8193)"},
      {"--tau", "PIXELS", "screen-space error tolerance, pixels (> 0, default 1)"},
      {"--morph", "SECONDS", "geomorph time (>= 0, default 0.3; 0 = off)"},
      {"--budget", "TRIANGLES", "triangle target of the budget mode (default 50000)"},
      {"--size", "WxH", "window or image size (default 1280x720)"},
      {"--clearance", "METRES", "terrain-following height over the ground (default 30)"},
      {"--record", "PATH.csv", "where C writes the recorded flight (default flight.csv)"},
      {"--replay", "FILE",
       "window mode: fly this path (PATH.csv, or a GPX/IGC track over --db) instead of the controls"},
      {"--frames", "N", "frames to run (headless: default the whole path; window: until closed)"},
      {"--screenshot", "FILE.png", "window mode: write the last frame here on exit"},
      {"--headless", "", "render through OSMesa along --path, no window"},
      {"--path", "FILE",
       "headless: the scripted camera path, PATH.csv or a GPX/IGC track over --db (default: a built-in "
       "circle that avoids flat ground such as sea)"},
      {"--out", "DIR", "headless: output folder (created; default fly_out)"},
      {"--dump-meshes", "", "headless: also write each frame's drawn mesh as PLY"},
      {"--hud", "", "headless: draw the heads-up display into the frames (without its timings)"},
      {"--wireframe", "", "draw the triangle edges over the shading (the window's X toggles it)"},
  };
  s.options.push_back(objects_option_spec());
  for (OptionSpec& o : cli::track_option_specs()) s.options.push_back(std::move(o));
  for (OptionSpec& o : layer_option_specs()) s.options.push_back(std::move(o));
  s.options = with_dem_options(std::move(s.options));  // for --input: --keep-voids, --crs, ...
  return s;
}

std::optional<LayerSetup> layer_setup(const Args& a) {
  const std::vector<std::string> specs = a.get_all("--layer");
  if (a.has("--texture-db") && specs.empty()) throw UsageError("--texture-db needs --layer");
  if (!specs.empty() && !a.has("--texture-db") && !a.has("--db"))
    throw UsageError("--layer needs --texture-db (or --db holding the layers)");
  if (a.has("--lens") && specs.empty()) throw UsageError("--lens needs --layer");
  if (specs.size() > 9) throw UsageError("at most 9 --layer (keys 1..9 switch them)");
  for (const std::string& s : specs) parse_layer_spec(s);
  if (specs.empty()) return std::nullopt;
  std::optional<LensSpec> lens;
  if (a.has("--lens")) lens = parse_lens("--lens", a.get("--lens"));
  const LayerSetupOptions lo = layer_setup_options(a);
  if (a.has("--gamma") && !a.has("--db"))
    throw UsageError("--gamma needs --db (textures per patch of its tree)");
  if (!a.has("--db")) return LayerSetup::open(a.get("--texture-db"), specs, lens, lo);
  // --db: textures per drawn patch, over the drawn database's tree.
  const std::vector<render::PatchDomain> tree =
      render::tree_domains(blocks::BlockDatabase::open(a.get("--db")));
  return LayerSetup::open(a.get("--texture-db", a.get("--db")), specs, lens, lo, &tree);
}

std::optional<blocks::ObjectPlacer> fly_objects(const Args& a) {
  if (a.has("--objects") && !a.has("--db")) throw UsageError("--objects needs --db (the layers are in it)");
  return a.has("--objects") ? object_placer(a, a.get("--db")) : std::nullopt;
}

std::pair<int, int> parse_size(const Args& a) {
  const auto [w, h] = a.get_size("--size", {1280, 720}, 1, 16384);
  return {int(w), int(h)};
}

pm::RefinementOptions refinement_options(const Args& a) {
  pm::RefinementOptions o;
  o.tolerance_px = a.get_double("--tau", 1.0);
  if (!(o.tolerance_px > 0)) throw UsageError("--tau must be > 0");
  o.morph_seconds = a.get_double("--morph", 0.3);
  if (!(o.morph_seconds >= 0)) throw UsageError("--morph must be >= 0");
  o.cull_margin = 1.3;  // terrain turning into view is already refined
  return o;
}

std::unique_ptr<LodSource> open_terrain(const Args& a) {
  if (a.has("--db") && a.has("--input")) throw UsageError("--db and --input exclude each other");
  if (a.has("--db") && a.has("--terrain-size"))
    throw UsageError("--terrain-size is for the built-in terrain, not --db");
  const pm::RefinementOptions o = refinement_options(a);
  const int size = int(a.get_int("--terrain-size", kDemoTerrainSize, 2, 8193));
  if (!a.has("--db") && (a.has("--memory") || a.has("--theta")))
    throw UsageError("--memory and --theta need --db");
  if (a.has("--db")) {
    blocks::RuntimeOptions ro;
    ro.region.theta_deg = a.get_double("--theta", ro.region.theta_deg);
    if (!(ro.region.theta_deg > 0 && ro.region.theta_deg < 90))
      throw UsageError("--theta must be in (0, 90) degrees");
    const double mb = a.get_double("--memory", double(ro.budget_bytes) / 1e6);
    if (!(mb > 0)) throw UsageError("--memory must be > 0 megabytes");
    ro.budget_bytes = std::size_t(mb * 1e6);
    return open_db_source(a.get("--db"), o, ro);
  }
  return open_pm_source(a.get("--input"), size, o, dem_options_from(a));
}

}  // namespace terralod::fly
