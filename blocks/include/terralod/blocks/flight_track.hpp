// Flight tracks: a GPX track (or route) or an IGC flight log, read and turned into a camera path
// over a block database, so that `terralod fly` and `terralod-fly` replay a real flight where it
// happened. The database's world frame is built by terralod (for a geographic DEM, an azimuthal
// equidistant projection of its own), so a user cannot write world metres by hand; a track's
// longitude, latitude and height can be.
//
// Usage:
//   namespace tb = terralod::blocks;
//   tb::FlightTrack track = tb::read_flight_track("flight.igc");
//   tb::TrackPath p = tb::track_camera_path(track, tb::BlockDatabase::open("alps.db"), {}, {});
//   // p.cameras: one pose per frame at 60 fps, in the conventions of camera_path.hpp
//
// Reading (read_flight_track; by extension, any case: .gpx or .igc):
//   GPX   through GDAL's GPX driver: the track points (every <trkpt> of every <trk> and
//         <trkseg>, in file order), else the route points (<rtept>). <ele> is the height;
//         points without one are skipped (counted). Heights are taken as EGM96 heights (above
//         mean sea level, as GPS receivers write <ele>; GPX does not state a datum). <time>
//         gives the times when every kept point has one; otherwise the track is untimed.
//   IGC   the FAI format of gliding and paragliding loggers: B records (UTC time, latitude
//         DDMMmmm N/S, longitude DDDMMmmm E/W, fix validity A/V, pressure altitude, GNSS
//         altitude); times past midnight roll over to the next day. The GNSS altitude of every
//         3D fix (validity A) is the height, above the WGS 84 ellipsoid as the IGC specification
//         states, or above the geoid (EGM96) when the header says HFALGALTGPS:GEO; 2D fixes
//         are skipped. A log with no GNSS altitude at all uses the pressure altitude (ISA, taken
//         as EGM96 heights: off by the day's pressure, often tens of metres; the note says so).
//   Points whose time does not advance past the last kept one are skipped (counted).
//   Errors: std::runtime_error "<file>: <problem>" (IGC: "<file>: line N: <problem>") for a
//   missing or unreadable file, a malformed B record or a bad time, a track of fewer than two
//   points, and anything GDAL cannot read as GPX. Never crashes on arbitrary bytes.
//
// The camera path (track_camera_path):
//   - Positions: longitude/latitude through the database's CRS and georeference to the world
//     frame (the same transformation as the object layers, world_placement); heights from the
//     track's datum to the database's (its vertical datum; EGM96 when it states none, as the
//     exporters assume), through PROJ's geoid grids when they differ (GeoError when PROJ
//     lacks the grid).
//   - Time: frame k shows the track at time from_s + k * time_scale / fps, positions
//     interpolated linearly between the points around it; the last frame is at to_s, or the last
//     point when to_s is past it. An untimed track is flown at speed_mps along its ground
//     distance. A from_s at or past the track's end is a std::runtime_error.
//   - Orientation: yaw along the direction of travel over the heading_window_s around the frame
//     (so a logger's jitter does not shake the view; kept while the track stands still), pitch
//     and fovy as given.
//   - Errors: GeoError when the database has no CRS or the points cannot be transformed, or
//     when no point lies on the terrain; std::runtime_error when the path would exceed
//     max_frames (a longer replay needs a larger time_scale).
//   - Memory: about 100 bytes per track point and 110 per frame (pm::Camera).
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/pm/camera_path.hpp"

namespace terralod::blocks {

struct TrackPoint {
  double lon = 0.0, lat = 0.0;  ///< degrees, WGS 84
  double height = 0.0;          ///< metres in FlightTrack::height_datum
  double time_s = 0.0;          ///< seconds after the first point (0 for every point when untimed)
};

struct FlightTrack {
  std::string file;
  std::string format;              ///< "GPX" or "IGC"
  std::vector<TrackPoint> points;  ///< at least two
  bool timed = false;              ///< times strictly increase from 0
  std::string height_datum;        ///< as geo_grid.hpp's names: "egm96", "ellipsoid", ...
  std::string height_note;         ///< where the heights come from and why this datum
  std::size_t skipped = 0;         ///< points left out (no height, time not advancing, 2D fix)
};

/// Whether `path` names a GPX or IGC file (by its extension, any case).
bool is_flight_track(const std::string& path);

FlightTrack read_flight_track(const std::string& path);

/// The IGC reader on text in memory (`name` in messages).
FlightTrack parse_igc(std::string_view text, const std::string& name);

struct TrackCameraOptions {
  double pitch_deg = -10.0;       ///< above the horizon, [-90, 90]
  double fovy_deg = 60.0;         ///< (0, 180)
  double speed_mps = 50.0;        ///< ground speed of an untimed track, > 0
  double time_scale = 1.0;        ///< track seconds per replayed second, > 0
  double fps = 60.0;              ///< frames per replayed second, > 0
  double heading_window_s = 2.0;  ///< track seconds the direction of travel is taken over, >= 0
  double from_s = 0.0;            ///< replay from this track time (seconds after its first point), >= 0
  double to_s = std::numeric_limits<double>::infinity();  ///< ... to this one (or its end), > from_s
  std::string height_datum;                               ///< overrides the track's ("" = as read)
  std::size_t max_frames = 10'000'000;
};

struct TrackPath {
  std::vector<pm::Camera> cameras;
  double duration_s = 0.0;                  ///< the whole track's time (untimed: at speed_mps)
  double begin_s = 0.0, end_s = 0.0;        ///< the track times of the first and the last frame
  double ground_m = 0.0;                    ///< distance flown in the world frame's plan view
  std::size_t outside = 0;                  ///< track points off the terrain's samples
  std::string height_datum;                 ///< the track's, as used
  std::string terrain_datum;                ///< the database's, as used
  double shift_min = 0.0, shift_max = 0.0;  ///< metres added to the track's heights
};

TrackPath track_camera_path(const FlightTrack& track, const BlockDatabase& db,
                            const TrackCameraOptions& options, const pm::CameraPathOptions& view);

}  // namespace terralod::blocks
