// The camera path of the flight tools (`terralod fly --path`, `terralod-fly --path` and
// `--replay`): a PATH.csv in world metres (pm/camera_path.hpp), or a GPX track or IGC flight log
// replayed over --db where it was flown (blocks/flight_track.hpp), with the --track-* options.
//
// Usage:
//   s.options = concat(s.options, track_option_specs());
//   std::vector<pm::Camera> path = read_flight_path(a, "--path", a.get("--db"), view);
//
// Contract: a .gpx or .igc file needs a database (UsageError "--path FILE.igc needs --db ...");
// --track-* options without such a file are a UsageError too. A track prints one line on stdout:
// its format, points, duration, distance, frames, where its heights come from and how they were
// converted, and how many points lie off the terrain. Errors of the file or the database are
// those of read_camera_path, read_flight_track and track_camera_path.
#pragma once

#include <string>
#include <vector>

#include "cli_common.hpp"
#include "terralod/pm/camera_path.hpp"

namespace terralod::cli {

/// --track-pitch, --track-fovy, --track-speed, --track-time-scale, --track-heights.
std::vector<OptionSpec> track_option_specs();

/// The --help paragraph on flight tracks.
std::string track_help();

/// The path of `option`'s file (db_path empty: no database given).
std::vector<pm::Camera> read_flight_path(const Args& a, const std::string& option, const std::string& db_path,
                                         const pm::CameraPathOptions& view);

}  // namespace terralod::cli
