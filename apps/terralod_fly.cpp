// terralod-fly: the flight-simulation style navigation demo. A GLFW window with flight controls
// and a heads-up display, or, with --headless, the same frames rendered through OSMesa along a
// scripted camera path, written as PNG frames plus a per-frame statistics CSV.
//
// The terrain: a block database through blocks::TerrainRuntime (the approximation tree from its
// root, PM blocks streamed with prefetch, watertight seams, geomorphs, the bound of what is
// drawn), or a single progressive mesh run through pm::SelectiveRefinement: a DEM (built
// in memory, with a progress bar), a .pm file, or, given nothing, the built-in generated
// terrain of `terralod demo`. No terrain algorithm lives here: the app only maps input to a
// camera and library results to pixels and text.
#include <GLFW/glfw3.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "cli_common.hpp"
#include "flight_log.hpp"
#include "layer_options.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/pm/camera_path.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/height_query.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/selective_refinement.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/pm/view.hpp"
#include "terralod/render/camera.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/hud.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/terrain_renderer.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace rd = terralod::render;
namespace tb = terralod::blocks;
using namespace terralod::cli;
using Clock = std::chrono::steady_clock;

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
      "screenshot; Esc quit. G, B, [ and ] take effect at the next frame; nothing is read again.\n"
      "Texture layers (--layer NAME, from --texture-db, which defaults to --db): with --db each\n"
      "drawn patch gets its texture from the layer's texture tree, the coarsest whose texel covers\n"
      "at most --gamma pixels^2 on screen (the parent's texture while one loads; gamma is raised\n"
      "for a frame when the patches would not fit --texture-memory). Keys 1..9 switch\n"
      "layer 1..9 on/off; H switches the highlight lens, which follows the ground point at the\n"
      "screen's centre, or under the mouse while the right button is held (X shows the untextured\n"
      "wireframe).\n"
      "The heads-up display shows frames per second, tau, the bound of what is drawn, triangles,\n"
      "update and draw times, nodes drawn (PM blocks, blocks drawn as their stand-ins, coarse\n"
      "nodes, ancestors drawn for missing blocks), blocks resident/loading/evicted, prefetch misses, bytes "
      "read, resident memory and\n"
      "texture memory.\n\n"
      "--headless renders --frames frames of --path through OSMesa (no display needed) and\n"
      "writes DIR/frame_NNNNN.png, DIR/frames.csv and, with --dump-meshes, DIR/frame_NNNNN.ply\n"
      "(the drawn mesh, binary little-endian, double x y z in the world frame). Frame k is at time\n"
      "k/60 s. Every frame waits for its loads, so runs are reproducible; the window never waits.\n"
      "The same path gives the same statistics (apart from times) and identical images.\n"
      "frames.csv has the columns of 'terralod fly' (see 'terralod fly --help': the runtime's\n"
      "statistics; a single PM fills them as one PM block), then vertices, draw_ms, upload_ms (the\n"
      "drawn mesh converted and sent to the GPU), wait_ms (the wait for loads), texture_bytes (resident\n"
      "in the texture cache), texture_patches (wanted this frame) and textures_from_parent (those\n"
      "drawn with an ancestor's texture while they load; headless frames wait for them).\n"
      "PATH.csv: a header x,y,z,yaw,pitch,fovy and one row per frame (conventions of\n"
      "'terralod view': yaw clockwise from north, pitch above the horizon, degrees).";
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
      {"--replay", "PATH.csv", "window mode: fly this path instead of the controls"},
      {"--frames", "N", "frames to run (headless: default the whole path; window: until closed)"},
      {"--screenshot", "FILE.png", "window mode: write the last frame here on exit"},
      {"--headless", "", "render through OSMesa along --path, no window"},
      {"--path", "PATH.csv", "headless: the scripted camera path (default: a built-in circular flight)"},
      {"--out", "DIR", "headless: output folder (created; default fly_out)"},
      {"--dump-meshes", "", "headless: also write each frame's drawn mesh as PLY"},
      {"--hud", "", "headless: draw the heads-up display into the frames (without its timings)"},
      {"--wireframe", "", "draw the triangle edges over the shading (the window's X toggles it)"},
  };
  for (OptionSpec& o : layer_option_specs()) s.options.push_back(std::move(o));
  return s;
}

// ---------------------------------------------------------------------------------------------
// Terrains: what the frame loop needs from a single PM or a streamed block database.

// The terrain's grid and height range; the drawn mesh's vertices are relative to `origin`.
struct Extent {
  pm::GridTransform transform;
  int width = 0, height = 0;  // samples
  double zmin = 0, zmax = 0;
  glm::dvec3 origin{0.0};  // grid centre at mid height
  std::string name;

  double side_x() const { return transform.spacing_x() * (width - 1); }
  double side_y() const { return transform.spacing_y() * (height - 1); }
  std::pair<double, double> centre() const {
    return transform.to_world((width - 1) / 2.0, (height - 1) / 2.0);
  }
};

Extent make_extent(const pm::GridTransform& t, int width, int height, double zmin, double zmax,
                   std::string name) {
  Extent e{t, width, height, zmin, zmax, {}, std::move(name)};
  const auto [cx, cy] = e.centre();
  e.origin = {cx, cy, 0.5 * (zmin + zmax)};
  return e;
}

// One frame: the level of detail's statistics (the runtime's; a single PM fills the same
// fields as one PM block) and the drawing's.
struct FrameRecord {
  pm::Camera camera;
  tb::RuntimeFrameStats lod;
  bool streamed = false;  // --db: a block database through the runtime
  double draw_ms = 0, upload_ms = 0, wait_ms = 0;
  std::size_t vertices = 0;
  std::size_t texture_bytes = 0;                              // resident in the texture cache
  std::size_t texture_patches = 0, textures_from_parent = 0;  // per-patch textures (--db)
};

// The level-of-detail side of a frame: one selection update and the mesh it draws.
class LodSource {
 public:
  virtual ~LodSource() = default;
  virtual const Extent& extent() const = 0;
  // Height of the terrain under world (x, y), metres (clamped to the terrain).
  virtual double ground(double x, double y) const = 0;
  // A height at or above the terrain under world (x, y) known without loading anything (the
  // built-in flight's reference: it never goes underground).
  virtual double ceiling(double x, double y) const = 0;
  // Sets the camera's near and far planes for this terrain (the selection and the picture use
  // the same frustum, so the bound is true of the picture).
  virtual void fit_clip(pm::Camera& c) const = 0;
  // Runs this frame's selection at time_s; fills r's level-of-detail fields; rewrites `mesh`
  // (origin = extent().origin, CCW from above) and returns true when the drawn mesh changed.
  // wait: finish the loads this frame asks for before returning (headless determinism).
  // r.upload_ms: the time spent making `mesh` (the caller adds the GPU upload).
  virtual bool update(const pm::Camera& c, double time_s, bool wait, FrameRecord& r, rd::DrawMesh& mesh) = 0;
  virtual pm::RefinementOptions options() const = 0;
  virtual void set_options(const pm::RefinementOptions& o) = 0;
  // Triangle target of the budget mode for a whole-frame budget (RefinementOptions::target_triangles).
  virtual std::size_t budget_share(std::size_t budget) const = 0;
  // The approximation-tree node of each triangle of the last mesh (empty: no tree).
  virtual std::span<const std::int64_t> triangle_nodes() const { return {}; }
};

// CPU time of the calling thread, milliseconds (the update's own cost on a loaded machine).
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

// Bitwise equality of two arrays of plain values.
template <class T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// Bilinear ground of a heightfield, the terrain's low point where it has only holes.
double ground_of(const pm::Heightfield& hf, double x, double y, double fallback) {
  const double z = pm::bilinear_height(hf, x, y);
  return std::isfinite(z) ? z : fallback;
}

// One progressive mesh of the whole terrain, refined by pm::SelectiveRefinement.
class PmSource final : public LodSource {
 public:
  PmSource(pm::ProgressiveMesh mesh, const pm::RefinementOptions& o) : pm_(std::move(mesh)) {
    dag_ = std::make_unique<pm::CollapseDag>(pm_);
    sel_ = std::make_unique<pm::SelectiveRefinement>(*dag_, o);
    const pm::Heightfield& hf = pm_.heightfield();
    double zmin = std::numeric_limits<double>::infinity(), zmax = -zmin;
    for (std::size_t i = 0; i < hf.size(); ++i)
      if (hf.valid(i)) zmin = std::min(zmin, hf[i]), zmax = std::max(zmax, hf[i]);
    ext_ = make_extent(hf.transform, hf.width(), hf.height(), zmin, zmax, hf.source);
    normals_.resize(hf.size() * 3);
    for (int r = 0; r < hf.height(); ++r)
      for (int c = 0; c < hf.width(); ++c) {
        const glm::dvec3 n = rd::heightfield_normal(hf, c, r);
        float* p = &normals_[(std::size_t(r) * hf.width() + c) * 3];
        p[0] = float(n.x), p[1] = float(n.y), p[2] = float(n.z);
      }
  }
  const Extent& extent() const override { return ext_; }
  double ground(double x, double y) const override { return ground_of(pm_.heightfield(), x, y, ext_.zmin); }
  double ceiling(double x, double y) const override { return ground(x, y); }
  // Clip planes: reverse-Z depth keeps precision with a near plane close to the eye.
  void fit_clip(pm::Camera& c) const override {
    const double above = c.z - ground(c.x, c.y);
    c.near_m = std::clamp(0.25 * std::max(above, 0.0), 0.1, 100.0);
    const double extent = ext_.transform.spacing_x() * ext_.width + ext_.transform.spacing_y() * ext_.height;
    c.far_m = std::max(c.near_m * 2.0, 2.0 * extent + std::fabs(c.z - ext_.zmin) * 2.0);
  }
  pm::RefinementOptions options() const override { return sel_->options(); }
  void set_options(const pm::RefinementOptions& o) override { sel_->set_options(o); }
  std::size_t budget_share(std::size_t budget) const override { return budget; }
  const pm::ProgressiveMesh& pm() const { return pm_; }

  bool update(const pm::Camera& c, double time_s, bool /*wait*/, FrameRecord& r, rd::DrawMesh& dm) override {
    const double cpu0 = thread_cpu_ms();
    const pm::FrameStats& s = sel_->update(pm::View(c), time_s);
    tb::RuntimeFrameStats& l = r.lod;
    l.update_cpu_ms = thread_cpu_ms() - cpu0;
    l.update_ms = s.update_ms, l.moving_vertices = s.morphing;
    l.bound_px = s.bound_px, l.tolerance_px = s.tolerance_px, l.triangles = s.triangles;
    l.pm_blocks = l.blocks_resident = l.nodes_resident = l.nodes_visited = 1;
    // The displayed mesh (geomorph positions) relative to the origin, normals of the
    // full-resolution samples, triangles CCW seen from above.
    const auto t0 = Clock::now();
    const pm::RenderMesh m = sel_->render_mesh();
    const bool flip = ext_.transform.determinant() < 0;
    const glm::dvec3 o = ext_.origin;
    dm.origin = o;
    dm.z_target.clear();
    dm.xyz.resize(m.positions.size() * 3);
    dm.normals.resize(m.positions.size() * 3);
    for (std::size_t v = 0; v < m.positions.size(); ++v) {
      dm.xyz[3 * v] = float(m.positions[v].x - o.x);
      dm.xyz[3 * v + 1] = float(m.positions[v].y - o.y);
      dm.xyz[3 * v + 2] = float(m.positions[v].z - o.z);
      std::copy_n(&normals_[std::size_t(m.samples[v]) * 3], 3, &dm.normals[3 * v]);
    }
    dm.indices.resize(m.triangles.size() * 3);
    for (std::size_t f = 0; f < m.triangles.size(); ++f) {
      dm.indices[3 * f] = m.triangles[f][0];
      dm.indices[3 * f + 1] = m.triangles[f][flip ? 2 : 1];
      dm.indices[3 * f + 2] = m.triangles[f][flip ? 1 : 2];
    }
    r.upload_ms = ms_since(t0);
    return true;
  }

 private:
  pm::ProgressiveMesh pm_;
  std::unique_ptr<pm::CollapseDag> dag_;
  std::unique_ptr<pm::SelectiveRefinement> sel_;
  std::vector<float> normals_;  // per sample, world frame
  Extent ext_;
};

// The single-PM terrains: a DEM built in memory, a .pm file, or the built-in terrain.
std::unique_ptr<PmSource> open_pm_terrain(const std::string& input, int generated_size,
                                          const pm::RefinementOptions& o) {
  const auto t0 = Clock::now();
  pm::BuildOptions b;
  b.parallel_strips = false;  // no full-resolution cut column in the view-dependent mesh
  pm::ProgressiveMesh mesh = [&] {
    if (!input.empty()) return is_pm_file(input) ? read_pm_stage(input) : build_stage(read_stage(input), b);
    const pm::Heightfield hf = pm::generate_terrain(demo_terrain_options(generated_size));
    std::printf("terrain: the built-in generated terrain, %d x %d samples\n", hf.width(), hf.height());
    return build_stage(hf, b);
  }();
  auto src = std::make_unique<PmSource>(std::move(mesh), o);
  const Extent& e = src->extent();
  std::printf("terrain: %s, %d x %d samples, %zu vsplits, heights %.1f..%.1f m, ready in %s\n",
              e.name.c_str(), e.width, e.height, src->pm().vsplit_count(), e.zmin, e.zmax,
              format_duration(ms_since(t0)).c_str());
  return src;
}

// A block database through blocks::TerrainRuntime (the tree from its root, PM blocks streamed).
class DbSource final : public LodSource {
 public:
  DbSource(const std::string& path, const pm::RefinementOptions& o, const tb::RuntimeOptions& base)
      : path_(path) {
    const auto t0 = Clock::now();
    tb::RuntimeOptions ro = base;
    ro.tolerance_px = o.tolerance_px;
    ro.target_triangles = o.target_triangles;
    ro.morph_seconds = o.morph_seconds;
    rt_ = std::make_unique<tb::TerrainRuntime>(path, ro);
    opt_ = o;
    const tb::BlockGrid& g = rt_->grid();
    const pm::Box& box = rt_->terrain_box();
    ext_ = make_extent(g.transform(), g.grid_width(), g.grid_height(), box.lo.z, box.hi.z, path);
    std::printf(
        "terrain: %s, %d x %d samples in %d x %d blocks of %d, tree of %zu nodes, heights %.1f..%.1f m, "
        "ready in %s\n",
        path.c_str(), g.grid_width(), g.grid_height(), g.cols(), g.rows(), g.block_size(), rt_->tree().size(),
        box.lo.z, box.hi.z, format_duration(ms_since(t0)).c_str());
  }
  const Extent& extent() const override { return ext_; }
  pm::RefinementOptions options() const override { return opt_; }
  // Live: tau, the budget mode and the geomorph time apply from the next frame; nothing is
  // read again.
  void set_options(const pm::RefinementOptions& o) override {
    opt_ = o;
    tb::RuntimeOptions ro = rt_->options();
    ro.tolerance_px = o.tolerance_px;
    ro.target_triangles = o.target_triangles;
    ro.morph_seconds = o.morph_seconds;
    rt_->set_options(ro);
  }
  // The runtime regulates tau over the whole frame.
  std::size_t budget_share(std::size_t budget) const override { return budget; }
  // The surface as drawn last frame (the terrain's low point where nothing is drawn).
  double ground(double x, double y) const override {
    const double z = rt_->drawn_height(x, y);
    return std::isfinite(z) ? z : ext_.zmin;
  }
  // The highest sample under (x, y) that the tree knows without loading anything.
  double ceiling(double x, double y) const override { return rt_->max_height_at(x, y); }
  std::span<const std::int64_t> triangle_nodes() const override { return rt_->drawn_mesh().triangle_node; }
  void fit_clip(pm::Camera& c) const override { rt_->fit_clip_planes(c); }

  bool update(const pm::Camera& c, double time_s, bool wait, FrameRecord& r, rd::DrawMesh& dm) override {
    const pm::View view(c);
    r.streamed = true;
    if (wait) {
      // Headless: the frames must not depend on the loader thread's timing.
      const auto w0 = Clock::now();
      const tb::RuntimeFrameStats first = rt_->update_until_loaded(view, time_s);
      r.wait_ms = ms_since(w0) - first.update_ms;
      r.lod = rt_->stats();
      // The work of the frame is the first update's (the others only pick up loads).
      r.lod.update_ms = first.update_ms, r.lod.update_cpu_ms = first.update_cpu_ms;
    } else {
      r.lod = rt_->update(view, time_s);
    }
    const auto t0 = Clock::now();
    const tb::DrawnMesh& m = rt_->drawn_mesh();
    if (built_ && same_bytes(m.positions, prev_positions_) && same_bytes(m.triangles, prev_triangles_))
      return false;  // nothing moved: keep the uploaded mesh
    built_ = true;
    prev_positions_ = m.positions, prev_triangles_ = m.triangles;
    rd::fill_draw_mesh(m, ext_.origin, ext_.transform.determinant() < 0, dm);
    r.upload_ms = ms_since(t0);
    return true;
  }

 private:
  std::string path_;
  pm::RefinementOptions opt_;
  std::unique_ptr<tb::TerrainRuntime> rt_;
  Extent ext_;
  std::vector<pm::Vec3> prev_positions_;
  std::vector<std::array<std::uint32_t, 3>> prev_triangles_;
  bool built_ = false;
};

// ---------------------------------------------------------------------------------------------
// One frame of the pipeline: selection (and loads), upload, draw.

class Pipeline {
 public:
  Pipeline(LodSource& src, rd::GlContext& ctx) : src_(src), renderer_(ctx) {}

  // Texture layers: drawn through a LayeredRenderer on the same context (not in wireframe).
  void set_layers(rd::GlContext& ctx, LayerSetup* layers) {
    layers_ = layers;
    layered_ = std::make_unique<rd::LayeredRenderer>(ctx);
    layers_->attach(*layered_);
  }
  LayerSetup* layers() { return layers_; }
  bool drew_layered() const { return drew_layered_; }
  rd::Image read_color() const { return drew_layered_ ? layered_->read_color() : renderer_.read_color(); }

  rd::TerrainRenderer& renderer() { return renderer_; }
  LodSource& source() { return src_; }
  bool frozen = false, wireframe = false;

  // wait: headless, the frame waits for its block loads (see LodSource::update).
  FrameRecord frame(const pm::Camera& cam, double time_s, bool wait) {
    if (!frozen) {
      FrameRecord lod;
      if (src_.update(cam, time_s, wait, lod, dm_)) {
        // The whole mesh is replaced: with --db the runtime's heights already hold the
        // geomorphs, so it is drawn at alpha 0 with no target heights (see the README numbers:
        // replacing costs less than a tenth of the draw on llvmpipe).
        const auto t = Clock::now();
        if (!id_)
          id_ = renderer_.upload(dm_);
        else
          renderer_.replace(*id_, dm_);
        ++version_;
        lod.upload_ms += ms_since(t);
      }
      last_ = lod;
    } else {  // the frozen mesh: no selection work this frame
      last_.lod.update_ms = last_.lod.update_cpu_ms = last_.upload_ms = last_.wait_ms = 0;
    }
    FrameRecord r = last_;
    r.camera = cam;
    r.vertices = dm_.vertex_count();
    const rd::Camera& rc = cam;  // one camera type from the selection to the GPU
    drew_layered_ = layers_ && !wireframe;
    if (drew_layered_) {
      if (layers_->per_patch())
        draw_patches(rc, pm::View(cam), wait, r);
      else
        draw_whole_layers(rc, r);
      r.texture_bytes = layers_->resident_bytes();
      return r;
    }
    renderer_.options().wireframe = wireframe;
    r.draw_ms = renderer_.draw(rc, {{*id_, 0.0f}}).draw_ms;
    if (layers_) r.texture_bytes = layers_->resident_bytes();
    return r;
  }

  const rd::DrawMesh& draw_mesh() const { return dm_; }

 private:
  // Whole-layer mode: one texture per layer over the whole mesh.
  void draw_whole_layers(const rd::Camera& rc, FrameRecord& r) {
    if (!layered_id_ || layered_version_ != version_) {
      const auto t = Clock::now();
      if (layered_id_) layered_->remove(*layered_id_);
      layered_id_ = layered_->upload(dm_);
      layered_version_ = version_;
      r.upload_ms += ms_since(t);
    }
    const rd::LayeredItem item{*layered_id_, layers_->bindings(*layered_)};
    r.draw_ms = layered_->draw(rc, layers_->styles(), layers_->lens(), {item}).draw_ms;
  }

  // Per-patch mode (--db): the mesh's triangles ordered by the textures of their nodes, one
  // item per group. wait (headless): the frame waits for its wanted patches, so every frame
  // shows the textures gamma asks for and runs are reproducible.
  void draw_patches(const rd::Camera& rc, const pm::View& view, bool wait, FrameRecord& r) {
    const auto t_wait = Clock::now();
    const rd::PatchTextureFrame& f = layers_->patch_frame(view, src_.triangle_nodes(), wait);
    if (wait) r.wait_ms += ms_since(t_wait);
    if (!layered_id_ || layered_version_ != version_ || f.triangle_order != layered_order_) {
      const auto t = Clock::now();
      rd::order_triangles(dm_, f.triangle_order, sorted_);
      if (layered_id_) layered_->remove(*layered_id_);
      layered_id_ = layered_->upload(sorted_);
      layered_version_ = version_;
      layered_order_ = f.triangle_order;
      r.upload_ms += ms_since(t);
    }
    const std::vector<rd::LayeredItem> items = layers_->items(*layered_, *layered_id_, f);
    r.draw_ms = layered_->draw(rc, layers_->styles(), layers_->lens(), items).draw_ms;
    r.texture_patches = f.stats.wanted;
    r.textures_from_parent = f.stats.from_parent;
  }

  LodSource& src_;
  rd::TerrainRenderer renderer_;
  rd::DrawMesh dm_;
  std::optional<rd::MeshId> id_;
  FrameRecord last_;
  LayerSetup* layers_ = nullptr;
  std::unique_ptr<rd::LayeredRenderer> layered_;
  std::optional<rd::MeshId> layered_id_;
  std::uint64_t version_ = 0, layered_version_ = 0;
  std::vector<std::uint32_t> layered_order_;  // per-patch mode: the uploaded triangle order
  rd::DrawMesh sorted_;
  bool drew_layered_ = false;
};

// --texture-db (default --db) / --layer / --lens (layer_options.hpp); nullopt without layers.
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
  const std::vector<rd::PatchDomain> tree = rd::tree_domains(tb::BlockDatabase::open(a.get("--db")));
  return LayerSetup::open(a.get("--texture-db", a.get("--db")), specs, lens, lo, &tree);
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

// The terrain of the command line: --db, else --input or the built-in terrain.
std::unique_ptr<LodSource> open_terrain(const Args& a) {
  if (a.has("--db") && a.has("--input")) throw UsageError("--db and --input exclude each other");
  if (a.has("--db") && a.has("--terrain-size"))
    throw UsageError("--terrain-size is for the built-in terrain, not --db");
  const pm::RefinementOptions o = refinement_options(a);
  const int size = int(a.get_int("--terrain-size", kDemoTerrainSize, 2, 8193));
  if (!a.has("--db") && (a.has("--memory") || a.has("--theta")))
    throw UsageError("--memory and --theta need --db");
  if (a.has("--db")) {
    tb::RuntimeOptions ro;
    ro.region.theta_deg = a.get_double("--theta", ro.region.theta_deg);
    if (!(ro.region.theta_deg > 0 && ro.region.theta_deg < 90))
      throw UsageError("--theta must be in (0, 90) degrees");
    const double mb = a.get_double("--memory", double(ro.budget_bytes) / 1e6);
    if (!(mb > 0)) throw UsageError("--memory must be > 0 megabytes");
    ro.budget_bytes = std::size_t(mb * 1e6);
    return std::make_unique<DbSource>(a.get("--db"), o, ro);
  }
  return open_pm_terrain(a.get("--input"), size, o);
}

// The heads-up display's lines about the level of detail of a frame (the window's and, with
// --hud, the headless frames'; without timings the text is the same on every run).
std::vector<std::string> lod_lines(const FrameRecord& r, const pm::RefinementOptions& now, bool timings) {
  const tb::RuntimeFrameStats& l = r.lod;
  return {
      // One PM (no --db): its bound is the selection's; the display lags it while vertices morph.
      r.streamed
          ? strf("tau %.2f px%s   drawn within %.3f px%s", l.tolerance_px,
                 now.target_triangles ? strf(" (budget %zu)", now.target_triangles).c_str() : "", l.bound_px,
                 l.missing_in_view
                     ? strf(" (%zu blocks missing: over tau allowed)", l.missing_in_view).c_str()
                     : "")
          : strf("tau %.2f px%s   selection within %.3f px%s", l.tolerance_px,
                 now.target_triangles ? strf(" (budget %zu)", now.target_triangles).c_str() : "", l.bound_px,
                 l.moving_vertices ? strf(" (display lags: %zu vertices morphing)", l.moving_vertices).c_str()
                                   : ""),
      timings ? strf("%zu triangles   update %.2f ms   draw %.2f ms", l.triangles, l.update_ms, r.draw_ms)
              : strf("%zu triangles", l.triangles),
      r.streamed
          ? strf("nodes drawn %zu (%zu PM blocks, %zu stand-ins, %zu coarse, %zu for missing blocks)   "
                 "culled %zu",
                 l.pm_blocks + l.standin_blocks + l.coarse_nodes, l.pm_blocks, l.standin_blocks,
                 l.coarse_nodes, l.fallback_nodes, l.nodes_culled)
          : std::string("nodes drawn 1 (one PM)"),
      r.streamed
          ? strf("blocks resident %zu, loading %zu, evicted %zu   prefetch misses %zu   read %s   memory %s",
                 l.blocks_resident, l.blocks_loading, l.evicted_total, l.prefetch_misses_total,
                 format_bytes(l.bytes_read_total).c_str(), format_bytes(l.resident_bytes).c_str())
          : std::string("blocks resident 1, loading 0"),
      strf("texture memory %s%s", format_bytes(r.texture_bytes).c_str(),
           r.texture_patches ? strf(" (%zu patches wanted, %zu drawn with a parent's)", r.texture_patches,
                                    r.textures_from_parent)
                                   .c_str()
                             : "")};
}

// Draws text over an image at its top-left corner (alpha-blended, the HUD's look).
void overlay_text(rd::Image& img, const rd::TextImage& t, int margin) {
  for (int y = 0; y < t.height && y + margin < img.height; ++y)
    for (int x = 0; x < t.width && x + margin < img.width; ++x) {
      const std::uint8_t* s = &t.rgba[(std::size_t(y) * t.width + x) * 4];
      std::uint8_t* d = img.pixel(x + margin, y + margin);
      for (int c = 0; c < 3; ++c) d[c] = std::uint8_t((s[c] * s[3] + d[c] * (255 - s[3]) + 127) / 255);
    }
}

// ---------------------------------------------------------------------------------------------
// Headless

// The flight used when no --path is given: a circle of radius 30% of the extent around the
// terrain's centre, 200 m above the ground under the camera (with --db: above the highest
// sample of the block under it, as no block is loaded yet), looking along the path and 15
// degrees down, one lap in 20 s (1200 frames at 60 fps) or slower, so that the speed is at most
// 500 m/s (large terrains).
std::vector<pm::Camera> default_flight(const LodSource& t, int frames, int w, int h) {
  const Extent& e = t.extent();
  const auto [cx, cy] = e.centre();
  const double radius = 0.3 * std::min(e.side_x(), e.side_y());
  const double lap_frames = std::max(1200.0, 60.0 * 2.0 * std::numbers::pi * radius / 500.0);
  std::vector<pm::Camera> path;
  for (int k = 0; k < frames; ++k) {
    const double a = 2.0 * std::numbers::pi * k / lap_frames;
    pm::Camera c;
    c.x = cx + radius * std::cos(a), c.y = cy + radius * std::sin(a);
    c.z = t.ceiling(c.x, c.y) + 200.0;
    // Moving counter-clockwise: the direction of motion is (-sin a, cos a); yaw from north.
    c.yaw_deg = std::atan2(-std::sin(a), std::cos(a)) * 180.0 / std::numbers::pi;
    c.pitch_deg = -15.0, c.fovy_deg = 60.0, c.width_px = w, c.height_px = h;
    path.push_back(c);
  }
  return path;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(q * double(v.size())))];
}

int run_headless(const Args& a) {
  const auto [w, h] = parse_size(a);
  const std::string out = a.get("--out", "fly_out");
  pm::CameraPathOptions po;
  po.width_px = w, po.height_px = h;
  std::vector<pm::Camera> path;
  if (a.has("--path")) path = pm::read_camera_path(a.get("--path"), po);
  const bool dump = a.has("--dump-meshes"), hud = a.has("--hud");
  std::optional<LayerSetup> layers = layer_setup(a);
  const std::unique_ptr<LodSource> t = open_terrain(a);
  if (path.empty()) {
    path = default_flight(*t, int(a.get_int("--frames", 240, 1, 1000000)), w, h);
    std::printf(
        "path: built-in flight, %zu frames (a circle 200 m above the ground, with --db above its block's "
        "highest sample, looking 15 degrees down)\n",
        path.size());
  }
  const long long frames = a.get_int("--frames", (long long)path.size(), 1, (long long)path.size());
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec || !fs::is_directory(out)) throw std::runtime_error(out + ": cannot create the output folder");
  auto ctx = rd::create_offscreen_context({w, h});
  Pipeline p(*t, *ctx);
  p.wireframe = a.has("--wireframe");
  if (layers) {
    layers->wait_loaded(/*timeout_ms=*/600000);  // every frame sees every layer: deterministic
    p.set_layers(*ctx, &*layers);
  }
  FlightLog log(out, /*drawing=*/true);  // the columns of 'terralod fly', then the drawing's
  ProgressBar bar("render " + std::to_string(frames) + " frames");
  std::vector<double> update_ms, update_cpu_ms, frame_ms, triangles, resident;
  double worst_bound = 0, wait_ms = 0;  // worst bound / tau of the frames with nothing missing
  std::size_t complete = 0;
  for (long long k = 0; k < frames; ++k) {
    pm::Camera c = path[std::size_t(k)];
    t->fit_clip(c);
    const FrameRecord r = p.frame(c, double(k) / 60.0, /*wait=*/true);
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
    rd::Image img = p.read_color();
    if (hud) {
      std::vector<std::string> lines = lod_lines(r, t->options(), /*timings=*/false);
      lines[0] = strf("frame %lld   ", k) + lines[0];
      overlay_text(img, rd::rasterize_text(lines), rd::HudOptions{}.margin);
    }
    rd::write_png(img, (fs::path(out) / (std::string(name) + ".png")).string());
    if (dump)
      pm::write_mesh(rd::world_mesh(p.draw_mesh()), (fs::path(out) / (std::string(name) + ".ply")).string());
    bar.update(double(k + 1) / double(frames));
  }
  bar.finish();
  log.commit();
  std::printf("headless: %lld frames %dx%d -> %s (PNG%s, frames.csv); tau %g px\n", frames, w, h, out.c_str(),
              dump ? ", PLY" : "", t->options().tolerance_px);
  std::printf(
      "headless: frame (update + upload + draw) median %.2f ms, p99 %.2f ms; update median %.3f ms, p99 %.3f "
      "ms (thread CPU: median %.3f ms, p99 %.3f ms); triangles median %.0f, max %.0f\n",
      percentile(frame_ms, 0.5), percentile(frame_ms, 0.99), percentile(update_ms, 0.5),
      percentile(update_ms, 0.99), percentile(update_cpu_ms, 0.5), percentile(update_cpu_ms, 0.99),
      percentile(triangles, 0.5), percentile(triangles, 1.0));
  if (!resident.empty())
    std::printf("headless: blocks resident median %.0f, max %.0f; waited %s for block loads in all\n",
                percentile(resident, 0.5), percentile(resident, 1.0), format_duration(wait_ms).c_str());
  // The last line: the guarantee as measured on this run, and the update's cost.
  std::printf(
      "headless: guarantee: %zu of %lld frames had nothing missing, and in those the drawn mesh was within "
      "%.3f x tau (bound / tau <= 1 is the promise); update thread CPU median %.3f ms, p99 %.3f ms\n",
      complete, frames, worst_bound, percentile(update_cpu_ms, 0.5), percentile(update_cpu_ms, 0.99));
  return 0;
}

// ---------------------------------------------------------------------------------------------
// Window

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

struct Controls {
  double speed = 80.0;  // m/s along the view direction
  double climb = 0.0;   // m/s
  bool follow = true, recording = false;
};

int run_window(const Args& a) {
  const auto [w, h] = parse_size(a);
  std::optional<LayerSetup> layers = layer_setup(a);  // usage errors before the terrain loads
  const std::unique_ptr<LodSource> t = open_terrain(a);
  const Extent& ext = t->extent();
  std::vector<pm::Camera> replay;
  if (a.has("--replay")) {
    pm::CameraPathOptions po;
    po.width_px = w, po.height_px = h;
    replay = pm::read_camera_path(a.get("--replay"), po);
  }
  const long long max_frames =
      a.get_int("--frames", replay.empty() ? -1 : (long long)replay.size(), -1, 1LL << 40);
  const std::string record_path = a.get("--record", "flight.csv");
  const double clearance = a.get_double("--clearance", 30.0);
  const std::size_t budget = std::size_t(a.get_int("--budget", 50000, 100, 100000000));

  rd::WindowOptions wo;
  wo.width = w, wo.height = h, wo.title = "terralod-fly";
  auto win = rd::WindowContext::create(wo);
  Pipeline p(*t, *win);
  p.wireframe = a.has("--wireframe");
  if (layers) {
    p.set_layers(*win, &*layers);
    if (layers->lens_radius() <= 0) {  // no --lens: H shows one of 4% of the terrain's width
      layers->set_lens_radius(0.04 * ext.side_x());
    }
  }
  rd::Hud hud(*win);
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
        double mx = 0, my = 0;
        int ww = 1, wh = 1;
        glfwGetCursorPos(gw, &mx, &my);
        glfwGetWindowSize(gw, &ww, &wh);
        yaw_rate = 90.0 * (mx / ww - 0.5) * 2.0;
        pitch_rate = -60.0 * (my / wh - 0.5) * 2.0;
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
    }
    int fw = 1, fh = 1;
    glfwGetFramebufferSize(gw, &fw, &fh);
    cam.width_px = std::max(1, fw), cam.height_px = std::max(1, fh);
    t->fit_clip(cam);
    if (ctl.recording) recorded.push_back(cam);
    if (layers && layers->lens().enabled) {  // the lens follows the centre, or the mouse (right button)
      double sx = 0, sy = 0;
      if (glfwGetMouseButton(gw, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS) {
        double mx = 0, my = 0;
        int ww = 1, wh = 1;
        glfwGetCursorPos(gw, &mx, &my);
        glfwGetWindowSize(gw, &ww, &wh);
        sx = 2.0 * mx / ww - 1.0, sy = 1.0 - 2.0 * my / wh;
      }
      if (const auto g = ground_point(*t, cam, sx, sy)) layers->move_lens((*g)[0], (*g)[1]);
    }

    r = p.frame(cam, time_s, /*wait=*/false);
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
      rd::write_png(p.renderer().read_window_color(/*blit=*/false), name);
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
    rd::write_png(p.read_color(), a.get("--screenshot"));
    std::printf("wrote %s\n", a.get("--screenshot").c_str());
  }
  std::printf("flew %lld frames, last: %zu triangles, drawn within %.3f px\n", frame, r.lod.triangles,
              r.lod.bound_px);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const CommandSpec spec = fly_spec();
  try {
    const Args a(spec, std::vector<std::string>(argv + 1, argv + argc));
    if (a.help()) {
      std::fputs(spec.usage().c_str(), stdout);
      return 0;
    }
    return a.has("--headless") ? run_headless(a) : run_window(a);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "terralod-fly: %s (see 'terralod-fly --help')\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod-fly: %s\n", e.what());
    return 1;
  }
}
