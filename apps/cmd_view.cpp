// terralod view: renders a .pm file, a DEM or a database offscreen from a camera into a PNG. The
// --input path is here (a progressive mesh, its view-dependent selection or a uniform extraction);
// --db goes to cmd_view_db.cpp (a block database) or cmd_hybrid_view.cpp (a hybrid one).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"
#include "dem_options.hpp"
#include "layer_options.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/selective_refinement.hpp"
#include "terralod/pm/view.hpp"
#include "terralod/render/camera.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/layered_renderer.hpp"
#include "terralod/render/terrain_renderer.hpp"
#include "view_camera.hpp"

namespace terralod::cli {

CommandSpec view_spec() {
  CommandSpec s;
  s.name = "view";
  s.summary = "Render a .pm file, a DEM or a database offscreen from a camera and write a PNG.";
  s.description =
      std::string(
          "Draws the terrain seen from --camera into an offscreen OpenGL frame (OSMesa, no display\n"
          "needed), lit by a directional light, and writes it as an 8-bit RGB PNG.\n\n"
          "Camera: X,Y,Z in world metres (x east, y north, z up; the DEM's frame, see 'terralod info'),\n"
          "YAW degrees clockwise from north (0 looks north, 90 east), PITCH degrees above the horizon\n"
          "(negative looks down, -90..90), FOVY the vertical field of view in degrees (0..180).\n\n"
          "--db: a block database (from 'terralod build') is drawn as one frame of the runtime that\n"
          "'terralod fly' and 'terralod-fly --db' run: the approximation tree from its root, coarse nodes\n"
          "far away, PM blocks refined near, stitched seams, every block this view needs read first;\n"
          "its bound_px bounds the screen-space error of the picture (<= --tau when nothing needed is\n"
          "missing). --layer draws texture layers of --texture-db (default --db) per drawn patch: each\n"
          "patch gets the coarsest texture of its layer's texture tree whose texel covers at most --gamma\n"
          "pixels^2 (raised when the textures would not fit --texture-memory). A 'terralod hybrid'\n"
          "database is drawn from its own tree (TIN near, grid far), without layers.\n\n"
          "Mesh: the VIEW-DEPENDENT selection of the pm/ runtime (CollapseDag + SelectiveRefinement,\n"
          "one update from the camera): every collapse is kept only where its error, projected from the\n"
          "nearest point of its bounding box, is at most --tau pixels, so near terrain is fine and far\n"
          "terrain coarse. The guarantee: no vertical error segment inside the view frustum projects\n"
          "to more than bound_px <= --tau pixels (the near and far planes are those of the render).\n"
          "--uniform restores the earlier UNIFORM extraction at the largest error E that no part of\n"
          "the terrain can show larger than --tau pixels: E = TAU * d_min / K_max, where d_min is the\n"
          "distance from the camera to the nearest point of the terrain's bounding box and\n"
          "K_max = K (1 + r^2/K^2) bounds the pixels per radian anywhere in the image\n"
          "(K = H / (2 tan(FOVY/2)), r = half the image diagonal in pixels): conservative, distant\n"
          "terrain keeps more triangles than it needs.\n\n"
          "--stats writes JSON: the selection, the triangle and active vertex counts, the guaranteed\n"
          "error bound (pixels: bound_px; metres), tau and the time of every stage; for the\n"
          "view-dependent selection also the vsplits and ecols of the update and its time.\n\n") +
      kDemFormats;
  s.options = concat(
      concat({{"--input", "FILE", "a .pm file (from 'terralod pm') or a DEM (or --db)"},
              {"--db", "FILE.db",
               "instead of --input: a block database (the runtime's frame) or a 'terralod hybrid' one"},
              {"--camera", "X,Y,Z,YAW,PITCH,FOVY", "camera position (m) and angles (degrees)", true},
              {"--out", "IMAGE.png", "PNG file to write", true},
              {"--tau", "PIXELS", "screen-space error tolerance, pixels (> 0, default 1)"},
              {"--size", "WxH", "image size in pixels (default 1024x768, each 1..16384)"},
              {"--wireframe", "", "draw the triangle edges over the surface"},
              {"--uniform", "", "uniform extraction chosen conservatively from --tau (the old mesh)"},
              {"--dump-mesh", "MESH", "also write the rendered mesh: .ply, .obj, .glb or .gltf, world units"},
              {"--stats", "FILE.json", "write statistics and timings as JSON"}},
             concat(layer_option_specs(), build_option_specs())),
      dem_option_specs());
  return s;
}

int cmd_view(const Args& a) {
  using Clock = std::chrono::steady_clock;
  const std::string input = a.get("--input"), out = a.get("--out");
  if (lower_extension(out) != ".png")
    throw UsageError("option '--out' must name a .png file, not '" + out + "'");
  const ViewCamera view = view_camera_options(a);
  const double tau = view.tau;
  const int width = view.camera.width_px, height = view.camera.height_px;
  const std::string dump = a.get("--dump-mesh"), stats_path = a.get("--stats");
  if (a.has("--dump-mesh")) check_mesh_output("--dump-mesh", dump);
  const blocks::DemOptions dem = dem_options_from(a);
  const pm::BuildOptions build = build_options_from(a);
  const std::vector<std::string> layer_specs = a.get_all("--layer");
  if (!a.has("--db") && layer_specs.empty() != !a.has("--texture-db"))
    throw UsageError("--layer and --texture-db go together (with --db, --texture-db defaults to it)");
  if (a.has("--texture-db") && layer_specs.empty()) throw UsageError("--texture-db needs --layer");
  if ((a.has("--gamma") || a.has("--texture-memory")) && (!a.has("--db") || layer_specs.empty()))
    throw UsageError("--gamma and --texture-memory need --db and --layer (textures per patch of its tree)");
  if (a.has("--db")) layer_setup_options(a);  // usage errors before the terrain loads
  if (!layer_specs.empty() && a.has("--wireframe"))
    throw UsageError("--wireframe cannot be combined with --layer");
  if (a.has("--lens") && layer_specs.empty()) throw UsageError("--lens needs --layer");
  for (const std::string& spec : layer_specs) parse_layer_spec(spec);  // usage errors first
  check_output_folder(out);
  if (!dump.empty()) check_output_folder(dump);
  if (!stats_path.empty()) check_output_folder(stats_path);
  if (a.has("--db") == a.has("--input")) throw UsageError("view needs exactly one of '--input' and '--db'");
  if (a.has("--db") && a.has("--uniform")) throw UsageError("--uniform is for --input (a .pm file or a DEM)");
  if (a.has("--db")) {
    if (blocks::BlockDatabase::open(a.get("--db")).info().kind != "hybrid")
      return view_blocks(a, view.camera, tau);
    if (!layer_specs.empty()) throw UsageError("--layer draws on block databases, not on a hybrid one");
    if (a.has("--stats")) throw UsageError("--stats is not available for a hybrid database");
    return view_hybrid(a.get("--db"), view.camera, tau, out, dump, a.has("--wireframe"));
  }

  auto t = Clock::now();
  const pm::ProgressiveMesh mesh = pm_input_stage(input, dem, build);
  const double load_ms = ms_since(t);
  const pm::Heightfield& hf = mesh.heightfield();

  render::Camera cam = view.camera;

  // The terrain's bounding box: the clip planes of the render (and of the selection's view),
  // and, for --uniform, the conservative uniform error for tau: every point of a vertical error
  // segment lies in the box, hence at least d_min from the camera, so it covers at most
  // E * K_max / d_min pixels anywhere in the image.
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  for (const auto& [col, row] :
       {std::pair{0, 0}, {hf.width() - 1, 0}, {0, hf.height() - 1}, {hf.width() - 1, hf.height() - 1}}) {
    const auto [x, y] = hf.transform.to_world(col, row);
    lo = glm::min(lo, glm::dvec3(x, y, lo.z));
    hi = glm::max(hi, glm::dvec3(x, y, hi.z));
  }
  const auto [hmin, hmax] = height_range(hf);
  lo.z = std::isfinite(hmin) ? hmin : 0.0;
  hi.z = std::isfinite(hmax) ? hmax : 0.0;
  const double d_min = render::distance_to_box(render::camera_position(cam), lo, hi);
  const double k = render::focal_length_pixels(cam), k_max = render::max_pixels_per_radian(cam);
  fit_clip_to_box(cam, lo, hi);

  const bool uniform = a.has("--uniform");
  pm::TriangleMesh m;
  double max_error = 0.0, screen_bound = 0.0, extract_ms = 0.0, dag_ms = 0.0;
  pm::FrameStats sel_stats;
  if (uniform) {
    max_error = tau * d_min / k_max;
    print_line(
        strf("select tau=%g px: nearest terrain %.1f m, K %.1f px, K_max %.1f px/rad -> E=%.4g m "
             "(uniform extraction, --uniform)",
             tau, d_min, k, k_max, max_error));
    t = Clock::now();
    m = mesh.extract(max_error);
    extract_ms = ms_since(t);
    screen_bound = d_min > 0.0 ? m.error_bound * k_max / d_min : (m.error_bound > 0.0 ? INFINITY : 0.0);
    print_line(strf("extract E=%.4g m: %zu triangles, %zu vertices, bound %g m (<= %.3g px), %s", max_error,
                    m.triangles.size(), m.vertices.size(), m.error_bound, screen_bound,
                    format_duration(extract_ms).c_str()));
  } else {
    // View-dependent selection: the pm::Camera conventions are the CLI's; same clip planes as
    // the render, so the guarantee covers exactly what is drawn.
    t = Clock::now();
    const pm::CollapseDag dag(mesh);
    dag_ms = ms_since(t);
    pm::RefinementOptions ropt;
    ropt.tolerance_px = tau;
    pm::SelectiveRefinement sel(dag, ropt);
    sel_stats = sel.update(pm::View(cam), 0.0);
    t = Clock::now();
    m = sel.mesh();
    extract_ms = ms_since(t);
    screen_bound = sel_stats.bound_px;
    print_line(
        strf("select tau=%g px (view-dependent): dag %zu collapses in %s; update %zu vsplits, %zu ecols, "
             "%zu evaluated in %s",
             tau, dag.collapse_count(), format_duration(dag_ms).c_str(), sel_stats.vsplits, sel_stats.ecols,
             sel_stats.evaluated, format_duration(sel_stats.update_ms).c_str()));
    print_line(
        strf("selection: %zu triangles, %zu active vertices, bound %.4g px (<= tau %g), %g m at the samples",
             m.triangles.size(), sel_stats.active_vertices, sel_stats.bound_px, tau, sel_stats.bound_m));
  }

  t = Clock::now();
  auto ctx = render::create_offscreen_context({width, height});
  render::RendererOptions ropt;
  ropt.wireframe = a.has("--wireframe");
  render::TerrainRenderer renderer(*ctx, ropt);
  // Texture layers (layer_options.hpp): all loaded before the frame, drawn by LayeredRenderer.
  std::optional<LayerSetup> layers;
  std::optional<render::LayeredRenderer> layered;
  if (!layer_specs.empty()) {
    layers.emplace(LayerSetup::open(
        a.get("--texture-db"), layer_specs,
        a.has("--lens") ? std::optional(parse_lens("--lens", a.get("--lens"))) : std::nullopt));
    layers->wait_loaded(/*timeout_ms=*/600000);
    layered.emplace(*ctx);
    layers->attach(*layered);
  }
  const double context_ms = ms_since(t);
  t = Clock::now();
  const render::DrawMesh draw_mesh = render::make_draw_mesh(m, hf);
  const render::MeshId id = layered ? layered->upload(draw_mesh) : renderer.upload(draw_mesh);
  const double upload_ms = ms_since(t);
  render::FrameStats frame;
  if (layered) {
    const render::LayeredItem item{id, layers->bindings(*layered)};
    frame.draw_ms = layered->draw(cam, layers->styles(), layers->lens(), {item}).draw_ms;
  } else {
    frame = renderer.draw(cam, {{id, 0.0f}});
  }
  t = Clock::now();
  const render::Image img = layered ? layered->read_color() : renderer.read_color();
  const double readback_ms = ms_since(t);
  print_line(strf("render %d x %d on %s: context %s, upload %s, draw %s, read back %s", width, height,
                  ctx->info().renderer.c_str(), format_duration(context_ms).c_str(),
                  format_duration(upload_ms).c_str(), format_duration(frame.draw_ms).c_str(),
                  format_duration(readback_ms).c_str()));

  t = Clock::now();
  render::write_png(img, out);
  const double write_ms = ms_since(t);
  print_line(strf("write %s: %s, %s", out.c_str(), format_bytes(std::filesystem::file_size(out)).c_str(),
                  format_duration(write_ms).c_str()));

  const double dump_ms = dump.empty() ? 0.0 : write_mesh_stage(m, hf, dump, pm::Units::World);

  if (!stats_path.empty()) {
    JsonWriter j;
    j.begin_object();
    j.field("input", input);
    j.field("output", out);
    j.field("selection", uniform ? "uniform" : "view-dependent");
    write_view_json(j, cam, tau);
    j.field("nearest_distance", d_min);
    j.field("k", k);
    j.field("k_max", k_max);
    if (uniform) j.field("max_error", max_error);
    j.field("error_bound", m.error_bound);
    j.field("screen_error_bound", screen_bound);
    j.field("bound_px", screen_bound);
    j.field("triangles", std::uint64_t(m.triangles.size()));
    j.field("vertices", std::uint64_t(m.vertices.size()));
    if (!uniform) {
      j.field("active_vertices", std::uint64_t(sel_stats.active_vertices));
      j.field("vsplits", std::uint64_t(sel_stats.vsplits));
      j.field("ecols", std::uint64_t(sel_stats.ecols));
      j.field("evaluated", std::uint64_t(sel_stats.evaluated));
      j.field("tolerance_px", sel_stats.tolerance_px);
      j.field("bound_m", sel_stats.bound_m);
      j.field("update_ms", sel_stats.update_ms);
    }
    j.field("renderer", ctx->info().renderer);
    j.begin_object("timings_ms");
    j.field("load", load_ms);
    if (!uniform) {
      j.field("dag", dag_ms);
      j.field("update", sel_stats.update_ms);
    }
    j.field(uniform ? "extract" : "mesh", extract_ms);
    j.field("context", context_ms);
    j.field("upload", upload_ms);
    j.field("draw", frame.draw_ms);
    j.field("read_back", readback_ms);
    j.field("write_png", write_ms);
    if (!dump.empty()) j.field("dump_mesh", dump_ms);
    j.end_object();
    j.end_object();
    write_statistics(stats_path, j);
  }
  return 0;
}

}  // namespace terralod::cli
