// terralod-fly: the flight-simulation style navigation demo. A GLFW window with flight controls
// and a heads-up display, or, with --headless, the same frames rendered through OSMesa along a
// scripted camera path, written as PNG frames plus a per-frame statistics CSV.
//
// The terrain: a DEM (built into a progressive mesh in memory, with a progress bar), a .pm
// file, or, given nothing, the built-in generated terrain of `terralod demo`. Every frame runs
// the view-dependent selection (pm::SelectiveRefinement) at the tolerance tau with geomorphs,
// uploads the displayed mesh and draws it. No terrain algorithm lives here: the app only maps
// input to a camera and library results to pixels and text.
#include <GLFW/glfw3.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "layer_options.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/camera_path.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/pm_io.hpp"
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
using namespace terralod::cli;
using Clock = std::chrono::steady_clock;

CommandSpec fly_spec() {
  CommandSpec s;
  s.name = "terralod-fly";
  s.summary = "fly over a terrain with view-dependent level of detail";
  s.description =
      "Opens a window and flies over the terrain: a DEM (built into a progressive mesh in\n"
      "memory), a .pm file, or, given no --input, the built-in generated terrain. Every frame\n"
      "selects the mesh whose screen-space error is at most --tau pixels (guaranteed), with\n"
      "geomorphs, and draws it.\n\n"
      "Controls: hold the left mouse button and move the mouse off the window's centre to steer\n"
      "(the farther, the faster the turn); W/S throttle up/down; R/F climb/descend; arrow keys\n"
      "turn and pitch; T terrain following (never below --clearance over the ground); G geomorphs\n"
      "on/off; X wireframe; L freeze the level of detail (fly around it to inspect it from\n"
      "outside); B triangle-budget mode (holds --budget triangles by regulating tau); [ and ]\n"
      "tau down/up; C start/stop recording the flight to --record; P screenshot; Esc quit.\n"
      "Texture layers (--texture-db with --layer, as in 'terralod view'): keys 1..9 switch layer\n"
      "1..9 on/off; H switches the highlight lens, which follows the ground point at the screen's\n"
      "centre, or under the mouse while the right button is held (X shows the untextured wireframe).\n"
      "The heads-up display shows frames per second, tau, triangles, nodes selected, blocks\n"
      "resident/loading, texture memory and the guaranteed bound.\n\n"
      "--headless renders --frames frames of --path through OSMesa (no display needed) and\n"
      "writes DIR/frame_NNNNN.png, DIR/frames.csv (camera, tau, triangles, update time, bound,\n"
      "draw time, nodes, blocks, loads) and, with --dump-meshes, DIR/frame_NNNNN.ply (the drawn\n"
      "mesh, binary little-endian, double x y z in the world frame). Frame k is at time k/60 s,\n"
      "so the same path gives the same statistics (apart from times) and identical images.\n"
      "PATH.csv: a header x,y,z,yaw,pitch,fovy and one row per frame (conventions of\n"
      "'terralod view': yaw clockwise from north, pitch above the horizon, degrees).";
  s.options = {{"--input", "FILE", "a DEM or a .pm file (default: the built-in generated terrain)"},
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
               {"--texture-db", "FILE.db", "block database holding the texture layers of --layer"},
               {"--layer", "NAME[:OP[:W[:lens]]]",
                "draw a texture layer (repeatable, in order): OP blend|add|subtract|multiply, W in [0,1]", false,
                /*repeatable=*/true},
               {"--lens", "X,Y,RADIUS", "highlight lens (world metres) masking the layers marked ':lens'"}};
  return s;
}

// ---------------------------------------------------------------------------------------------
// Terrain

struct Terrain {
  pm::ProgressiveMesh pm;
  std::unique_ptr<pm::CollapseDag> dag;
  std::vector<float> normals;  // per sample, world frame
  double zmin = 0, zmax = 0;
  glm::dvec3 origin{0.0};
  std::array<double, 4> inverse{};  // (x, y) -> (col, row) linear part
};

Terrain load_terrain(const std::string& input, int generated_size) {
  auto t0 = Clock::now();
  pm::ProgressiveMesh mesh = [&] {
    if (input.empty()) {
      pm::TerrainOptions o;  // the built-in terrain of `terralod demo`
      o.width = o.height = generated_size;
      o.seed = 1;
      o.roughness = 0.42;
      o.height_quantum = 1.0 / 16.0;
      const pm::Heightfield hf = pm::generate_terrain(o);
      ProgressBar bar("build PM of the built-in terrain");
      pm::BuildOptions b;
      b.parallel_strips = false;  // no full-resolution cut column in the view-dependent mesh
      b.progress = [&](double f) { return bar.update(f); };
      return pm::ProgressiveMesh::build(hf, b);
    }
    std::string ext = fs::path(input).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (ext == ".pm") return pm::read_pm(input);
    const pm::Heightfield hf = terralod::blocks::read_dem(input);
    ProgressBar bar("build PM of " + input);
    pm::BuildOptions b;
    b.parallel_strips = false;
    b.progress = [&](double f) { return bar.update(f); };
    return pm::ProgressiveMesh::build(hf, b);
  }();
  Terrain t{std::move(mesh), nullptr, {}, 0, 0, {}, {}};
  t.dag = std::make_unique<pm::CollapseDag>(t.pm);
  const pm::Heightfield& hf = t.pm.heightfield();
  t.zmin = std::numeric_limits<double>::infinity(), t.zmax = -t.zmin;
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i)) t.zmin = std::min(t.zmin, hf[i]), t.zmax = std::max(t.zmax, hf[i]);
  t.normals.resize(hf.size() * 3);
  for (int r = 0; r < hf.height(); ++r)
    for (int c = 0; c < hf.width(); ++c) {
      const glm::dvec3 n = rd::heightfield_normal(hf, c, r);
      float* p = &t.normals[(std::size_t(r) * hf.width() + c) * 3];
      p[0] = float(n.x), p[1] = float(n.y), p[2] = float(n.z);
    }
  const auto [cx, cy] = hf.transform.to_world((hf.width() - 1) / 2.0, (hf.height() - 1) / 2.0);
  t.origin = {cx, cy, 0.5 * (t.zmin + t.zmax)};
  const pm::GridTransform& g = hf.transform;
  const double det = g.determinant();
  t.inverse = {g.yr / det, -g.xr / det, -g.yc / det, g.xc / det};
  std::printf("terrain: %s, %d x %d samples, %zu vsplits, heights %.1f..%.1f m, ready in %s\n",
              hf.source.c_str(), hf.width(), hf.height(), t.pm.vsplit_count(), t.zmin, t.zmax,
              format_duration(ms_since(t0)).c_str());
  return t;
}

// Bilinear ground height under world (x, y), clamped to the grid.
double ground(const Terrain& t, double x, double y) {
  const pm::Heightfield& hf = t.pm.heightfield();
  const double dx = x - hf.transform.x0, dy = y - hf.transform.y0;
  const double c = std::clamp(t.inverse[0] * dx + t.inverse[1] * dy, 0.0, double(hf.width() - 1));
  const double r = std::clamp(t.inverse[2] * dx + t.inverse[3] * dy, 0.0, double(hf.height() - 1));
  const int c0 = std::min(int(c), hf.width() - 2 < 0 ? 0 : hf.width() - 2);
  const int r0 = std::min(int(r), hf.height() - 2 < 0 ? 0 : hf.height() - 2);
  const int c1 = std::min(c0 + 1, hf.width() - 1), r1 = std::min(r0 + 1, hf.height() - 1);
  const double fc = c - c0, fr = r - r0;
  return (1 - fr) * ((1 - fc) * hf.at(c0, r0) + fc * hf.at(c1, r0)) + fr * ((1 - fc) * hf.at(c0, r1) + fc * hf.at(c1, r1));
}

// ---------------------------------------------------------------------------------------------
// One frame of the pipeline: selection, geomorphs, upload, draw.

struct FrameRecord {
  pm::Camera camera;
  double tau = 0, bound_px = 0, update_ms = 0, draw_ms = 0;
  std::size_t triangles = 0, vertices = 0, vsplits = 0, ecols = 0, morphing = 0;
  std::size_t texture_bytes = 0;  // resident in the texture cache
};

class Pipeline {
 public:
  Pipeline(const Terrain& t, rd::GlContext& ctx, const pm::RefinementOptions& o)
      : t_(t), sel_(*t.dag, o), renderer_(ctx) {}

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
  pm::SelectiveRefinement& selection() { return sel_; }
  bool frozen = false, wireframe = false;

  FrameRecord frame(const pm::Camera& cam, double time_s) {
    FrameRecord r;
    r.camera = cam;
    pm::Camera c = cam;
    if (!frozen) {
      const pm::FrameStats& s = sel_.update(pm::View(c), time_s);
      r.update_ms = s.update_ms, r.vsplits = s.vsplits, r.ecols = s.ecols, r.morphing = s.morphing;
      bound_ = s.bound_px;
      tau_ = s.tolerance_px;
      upload();
    }
    r.tau = tau_, r.bound_px = bound_;
    r.triangles = dm_.triangle_count(), r.vertices = dm_.vertex_count();
    rd::Camera rc;
    rc.position = {c.x, c.y, c.z};
    rc.yaw_deg = c.yaw_deg, rc.pitch_deg = c.pitch_deg, rc.fovy_deg = c.fovy_deg;
    rc.width = c.width_px, rc.height = c.height_px;
    rc.z_near = c.near_m, rc.z_far = c.far_m;
    drew_layered_ = layers_ && !wireframe;
    if (drew_layered_) {
      if (!layered_id_ || layered_version_ != version_) {
        if (layered_id_) layered_->remove(*layered_id_);
        layered_id_ = layered_->upload(dm_);
        layered_version_ = version_;
      }
      const rd::LayeredItem item{*layered_id_, layers_->bindings(*layered_)};
      r.draw_ms = layered_->draw(rc, layers_->styles(), layers_->lens(), {item}).draw_ms;
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
  // The displayed mesh (geomorph positions) as a DrawMesh relative to the terrain's origin,
  // normals of the full-resolution samples, triangles CCW seen from above.
  void upload() {
    const pm::RenderMesh m = sel_.render_mesh();
    const bool flip = t_.pm.heightfield().transform.determinant() < 0;
    dm_.origin = t_.origin;
    dm_.xyz.resize(m.positions.size() * 3);
    dm_.normals.resize(m.positions.size() * 3);
    for (std::size_t v = 0; v < m.positions.size(); ++v) {
      dm_.xyz[3 * v] = float(m.positions[v].x - t_.origin.x);
      dm_.xyz[3 * v + 1] = float(m.positions[v].y - t_.origin.y);
      dm_.xyz[3 * v + 2] = float(m.positions[v].z - t_.origin.z);
      std::copy_n(&t_.normals[std::size_t(m.samples[v]) * 3], 3, &dm_.normals[3 * v]);
    }
    dm_.indices.resize(m.triangles.size() * 3);
    for (std::size_t f = 0; f < m.triangles.size(); ++f) {
      dm_.indices[3 * f] = m.triangles[f][0];
      dm_.indices[3 * f + 1] = m.triangles[f][flip ? 2 : 1];
      dm_.indices[3 * f + 2] = m.triangles[f][flip ? 1 : 2];
    }
    if (!id_)
      id_ = renderer_.upload(dm_);
    else
      renderer_.replace(*id_, dm_);
    ++version_;
  }

  const Terrain& t_;
  pm::SelectiveRefinement sel_;
  rd::TerrainRenderer renderer_;
  rd::DrawMesh dm_;
  std::optional<rd::MeshId> id_;
  double bound_ = 0, tau_ = 0;
  LayerSetup* layers_ = nullptr;
  std::unique_ptr<rd::LayeredRenderer> layered_;
  std::optional<rd::MeshId> layered_id_;
  std::uint64_t version_ = 0, layered_version_ = 0;
  bool drew_layered_ = false;
};

// --texture-db / --layer / --lens (layer_options.hpp); nullopt without layers.
std::optional<LayerSetup> layer_setup(const Args& a) {
  const std::vector<std::string> specs = a.get_all("--layer");
  if (specs.empty() != !a.has("--texture-db")) throw UsageError("--layer and --texture-db go together");
  if (a.has("--lens") && specs.empty()) throw UsageError("--lens needs --layer");
  if (specs.size() > 9) throw UsageError("at most 9 --layer (keys 1..9 switch them)");
  for (const std::string& s : specs) parse_layer_spec(s);
  if (specs.empty()) return std::nullopt;
  std::optional<LensSpec> lens;
  if (a.has("--lens")) lens = parse_lens("--lens", a.get("--lens"));
  return LayerSetup::open(a.get("--texture-db"), specs, lens);
}

// World-frame PLY of the drawn mesh (double x y z, int faces).
void dump_mesh(const Terrain& t, const rd::DrawMesh& dm, const std::string& path) {
  pm::TriangleMeshData d;
  d.positions.resize(dm.vertex_count());
  for (std::size_t v = 0; v < dm.vertex_count(); ++v)
    d.positions[v] = {t.origin.x + double(dm.xyz[3 * v]), t.origin.y + double(dm.xyz[3 * v + 1]),
                      t.origin.z + double(dm.xyz[3 * v + 2])};
  d.triangles.resize(dm.triangle_count());
  for (std::size_t f = 0; f < dm.triangle_count(); ++f)
    d.triangles[f] = {dm.indices[3 * f], dm.indices[3 * f + 1], dm.indices[3 * f + 2]};
  pm::write_mesh(d, path);
}

std::pair<int, int> parse_size(const Args& a) {
  const std::string s = a.get("--size", "1280x720");
  int w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(s.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X') || w < 1 || h < 1 ||
      w > 16384 || h > 16384)
    throw UsageError("--size must be WxH with each in 1..16384, not '" + s + "'");
  return {w, h};
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

// Clip planes for a camera: reverse-Z depth keeps precision with a near plane close to the eye.
void set_clip(const Terrain& t, pm::Camera& c) {
  const double above = c.z - ground(t, c.x, c.y);
  c.near_m = std::clamp(0.25 * std::max(above, 0.0), 0.1, 100.0);
  const pm::Heightfield& hf = t.pm.heightfield();
  const double extent = hf.transform.spacing_x() * hf.width() + hf.transform.spacing_y() * hf.height();
  c.far_m = std::max(c.near_m * 2.0, 2.0 * extent + std::fabs(c.z - t.zmin) * 2.0);
}

const char* kCsvHeader =
    "frame,x,y,z,yaw,pitch,fovy,tau_px,triangles,vertices,update_ms,draw_ms,bound_px,vsplits,ecols,morphing,"
    "nodes_selected,blocks_resident,blocks_loading,texture_bytes\n";

void csv_row(std::FILE* f, std::size_t k, const FrameRecord& r) {
  const pm::Camera& c = r.camera;
  std::fprintf(f, "%zu,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%zu,%zu,%.4f,%.4f,%.17g,%zu,%zu,%zu,1,1,0,%zu\n", k,
               c.x, c.y, c.z, c.yaw_deg, c.pitch_deg, c.fovy_deg, r.tau, r.triangles, r.vertices, r.update_ms,
               r.draw_ms, r.bound_px, r.vsplits, r.ecols, r.morphing, r.texture_bytes);
}

// ---------------------------------------------------------------------------------------------
// Headless

// The flight used when no --path is given: a circle of radius 30% of the extent around the
// terrain's centre, 200 m above the ground under the camera, looking along the path and 15
// degrees down, one lap in 20 s (1200 frames at 60 fps).
std::vector<pm::Camera> default_flight(const Terrain& t, int frames, int w, int h) {
  const pm::Heightfield& hf = t.pm.heightfield();
  const auto [cx, cy] = hf.transform.to_world((hf.width() - 1) / 2.0, (hf.height() - 1) / 2.0);
  const double radius = 0.3 * std::min(hf.transform.spacing_x() * (hf.width() - 1), hf.transform.spacing_y() * (hf.height() - 1));
  std::vector<pm::Camera> path;
  for (int k = 0; k < frames; ++k) {
    const double a = 2.0 * std::numbers::pi * k / 1200.0;
    pm::Camera c;
    c.x = cx + radius * std::cos(a), c.y = cy + radius * std::sin(a);
    c.z = ground(t, c.x, c.y) + 200.0;
    // Moving counter-clockwise: the direction of motion is (-sin a, cos a); yaw from north.
    c.yaw_deg = std::atan2(-std::sin(a), std::cos(a)) * 180.0 / std::numbers::pi;
    c.pitch_deg = -15.0, c.fovy_deg = 60.0, c.width_px = w, c.height_px = h;
    path.push_back(c);
  }
  return path;
}

int run_headless(const Args& a) {
  const auto [w, h] = parse_size(a);
  const std::string out = a.get("--out", "fly_out");
  pm::CameraPathOptions po;
  po.width_px = w, po.height_px = h;
  std::vector<pm::Camera> path;
  if (a.has("--path")) path = pm::read_camera_path(a.get("--path"), po);
  const bool dump = a.has("--dump-meshes");
  std::optional<LayerSetup> layers = layer_setup(a);
  const Terrain t = load_terrain(a.get("--input"), int(a.get_int("--terrain-size", 513, 2, 8193)));
  if (path.empty()) {
    path = default_flight(t, int(a.get_int("--frames", 240, 1, 1000000)), w, h);
    std::printf("path: built-in flight, %zu frames (a circle 200 m above the ground, looking 15 degrees down)\n",
                path.size());
  }
  const long long frames = a.get_int("--frames", (long long)path.size(), 1, (long long)path.size());
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec || !fs::is_directory(out)) throw std::runtime_error(out + ": cannot create the output folder");
  auto ctx = rd::create_offscreen_context({w, h});
  Pipeline p(t, *ctx, refinement_options(a));
  if (layers) {
    layers->wait_loaded(/*timeout_ms=*/600000);  // every frame sees every layer: deterministic
    p.set_layers(*ctx, &*layers);
  }
  const std::string csv = (fs::path(out) / "frames.csv").string();
  std::FILE* f = std::fopen((csv + ".tmp").c_str(), "wb");
  if (!f) throw std::runtime_error(csv + ": cannot write");
  std::fputs(kCsvHeader, f);
  ProgressBar bar("render " + std::to_string(frames) + " frames");
  std::vector<double> update_ms;
  double worst_bound = 0;
  for (long long k = 0; k < frames; ++k) {
    pm::Camera c = path[std::size_t(k)];
    set_clip(t, c);
    const FrameRecord r = p.frame(c, double(k) / 60.0);
    update_ms.push_back(r.update_ms);
    worst_bound = std::max(worst_bound, r.bound_px);
    csv_row(f, std::size_t(k), r);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05lld", k);
    rd::write_png(p.read_color(), (fs::path(out) / (std::string(name) + ".png")).string());
    if (dump) dump_mesh(t, p.draw_mesh(), (fs::path(out) / (std::string(name) + ".ply")).string());
    bar.update(double(k + 1) / double(frames));
  }
  bar.finish();
  const bool ok = std::fclose(f) == 0;
  if (!ok || (fs::rename(csv + ".tmp", csv, ec), ec)) throw std::runtime_error(csv + ": cannot write");
  std::sort(update_ms.begin(), update_ms.end());
  std::printf("headless: %lld frames %dx%d -> %s (PNG%s, frames.csv); update median %.3f ms, p99 %.3f ms; "
              "largest bound %.3f px (tau %g)\n",
              frames, w, h, out.c_str(), dump ? ", PLY" : "", update_ms[update_ms.size() / 2],
              update_ms[std::min(update_ms.size() - 1, update_ms.size() * 99 / 100)], worst_bound,
              p.selection().options().tolerance_px);
  return 0;
}

// ---------------------------------------------------------------------------------------------
// Window

// The ground point seen through normalised screen position (sx, sy) in [-1,1]^2 (y up): march
// along the ray in steps of one grid spacing, then bisect; nullopt when it leaves the terrain's
// range or misses it within the far plane.
std::optional<std::array<double, 2>> ground_point(const Terrain& t, const pm::Camera& c, double sx, double sy) {
  const double yr = c.yaw_deg * std::numbers::pi / 180, pr = c.pitch_deg * std::numbers::pi / 180;
  const glm::dvec3 f(std::sin(yr) * std::cos(pr), std::cos(yr) * std::cos(pr), std::sin(pr));
  const glm::dvec3 right(std::cos(yr), -std::sin(yr), 0.0);
  const glm::dvec3 up = glm::cross(right, f);
  const double th = std::tan(0.5 * c.fovy_deg * std::numbers::pi / 180);
  const glm::dvec3 d = glm::normalize(f + sx * th * double(c.width_px) / double(c.height_px) * right + sy * th * up);
  const glm::dvec3 o(c.x, c.y, c.z);
  const pm::Heightfield& hf = t.pm.heightfield();
  const double step = std::max(1e-3, std::min(hf.transform.spacing_x(), hf.transform.spacing_y()));
  double a = 0;
  for (double s = step; s <= c.far_m; s += step) {
    const glm::dvec3 p = o + s * d;
    if (p.z <= ground(t, p.x, p.y)) {
      double lo = a, hi = s;
      for (int i = 0; i < 40; ++i) {
        const double m = 0.5 * (lo + hi);
        const glm::dvec3 q = o + m * d;
        (q.z <= ground(t, q.x, q.y) ? hi : lo) = m;
      }
      const glm::dvec3 q = o + hi * d;
      return std::array<double, 2>{q.x, q.y};
    }
    if (p.z < t.zmin - 1.0 || (d.z >= 0 && p.z > t.zmax + 1.0)) return std::nullopt;
    a = s;
  }
  return std::nullopt;
}

// Shows a LayeredRenderer frame in the window: its framebuffer is still bound after draw();
// blit it to the default framebuffer (GL 3.0 entry points through GLFW).
void present_layered(int w, int h) {
  using GetIntegerv = void (*)(GLenum, GLint*);
  using BindFramebuffer = void (*)(GLenum, GLuint);
  using BlitFramebuffer = void (*)(GLint, GLint, GLint, GLint, GLint, GLint, GLint, GLint, GLbitfield, GLenum);
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
  const Terrain t = load_terrain(a.get("--input"), int(a.get_int("--terrain-size", 513, 2, 8193)));
  std::vector<pm::Camera> replay;
  if (a.has("--replay")) {
    pm::CameraPathOptions po;
    po.width_px = w, po.height_px = h;
    replay = pm::read_camera_path(a.get("--replay"), po);
  }
  const long long max_frames = a.get_int("--frames", replay.empty() ? -1 : (long long)replay.size(), -1, 1LL << 40);
  const std::string record_path = a.get("--record", "flight.csv");
  const double clearance = a.get_double("--clearance", 30.0);
  const std::size_t budget = std::size_t(a.get_int("--budget", 50000, 100, 100000000));
  std::optional<LayerSetup> layers = layer_setup(a);

  rd::WindowOptions wo;
  wo.width = w, wo.height = h, wo.title = "terralod-fly";
  auto win = rd::WindowContext::create(wo);
  Pipeline p(t, *win, refinement_options(a));
  if (layers) {
    p.set_layers(*win, &*layers);
    if (layers->lens_radius() <= 0) {  // no --lens: H shows one of 4% of the terrain's width
      const pm::Heightfield& g = t.pm.heightfield();
      layers->set_lens_radius(0.04 * g.transform.spacing_x() * (g.width() - 1));
    }
  }
  rd::Hud hud(*win);
  if (!hud.has_font()) std::fprintf(stderr, "terralod-fly: no heads-up display: %s\n", hud.font_error().c_str());
  GLFWwindow* gw = win->glfw_window();

  // Start above the south-west quarter, heading north-east, looking slightly down.
  const pm::Heightfield& hf = t.pm.heightfield();
  const auto [sx, sy] = hf.transform.to_world(hf.width() * 0.25, hf.height() * 0.75);
  pm::Camera cam;
  cam.x = sx, cam.y = sy, cam.z = ground(t, sx, sy) + 4 * clearance;
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
    pm::RefinementOptions o = p.selection().options();
    bool options_changed = false;
    if (pressed(GLFW_KEY_T)) ctl.follow = !ctl.follow;
    if (pressed(GLFW_KEY_G)) o.morph_seconds = o.morph_seconds > 0 ? 0.0 : 0.3, options_changed = true;
    if (pressed(GLFW_KEY_X)) p.wireframe = !p.wireframe;
    if (pressed(GLFW_KEY_L)) p.frozen = !p.frozen;
    if (layers) {
      for (int k = 0; k < int(layers->styles().size()); ++k)
        if (pressed(GLFW_KEY_1 + k)) layers->styles()[std::size_t(k)].enabled = !layers->styles()[std::size_t(k)].enabled;
      if (pressed(GLFW_KEY_H)) layers->lens().enabled = !layers->lens().enabled;
    }
    if (pressed(GLFW_KEY_B)) o.target_triangles = o.target_triangles ? 0 : budget, options_changed = true;
    if (pressed(GLFW_KEY_LEFT_BRACKET)) o.tolerance_px = std::max(0.05, o.tolerance_px / 1.25), options_changed = true;
    if (pressed(GLFW_KEY_RIGHT_BRACKET)) o.tolerance_px = std::min(64.0, o.tolerance_px * 1.25), options_changed = true;
    if (options_changed) p.selection().set_options(o);
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
      if (ctl.follow) cam.z = std::max(cam.z, ground(t, cam.x, cam.y) + clearance);
    } else {
      cam = replay[std::size_t(std::min<long long>(frame, (long long)replay.size() - 1))];
    }
    int fw = 1, fh = 1;
    glfwGetFramebufferSize(gw, &fw, &fh);
    cam.width_px = std::max(1, fw), cam.height_px = std::max(1, fh);
    set_clip(t, cam);
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
      if (const auto g = ground_point(t, cam, sx, sy)) layers->move_lens((*g)[0], (*g)[1]);
    }

    r = p.frame(cam, time_s);
    const pm::RefinementOptions& now_o = p.selection().options();
    std::vector<std::string> lines = {strf("%5.1f fps   tau %.2f px%s   bound %.3f px", fps, r.tau,
                        now_o.target_triangles ? strf(" (budget %zu)", now_o.target_triangles).c_str() : "",
                        r.bound_px),
                   strf("%zu triangles   update %.2f ms   draw %.2f ms", r.triangles, r.update_ms, r.draw_ms),
                   strf("nodes selected 1   blocks resident 1, loading 0   texture memory %s",
                        format_bytes(r.texture_bytes).c_str()),
                   strf("speed %.0f m/s   height %.0f m above ground%s", ctl.speed, cam.z - ground(t, cam.x, cam.y),
                        ctl.follow ? " (following)" : ""),
                   strf("%s%s%s%s", now_o.morph_seconds > 0 ? "geomorphs" : "no geomorphs",
                        p.wireframe ? "  wireframe" : "", p.frozen ? "  LOD FROZEN" : "",
                        ctl.recording ? "  REC" : "")};
    if (layers) {
      std::string on = "layers";
      for (std::size_t k = 0; k < layers->styles().size(); ++k)
        on += strf("  %zu:%s%s", k + 1, layers->styles()[k].name.c_str(), layers->styles()[k].enabled ? "" : "(off)");
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
  std::printf("flew %lld frames, last: %zu triangles, bound %.3f px\n", frame, r.triangles, r.bound_px);
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
