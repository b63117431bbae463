// GPX and IGC flight tracks, and their camera paths over a block database (flight_track.hpp).
#include "terralod/blocks/flight_track.hpp"

#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

#include "gdal_support.hpp"
#include "terralod/blocks/geo_grid.hpp"
#include "world_placement.hpp"

namespace terralod::blocks {

namespace {

namespace fs = std::filesystem;
using detail::gdal_message;
using detail::QuietGdal;

std::string extension(const std::string& path) { return detail::lower(fs::path(path).extension().string()); }

// Days from 1970-01-01 to the civil date y-m-d (proleptic Gregorian; H. Hinnant's algorithm).
long long days_from_civil(long long y, unsigned m, unsigned d) {
  y -= m <= 2;
  const long long era = (y >= 0 ? y : y - 399) / 400;
  const unsigned yoe = unsigned(y - era * 400);
  const unsigned doy = (153 * (m > 2 ? m - 3 : m + 9) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + (long long)doe - 719468;
}

// Keeps the points whose time advances past the last kept one; times then start at 0.
void keep_advancing(FlightTrack& t, const std::vector<double>& absolute) {
  std::vector<TrackPoint> kept;
  double last = -std::numeric_limits<double>::infinity(), first = 0.0;
  for (std::size_t i = 0; i < t.points.size(); ++i) {
    if (!(absolute[i] > last)) {
      ++t.skipped;
      continue;
    }
    if (kept.empty()) first = absolute[i];
    last = absolute[i];
    kept.push_back(t.points[i]);
    kept.back().time_s = absolute[i] - first;
  }
  t.points = std::move(kept);
}

void check_length(const FlightTrack& t) {
  if (t.points.size() < 2)
    throw std::runtime_error(t.file + ": " + std::to_string(t.points.size()) + " usable track point(s) (" +
                             std::to_string(t.skipped) + " skipped); a flight needs at least two");
}

FlightTrack read_gpx(const std::string& path) {
  detail::register_gdal();
  const QuietGdal quiet;
  const char* const drivers[] = {"GPX", nullptr};
  const GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, drivers));
  if (!ds)
    throw std::runtime_error(path + ": not a GPX file GDAL reads (" + gdal_message("GPX driver refused it") +
                             ")");
  OGRLayer* layer = nullptr;
  for (const char* name : {"track_points", "route_points"}) {
    OGRLayer* l = ds->GetLayerByName(name);
    if (l != nullptr && l->GetFeatureCount() > 0) {
      layer = l;
      break;
    }
  }
  if (layer == nullptr)
    throw std::runtime_error(path + ": no track points (<trkpt>) or route points (<rtept>)");
  FlightTrack t;
  t.file = path;
  t.format = "GPX";
  t.height_datum = "egm96";
  t.height_note = std::string("GPX <ele> of the ") + (layer->GetName()[0] == 't' ? "track" : "route") +
                  " points, taken as EGM96 heights (above mean sea level, as GPS receivers write it; GPX "
                  "states no datum)";
  const int ele = layer->GetLayerDefn()->GetFieldIndex("ele"),
            time = layer->GetLayerDefn()->GetFieldIndex("time");
  std::vector<double> absolute;
  bool all_timed = time >= 0;
  layer->ResetReading();
  for (OGRFeatureUniquePtr f(layer->GetNextFeature()); f; f.reset(layer->GetNextFeature())) {
    const OGRGeometry* g = f->GetGeometryRef();
    if (g == nullptr || wkbFlatten(g->getGeometryType()) != wkbPoint || ele < 0 ||
        !f->IsFieldSetAndNotNull(ele)) {
      ++t.skipped;
      continue;
    }
    const OGRPoint& p = *g->toPoint();
    const double h = f->GetFieldAsDouble(ele);
    if (!std::isfinite(p.getX()) || !std::isfinite(p.getY()) || !std::isfinite(h) ||
        std::abs(p.getY()) > 90.0) {
      ++t.skipped;
      continue;
    }
    t.points.push_back({p.getX(), p.getY(), h, 0.0});
    int y = 0, mo = 0, d = 0, hh = 0, mi = 0, tz = 0;
    float sec = 0.0f;
    if (all_timed && f->IsFieldSetAndNotNull(time) &&
        f->GetFieldAsDateTime(time, &y, &mo, &d, &hh, &mi, &sec, &tz) && mo >= 1 && mo <= 12 && d >= 1 &&
        d <= 31) {
      // OGR's time zone flag: 100 is UTC, 100 + k is k quarter hours east of it (0, 1: unknown, local).
      const double offset = tz > 1 ? (tz - 100) * 900.0 : 0.0;
      absolute.push_back(double(days_from_civil(y, unsigned(mo), unsigned(d))) * 86400.0 + hh * 3600.0 +
                         mi * 60.0 + double(sec) - offset);
    } else {
      all_timed = false;
    }
  }
  t.timed = all_timed && !t.points.empty();
  if (t.timed) keep_advancing(t, absolute);
  check_length(t);
  return t;
}

// Digits [a, a + n) of `s` as a number; nullopt unless all are digits.
std::optional<int> digits(std::string_view s, std::size_t a, std::size_t n) {
  int v = 0;
  for (std::size_t i = a; i < a + n; ++i) {
    if (s[i] < '0' || s[i] > '9') return std::nullopt;
    v = v * 10 + (s[i] - '0');
  }
  return v;
}

// An altitude field of five characters: digits, or '-' and four digits.
std::optional<int> altitude(std::string_view s, std::size_t a) {
  if (s[a] == '-') {
    const std::optional<int> v = digits(s, a + 1, 4);
    return v ? std::optional<int>(-*v) : std::nullopt;
  }
  return digits(s, a, 5);
}

// "600", "12.5": a number as a person writes it.
std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

}  // namespace

bool is_flight_track(const std::string& path) {
  const std::string e = extension(path);
  return e == ".gpx" || e == ".igc";
}

FlightTrack parse_igc(std::string_view text, const std::string& name) {
  struct Fix {
    double lon, lat, seconds;
    int pressure, gnss;
    bool three_d;
  };
  std::vector<Fix> fixes;
  std::string alt_reference;  // HFALG: GEO, ELL or NIL
  std::size_t line_no = 0;
  double day = 0.0, last_of_day = -1.0;
  for (std::size_t pos = 0; pos < text.size();) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.remove_suffix(1);
    const auto fail = [&](const std::string& what) {
      throw std::runtime_error(name + ": line " + std::to_string(line_no) + ": " + what);
    };
    if (line.rfind("HFALG", 0) == 0 || line.rfind("HPALG", 0) == 0) {
      const std::string v = detail::lower(std::string(line));
      alt_reference = v.find("geo") != std::string::npos   ? "GEO"
                      : v.find("ell") != std::string::npos ? "ELL"
                      : v.find("nil") != std::string::npos ? "NIL"
                                                           : "";
      continue;
    }
    if (line.empty() || line[0] != 'B') continue;
    if (line.size() < 35)
      fail("a B record has 35 characters or more, this one " + std::to_string(line.size()));
    const auto hh = digits(line, 1, 2), mm = digits(line, 3, 2), ss = digits(line, 5, 2);
    if (!hh || !mm || !ss || *hh > 23 || *mm > 59 || *ss > 59)
      fail("bad time '" + std::string(line.substr(1, 6)) + "'");
    const auto lat_d = digits(line, 7, 2), lat_m = digits(line, 9, 5);
    const auto lon_d = digits(line, 15, 3), lon_m = digits(line, 18, 5);
    if (!lat_d || !lat_m || (line[14] != 'N' && line[14] != 'S') || *lat_m >= 60000 || *lat_d > 90)
      fail("bad latitude '" + std::string(line.substr(7, 8)) + "' (DDMMmmm then N or S)");
    if (!lon_d || !lon_m || (line[23] != 'E' && line[23] != 'W') || *lon_m >= 60000 || *lon_d > 180)
      fail("bad longitude '" + std::string(line.substr(15, 9)) + "' (DDDMMmmm then E or W)");
    if (line[24] != 'A' && line[24] != 'V')
      fail("bad fix validity '" + std::string(1, line[24]) + "' (A or V)");
    const auto pressure = altitude(line, 25), gnss = altitude(line, 30);
    if (!pressure || !gnss)
      fail("bad altitude '" + std::string(line.substr(25, 10)) + "' (two fields of five digits)");
    const double lat = (*lat_d + *lat_m / 60000.0) * (line[14] == 'S' ? -1.0 : 1.0);
    const double lon = (*lon_d + *lon_m / 60000.0) * (line[23] == 'W' ? -1.0 : 1.0);
    if (std::abs(lat) > 90.0 || std::abs(lon) > 180.0) fail("position off the Earth");
    const double of_day = *hh * 3600.0 + *mm * 60.0 + *ss;
    // Fixes are in UTC; a time well before the last one is the next day (a flight over midnight),
    // a time a little before it a logger's glitch (skipped below as not advancing).
    if (last_of_day >= 0.0 && of_day < last_of_day - 43200.0) day += 86400.0;
    last_of_day = of_day;
    fixes.push_back({lon, lat, day + of_day, *pressure, *gnss, line[24] == 'A'});
  }
  FlightTrack t;
  t.file = name;
  t.format = "IGC";
  t.timed = true;
  const bool any_gnss = alt_reference != "NIL" && std::any_of(fixes.begin(), fixes.end(), [](const Fix& f) {
                          return f.three_d && f.gnss != 0;
                        });
  if (any_gnss) {
    t.height_datum = alt_reference == "GEO" ? "egm96" : "ellipsoid";
    t.height_note =
        alt_reference == "GEO"
            ? "IGC GNSS altitude of the 3D fixes, above the geoid (HFALGALTGPS:GEO, taken as EGM96)"
            : std::string(
                  "IGC GNSS altitude of the 3D fixes, above the WGS 84 ellipsoid (the IGC "
                  "specification's datum") +
                  (alt_reference == "ELL" ? ", HFALGALTGPS:ELL)" : ")");
  } else {
    t.height_datum = "egm96";
    t.height_note =
        "IGC pressure altitude (the log has no GNSS altitude): ISA 1013.25 hPa, taken as EGM96 heights, "
        "off by the day's pressure (often tens of metres)";
  }
  std::vector<double> absolute;
  for (const Fix& f : fixes) {
    if (any_gnss && !f.three_d) {
      ++t.skipped;
      continue;
    }
    t.points.push_back({f.lon, f.lat, double(any_gnss ? f.gnss : f.pressure), 0.0});
    absolute.push_back(f.seconds);
  }
  keep_advancing(t, absolute);
  check_length(t);
  return t;
}

FlightTrack read_flight_track(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw std::runtime_error(path + ": no such file");
  const std::string e = extension(path);
  if (e == ".gpx") return read_gpx(path);
  if (e != ".igc") throw std::runtime_error(path + ": not a flight track (a .gpx or .igc file)");
  std::ifstream in(path, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), {});
  if (!in.good() && !in.eof()) throw std::runtime_error(path + ": cannot be read");
  return parse_igc(text, path);
}

TrackPath track_camera_path(const FlightTrack& track, const BlockDatabase& db, const TrackCameraOptions& o,
                            const pm::CameraPathOptions& view) {
  if (!(o.pitch_deg >= -90 && o.pitch_deg <= 90 && o.fovy_deg > 0 && o.fovy_deg < 180 && o.speed_mps > 0 &&
        o.time_scale > 0 && o.fps > 0 && o.heading_window_s >= 0 && o.from_s >= 0 && o.to_s > o.from_s))
    throw std::invalid_argument("track_camera_path: options out of range");
  const std::vector<TrackPoint>& pts = track.points;
  if (pts.size() < 2) throw std::runtime_error(track.file + ": a flight needs at least two track points");
  TrackPath out;
  // Plan view: longitude/latitude -> the terrain's world frame.
  OGRSpatialReference wgs84;
  wgs84.SetWellKnownGeogCS("WGS84");
  detail::WorldPlacement placement(db, wgs84, track.file);
  const DatabaseInfo& info = db.info();
  struct XY {
    double x, y;
  };
  std::vector<XY> xy(pts.size());
  std::vector<double> lon(pts.size()), lat(pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    double x = pts[i].lon, y = pts[i].lat;
    std::array<double, 4> box = detail::empty_sample_box();
    if (!placement.place({&x, 1}, {&y, 1}, box))
      throw GeoError(track.file + ": point " + std::to_string(i + 1) + " (longitude " +
                     std::to_string(pts[i].lon) + ", latitude " + std::to_string(pts[i].lat) +
                     ") cannot be moved to the terrain's frame");
    xy[i] = {x, y};
    lon[i] = pts[i].lon, lat[i] = pts[i].lat;
    constexpr double tol = 1e-6;
    if (box[0] < -tol || box[1] < -tol || box[0] > info.grid_width - 1 + tol ||
        box[1] > info.grid_height - 1 + tol)
      ++out.outside;
  }
  if (out.outside == pts.size())
    throw GeoError(track.file + ": no point of the track lies on the terrain " + db.path() +
                   " (first at longitude " + std::to_string(pts[0].lon) + ", latitude " +
                   std::to_string(pts[0].lat) + ")");
  // Heights: the track's datum -> the terrain's (EGM96 when it states none, as the exporters assume).
  const std::optional<Georeference> geo = db.georeference();
  out.height_datum = o.height_datum.empty() ? track.height_datum : o.height_datum;
  out.terrain_datum =
      geo && !geo->vertical_datum.empty() ? geo->vertical_datum : "EGM96 (assumed: the terrain states none)";
  std::vector<double> shift(pts.size(), 0.0);
  if (detail::vertical_crs(out.height_datum) != detail::vertical_crs(geo ? geo->vertical_datum : "")) {
    const std::vector<double> n_track = geoid_undulations(out.height_datum, lon, lat, track.file);
    const std::vector<double> n_terrain = geoid_undulations(
        geo && !geo->vertical_datum.empty() ? geo->vertical_datum : "egm96", lon, lat, db.path());
    for (std::size_t i = 0; i < pts.size(); ++i) shift[i] = n_track[i] - n_terrain[i];
  }
  out.shift_min = *std::min_element(shift.begin(), shift.end());
  out.shift_max = *std::max_element(shift.begin(), shift.end());
  // Times: the track's, or its ground distance at speed_mps.
  std::vector<double> t(pts.size(), 0.0);
  for (std::size_t i = 1; i < pts.size(); ++i) {
    const double d = std::hypot(xy[i].x - xy[i - 1].x, xy[i].y - xy[i - 1].y);
    out.ground_m += d;
    t[i] = track.timed ? pts[i].time_s : t[i - 1] + d / o.speed_mps;
  }
  out.duration_s = t.back();
  if (!(out.duration_s > 0))
    throw std::runtime_error(track.file + ": the track " + (track.timed ? "lasts no time" : "does not move"));
  out.begin_s = o.from_s;
  out.end_s = std::min(o.to_s, out.duration_s);
  if (!(out.begin_s < out.end_s))
    throw std::runtime_error(track.file + ": the track lasts " + number(out.duration_s) +
                             " s; a replay from " + number(o.from_s) + " s shows none of it");
  const double dt = o.time_scale / o.fps;
  const double frames = std::ceil((out.end_s - out.begin_s) / dt - 1e-9) + 1.0;
  if (frames > double(o.max_frames))
    throw std::runtime_error(track.file + ": " + number(out.end_s - out.begin_s) + " s of track would be " +
                             std::to_string((long long)frames) + " frames, more than " +
                             std::to_string(o.max_frames) + "; replay it faster (a larger time scale)");
  // Position at track time s, by linear interpolation; `j` is a cursor that only moves forward
  // for increasing s.
  struct At {
    double x, y, z;
  };
  const auto at = [&](double s, std::size_t& j) -> At {
    s = std::clamp(s, 0.0, out.duration_s);
    while (j + 2 < t.size() && t[j + 1] <= s) ++j;
    while (j > 0 && t[j] > s) --j;
    const double span = t[j + 1] - t[j], a = span > 0 ? std::clamp((s - t[j]) / span, 0.0, 1.0) : 0.0;
    const double z0 = pts[j].height + shift[j], z1 = pts[j + 1].height + shift[j + 1];
    return {xy[j].x + a * (xy[j + 1].x - xy[j].x), xy[j].y + a * (xy[j + 1].y - xy[j].y), z0 + a * (z1 - z0)};
  };
  const std::size_t n = std::size_t(frames);
  out.cameras.resize(n);
  std::vector<double> yaw(n, std::numeric_limits<double>::quiet_NaN());
  std::size_t jp = 0, jb = 0, ja = 0;
  const double half = o.heading_window_s / 2.0;
  for (std::size_t k = 0; k < n; ++k) {
    const double s = std::min(out.begin_s + double(k) * dt, out.end_s);
    const At p = at(s, jp);
    // Direction of travel: from the position half a window before to half a window after (at
    // least across the segment the frame lies on, so a zero window still has a direction).
    At b = at(s - half, jb), a = at(s + half, ja);
    if (std::hypot(a.x - b.x, a.y - b.y) < 1e-6) {
      const std::size_t j = jp;
      b = {xy[j].x, xy[j].y, 0.0}, a = {xy[j + 1].x, xy[j + 1].y, 0.0};
    }
    if (std::hypot(a.x - b.x, a.y - b.y) >= 1e-6)
      yaw[k] = std::remainder(std::atan2(a.x - b.x, a.y - b.y) * 180.0 / std::numbers::pi, 360.0);
    pm::Camera& c = out.cameras[k];
    c.x = p.x, c.y = p.y, c.z = p.z;
    c.pitch_deg = o.pitch_deg, c.fovy_deg = o.fovy_deg;
    c.width_px = view.width_px, c.height_px = view.height_px, c.near_m = view.near_m, c.far_m = view.far_m;
  }
  // Standing still keeps the last direction; before the first move, the first one.
  const auto first = std::find_if(yaw.begin(), yaw.end(), [](double v) { return !std::isnan(v); });
  double last = first == yaw.end() ? 0.0 : *first;
  for (std::size_t k = 0; k < n; ++k) {
    if (!std::isnan(yaw[k])) last = yaw[k];
    out.cameras[k].yaw_deg = last < 0 ? last + 360.0 : last;
  }
  return out;
}

}  // namespace terralod::blocks
