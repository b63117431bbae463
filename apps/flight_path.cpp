#include "flight_path.hpp"

#include <algorithm>
#include <cmath>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/flight_track.hpp"

namespace terralod::cli {

std::vector<OptionSpec> track_option_specs() {
  return {
      {"--track-pitch", "DEGREES", "GPX/IGC path: camera pitch above the horizon, -90..90 (default -10)"},
      {"--track-fovy", "DEGREES", "GPX/IGC path: vertical field of view, (0, 180) (default 60)"},
      {"--track-speed", "M/S", "GPX/IGC path without times: ground speed, > 0 (default 50)"},
      {"--track-time-scale", "K", "GPX/IGC path: track seconds per replayed second, > 0 (default 1)"},
      {"--track-from", "SECONDS",
       "GPX/IGC path: replay from this many seconds after the track's start (default 0)"},
      {"--track-to", "SECONDS",
       "GPX/IGC path: replay up to this many seconds after its start (default: its end)"},
      {"--track-clearance", "METRES",
       "GPX/IGC path: keep the eye this far above the ground, >= 0 (default 2; 0: the track's heights)"},
      {"--track-heights", "DATUM",
       "GPX/IGC path: datum of the track's heights: egm96, egm2008, ellipsoid or a PROJ vertical CRS "
       "(default: EGM96 for GPX, the log's for IGC)"},
  };
}

std::string track_help() {
  return "A path ending in .gpx or .igc is a flight track, replayed over --db where it was flown: a GPX\n"
         "track (else route) with <ele> heights, taken as EGM96 (above mean sea level; --track-heights\n"
         "if yours are ellipsoidal), or an IGC log's GNSS altitude (WGS 84 ellipsoid, or the geoid when\n"
         "its header says HFALGALTGPS:GEO; the pressure altitude when it has none). Longitude and\n"
         "latitude go through the database's CRS to its world frame (the frame the object layers use),\n"
         "heights to its vertical datum through PROJ's geoid grids. Frame k shows the track at\n"
         "F + k * K / 60 s (--track-from F, --track-time-scale K) up to --track-to (else its end),\n"
         "positions interpolated between its points; a track without times is flown at --track-speed.\n"
         "The camera looks along the direction of travel (over 2 s of track) at --track-pitch with\n"
         "--track-fovy, and never lower than --track-clearance above the ground under it (the terrain's\n"
         "samples where their block is resident, or the surface drawn the frame before, whichever is\n"
         "higher): GPS heights near take-off and landing fall below the terrain. frames.csv gives the\n"
         "eye where it was. A line on stdout gives the points, duration, distance, frames, the heights'\n"
         "datum and shift, and the points off the terrain; the summary, the frames whose eye was lifted.";
}

bool keep_clear(pm::Camera& c, const blocks::TerrainRuntime& rt, double clearance_m) {
  if (!(clearance_m > 0)) return false;
  const double drawn = rt.drawn_height(c.x, c.y), terrain = rt.terrain_height(c.x, c.y);
  const double ground = std::isnan(drawn) ? terrain : std::isnan(terrain) ? drawn : std::max(drawn, terrain);
  if (!std::isfinite(ground) || c.z >= ground + clearance_m) return false;
  c.z = ground + clearance_m;
  return true;
}

FlightPath read_flight_path(const Args& a, const std::string& option, const std::string& db_path,
                            const pm::CameraPathOptions& view) {
  const std::string file = a.get(option);
  const std::vector<OptionSpec> specs = track_option_specs();
  if (!blocks::is_flight_track(file)) {
    for (const OptionSpec& s : specs)
      if (a.has(s.name))
        throw UsageError(s.name + " is for a GPX or IGC path, and " + option + " is '" + file + "'");
    return {pm::read_camera_path(file, view), 0.0};
  }
  if (db_path.empty())
    throw UsageError(option + " " + file +
                     " needs --db (a block database with a CRS: the track is placed by its coordinates)");
  blocks::TrackCameraOptions o;
  o.pitch_deg = a.get_double("--track-pitch", o.pitch_deg);
  if (!(o.pitch_deg >= -90 && o.pitch_deg <= 90))
    throw UsageError("option '--track-pitch' must be in -90..90 degrees, not '" + a.get("--track-pitch") +
                     "'");
  o.fovy_deg = a.get_double("--track-fovy", o.fovy_deg);
  if (!(o.fovy_deg > 0 && o.fovy_deg < 180))
    throw UsageError("option '--track-fovy' must be in (0, 180) degrees, not '" + a.get("--track-fovy") +
                     "'");
  o.speed_mps = a.get_double("--track-speed", o.speed_mps);
  if (!(o.speed_mps > 0))
    throw UsageError("option '--track-speed' must be > 0 m/s, not '" + a.get("--track-speed") + "'");
  o.time_scale = a.get_double("--track-time-scale", o.time_scale);
  if (!(o.time_scale > 0))
    throw UsageError("option '--track-time-scale' must be > 0, not '" + a.get("--track-time-scale") + "'");
  o.from_s = a.get_double("--track-from", 0.0);
  if (!(o.from_s >= 0))
    throw UsageError("option '--track-from' must be >= 0 seconds, not '" + a.get("--track-from") + "'");
  o.to_s = a.get_double("--track-to", o.to_s);
  if (!(o.to_s > o.from_s))
    throw UsageError("option '--track-to' must be after --track-from (" + strf("%g", o.from_s) +
                     " s), not '" + a.get("--track-to") + "'");
  const double clearance = a.get_double("--track-clearance", 2.0);
  if (!(clearance >= 0))
    throw UsageError("option '--track-clearance' must be >= 0 metres, not '" + a.get("--track-clearance") +
                     "'");
  o.height_datum = a.get("--track-heights");
  const blocks::FlightTrack track = blocks::read_flight_track(file);
  const blocks::TrackPath p = track_camera_path(track, blocks::BlockDatabase::open(db_path), o, view);
  const std::string shift = p.shift_min == p.shift_max ? strf("%+.2f m", p.shift_min)
                                                       : strf("%+.2f..%+.2f m", p.shift_min, p.shift_max);
  const std::string window = p.begin_s == 0 && p.end_s == p.duration_s
                                 ? ""
                                 : strf(", from %.1f s to %.1f s of it", p.begin_s, p.end_s);
  print_line(
      strf("track %s: %s, %zu points%s, %s, %.1f km, %s, %zu frames at 60 fps (time scale %g%s); heights: "
           "%s, to the terrain's %s (%s)%s",
           file.c_str(), track.format.c_str(), track.points.size(),
           track.skipped ? strf(" (%zu skipped)", track.skipped).c_str() : "",
           format_duration(p.duration_s * 1000.0).c_str(), p.ground_m / 1000.0,
           track.timed ? "timed" : strf("untimed, flown at %g m/s", o.speed_mps).c_str(), p.cameras.size(),
           o.time_scale, window.c_str(),
           o.height_datum.empty() ? track.height_note.c_str()
                                  : ("taken as " + o.height_datum + " (--track-heights)").c_str(),
           p.terrain_datum.c_str(), shift.c_str(),
           p.outside ? strf("; %zu points off the terrain", p.outside).c_str() : ""));
  return {p.cameras, clearance};
}

}  // namespace terralod::cli
