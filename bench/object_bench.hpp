// What the map-object benchmarks share (terralod-bench-objects, -shapes, -drape): the database of
// N44W072 they build once in the temporary folder, and their flight along an arc.
//
// Usage:
//   const pm::Heightfield hf = tb::read_dem(terralod::bench::n44w072_path());
//   const std::string db = terralod::bench::n44w072_database(hf);   // built, or reused
//   terralod::bench::ArcFlight flight{x, y, /*heading=*/0.2, /*speed=*/400, /*radius=*/12000,
//                                     /*above=*/700, rt.terrain_box().hi.z};
//   for (long f = 0; f < frames; ++f) { pm::Camera c = flight.next(); ... }
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <initializer_list>
#include <numbers>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::bench {

/// The benchmarks' DEM: TERRALOD_DATA_DIR/N44W072.hgt (callers skip when it is missing).
inline std::string n44w072_path() { return std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt"; }

/// The benchmarks' command line: options that each take a whole number (`--name N`), stored
/// where given, and --help. Returns the status main returns at once: 0 after --help or -h
/// (`usage` printed), 2 for anything else; nullopt to run.
inline std::optional<int> parse_options(int argc, char** argv,
                                        std::initializer_list<std::pair<const char*, long*>> options,
                                        const char* usage) {
  for (int i = 1; i < argc; ++i) {
    long* value = nullptr;
    for (const auto& [name, v] : options)
      if (!std::strcmp(argv[i], name) && i + 1 < argc) value = v;
    if (value) {
      *value = std::atol(argv[++i]);
      continue;
    }
    std::puts(usage);
    return std::strcmp(argv[i], "--help") && std::strcmp(argv[i], "-h") ? 2 : 0;
  }
  return std::nullopt;
}

/// Whether N44W072.hgt is missing; then says that the benchmark is skipped (main returns 0).
inline bool skipped_without_n44w072() {
  if (std::filesystem::exists(n44w072_path())) return false;
  std::printf("skip: N44W072.hgt not in %s\n", TERRALOD_DATA_DIR);
  return true;
}

/// The block database of `hf` (N44W072, blocks of 129 samples, every core) in the temporary
/// folder: built on the first run, reused while its build parameters and samples match (the
/// build resumes or reuses, tree_builder.hpp). Prints one line. Object layers are added to it by
/// the benchmarks under their own names.
inline std::string n44w072_database(const pm::Heightfield& hf) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "terralod-bench-objects-129.db").string();
  blocks::DatabaseBuildOptions o;
  o.block_size = 129;
  o.threads = int(std::max(1u, std::thread::hardware_concurrency()));
  const blocks::DatabaseSummary s = blocks::build_database(hf, path, o);
  std::printf("%s %s: %d x %d samples in %zu blocks of %d, %.1f s\n",
              s.blocks_built.value_or(0) == 0 ? "reuse" : "build", path.c_str(), s.grid_width, s.grid_height,
              s.blocks, s.block_size, s.seconds);
  return path;
}

/// A flight at 60 frames a second along an arc turning right: `speed_mps` along a circle of
/// `radius_m`, `above_m` over `zmax` (the terrain's highest sample), looking ahead and 20
/// degrees down with a 60-degree vertical field of view, at 1280 x 720.
struct ArcFlight {
  double x = 0, y = 0, heading = 0;  ///< world metres; radians clockwise from north
  double speed_mps = 400, radius_m = 12000, above_m = 700, zmax = 0;

  /// The next frame's camera (the first call moves one frame from the start).
  pm::Camera next() {
    heading += speed_mps / radius_m / 60.0;
    x += speed_mps / 60 * std::sin(heading), y += speed_mps / 60 * std::cos(heading);
    pm::Camera c;
    c.x = x, c.y = y, c.z = zmax + above_m;
    c.yaw_deg = heading * 180 / std::numbers::pi, c.pitch_deg = -20, c.fovy_deg = 60;
    c.width_px = 1280, c.height_px = 720;
    return c;
  }
};

}  // namespace terralod::bench
