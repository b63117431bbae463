// Terrain inputs shared by the terralod tools and terralod-fly (see terrain_input.hpp).
#include "terrain_input.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>

#include "cli_common.hpp"
#include "terralod/pm/mesh_io.hpp"
#include "terralod/pm/pm_io.hpp"

namespace terralod::cli {

namespace {

using Clock = std::chrono::steady_clock;

void line(const std::string& s) {
  std::fputs((s + "\n").c_str(), stdout);
  std::fflush(stdout);
}

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

const char* metric_name(pm::ErrorMetric m) {
  return m == pm::ErrorMetric::Samples ? "samples" : "continuous";
}

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
  ProgressBar bar("build");
  options.progress = [&bar](double f) { return bar.update(f); };
  const auto t = Clock::now();
  pm::ProgressiveMesh mesh = pm::ProgressiveMesh::build(hf, options);
  const double ms = ms_since(t);
  bar.finish();
  line(strf("build %zu vertices -> %zu base vertices, %zu vsplits, max error %.1f m, %s",
            mesh.full_vertex_count(), mesh.base_vertex_count(), mesh.vsplit_count(), mesh.max_error(),
            format_duration(ms).c_str()));
  return mesh;
}

pm::ProgressiveMesh read_pm_stage(const std::string& path) {
  const auto t = Clock::now();
  pm::ProgressiveMesh mesh = pm::read_pm(path);
  const double ms = ms_since(t);
  line(strf("read  %s: %d x %d samples, %zu vertices, %zu vsplits, metric %s, %s", path.c_str(),
            mesh.heightfield().width(), mesh.heightfield().height(), mesh.full_vertex_count(),
            mesh.vsplit_count(), metric_name(mesh.metric()), format_duration(ms).c_str()));
  return mesh;
}

}  // namespace terralod::cli
