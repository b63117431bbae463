// The terralod command-line tool: builds, inspects and extracts progressive meshes of DEMs
// (subcommands pm, extract, info, demo); parsing and printing only, the work is the library's.
#include <algorithm>
#include <cctype>
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
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/terrain_generator.hpp"

#ifndef TERRALOD_VERSION
#define TERRALOD_VERSION "unknown"
#endif

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace blocks = terralod::blocks;
using terralod::cli::Args;
using terralod::cli::CommandSpec;
using terralod::cli::format_bytes;
using terralod::cli::format_duration;
using terralod::cli::ms_since;
using terralod::cli::OptionSpec;
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
      {"--metric", "NAME", "error metric: continuous (true L-infinity, default) or samples (at the samples only)"},
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

const char* metric_name(pm::ErrorMetric m) { return m == pm::ErrorMetric::Samples ? "samples" : "continuous"; }

std::string lower_extension(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

bool is_pm_file(const std::string& path) { return lower_extension(path) == ".pm"; }

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

// ---------------------------------------------------------------------------------------------
// Stages shared by the subcommands (each prints its one line)

pm::Heightfield read_stage(const std::string& path, const blocks::DemOptions& options) {
  const auto t = Clock::now();
  pm::Heightfield hf = blocks::read_dem(path, options);
  const double ms = ms_since(t);
  std::string voids;
  if (hf.voids.voids == hf.voids.filled)
    voids = strf("%zu voids filled", hf.voids.filled);
  else
    voids = strf("%zu voids (%zu filled, %zu kept as holes)", hf.voids.voids, hf.voids.filled,
                 hf.voids.voids - hf.voids.filled);
  line(strf("read  %s: %d x %d samples, %s, %s", path.c_str(), hf.width(), hf.height(), voids.c_str(),
            format_duration(ms).c_str()));
  return hf;
}

pm::ProgressiveMesh build_stage(const pm::Heightfield& hf, pm::BuildOptions options) {
  terralod::cli::ProgressBar bar("build");
  options.progress = [&bar](double f) { return bar.update(f); };
  const auto t = Clock::now();
  pm::ProgressiveMesh mesh = pm::ProgressiveMesh::build(hf, options);
  const double ms = ms_since(t);
  bar.finish();
  line(strf("build %zu vertices -> %zu base vertices, %zu vsplits, max error %.1f m, %s", mesh.full_vertex_count(),
            mesh.base_vertex_count(), mesh.vsplit_count(), mesh.max_error(), format_duration(ms).c_str()));
  return mesh;
}

pm::ProgressiveMesh read_pm_stage(const std::string& path) {
  const auto t = Clock::now();
  pm::ProgressiveMesh mesh = pm::read_pm(path);
  const double ms = ms_since(t);
  line(strf("read  %s: %d x %d samples, %zu vertices, %zu vsplits, metric %s, %s", path.c_str(),
            mesh.heightfield().width(), mesh.heightfield().height(), mesh.full_vertex_count(), mesh.vsplit_count(),
            metric_name(mesh.metric()), format_duration(ms).c_str()));
  return mesh;
}

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
  s.description = std::string(
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
            double(bytes) / double(std::max<std::size_t>(1, mesh.full_vertex_count())), format_duration(ms).c_str()));
  return 0;
}

// ---------------------------------------------------------------------------------------------
// terralod extract

CommandSpec extract_spec() {
  CommandSpec s;
  s.name = "extract";
  s.summary = "Extract the mesh within a given L-infinity error from a .pm file or a DEM and write it.";
  s.description = std::string(
                      "The mesh's error against the full-resolution surface is at most --max-error (the 'bound'\n"
                      "printed is the guaranteed error actually reached). A DEM input is built into a progressive\n"
                      "mesh in memory first (--metric, --threads and the DEM options apply to it).\n"
                      "Output by extension: .ply (binary little-endian, double x y z) or .obj (text).\n"
                      "Units: samples = x column, y row (row 0 = the file's first row), z metres;\n"
                      "       world   = x east, y north in metres from the DEM's transform (see 'terralod info'),\n"
                      "                 z metres; faces counter-clockwise seen from above.\n\n") +
                  kDemFormats;
  s.options = concat(concat({{"--input", "FILE", "a .pm file (from 'terralod pm') or a DEM", true},
                             {"--max-error", "E", "largest L-infinity error allowed, metres (finite, >= 0)", true},
                             {"--out", "MESH", "mesh file to write: .ply or .obj", true},
                             {"--units", "UNITS", "vertex coordinates: world (default) or samples"}},
                            build_options()),
                     dem_options());
  return s;
}

int cmd_extract(const Args& a) {
  const std::string input = a.get("--input"), out = a.get("--out");
  const double max_error = a.get_double("--max-error", 0.0);
  if (max_error < 0.0) throw UsageError("option '--max-error' must be >= 0, not '" + a.get("--max-error") + "'");
  const std::string ext = lower_extension(out);
  if (ext != ".ply" && ext != ".obj") throw UsageError("option '--out' must name a .ply or .obj file, not '" + out + "'");
  const pm::Units units = a.get_choice("--units", {"world", "samples"}, "world") == "samples" ? pm::Units::Samples
                                                                                             : pm::Units::World;
  const blocks::DemOptions dem = dem_options_from(a);
  const pm::BuildOptions build = build_options_from(a);
  check_output_folder(out);

  const pm::ProgressiveMesh mesh = is_pm_file(input) ? read_pm_stage(input) : build_stage(read_stage(input, dem), build);

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
  s.summary = "Describe a .pm file or a DEM as JSON on stdout.";
  s.description = std::string(
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
  pm::TerrainOptions topt;
  topt.width = topt.height = int(a.get_int("--size", 513, 2, 8193));
  topt.seed = std::uint64_t(a.get_int("--seed", 1, 0, std::numeric_limits<long long>::max()));
  // A DEM-like terrain: 30 m spacing, 1/16 m vertical resolution, relief that fades with
  // scale as real landscapes do (the library's default generator is rougher, for tests).
  topt.roughness = 0.42;
  topt.height_quantum = 1.0 / 16.0;
  pm::BuildOptions bopt;
  bopt.threads = int(a.get_int("--threads", 0, 0, 1024));

  auto t = Clock::now();
  const pm::Heightfield hf = pm::generate_terrain(topt);
  const auto [hmin, hmax] = height_range(hf);
  line(strf("terrain %d x %d samples, seed %llu, %g m spacing, heights %.1f .. %.1f m, %s", hf.width(), hf.height(),
            static_cast<unsigned long long>(topt.seed), topt.spacing, hmin, hmax,
            format_duration(ms_since(t)).c_str()));

  terralod::cli::ProgressBar bar("build");
  bopt.progress = [&bar](double f) { return bar.update(f); };
  t = Clock::now();
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
  line(strf("build %zu vertices -> %zu base vertices, %zu vsplits, max error %.1f m, %s", mesh.full_vertex_count(),
            mesh.base_vertex_count(), mesh.vsplit_count(), mesh.max_error(), format_duration(build_ms).c_str()));
  t = Clock::now();
  const std::size_t bytes = pm::encode_pm(mesh).size();
  line(strf("encode %s, %.2f bytes/vertex, %s", format_bytes(bytes).c_str(),
            double(bytes) / double(std::max<std::size_t>(1, mesh.full_vertex_count())),
            format_duration(ms_since(t)).c_str()));
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
      {pm_spec, cmd_pm}, {extract_spec, cmd_extract}, {info_spec, cmd_info}, {demo_spec, cmd_demo}};
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
  u +=
      "\nRun 'terralod <command> --help' for a command's options.\n"
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
    std::fprintf(stderr, "terralod %s: %s (see 'terralod %s --help')\n", spec.name.c_str(), e.what(), spec.name.c_str());
    return 2;
  } catch (const std::bad_alloc&) {
    std::fputs("terralod: out of memory\n", stderr);
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod: %s\n", e.what());
    return 1;
  }
}
