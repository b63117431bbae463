// Terrain inputs shared by the terralod tools and the terralod-fly demo: the built-in generated
// terrain of `terralod demo`, the read / build / read-.pm stages that print one line each, and
// the checks of file names by kind (.pm, mesh outputs).
//
// Usage:
//   const pm::Heightfield hf = terralod::pm::generate_terrain(terralod::cli::demo_terrain_options(513));
//   pm::ProgressiveMesh m = terralod::cli::is_pm_file(path)
//                               ? terralod::cli::read_pm_stage(path)
//                               : terralod::cli::build_stage(terralod::cli::read_stage(path, {}), {});
//
// Contract:
//   - demo_terrain_options(size, seed): size in 2..8193 samples per side (callers check it), any
//     seed. A DEM-like terrain: 30 m spacing, 1/16 m vertical resolution, relief that fades with
//     scale (roughness 0.42) as real landscapes do; the library's default generator is rougher,
//     for tests.
//   - read_stage / build_stage / read_pm_stage print one line to stdout ("read  ...",
//     "build ...": sizes in and out, error, milliseconds); build_stage shows a ProgressBar on
//     stderr and replaces options.progress. Errors propagate (DemError, PmFormatError: each
//     names the file).
//   - check_mesh_output(option, path): UsageError "option '--out' must name a .ply, .obj, .glb or
//     .gltf file, not 'x.stl'" unless pm::mesh_format_of(path) knows the extension.
#pragma once

#include <cstdint>
#include <string>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace terralod::cli {

/// Samples per side of the built-in terrain when none is given.
inline constexpr int kDemoTerrainSize = 513;

/// The generated terrain of `terralod demo` and `terralod-fly` (see the contract).
pm::TerrainOptions demo_terrain_options(int size = kDemoTerrainSize, std::uint64_t seed = 1);

/// The file's extension in lower case, with its dot ("" when it has none).
std::string lower_extension(const std::string& path);
/// True for a .pm file (any case).
bool is_pm_file(const std::string& path);
/// Checks that `path`, the value of `option`, names a mesh format pm::write_mesh writes
/// (.ply, .obj, .glb or .gltf, any case); UsageError naming the option and the path otherwise.
void check_mesh_output(const std::string& option, const std::string& path);
/// "samples" or "continuous".
const char* metric_name(pm::ErrorMetric metric);

/// Reads a DEM (blocks::read_dem); prints its size and voids.
pm::Heightfield read_stage(const std::string& path, const blocks::DemOptions& options = {});
/// Builds its progressive mesh with a progress bar; prints vertices in -> out, max error, time.
pm::ProgressiveMesh build_stage(const pm::Heightfield& hf, pm::BuildOptions options = {});
/// Reads a .pm file; prints its size, vsplits and metric.
pm::ProgressiveMesh read_pm_stage(const std::string& path);

}  // namespace terralod::cli
