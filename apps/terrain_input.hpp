// Terrain inputs shared by the terralod tools and the terralod-fly demo: the built-in generated
// terrain of `terralod demo`, the generate / read / build / read-.pm stages that print one line
// each, the checks of file names by kind (.pm, mesh outputs) and the stage that writes a mesh.
//
// Usage:
//   const pm::Heightfield hf = terralod::pm::generate_terrain(terralod::cli::demo_terrain_options(513));
//   pm::ProgressiveMesh m = terralod::cli::pm_input_stage(path, {}, {});  // a .pm, or a DEM built
//
// Contract:
//   - demo_terrain_options(size, seed): size in 2..8193 samples per side (callers check it), any
//     seed. A DEM-like terrain: 30 m spacing, 1/16 m vertical resolution, relief that fades with
//     scale (roughness 0.42) as real landscapes do; the library's default generator is rougher,
//     for tests.
//   - generate_stage / read_stage / build_stage / read_pm_stage print one line to stdout
//     ("terrain ...", "read  ...", "build ...": sizes in and out, error, milliseconds);
//     build_stage shows a ProgressBar on stderr and replaces options.progress. Errors propagate
//     (DemError, PmFormatError: each names the file).
//   - check_mesh_output(option, path): UsageError "option '--out' must name a .ply, .obj, .glb or
//     .gltf file, not 'x.stl'" unless pm::mesh_format_of(path) knows the extension.
#pragma once

#include <cstdint>
#include <string>
#include <utility>

#include "cli_common.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/mesh_io.hpp"
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
/// Writes `mesh` (pm::write_mesh: the format by extension, vertices in `units`) and prints
/// "write PATH: SIZE, UNITS units, TIME"; returns the milliseconds it took.
double write_mesh_stage(const pm::TriangleMesh& mesh, const pm::Heightfield& hf, const std::string& path,
                        pm::Units units);
/// The same for explicit world positions (the line says "world units").
double write_mesh_stage(const pm::TriangleMeshData& world, const std::string& path);
/// "samples" or "continuous".
const char* metric_name(pm::ErrorMetric metric);

/// The lowest and highest valid sample of `hf`, metres (+inf and -inf when it has none).
std::pair<double, double> height_range(const pm::Heightfield& hf);

/// Generates the built-in terrain of options --size (default kDemoTerrainSize, 2..8193) and --seed
/// (default 1) of `a` (terralod demo and generate); prints its size, seed, spacing and height range.
pm::Heightfield generate_stage(const Args& a);
/// Reads a DEM (blocks::read_dem); prints its size and voids.
pm::Heightfield read_stage(const std::string& path, const blocks::DemOptions& options = {});
/// Builds its progressive mesh with a progress bar; prints vertices in -> out, max error, time.
pm::ProgressiveMesh build_stage(const pm::Heightfield& hf, pm::BuildOptions options = {});
/// A function that builds a PM: pm::ProgressiveMesh::build, or pm::build_with_decimater
/// (terralod pm --decimater openmesh).
using BuildFn = pm::ProgressiveMesh (*)(const pm::Heightfield&, const pm::BuildOptions&);
/// build_stage's work without its line: the mesh built by `build` and, in `ms`, the build's time
/// (for a caller that prints build_line later).
pm::ProgressiveMesh build_with_progress(const pm::Heightfield& hf, pm::BuildOptions options, double& ms,
                                        BuildFn build = &pm::ProgressiveMesh::build);
/// build_stage's line: "build V vertices -> B base vertices, N vsplits, max error E m, TIME".
std::string build_line(const pm::ProgressiveMesh& mesh, double ms);
/// Reads a .pm file; prints its size, vsplits and metric.
pm::ProgressiveMesh read_pm_stage(const std::string& path);
/// The progressive mesh of a command's input: read_pm_stage for a .pm file, else the DEM read
/// with `dem` and built with `build` (read_stage, then build_stage).
pm::ProgressiveMesh pm_input_stage(const std::string& path, const blocks::DemOptions& dem,
                                   const pm::BuildOptions& build);

}  // namespace terralod::cli
