// The camera path of the flight tools (`terralod fly --path`, `terralod-fly --path` and
// `--replay`): a PATH.csv in world metres (pm/camera_path.hpp), or a GPX track or IGC flight log
// replayed over --db where it was flown (blocks/flight_track.hpp), with the --track-* options.
//
// Usage:
//   s.options = concat(s.options, track_option_specs());
//   FlightPath path = read_flight_path(a, "--path", a.get("--db"), view);
//   for (pm::Camera c : path.cameras) {              // each frame, before its update:
//     keep_clear(c, runtime, path.clearance_m);
//
// Contract: a .gpx or .igc file needs a database (UsageError "--path FILE.igc needs --db ...");
// --track-* options without such a file are a UsageError too. A track prints one line on stdout:
// its format, points, duration, distance, frames, where its heights come from and how they were
// converted, and how many points lie off the terrain. The callers keep a track's eye
// clearance_m above the ground (keep_clear; the first frame is updated once beforehand, so that
// there is one) and say in how many frames they lifted it. Errors of the file or the database are
// those of read_camera_path, read_flight_track and track_camera_path.
#pragma once

#include <string>
#include <vector>

#include "cli_common.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/pm/camera_path.hpp"

namespace terralod::cli {

/// --track-pitch, --track-fovy, --track-speed, --track-time-scale, --track-heights.
std::vector<OptionSpec> track_option_specs();

/// The --help paragraph on flight tracks.
std::string track_help();

struct FlightPath {
  std::vector<pm::Camera> cameras;
  /// A track's eye is kept this far above the ground (--track-clearance); 0 for a PATH.csv,
  /// which is flown as written.
  double clearance_m = 0.0;
};

/// The path of `option`'s file (db_path empty: no database given).
FlightPath read_flight_path(const Args& a, const std::string& option, const std::string& db_path,
                            const pm::CameraPathOptions& view);

/// Lifts c.z to clearance_m above the ground under the eye where it is lower (a track's
/// heights near take-off and landing, or the DEM's own error, put it under the terrain). The
/// ground: the higher of the terrain's samples there (TerrainRuntime::terrain_height, from the
/// resident block) and the surface drawn last update (drawn_height); where neither is known
/// (nothing resident or drawn there yet), or clearance_m <= 0, c is left. True when lifted.
bool keep_clear(pm::Camera& c, const blocks::TerrainRuntime& rt, double clearance_m);

}  // namespace terralod::cli
