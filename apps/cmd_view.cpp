// terralod view: renders a .pm file, a DEM or a database offscreen from a camera into a PNG. The
// --input path is here (a progressive mesh, its view-dependent selection or a uniform extraction,
// or with --morph-to the frames of a static geomorph between two selections, pm/geomorph.hpp);
// --db goes to cmd_view_db.cpp (a block database) or cmd_hybrid_view.cpp (a hybrid one).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "commands.hpp"
#include "dem_options.hpp"
#include "flight_objects.hpp"
#include "layer_options.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/ground_scale.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/geomorph.hpp"
#include "terralod/pm/mesh_io.hpp"
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
          "pixels^2 (raised when the textures would not fit --texture-memory). --objects NAME draws an\n"
          "object layer of --db on that frame as its rules choose (icons, decluttered labels, draped\n"
          "lines, extruded shapes; each anchor at the drawn terrain's height). A 'terralod hybrid'\n"
          "database is drawn from its own tree (TIN near, grid far), without layers.\n\n"
          "Mesh: the VIEW-DEPENDENT selection of the pm/ runtime (CollapseDag + SelectiveRefinement,\n"
          "one update from the camera): every collapse is kept only where its error, projected from the\n"
          "nearest point of its bounding box, is at most --tau pixels, so near terrain is fine and far\n"
          "terrain coarse. The guarantee: no vertical error segment inside the view frustum projects\n"
          "to more than bound_px <= --tau pixels (the near and far planes are those of the render).\n"
          "--uniform restores the earlier UNIFORM extraction at the largest error E that no part of\n"
          "the terrain can show larger than --tau pixels: E = TAU * d_min / K_max, where d_min is the\n"
          "distance from the camera to the nearest point of the terrain's bounding box (as seen) and\n"
          "K_max = K (1 + r^2/K^2) bounds the pixels per radian anywhere in the image\n"
          "(K = H / (2 tan(FOVY/2)), r = half the image diagonal in pixels): conservative, distant\n"
          "terrain keeps more triangles than it needs.\n\n"
          "--stats writes JSON: the selection, the triangle and active vertex counts, the guaranteed\n"
          "error bound (pixels: bound_px; metres), tau and the time of every stage; for the\n"
          "view-dependent selection also the vsplits and ecols of the update and its time.\n"
          "A terrain with a CRS is seen through the camera's ground scale, the frame's at the eye: world\n"
          "offsets about the eye are stretched so that they are ground metres near it, however wide\n"
          "the frame (--stats gives it as the camera's ground_xx, ground_xy, ground_yy).\n\n"
          "--morph-to (with --input): a smooth transition between two viewpoints. M^A is the mesh\n"
          "selected for --camera and M^B the one for --morph-to (same --tau and options); their\n"
          "static geomorph M^G(a) (pm/geomorph.hpp: the plan-view overlay of both, heights blended\n"
          "pointwise, (1-a) M^A + a M^B, no triangle flipping) is drawn as --frames images:\n"
          "frame k (k = 0..N-1) shows M^G(a) for a = k/(N-1) from the camera interpolated linearly\n"
          "between the two (position, PITCH, FOVY; YAW the shorter way round) at the same a. Frame 0\n"
          "draws M^A and the last frame M^B, as the plain view does. OUT.png becomes OUT_00000.png,\n"
          "OUT_00001.png, ..., and --dump-mesh likewise. --stats records per frame a, the camera, the\n"
          "triangle and vertex counts and the L-infinity error bounds e_A and e_B (metres) of M^A and\n"
          "M^B: the blend is vertically within (1-a) e_A + a e_B <= max(e_A, e_B) of the\n"
          "full-resolution surface at every point. No screen-space bound is claimed for frames in\n"
          "between (bound_px is given for M^A and M^B from their own cameras only).\n\n") +
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
              {"--stats", "FILE.json", "write statistics and timings as JSON"},
              {"--morph-to", "CAMERA",
               "with --input: end camera X,Y,Z,YAW,PITCH,FOVY of a geomorph from --camera"},
              {"--frames", "N", "images of the --morph-to transition (2..10000, default 2)"},
              objects_option_spec()},
             concat(layer_option_specs(), build_option_specs())),
      dem_option_specs());
  return s;
}

namespace {

using Clock = std::chrono::steady_clock;

/// The terrain's bounding box, world metres: the grid's corners, the valid heights (0 without).
std::pair<glm::dvec3, glm::dvec3> terrain_box(const pm::Heightfield& hf) {
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
  return {lo, hi};
}

/// One view-dependent selection: what the update did and the mesh it left.
struct Selected {
  pm::FrameStats stats;
  pm::TriangleMesh mesh;
  double mesh_ms = 0.0;
};

/// Updates `sel` (fresh, on `dag`, built in dag_ms; < 0: the DAG of the previous call) once for
/// `cam` (clip planes set) and prints the view's two selection lines; `which` (empty for one
/// camera) names the camera.
Selected select_stage(const pm::CollapseDag& dag, double dag_ms, pm::SelectiveRefinement& sel,
                      const pm::Camera& cam, double tau, const std::string& which) {
  Selected r;
  r.stats = sel.update(pm::View(cam), 0.0);
  const auto t = Clock::now();
  r.mesh = sel.mesh();
  r.mesh_ms = ms_since(t);
  const pm::FrameStats& s = r.stats;
  const std::string tag = which.empty() ? "" : ", " + which;
  const std::string dag_text =
      dag_ms < 0.0 ? strf("the same dag of %zu collapses", dag.collapse_count())
                   : strf("dag %zu collapses in %s", dag.collapse_count(), format_duration(dag_ms).c_str());
  print_line(strf(
      "select tau=%g px (view-dependent%s): %s; update %zu vsplits, %zu ecols, %zu evaluated in %s", tau,
      tag.c_str(), dag_text.c_str(), s.vsplits, s.ecols, s.evaluated, format_duration(s.update_ms).c_str()));
  print_line(
      strf("selection%s: %zu triangles, %zu active vertices, bound %.4g px (<= tau %g), %g m at the "
           "samples",
           which.empty() ? "" : (" (" + which + ")").c_str(), r.mesh.triangles.size(), s.active_vertices,
           s.bound_px, tau, s.bound_m));
  return r;
}

/// `path` with "_NNNNN" (frame, 5 digits) inserted before its extension: out.png -> out_00003.png.
std::string frame_path(const std::string& path, int frame) {
  std::filesystem::path p(path);
  p.replace_filename(p.stem().string() + strf("_%05d", frame) + p.extension().string());
  return p.string();
}

/// Unit normal of the full-resolution surface at plan point (col, row), index space: the
/// samples' normals (render::heightfield_normal) interpolated bilinearly, exactly a sample's
/// normal on a sample. Like the plain view's sample normals, it does not change with the mesh.
glm::dvec3 surface_normal(const pm::Heightfield& hf, double col, double row) {
  const int c0 = std::clamp(int(std::floor(col)), 0, std::max(hf.width() - 2, 0));
  const int r0 = std::clamp(int(std::floor(row)), 0, std::max(hf.height() - 2, 0));
  const int c1 = std::min(c0 + 1, hf.width() - 1), r1 = std::min(r0 + 1, hf.height() - 1);
  const double fc = std::clamp(col - c0, 0.0, 1.0), fr = std::clamp(row - r0, 0.0, 1.0);
  if ((fc == 0.0 || c1 == c0) && (fr == 0.0 || r1 == r0)) return render::heightfield_normal(hf, c0, r0);
  const glm::dvec3 n = (1 - fc) * (1 - fr) * render::heightfield_normal(hf, c0, r0) +
                       fc * (1 - fr) * render::heightfield_normal(hf, c1, r0) +
                       (1 - fc) * fr * render::heightfield_normal(hf, c0, r1) +
                       fc * fr * render::heightfield_normal(hf, c1, r1);
  return glm::length(n) > 0 ? glm::normalize(n) : glm::dvec3(0, 0, 1);
}

/// M^G(alpha) as the renderer draws it, relative to `origin`: normals of the full-resolution
/// surface (surface_normal of each vertex's plan point), triangles CCW from above.
render::DrawMesh geomorph_draw_mesh(const pm::RenderMesh& m, const pm::Heightfield& hf,
                                    const glm::dvec3& origin, const std::vector<glm::vec3>& normals) {
  render::DrawMesh d;
  render::fill_draw_geometry(m.positions, m.triangles, origin, hf.transform.determinant() < 0.0, d);
  d.normals.resize(3 * m.positions.size());
  for (std::size_t v = 0; v < m.positions.size(); ++v)
    for (int k = 0; k < 3; ++k) d.normals[3 * v + std::size_t(k)] = normals[v][k];
  return d;
}

/// What the --morph-to path needs from cmd_view's checks and load.
struct MorphJob {
  std::string input, out, dump, stats_path;
  pm::Camera from, to;  ///< --camera and --morph-to, image size set, no clip planes yet
  double tau = 1.0;
  int frames = 2;
  bool wireframe = false;
  double load_ms = 0.0;
};

/// terralod view --morph-to: the frames of the static geomorph from M^A (--camera) to M^B.
int view_morph(const MorphJob& job, const pm::ProgressiveMesh& mesh) {
  const pm::Heightfield& hf = mesh.heightfield();
  const auto [lo, hi] = terrain_box(hf);
  // Every camera sees the frame in ground metres near its eye, as a flight does.
  const blocks::GroundScaleMap ground = blocks::GroundScaleMap::of(hf);
  pm::Camera cam_a = job.from, cam_b = job.to;
  cam_a.ground = ground.at(cam_a.x, cam_a.y), cam_b.ground = ground.at(cam_b.x, cam_b.y);
  fit_clip_to_box(cam_a, lo, hi);
  fit_clip_to_box(cam_b, lo, hi);

  // M^A and M^B: the plain view's selection for each camera, on one DAG.
  auto t = Clock::now();
  const pm::CollapseDag dag(mesh);
  const double dag_ms = ms_since(t);
  pm::RefinementOptions ropt;
  ropt.tolerance_px = job.tau;
  pm::SelectiveRefinement sel_a(dag, ropt), sel_b(dag, ropt);
  const Selected a = select_stage(dag, dag_ms, sel_a, cam_a, job.tau, "--camera");
  const Selected b = select_stage(dag, /*dag_ms=*/-1.0, sel_b, cam_b, job.tau, "--morph-to");
  const double e_a = a.mesh.error_bound, e_b = b.mesh.error_bound;

  t = Clock::now();
  const pm::Geomorph g = pm::make_geomorph(sel_a, sel_b);
  const double geomorph_ms = ms_since(t);
  const auto crossings = std::size_t(std::count(g.samples.begin(), g.samples.end(), pm::Geomorph::kNoSample));
  print_line(
      strf("geomorph: overlay of %zu and %zu triangles -> %zu triangles, %zu vertices (%zu edge "
           "crossings), %s; L-infinity bounds e_A %.4g m, e_B %.4g m",
           a.mesh.triangles.size(), b.mesh.triangles.size(), g.triangles.size(), g.plan.size(), crossings,
           format_duration(geomorph_ms).c_str(), e_a, e_b));
  std::vector<glm::vec3> normals(g.plan.size());
  for (std::size_t v = 0; v < g.plan.size(); ++v)
    normals[v] = glm::vec3(surface_normal(hf, g.plan[v][0], g.plan[v][1]));

  t = Clock::now();
  auto ctx = render::create_offscreen_context({cam_a.width_px, cam_a.height_px});
  render::RendererOptions rend;
  rend.wireframe = job.wireframe;
  render::TerrainRenderer renderer(*ctx, rend);
  const double context_ms = ms_since(t);
  // Frames 0 and N-1 draw M^A and M^B as the plain view does (their surfaces are M^G(0) and
  // M^G(1)); the frames between draw M^G(alpha), all relative to one origin.
  const render::DrawMesh dm_a = render::make_draw_mesh(a.mesh, hf), dm_b = render::make_draw_mesh(b.mesh, hf);
  std::optional<render::MeshId> id;

  JsonWriter j;
  j.begin_object();
  j.field("input", job.input);
  j.field("output", job.out);
  j.field("selection", "geomorph");
  j.field("frame_count", job.frames);
  for (const auto& [key, cam, sel] : {std::tuple{"from", &cam_a, &a}, {"to", &cam_b, &b}}) {
    j.begin_object(key);
    write_view_json(j, *cam, job.tau);
    j.field("error_bound", sel->mesh.error_bound);
    j.field("bound_px", sel->stats.bound_px);
    j.field("triangles", std::uint64_t(sel->mesh.triangles.size()));
    j.field("vertices", std::uint64_t(sel->mesh.vertices.size()));
    j.field("update_ms", sel->stats.update_ms);
    j.end_object();
  }
  j.begin_object("geomorph");
  j.field("triangles", std::uint64_t(g.triangles.size()));
  j.field("vertices", std::uint64_t(g.plan.size()));
  j.field("crossings", std::uint64_t(crossings));
  j.end_object();
  j.field("renderer", ctx->info().renderer);
  j.begin_array("frames");  // frame k is item k

  const auto t_frames = Clock::now();
  for (int k = 0; k < job.frames; ++k) {
    const auto t_frame = Clock::now();
    const double alpha = double(k) / double(job.frames - 1);  // exactly 0 and 1 at the ends
    pm::Camera cam = interpolate_camera(job.from, job.to, alpha);
    cam.ground = ground.at(cam.x, cam.y);
    fit_clip_to_box(cam, lo, hi);
    const bool end_a = k == 0, end_b = k == job.frames - 1;
    std::optional<pm::RenderMesh> blend;
    if (!end_a && !end_b) blend = g.at(alpha);
    const render::DrawMesh dm_blend =
        blend ? geomorph_draw_mesh(*blend, hf, dm_a.origin, normals) : render::DrawMesh{};
    const render::DrawMesh& dm = end_a ? dm_a : end_b ? dm_b : dm_blend;
    if (id)
      renderer.replace(*id, dm);
    else
      id = renderer.upload(dm);
    const render::FrameStats frame = renderer.draw(cam, {{*id, 0.0f}});
    const std::string png = frame_path(job.out, k);
    render::write_png(renderer.read_color(), png);
    const std::size_t triangles = dm.triangle_count(), vertices = dm.vertex_count();
    if (!job.dump.empty()) {
      const std::string path = frame_path(job.dump, k);
      if (blend) {
        pm::TriangleMeshData world;
        world.positions.reserve(blend->positions.size());
        for (const pm::Vec3& p : blend->positions) world.positions.push_back({p.x, p.y, p.z});
        world.triangles = blend->triangles;
        if (hf.transform.determinant() < 0)  // CCW seen from above, as the plain view writes
          for (auto& tri : world.triangles) std::swap(tri[1], tri[2]);
        pm::write_mesh(world, path);
      } else {
        pm::write_mesh(end_a ? a.mesh : b.mesh, hf, path, pm::Units::World);
      }
    }
    const double bound = (1.0 - alpha) * e_a + alpha * e_b;
    // One line per frame (k is the file's index, 0..N-1): long runs show their progress.
    print_line(
        strf("frame %d/%d alpha=%.4f: %zu triangles, %zu vertices, within %.4g m of the full surface, "
             "draw %s, write %s%s, %s",
             k, job.frames - 1, alpha, triangles, vertices, bound, format_duration(frame.draw_ms).c_str(),
             png.c_str(), job.dump.empty() ? "" : (" and " + frame_path(job.dump, k)).c_str(),
             format_duration(ms_since(t_frame)).c_str()));
    j.begin_object();
    j.field("alpha", alpha);
    j.field("output", png);
    write_view_json(j, cam, job.tau);
    j.field("mesh", end_a ? "from" : end_b ? "to" : "geomorph");
    j.field("triangles", std::uint64_t(triangles));
    j.field("vertices", std::uint64_t(vertices));
    j.field("error_bound_from", e_a);
    j.field("error_bound_to", e_b);
    j.field("error_bound", bound);
    j.field("draw_ms", frame.draw_ms);
    j.end_object();
  }
  const double frames_ms = ms_since(t_frames);
  print_line(strf("morph: %d frames in %s (%s per frame)", job.frames, format_duration(frames_ms).c_str(),
                  format_duration(frames_ms / job.frames).c_str()));
  j.end_array();
  j.begin_object("timings_ms");
  j.field("load", job.load_ms);
  j.field("dag", dag_ms);
  j.field("update_from", a.stats.update_ms);
  j.field("update_to", b.stats.update_ms);
  j.field("geomorph", geomorph_ms);
  j.field("context", context_ms);
  j.field("frames", frames_ms);
  j.end_object();
  j.end_object();
  if (!job.stats_path.empty()) write_statistics(job.stats_path, j);
  return 0;
}

}  // namespace

int cmd_view(const Args& a) {
  const std::string input = a.get("--input"), out = a.get("--out");
  if (lower_extension(out) != ".png")
    throw UsageError("option '--out' must name a .png file, not '" + out + "'");
  const ViewCamera view = view_camera_options(a);
  const double tau = view.tau;
  // --morph-to: its camera and --frames, and what it cannot go with, before anything is read.
  const bool morph = a.has("--morph-to");
  if (a.has("--frames") && !morph) throw UsageError("--frames needs --morph-to");
  MorphJob job;
  if (morph) {
    job.to = camera_option(a, "--morph-to", view.camera);
    job.frames = int(a.get_int("--frames", 2, 2, 10000));
    if (a.has("--db")) throw UsageError("--morph-to is for --input (a .pm file or a DEM), not for --db");
    if (a.has("--uniform"))
      throw UsageError("--morph-to morphs between view-dependent selections, not with --uniform");
    if (a.has("--layer") || a.has("--texture-db") || a.has("--lens"))
      throw UsageError("--morph-to draws the terrain without --layer, --texture-db or --lens");
  }
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
  if (a.has("--objects") && !a.has("--db")) throw UsageError("--objects needs --db (a block database)");
  if (a.has("--db")) {
    if (blocks::BlockDatabase::open(a.get("--db")).info().kind != "hybrid")
      return view_blocks(a, view.camera, tau);
    if (!layer_specs.empty()) throw UsageError("--layer draws on block databases, not on a hybrid one");
    if (a.has("--objects")) throw UsageError("--objects draws on block databases, not on a hybrid one");
    if (a.has("--stats")) throw UsageError("--stats is not available for a hybrid database");
    return view_hybrid(a.get("--db"), view.camera, tau, out, dump, a.has("--wireframe"));
  }

  auto t = Clock::now();
  const pm::ProgressiveMesh mesh = pm_input_stage(input, dem, build);
  const double load_ms = ms_since(t);
  const pm::Heightfield& hf = mesh.heightfield();
  if (morph) {
    job.input = input, job.out = out, job.dump = dump, job.stats_path = stats_path;
    job.from = view.camera, job.tau = tau, job.wireframe = a.has("--wireframe"), job.load_ms = load_ms;
    return view_morph(job, mesh);
  }

  // The frame in ground metres near the eye, as a flight sees it (the identity without a CRS).
  render::Camera cam = view.camera;
  cam.ground = blocks::GroundScaleMap::of(hf).at(cam.x, cam.y);

  // The terrain's bounding box: the clip planes of the render (and of the selection's view),
  // and, for --uniform, the conservative uniform error for tau: every point of a vertical error
  // segment lies in the box, hence at least d_min from the camera as seen (the world distance
  // times the ground scale's smallest singular value, when under 1), so it covers at most
  // E * K_max / d_min pixels anywhere in the image.
  const auto [lo, hi] = terrain_box(hf);
  const double d_min =
      cam.ground.min_distance_scale() *
      pm::distance_to_box({cam.x, cam.y, cam.z}, pm::Box{{lo.x, lo.y, lo.z}, {hi.x, hi.y, hi.z}});
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
    Selected r = select_stage(dag, dag_ms, sel, cam, tau, /*which=*/"");
    sel_stats = r.stats;
    m = std::move(r.mesh);
    extract_ms = r.mesh_ms;
    screen_bound = sel_stats.bound_px;
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
