// The terralod command-line tool: builds, inspects, extracts and renders progressive meshes of
// DEMs (subcommands pm, extract, info, demo, view); parsing and printing only, the work is the
// library's.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <limits>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "commands.hpp"
#include "layer_options.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/database_extract.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/dem_writer.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/selective_refinement.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/pm/view.hpp"
#include "terralod/render/camera.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/image.hpp"
#include "terralod/render/terrain_renderer.hpp"

#ifndef TERRALOD_VERSION
#define TERRALOD_VERSION "unknown"
#endif

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace blocks = terralod::blocks;
namespace render = terralod::render;
using terralod::cli::Args;
using terralod::cli::build_stage;
using terralod::cli::check_mesh_output;
using terralod::cli::CommandSpec;
using terralod::cli::format_bytes;
using terralod::cli::format_duration;
using terralod::cli::is_pm_file;
using terralod::cli::lower_extension;
using terralod::cli::metric_name;
using terralod::cli::ms_since;
using terralod::cli::OptionSpec;
using terralod::cli::read_pm_stage;
using terralod::cli::read_stage;
using terralod::cli::strf;
using terralod::cli::UsageError;
using Clock = std::chrono::steady_clock;

// ---------------------------------------------------------------------------------------------
// Shared option groups

std::vector<OptionSpec> dem_options() {
  return {
      {"--keep-voids", "", "keep DEM voids as holes instead of filling them"},
      {"--vertical-scale", "S", "heightmaps: metres per raw unit (default 1)"},
      {"--spacing", "M", "heightmaps and rasters without georeferencing: metres between samples (default 1)"},
  };
}

std::vector<OptionSpec> build_options() {
  return {
      {"--metric", "NAME",
       "error metric: continuous (true L-infinity, default) or samples (at the samples only)"},
      {"--threads", "N", "worker threads for the build, 0 = all cores (default 0)"},
  };
}

std::vector<OptionSpec> concat(std::vector<OptionSpec> a, const std::vector<OptionSpec>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

const char* kDemFormats =
    "DEM formats: SRTM .hgt, Esri ASCII grid .asc, PNG/TIFF heightmaps, any single-band raster\n"
    "GDAL reads. Geographic DEMs are mapped to a local metric frame (x east, y north, metres).";

blocks::DemOptions dem_options_from(const Args& a) {
  blocks::DemOptions o;
  o.fill_voids = !a.has("--keep-voids");
  o.vertical_scale = a.get_double("--vertical-scale", o.vertical_scale);
  o.heightmap_spacing = a.get_double("--spacing", o.heightmap_spacing);
  if (o.vertical_scale == 0.0) throw UsageError("option '--vertical-scale' must not be 0");
  if (o.heightmap_spacing <= 0.0) throw UsageError("option '--spacing' must be > 0");
  return o;
}

pm::BuildOptions build_options_from(const Args& a) {
  pm::BuildOptions o;
  const std::string metric = a.get_choice("--metric", {"continuous", "samples"}, "continuous");
  o.metric = metric == "samples" ? pm::ErrorMetric::Samples : pm::ErrorMetric::Continuous;
  o.threads = int(a.get_int("--threads", 0, 0, 1024));
  return o;
}

/// Fails early (before a long build) when the output's folder does not exist.
void check_output_folder(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  std::error_code ec;
  if (!parent.empty() && !fs::is_directory(parent, ec))
    throw std::runtime_error(path + ": cannot write, folder '" + parent.string() + "' does not exist");
}

void line(const std::string& s) {
  std::fputs((s + "\n").c_str(), stdout);
  std::fflush(stdout);
}

// The stages shared by the subcommands (read_stage, build_stage, read_pm_stage: one line each)
// are in terrain_input.hpp, shared with terralod-fly.

std::pair<double, double> height_range(const pm::Heightfield& hf) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i)) lo = std::min(lo, hf[i]), hi = std::max(hi, hf[i]);
  return {lo, hi};
}

// ---------------------------------------------------------------------------------------------
// terralod pm

CommandSpec pm_spec() {
  CommandSpec s;
  s.name = "pm";
  s.summary = "Build the progressive mesh of a DEM and write it to a .pm file.";
  s.description =
      std::string(
          "Collapses edges in order of increasing L-infinity error until nothing can collapse; the file\n"
          "holds the grid and the whole collapse sequence, so any error level can be extracted later.\n"
          "A progress bar goes to stderr, one line per stage to stdout.\n\n") +
      kDemFormats;
  s.options = concat(concat({{"--input", "DEM", "elevation model to read", true},
                             {"--out", "FILE.pm", "progressive mesh file to write", true}},
                            build_options()),
                     dem_options());
  return s;
}

int cmd_pm(const Args& a) {
  const std::string input = a.get("--input"), out = a.get("--out");
  if (!is_pm_file(out)) throw UsageError("option '--out' must name a .pm file, not '" + out + "'");
  const blocks::DemOptions dem = dem_options_from(a);
  const pm::BuildOptions build = build_options_from(a);
  check_output_folder(out);

  const pm::Heightfield hf = read_stage(input, dem);
  const pm::ProgressiveMesh mesh = build_stage(hf, build);
  const auto t = Clock::now();
  pm::write_pm(mesh, out);
  const double ms = ms_since(t);
  const std::uintmax_t bytes = fs::file_size(out);
  line(strf("write %s: %s, %.2f bytes/vertex, %s", out.c_str(), format_bytes(bytes).c_str(),
            double(bytes) / double(std::max<std::size_t>(1, mesh.full_vertex_count())),
            format_duration(ms).c_str()));
  return 0;
}

// ---------------------------------------------------------------------------------------------
// terralod extract

CommandSpec extract_spec() {
  CommandSpec s;
  s.name = "extract";
  s.summary = "Extract the mesh within a given L-infinity error from a .pm file, a DEM or a block database.";
  s.description =
      std::string(
          "The mesh's error against the full-resolution surface is at most --max-error (the 'bound'\n"
          "printed is the guaranteed error actually reached). A DEM input is built into a progressive\n"
          "mesh in memory first (--metric, --threads and the DEM options apply to it).\n"
          "Output by extension: .ply (binary little-endian, double x y z), .obj (text), .glb (binary\n"
          "glTF 2.0) or .gltf (glTF JSON, buffer inline as base64). glTF is Y-up: (x, y, z) is stored\n"
          "as (x, z, -y), float positions relative to the mesh's centre, which is the node's translation;\n"
          "with area-weighted vertex normals.\n"
          "Units: samples = x column, y row (row 0 = the file's first row), z metres;\n"
          "       world   = x east, y north in metres from the DEM's transform (see 'terralod info'),\n"
          "                 z metres; faces counter-clockwise seen from above.\n\n") +
      kDemFormats;
  s.description +=
      "\n\nWith --db DB (a block database from 'terralod build') instead of --input, the blocks are\n"
      "extracted, their seams stitched (neighbours' border vertices inserted) and blocks whose\n"
      "stitched triangles exceed E re-extracted at E/2; the printed bound is measured exactly.";
  s.options = concat(
      concat({{"--input", "FILE", "a .pm file (from 'terralod pm') or a DEM (or use --db)"},
              {"--db", "DB", "a block database (from 'terralod build') instead of --input"},
              {"--max-error", "E",
               "largest L-infinity error allowed, metres (finite, >= 0); required except with --grid-level"},
              {"--grid-level", "L",
               "with --db of a hybrid database ('terralod hybrid'): its grid level L (0 = finest)"},
              {"--scheme", "S", "with --grid-level: triangles (default) or subcells (the paper's section 5)"},
              {"--out", "MESH", "mesh file to write: .ply, .obj, .glb or .gltf", true},
              {"--units", "UNITS", "vertex coordinates: world (default) or samples"}},
             build_options()),
      dem_options());
  return s;
}

int cmd_extract(const Args& a) {
  const std::string input = a.get("--input"), out = a.get("--out");
  check_mesh_output("--out", out);
  if (a.has("--grid-level")) return terralod::cli::cmd_extract_hybrid(a);  // hybrid database (cmd_hybrid.cpp)
  if (!a.has("--max-error")) throw UsageError("missing option '--max-error'");
  const double max_error = a.get_double("--max-error", 0.0);
  if (max_error < 0.0)
    throw UsageError("option '--max-error' must be >= 0, not '" + a.get("--max-error") + "'");
  const pm::Units units = a.get_choice("--units", {"world", "samples"}, "world") == "samples"
                              ? pm::Units::Samples
                              : pm::Units::World;
  if (a.has("--db") == a.has("--input")) throw UsageError("give exactly one of '--input' and '--db'");
  if (a.has("--db")) {
    check_output_folder(out);
    auto t = Clock::now();
    const blocks::ExtractedMesh m = blocks::extract_mesh(a.get("--db"), max_error);
    line(strf(
        "extract %s E=%g m: %zu blocks (%zu re-extracted for seams, %zu rounds), %zu triangles, %zu "
        "vertices, "
        "%zu seam vertices inserted, measured error %g m, %s",
        a.get("--db").c_str(), max_error, m.blocks, m.blocks_refined, m.iterations, m.mesh.triangles.size(),
        m.mesh.vertices.size(), m.inserted_vertices, m.measured_error, format_duration(ms_since(t)).c_str()));
    t = Clock::now();
    pm::write_mesh(m.mesh, m.heightfield, out, units);
    line(strf("write %s: %s, %s units, %s", out.c_str(), format_bytes(fs::file_size(out)).c_str(),
              units == pm::Units::Samples ? "samples" : "world", format_duration(ms_since(t)).c_str()));
    return 0;
  }
  const blocks::DemOptions dem = dem_options_from(a);
  const pm::BuildOptions build = build_options_from(a);
  check_output_folder(out);

  const pm::ProgressiveMesh mesh =
      is_pm_file(input) ? read_pm_stage(input) : build_stage(read_stage(input, dem), build);

  auto t = Clock::now();
  const pm::TriangleMesh m = mesh.extract(max_error);
  double ms = ms_since(t);
  line(strf("extract E=%g m: %zu triangles, %zu vertices, bound %g m, %s", max_error, m.triangles.size(),
            m.vertices.size(), m.error_bound, format_duration(ms).c_str()));

  t = Clock::now();
  pm::write_mesh(m, mesh.heightfield(), out, units);
  ms = ms_since(t);
  line(strf("write %s: %s, %s units, %s", out.c_str(), format_bytes(fs::file_size(out)).c_str(),
            units == pm::Units::Samples ? "samples" : "world", format_duration(ms).c_str()));
  return 0;
}

// ---------------------------------------------------------------------------------------------
// terralod info

CommandSpec info_spec() {
  CommandSpec s;
  s.name = "info";
  s.positionals = "FILE";
  s.min_positionals = s.max_positionals = 1;
  s.summary = "Describe a .pm file, a block database (.db) or a DEM as JSON on stdout.";
  s.description =
      std::string(
          "Fields: file, kind (pm|dem), grid {width, height}, transform {x0, xc, xr, y0, yc, yr, formula}\n"
          "(sample (col,row) -> world (x,y) metres), spacing {x, y} metres, frame, crs_wkt,\n"
          "height {min, max} metres, voids {found, filled}; for a .pm also metric, vertices,\n"
          "base_vertices, vsplits, max_error, error_quantum (metres), bytes, bytes_per_vertex.\n\n") +
      kDemFormats;
  s.options = dem_options();
  return s;
}

int cmd_info(const Args& a) {
  const std::string file = a.positionals().at(0);
  if (lower_extension(file) == ".db") {
    const blocks::BlockDatabase db = blocks::BlockDatabase::open(file);
    if (db.info().kind == "hybrid") return terralod::cli::info_hybrid(file);  // cmd_hybrid.cpp
    std::fputs(blocks::summarize_database(db).to_json().c_str(), stdout);
    return 0;
  }
  const blocks::DemOptions dem = dem_options_from(a);
  const bool is_pm = is_pm_file(file);
  std::optional<pm::ProgressiveMesh> mesh;
  pm::Heightfield dem_hf;
  if (is_pm)
    mesh = pm::read_pm(file);
  else
    dem_hf = blocks::read_dem(file, dem);
  const pm::Heightfield& hf = is_pm ? mesh->heightfield() : dem_hf;
  const pm::GridTransform& t = hf.transform;
  const auto [hmin, hmax] = height_range(hf);

  terralod::cli::JsonWriter j;
  j.begin_object();
  j.field("file", file);
  j.field("kind", is_pm ? "pm" : "dem");
  j.begin_object("grid");
  j.field("width", hf.width());
  j.field("height", hf.height());
  j.end_object();
  j.begin_object("transform");
  j.field("x0", t.x0);
  j.field("xc", t.xc);
  j.field("xr", t.xr);
  j.field("y0", t.y0);
  j.field("yc", t.yc);
  j.field("yr", t.yr);
  j.field("formula", "x = x0 + col*xc + row*xr; y = y0 + col*yc + row*yr");
  j.end_object();
  j.begin_object("spacing");
  j.field("x", t.spacing_x());
  j.field("y", t.spacing_y());
  j.end_object();
  j.field("frame", hf.frame);
  j.field("crs_wkt", hf.crs_wkt);
  j.begin_object("height");
  j.field("min", hmin);
  j.field("max", hmax);
  j.end_object();
  j.begin_object("voids");
  j.field("found", std::uint64_t(hf.voids.voids));
  j.field("filled", std::uint64_t(hf.voids.filled));
  j.end_object();
  if (is_pm) {
    const std::uintmax_t bytes = fs::file_size(file);
    j.field("metric", metric_name(mesh->metric()));
    j.field("vertices", std::uint64_t(mesh->full_vertex_count()));
    j.field("base_vertices", std::uint64_t(mesh->base_vertex_count()));
    j.field("vsplits", std::uint64_t(mesh->vsplit_count()));
    j.field("max_error", mesh->max_error());
    j.field("error_quantum", mesh->error_quantum());
    j.field("bytes", std::uint64_t(bytes));
    j.field("bytes_per_vertex", double(bytes) / double(std::max<std::size_t>(1, mesh->full_vertex_count())));
  }
  j.end_object();
  std::fputs(j.str().c_str(), stdout);
  return 0;
}

// ---------------------------------------------------------------------------------------------
// terralod demo

// The built-in terrain of --size and --seed (demo, generate), with its line of output: a
// DEM-like terrain, 30 m spacing, 1/16 m vertical resolution, relief that fades with scale as
// real landscapes do (the library's default generator is rougher, for tests).
pm::Heightfield generated_terrain(const Args& a) {
  const pm::TerrainOptions topt = terralod::cli::demo_terrain_options(
      int(a.get_int("--size", terralod::cli::kDemoTerrainSize, 2, 8193)),
      std::uint64_t(a.get_int("--seed", 1, 0, std::numeric_limits<long long>::max())));
  const auto t = Clock::now();
  pm::Heightfield hf = pm::generate_terrain(topt);
  const auto [hmin, hmax] = height_range(hf);
  line(strf("terrain %d x %d samples, seed %llu, %g m spacing, heights %.1f .. %.1f m, %s", hf.width(),
            hf.height(), static_cast<unsigned long long>(topt.seed), topt.spacing, hmin, hmax,
            format_duration(ms_since(t)).c_str()));
  return hf;
}

CommandSpec demo_spec() {
  CommandSpec s;
  s.name = "demo";
  s.summary = "Build the progressive mesh of a generated terrain and print its levels of detail.";
  s.description =
      "Generates a fractal terrain (30 m spacing, about 1200 m of relief, heights not rounded), builds\n"
      "its progressive mesh and extracts it at E = 0, 0.5, 1, 2, 5, 10, 20 and 50 m: one line per\n"
      "level with the triangles kept and the guaranteed error bound, then the build time and the\n"
      "size of the encoded .pm.";
  s.options = {{"--size", "N", "samples per side of the terrain (default 513, 2..8193)"},
               {"--seed", "S", "terrain seed (default 1)"},
               {"--threads", "N", "worker threads for the build, 0 = all cores (default 0)"}};
  return s;
}

int cmd_demo(const Args& a) {
  pm::BuildOptions bopt;
  bopt.threads = int(a.get_int("--threads", 0, 0, 1024));
  const pm::Heightfield hf = generated_terrain(a);

  terralod::cli::ProgressBar bar("build");
  bopt.progress = [&bar](double f) { return bar.update(f); };
  auto t = Clock::now();
  const pm::ProgressiveMesh mesh = pm::ProgressiveMesh::build(hf, bopt);
  const double build_ms = ms_since(t);
  bar.finish();

  const std::size_t full = mesh.extract_after(0).triangles.size();
  for (const double e : {0.0, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0}) {
    t = Clock::now();
    const pm::TriangleMesh m = mesh.extract(e);
    const double ms = ms_since(t);
    line(strf("E=%g m: %zu triangles (%.1f%% of full), bound %g m, extract %s", e, m.triangles.size(),
              100.0 * double(m.triangles.size()) / double(std::max<std::size_t>(1, full)), m.error_bound,
              format_duration(ms).c_str()));
  }
  line(strf("build %zu vertices -> %zu base vertices, %zu vsplits, max error %.1f m, %s",
            mesh.full_vertex_count(), mesh.base_vertex_count(), mesh.vsplit_count(), mesh.max_error(),
            format_duration(build_ms).c_str()));
  t = Clock::now();
  const std::size_t bytes = pm::encode_pm(mesh).size();
  line(strf("encode %s, %.2f bytes/vertex, %s", format_bytes(bytes).c_str(),
            double(bytes) / double(std::max<std::size_t>(1, mesh.full_vertex_count())),
            format_duration(ms_since(t)).c_str()));
  return 0;
}

// ---------------------------------------------------------------------------------------------
// terralod generate

CommandSpec generate_spec() {
  CommandSpec s;
  s.name = "generate";
  s.summary = "Write the built-in generated terrain of any size as a GeoTIFF DEM.";
  s.description =
      "Generates the fractal terrain of 'terralod demo' and 'terralod-fly' (30 m spacing, about\n"
      "1200 m of relief, heights in 1/16 m) with --size x --size samples and writes it as a\n"
      "single-band Float32 GeoTIFF (tiled, deflate) with the sample spacing in its geotransform\n"
      "and no CRS, so that 'terralod build --input FILE.tif' reads it back as metres, exactly. For\n"
      "terrains larger than the examples, e.g. the runtime benchmark's 4097 x 4097 (123 km).";
  s.options = {{"--size", "N", "samples per side (2..8193)", true},
               {"--seed", "S", "terrain seed (default 1)"},
               {"--out", "FILE.tif", "output GeoTIFF (written to a temporary, then renamed)", true}};
  return s;
}

int cmd_generate(const Args& a) {
  const pm::Heightfield hf = generated_terrain(a);
  const auto t = Clock::now();
  const std::string out = a.get("--out");
  terralod::blocks::write_geotiff(hf, out);
  std::error_code ec;
  line(strf("write %s: %s in %s", out.c_str(), format_bytes(std::filesystem::file_size(out, ec)).c_str(),
            format_duration(ms_since(t)).c_str()));
  return 0;
}

// ---------------------------------------------------------------------------------------------
// terralod view

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
             concat(terralod::cli::layer_option_specs(), build_options())),
      dem_options());
  return s;
}

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

int cmd_view(const Args& a) {
  const std::string input = a.get("--input"), out = a.get("--out");
  if (lower_extension(out) != ".png")
    throw UsageError("option '--out' must name a .png file, not '" + out + "'");
  const std::vector<double> c = parse_numbers("--camera", a.get("--camera"), 6);
  if (c[4] < -90.0 || c[4] > 90.0) throw UsageError("--camera: PITCH must be in [-90, 90] degrees");
  if (c[5] <= 0.0 || c[5] >= 180.0) throw UsageError("--camera: FOVY must be in (0, 180) degrees");
  const double tau = a.get_double("--tau", 1.0);
  if (tau <= 0.0) throw UsageError("option '--tau' must be > 0 pixels, not '" + a.get("--tau") + "'");
  int width = 1024, height = 768;
  if (a.has("--size")) {
    const std::string sz = a.get("--size");
    int consumed = 0;
    if (std::sscanf(sz.c_str(), "%dx%d%n", &width, &height, &consumed) != 2 || consumed != int(sz.size()) ||
        width < 1 || height < 1 || width > 16384 || height > 16384)
      throw UsageError("option '--size' needs WxH with each in 1..16384, not '" + sz + "'");
  }
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
  if (a.has("--db")) terralod::cli::layer_setup_options(a);  // usage errors before the terrain loads
  if (!layer_specs.empty() && a.has("--wireframe"))
    throw UsageError("--wireframe cannot be combined with --layer");
  if (a.has("--lens") && layer_specs.empty()) throw UsageError("--lens needs --layer");
  for (const std::string& spec : layer_specs) terralod::cli::parse_layer_spec(spec);  // usage errors first
  check_output_folder(out);
  if (!dump.empty()) check_output_folder(dump);
  if (!stats_path.empty()) check_output_folder(stats_path);
  if (a.has("--db") == a.has("--input")) throw UsageError("view needs exactly one of '--input' and '--db'");
  if (a.has("--db") && a.has("--uniform")) throw UsageError("--uniform is for --input (a .pm file or a DEM)");
  if (a.has("--db")) {
    if (blocks::BlockDatabase::open(a.get("--db")).info().kind != "hybrid")
      return terralod::cli::view_blocks(a, c, tau, width, height);
    if (!layer_specs.empty()) throw UsageError("--layer draws on block databases, not on a hybrid one");
    if (a.has("--stats")) throw UsageError("--stats is not available for a hybrid database");
    return terralod::cli::view_hybrid(a.get("--db"), c, tau, width, height, out, dump, a.has("--wireframe"));
  }

  auto t = Clock::now();
  const pm::ProgressiveMesh mesh =
      is_pm_file(input) ? read_pm_stage(input) : build_stage(read_stage(input, dem), build);
  const double load_ms = ms_since(t);
  const pm::Heightfield& hf = mesh.heightfield();

  render::Camera cam;
  cam.x = c[0], cam.y = c[1], cam.z = c[2];
  cam.yaw_deg = c[3];
  cam.pitch_deg = c[4];
  cam.fovy_deg = c[5];
  cam.width_px = width;
  cam.height_px = height;

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
  const double d_min = render::distance_to_box(terralod::render::camera_position(cam), lo, hi);
  const double k = render::focal_length_pixels(cam), k_max = render::max_pixels_per_radian(cam);
  // Clip planes: reverse-Z keeps depth precise even with a near plane close to the eye.
  cam.near_m = std::clamp(0.5 * d_min, 0.05, 1000.0);
  cam.far_m =
      std::max(cam.near_m * 2.0,
               1.01 * render::max_distance_to_box(terralod::render::camera_position(cam), lo, hi) + 1.0);

  const bool uniform = a.has("--uniform");
  pm::TriangleMesh m;
  double max_error = 0.0, screen_bound = 0.0, extract_ms = 0.0, dag_ms = 0.0;
  pm::FrameStats sel_stats;
  if (uniform) {
    max_error = tau * d_min / k_max;
    line(
        strf("select tau=%g px: nearest terrain %.1f m, K %.1f px, K_max %.1f px/rad -> E=%.4g m "
             "(uniform extraction, --uniform)",
             tau, d_min, k, k_max, max_error));
    t = Clock::now();
    m = mesh.extract(max_error);
    extract_ms = ms_since(t);
    screen_bound = d_min > 0.0 ? m.error_bound * k_max / d_min : (m.error_bound > 0.0 ? INFINITY : 0.0);
    line(strf("extract E=%.4g m: %zu triangles, %zu vertices, bound %g m (<= %.3g px), %s", max_error,
              m.triangles.size(), m.vertices.size(), m.error_bound, screen_bound,
              format_duration(extract_ms).c_str()));
  } else {
    // View-dependent selection: the pm::Camera conventions are the CLI's; same clip planes as
    // the render, so the guarantee covers exactly what is drawn.
    pm::Camera pc;
    pc.x = c[0];
    pc.y = c[1];
    pc.z = c[2];
    pc.yaw_deg = c[3];
    pc.pitch_deg = c[4];
    pc.fovy_deg = c[5];
    pc.width_px = width;
    pc.height_px = height;
    pc.near_m = cam.near_m;
    pc.far_m = cam.far_m;
    t = Clock::now();
    const pm::CollapseDag dag(mesh);
    dag_ms = ms_since(t);
    pm::RefinementOptions ropt;
    ropt.tolerance_px = tau;
    pm::SelectiveRefinement sel(dag, ropt);
    sel_stats = sel.update(pm::View(pc), 0.0);
    t = Clock::now();
    m = sel.mesh();
    extract_ms = ms_since(t);
    screen_bound = sel_stats.bound_px;
    line(
        strf("select tau=%g px (view-dependent): dag %zu collapses in %s; update %zu vsplits, %zu ecols, "
             "%zu evaluated in %s",
             tau, dag.collapse_count(), format_duration(dag_ms).c_str(), sel_stats.vsplits, sel_stats.ecols,
             sel_stats.evaluated, format_duration(sel_stats.update_ms).c_str()));
    line(strf("selection: %zu triangles, %zu active vertices, bound %.4g px (<= tau %g), %g m at the samples",
              m.triangles.size(), sel_stats.active_vertices, sel_stats.bound_px, tau, sel_stats.bound_m));
  }

  t = Clock::now();
  auto ctx = render::create_offscreen_context({width, height});
  render::RendererOptions ropt;
  ropt.wireframe = a.has("--wireframe");
  render::TerrainRenderer renderer(*ctx, ropt);
  // Texture layers (layer_options.hpp): all loaded before the frame, drawn by LayeredRenderer.
  std::optional<terralod::cli::LayerSetup> layers;
  std::optional<render::LayeredRenderer> layered;
  if (!layer_specs.empty()) {
    layers.emplace(terralod::cli::LayerSetup::open(
        a.get("--texture-db"), layer_specs,
        a.has("--lens") ? std::optional(terralod::cli::parse_lens("--lens", a.get("--lens")))
                        : std::nullopt));
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
  line(strf("render %d x %d on %s: context %s, upload %s, draw %s, read back %s", width, height,
            ctx->info().renderer.c_str(), format_duration(context_ms).c_str(),
            format_duration(upload_ms).c_str(), format_duration(frame.draw_ms).c_str(),
            format_duration(readback_ms).c_str()));

  t = Clock::now();
  render::write_png(img, out);
  const double write_ms = ms_since(t);
  line(strf("write %s: %s, %s", out.c_str(), format_bytes(fs::file_size(out)).c_str(),
            format_duration(write_ms).c_str()));

  double dump_ms = 0.0;
  if (!dump.empty()) {
    t = Clock::now();
    pm::write_mesh(m, hf, dump, pm::Units::World);
    dump_ms = ms_since(t);
    line(strf("write %s: %s, world units, %s", dump.c_str(), format_bytes(fs::file_size(dump)).c_str(),
              format_duration(dump_ms).c_str()));
  }

  if (!stats_path.empty()) {
    terralod::cli::JsonWriter j;
    j.begin_object();
    j.field("input", input);
    j.field("output", out);
    j.field("selection", uniform ? "uniform" : "view-dependent");
    j.begin_object("camera");
    j.field("x", c[0]);
    j.field("y", c[1]);
    j.field("z", c[2]);
    j.field("yaw", c[3]);
    j.field("pitch", c[4]);
    j.field("fovy", c[5]);
    j.field("near", cam.near_m);
    j.field("far", cam.far_m);
    j.end_object();
    j.field("width", width);
    j.field("height", height);
    j.field("tau", tau);
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
    terralod::cli::write_text_file(stats_path, j.str());
    line(strf("write %s: statistics", stats_path.c_str()));
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------
// Dispatch

struct Command {
  CommandSpec (*spec)();
  int (*run)(const Args&);
};

const std::vector<Command>& commands() {
  static const std::vector<Command> c = {
      {pm_spec, cmd_pm},
      {extract_spec, cmd_extract},
      {info_spec, cmd_info},
      {demo_spec, cmd_demo},
      {generate_spec, cmd_generate},
      {view_spec, cmd_view},
      {terralod::cli::build_spec, terralod::cli::cmd_build},
      {terralod::cli::tin_spec, terralod::cli::cmd_tin},
      {terralod::cli::hybrid_spec, terralod::cli::cmd_hybrid},
      {terralod::cli::texture_spec, terralod::cli::cmd_texture},
      {terralod::cli::fly_spec, terralod::cli::cmd_fly},
      {terralod::cli::export_spec, terralod::cli::cmd_export},
      {terralod::cli::testdem_spec, terralod::cli::cmd_testdem},
#ifdef TERRALOD_HAVE_BENCH  // terralod bench: only when bench/ is built (it adds cmd_bench.cpp)
      {terralod::cli::bench_spec, terralod::cli::cmd_bench},
#endif
  };
  return c;
}

std::string main_usage() {
  std::string u =
      "usage: terralod <command> [options]\n\n"
      "Terrain level of detail with a guaranteed L-infinity error bound.\n\ncommands:\n";
  for (const Command& c : commands()) {
    const CommandSpec s = c.spec();
    u += "  " + s.name + std::string(9 - s.name.size(), ' ') + s.summary + "\n";
  }
  u += "\nRun 'terralod <command> --help' for a command's options.\n"
       "Exit status: 0 success, 1 error (bad data, I/O), 2 bad command line.\n"
       "\noptions:\n  -h, --help  show this help and exit\n  --version   print the version and exit\n";
  return u;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty()) {
    std::fputs(main_usage().c_str(), stderr);
    return 2;
  }
  if (args[0] == "-h" || args[0] == "--help" || args[0] == "help") {
    std::fputs(main_usage().c_str(), stdout);
    return 0;
  }
  if (args[0] == "--version") {
    std::puts("terralod " TERRALOD_VERSION);
    return 0;
  }
  const Command* cmd = nullptr;
  for (const Command& c : commands())
    if (c.spec().name == args[0]) cmd = &c;
  if (!cmd) {
    std::fprintf(stderr, "terralod: unknown %s '%s' (see 'terralod --help')\n",
                 args[0].rfind("-", 0) == 0 ? "option" : "command", args[0].c_str());
    return 2;
  }
  const CommandSpec spec = cmd->spec();
  try {
    const Args parsed(spec, std::vector<std::string>(args.begin() + 1, args.end()));
    if (parsed.help()) {
      std::fputs(spec.usage().c_str(), stdout);
      return 0;
    }
    return cmd->run(parsed);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "terralod %s: %s (see 'terralod %s --help')\n", spec.name.c_str(), e.what(),
                 spec.name.c_str());
    return 2;
  } catch (const std::bad_alloc&) {
    std::fputs("terralod: out of memory\n", stderr);
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod: %s\n", e.what());
    return 1;
  }
}
