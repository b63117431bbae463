// Terrain inputs shared by the terralod tools and terralod-fly (see terrain_input.hpp).
#include "terrain_input.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <limits>

#include "cli_common.hpp"
#include "dem_options.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/pm_io.hpp"

namespace terralod::cli {

namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

pm::TerrainOptions demo_terrain_options(int size, std::uint64_t seed) {
  pm::TerrainOptions o;
  o.width = o.height = size;
  o.seed = seed;
  o.roughness = 0.42;
  o.height_quantum = 1.0 / 16.0;
  return o;
}

std::string lower_extension(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

bool is_pm_file(const std::string& path) { return lower_extension(path) == ".pm"; }

void check_mesh_output(const std::string& option, const std::string& path) {
  if (!pm::mesh_format_of(path))
    throw UsageError("option '" + option + "' must name a " + std::string(pm::kMeshWriteExtensions) +
                     " file, not '" + path + "'");
}

namespace {

// The line of write_mesh_stage, once the mesh written in `ms` is on disk.
double print_write_line(const std::string& path, const char* units, double ms) {
  print_line(strf("write %s: %s, %s units, %s", path.c_str(),
                  format_bytes(std::filesystem::file_size(path)).c_str(), units,
                  format_duration(ms).c_str()));
  return ms;
}

}  // namespace

double write_mesh_stage(const pm::TriangleMesh& mesh, const pm::Heightfield& hf, const std::string& path,
                        pm::Units units) {
  const auto t = Clock::now();
  pm::write_mesh(mesh, hf, path, units);
  return print_write_line(path, units == pm::Units::Samples ? "samples" : "world", ms_since(t));
}

double write_mesh_stage(const pm::TriangleMeshData& world, const std::string& path) {
  const auto t = Clock::now();
  pm::write_mesh(world, path);
  return print_write_line(path, "world", ms_since(t));
}

const char* metric_name(pm::ErrorMetric m) {
  return m == pm::ErrorMetric::Samples ? "samples" : "continuous";
}

std::pair<double, double> height_range(const pm::Heightfield& hf) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i)) lo = std::min(lo, hf[i]), hi = std::max(hi, hf[i]);
  return {lo, hi};
}

pm::Heightfield generate_stage(const Args& a) {
  const pm::TerrainOptions topt =
      demo_terrain_options(int(a.get_int("--size", kDemoTerrainSize, 2, 8193)),
                           std::uint64_t(a.get_int("--seed", 1, 0, std::numeric_limits<long long>::max())));
  const auto t = Clock::now();
  pm::Heightfield hf = pm::generate_terrain(topt);
  const auto [hmin, hmax] = height_range(hf);
  print_line(strf("terrain %d x %d samples, seed %llu, %g m spacing, heights %.1f .. %.1f m, %s", hf.width(),
                  hf.height(), static_cast<unsigned long long>(topt.seed), topt.spacing, hmin, hmax,
                  format_duration(ms_since(t)).c_str()));
  return hf;
}

pm::Heightfield read_stage(const std::string& path, const blocks::DemOptions& options) {
  const auto t = Clock::now();
  pm::Heightfield hf = blocks::read_dem(path, options);
  const double ms = ms_since(t);
  warn_about_frame(blocks::DemGrid::of(hf));
  std::string voids;
  if (hf.voids.voids == hf.voids.filled)
    voids = strf("%zu voids filled", hf.voids.filled);
  else
    voids = strf("%zu voids (%zu filled, %zu kept as holes)", hf.voids.voids, hf.voids.filled,
                 hf.voids.voids - hf.voids.filled);
  print_line(strf("read  %s: %d x %d samples, %s, %s", path.c_str(), hf.width(), hf.height(), voids.c_str(),
                  format_duration(ms).c_str()));
  return hf;
}

pm::ProgressiveMesh build_with_progress(const pm::Heightfield& hf, pm::BuildOptions options, double& ms,
                                        BuildFn build) {
  ProgressBar bar("build");
  options.progress = [&bar](double f) { return bar.update(f); };
  const auto t = Clock::now();
  pm::ProgressiveMesh mesh = build(hf, options);
  ms = ms_since(t);
  bar.finish();
  return mesh;
}

std::string build_line(const pm::ProgressiveMesh& mesh, double ms) {
  return strf("build %zu vertices -> %zu base vertices, %zu vsplits, max error %.1f m, %s",
              mesh.full_vertex_count(), mesh.base_vertex_count(), mesh.vsplit_count(), mesh.max_error(),
              format_duration(ms).c_str());
}

pm::ProgressiveMesh build_stage(const pm::Heightfield& hf, pm::BuildOptions options) {
  double ms = 0.0;
  pm::ProgressiveMesh mesh = build_with_progress(hf, std::move(options), ms);
  print_line(build_line(mesh, ms));
  return mesh;
}

pm::ProgressiveMesh read_pm_stage(const std::string& path) {
  const auto t = Clock::now();
  pm::ProgressiveMesh mesh = pm::read_pm(path);
  const double ms = ms_since(t);
  print_line(strf("read  %s: %d x %d samples, %zu vertices, %zu vsplits, metric %s, %s", path.c_str(),
                  mesh.heightfield().width(), mesh.heightfield().height(), mesh.full_vertex_count(),
                  mesh.vsplit_count(), metric_name(mesh.metric()), format_duration(ms).c_str()));
  return mesh;
}

pm::ProgressiveMesh pm_input_stage(const std::string& path, const blocks::DemOptions& dem,
                                   const pm::BuildOptions& build) {
  return is_pm_file(path) ? read_pm_stage(path) : build_stage(read_stage(path, dem), build);
}

}  // namespace terralod::cli
