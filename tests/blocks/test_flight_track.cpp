// Flight tracks (blocks/flight_track.hpp): IGC logs and GPX files written here are read back
// (positions, times, the heights' datum, what is skipped, malformed input), and turned into
// camera paths over a real database file (SQLite) with a UTM georeference, whose world positions
// are checked against OGR's own transformation of the track's longitudes and latitudes.
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include "object_terrain.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/flight_track.hpp"
#include "terralod/blocks/geo_grid.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
namespace pm = terralod::pm;

struct TempDir {
  fs::path dir;
  TempDir() {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    dir = fs::temp_directory_path() / (std::string("terralod_track_") + info->name());
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~TempDir() { fs::remove_all(dir); }
  std::string operator/(const std::string& name) const { return (dir / name).string(); }
};

void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// The error text of `f()`, which must throw E.
template <typename E, typename F>
std::string error_of(F f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  ADD_FAILURE() << "no exception";
  return {};
}

// UTM zone 33N terrain: 201 x 201 samples 100 m apart, sample (col, row) at easting 490000 +
// 100 col, northing 5000000 - 100 row; world = (easting - 500000, northing - 4990000).
constexpr int kSize = 201;
constexpr double kE0 = 490000.0, kN0 = 5000000.0, kWorldE = 500000.0, kWorldN = 4990000.0;

void make_db(const std::string& path, bool with_crs) {
  tb::DatabaseInfo info;
  info.grid_width = info.grid_height = kSize;
  info.block_size = 201;
  info.transform = pm::GridTransform::north_up(kE0 - kWorldE, kN0 - kWorldN, 100.0, 100.0);
  if (with_crs) info.crs_wkt = terralod::test::utm33_wkt();
  info.source = "test";
  auto db = tb::BlockDatabase::create(path, info);
  if (with_crs) db.put_georeference({pm::GridTransform::north_up(kE0, kN0, 100.0, 100.0), "EGM96 height"});
}

// Where OGR puts (lon, lat) in the test's world frame.
std::pair<double, double> expected_world(double lon, double lat) {
  OGRSpatialReference wgs84, utm;
  wgs84.SetWellKnownGeogCS("WGS84");
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  utm.importFromEPSG(32633);
  utm.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&wgs84, &utm));
  double x = lon, y = lat;
  EXPECT_TRUE(ct->Transform(1, &x, &y));
  return {x - kWorldE, y - kWorldN};
}

// IGC coordinates: DDMMmmmN and DDDMMmmmE from degrees (rounded to 1/1000 minute).
std::string igc_lat(double lat) {
  const long m = std::lround(std::abs(lat) * 60000.0);
  char buf[48];
  std::snprintf(buf, sizeof buf, "%02ld%05ld%c", m / 60000, m % 60000, lat < 0 ? 'S' : 'N');
  return buf;
}
std::string igc_lon(double lon) {
  const long m = std::lround(std::abs(lon) * 60000.0);
  char buf[48];
  std::snprintf(buf, sizeof buf, "%03ld%05ld%c", m / 60000, m % 60000, lon < 0 ? 'W' : 'E');
  return buf;
}
std::string b_record(const char* hhmmss, double lat, double lon, char validity, int pressure, int gnss) {
  char alt[48];
  std::snprintf(alt, sizeof alt, "%05d%05d", pressure, gnss);
  return std::string("B") + hhmmss + igc_lat(lat) + igc_lon(lon) + validity + alt + "\r\n";
}

TEST(FlightTrack, IgcGivesTimesPositionsAndTheLoggersHeightDatum) {
  const std::string text = "AXXX001\r\nHFDTE010726\r\nHFALGALTGPS:GEO\r\n" +
                           b_record("235958", -33.5, -70.25, 'A', 1000, 1010) +  // S, W
                           b_record("235959", -33.5, -70.25, 'V', 1001, 0) +     // 2D fix: skipped
                           b_record("235959", -33.51, -70.26, 'A', 1002, 1012) +
                           b_record("235959", -33.52, -70.27, 'A', 1003, 1013) +  // same time: skipped
                           b_record("000004", -33.53, -70.28, 'A', 1004, 1014) +  // after midnight
                           "G0123456789ABCDEF\r\n";
  const tb::FlightTrack t = tb::parse_igc(text, "t.igc");
  EXPECT_EQ(t.format, "IGC");
  EXPECT_TRUE(t.timed);
  EXPECT_EQ(t.height_datum, "egm96");
  EXPECT_NE(t.height_note.find("HFALGALTGPS:GEO"), std::string::npos) << t.height_note;
  EXPECT_EQ(t.skipped, 2u);
  ASSERT_EQ(t.points.size(), 3u);
  EXPECT_DOUBLE_EQ(t.points[0].lat, -33.5);
  EXPECT_DOUBLE_EQ(t.points[0].lon, -70.25);
  EXPECT_NEAR(t.points[2].lat, -33.53, 1e-9);
  EXPECT_NEAR(t.points[2].lon, -70.28, 1e-9);
  EXPECT_EQ(t.points[0].height, 1010.0);
  EXPECT_EQ(t.points[1].height, 1012.0);
  EXPECT_EQ(t.points[0].time_s, 0.0);
  EXPECT_EQ(t.points[1].time_s, 1.0);
  EXPECT_EQ(t.points[2].time_s, 6.0);  // 23:59:58 -> 00:00:04
}

TEST(FlightTrack, IgcHeightsAreEllipsoidalByDefaultAndPressureWithoutGnss) {
  const std::string fixes =
      b_record("100000", 45.0, -69.0, 'A', 500, 530) + b_record("100001", 45.001, -69.0, 'A', 501, 531);
  const tb::FlightTrack plain = tb::parse_igc("HFDTE010726\n" + fixes, "p.igc");
  EXPECT_EQ(plain.height_datum, "ellipsoid");
  EXPECT_EQ(plain.points[1].height, 531.0);
  const tb::FlightTrack ell = tb::parse_igc("HFALGALTGPS:ELL\n" + fixes, "e.igc");
  EXPECT_EQ(ell.height_datum, "ellipsoid");
  const std::string no_gnss =
      b_record("100000", 45.0, -69.0, 'V', 500, 0) + b_record("100001", 45.001, -69.0, 'V', 501, 0);
  const tb::FlightTrack pressure = tb::parse_igc(no_gnss, "q.igc");
  EXPECT_EQ(pressure.height_datum, "egm96");
  EXPECT_EQ(pressure.skipped, 0u);
  EXPECT_EQ(pressure.points[1].height, 501.0);
  EXPECT_NE(pressure.height_note.find("pressure altitude"), std::string::npos) << pressure.height_note;
  const tb::FlightTrack nil = tb::parse_igc("HFALGALTGPS:NIL\n" + fixes, "n.igc");
  EXPECT_EQ(nil.points[0].height, 500.0);  // the log says its GNSS altitude is not there
}

TEST(FlightTrack, MalformedIgcNamesTheFileAndTheLine) {
  const std::string good = b_record("100000", 45.0, -69.0, 'A', 500, 530);
  EXPECT_NE(error_of<std::runtime_error>([&] {
              tb::parse_igc("HFDTE010726\n" + good + "B1000014500000X06900000WA0050000530\n", "t.igc");
            }).find("t.igc: line 3: bad latitude"),
            std::string::npos);
  EXPECT_NE(error_of<std::runtime_error>([&] {
              tb::parse_igc(good + "B10000145\n", "t.igc");
            }).find("t.igc: line 2: a B record has 35 characters or more"),
            std::string::npos);
  EXPECT_NE(error_of<std::runtime_error>([&] {
              tb::parse_igc(good + "B2560004500000N06900000WA0050000530\n", "t.igc");
            }).find("line 2: bad time"),
            std::string::npos);
  EXPECT_NE(error_of<std::runtime_error>([&] {
              tb::parse_igc(good + "B1000014500000N06900000WA00500ab530\n", "t.igc");
            }).find("line 2: bad altitude"),
            std::string::npos);
  EXPECT_NE(error_of<std::runtime_error>([&] {
              tb::parse_igc(good, "t.igc");
            }).find("t.igc: 1 usable track point(s)"),
            std::string::npos);
  // Arbitrary bytes: an error or a track, never a crash.
  std::string junk;
  for (int i = 0; i < 4000; ++i) junk += char((i * 7919 + 13) % 256);
  for (std::size_t cut = 0; cut < junk.size(); cut += 97) {
    // A B record of junk, then the junk as lines (string_view: no copies of it).
    const std::string_view tail(junk);
    std::string text(1, 'B');
    text.append(tail.substr(cut, 50)).append(1, '\n').append(tail);
    try {
      tb::parse_igc(text, "j.igc");
    } catch (const std::runtime_error&) {
    }
  }
}

TEST(FlightTrack, GpxTrackPointsWithTimesAndPointsWithoutHeights) {
  const TempDir tmp;
  const std::string gpx = tmp / "t.GPX";
  write_text(
      gpx,
      "<?xml version=\"1.0\"?>\n<gpx version=\"1.1\" creator=\"t\" "
      "xmlns=\"http://www.topografix.com/GPX/1/1\">\n"
      "<trk><trkseg>\n"
      "<trkpt lat=\"45.0\" lon=\"-69.0\"><ele>800.5</ele><time>2026-07-01T12:00:00Z</time></trkpt>\n"
      "<trkpt lat=\"45.01\" lon=\"-69.0\"><time>2026-07-01T12:00:05Z</time></trkpt>\n"
      "</trkseg><trkseg>\n"
      "<trkpt lat=\"45.02\" lon=\"-69.01\"><ele>810</ele><time>2026-07-01T14:00:10+02:00</time></trkpt>\n"
      "</trkseg></trk></gpx>\n");
  EXPECT_TRUE(tb::is_flight_track(gpx));
  const tb::FlightTrack t = tb::read_flight_track(gpx);
  EXPECT_EQ(t.format, "GPX");
  EXPECT_EQ(t.height_datum, "egm96");
  EXPECT_EQ(t.skipped, 1u);  // no <ele>
  ASSERT_EQ(t.points.size(), 2u);
  EXPECT_TRUE(t.timed);
  EXPECT_DOUBLE_EQ(t.points[1].lat, 45.02);
  EXPECT_DOUBLE_EQ(t.points[1].lon, -69.01);
  EXPECT_EQ(t.points[0].height, 800.5);
  EXPECT_EQ(t.points[1].time_s, 10.0);  // 14:00:10+02:00 is 12:00:10 UTC

  const std::string route = tmp / "r.gpx";
  write_text(route,
             "<?xml version=\"1.0\"?>\n<gpx version=\"1.1\" creator=\"t\" "
             "xmlns=\"http://www.topografix.com/GPX/1/1\">\n"
             "<rte><rtept lat=\"45.0\" lon=\"-69.0\"><ele>800</ele></rtept>"
             "<rtept lat=\"45.0\" lon=\"-68.99\"><ele>800</ele></rtept></rte></gpx>\n");
  const tb::FlightTrack r = tb::read_flight_track(route);
  EXPECT_FALSE(r.timed);
  EXPECT_EQ(r.points.size(), 2u);
  EXPECT_NE(r.height_note.find("route points"), std::string::npos);

  write_text(tmp / "bad.gpx", "<gpx><trk><trkseg><trkpt lat=");
  EXPECT_NE(error_of<std::runtime_error>([&] { tb::read_flight_track(tmp / "bad.gpx"); }).find("bad.gpx: "),
            std::string::npos);
  EXPECT_NE(error_of<std::runtime_error>([&] {
              tb::read_flight_track(tmp / "none.igc");
            }).find("none.igc: no such file"),
            std::string::npos);
  EXPECT_FALSE(tb::is_flight_track(tmp / "path.csv"));
}

TEST(FlightTrack, CameraPathFollowsTheTrackInTheTerrainsWorldFrame) {
  const TempDir tmp;
  const std::string db_path = tmp / "utm.db";
  make_db(db_path, true);
  const tb::BlockDatabase db = tb::BlockDatabase::open(db_path);
  // Ten seconds east, then ten seconds north, over the terrain (lon 14.95 is inside zone 33's grid).
  tb::FlightTrack t;
  t.file = "t.igc";
  t.format = "IGC";
  t.timed = true;
  t.height_datum = "ellipsoid";
  t.points = {{14.95, 45.05, 1000.0, 0.0}, {14.96, 45.05, 1100.0, 10.0}, {14.96, 45.06, 1050.0, 20.0}};
  pm::CameraPathOptions view;
  view.width_px = 640, view.height_px = 480;
  const tb::TrackPath p = tb::track_camera_path(t, db, {}, view);
  ASSERT_EQ(p.cameras.size(), 20u * 60u + 1u);
  EXPECT_EQ(p.outside, 0u);
  EXPECT_DOUBLE_EQ(p.duration_s, 20.0);
  // EGM96 lies about 46 m above the ellipsoid there: ellipsoidal heights lose about that much.
  EXPECT_GT(p.shift_min, -55.0);
  EXPECT_LT(p.shift_max, -35.0);
  std::vector<std::pair<double, double>> w;
  for (const tb::TrackPoint& q : t.points) w.push_back(expected_world(q.lon, q.lat));
  for (const auto& [frame, point] : std::vector<std::pair<int, int>>{{0, 0}, {600, 1}, {1200, 2}}) {
    const pm::Camera& c = p.cameras[std::size_t(frame)];
    EXPECT_NEAR(c.x, w[std::size_t(point)].first, 1e-6) << frame;
    EXPECT_NEAR(c.y, w[std::size_t(point)].second, 1e-6) << frame;
    EXPECT_GE(c.z - t.points[std::size_t(point)].height, p.shift_min - 1e-9);
    EXPECT_LE(c.z - t.points[std::size_t(point)].height, p.shift_max + 1e-9);
    EXPECT_EQ(c.width_px, 640);
    EXPECT_EQ(c.pitch_deg, -10.0);
    EXPECT_EQ(c.fovy_deg, 60.0);
  }
  // Halfway along the first leg: halfway between its ends; looking along it.
  const pm::Camera& mid = p.cameras[300];
  EXPECT_NEAR(mid.x, (w[0].first + w[1].first) / 2, 1e-6);
  EXPECT_NEAR(mid.y, (w[0].second + w[1].second) / 2, 1e-6);
  const auto bearing = [](std::pair<double, double> a, std::pair<double, double> b) {
    const double d = std::atan2(b.first - a.first, b.second - a.second) * 180.0 / std::numbers::pi;
    return d < 0 ? d + 360.0 : d;
  };
  EXPECT_NEAR(mid.yaw_deg, bearing(w[0], w[1]), 1e-6);
  EXPECT_NEAR(p.cameras[900].yaw_deg, bearing(w[1], w[2]), 1e-6);
  EXPECT_NEAR(p.cameras[0].yaw_deg, bearing(w[0], w[1]), 1e-6);
  EXPECT_NEAR(p.cameras[1200].yaw_deg, bearing(w[1], w[2]), 1e-6);
  for (const pm::Camera& c : p.cameras) EXPECT_TRUE(c.yaw_deg >= 0 && c.yaw_deg < 360) << c.yaw_deg;
  const double leg1 = std::hypot(w[1].first - w[0].first, w[1].second - w[0].second);
  const double leg2 = std::hypot(w[2].first - w[1].first, w[2].second - w[1].second);
  EXPECT_NEAR(p.ground_m, leg1 + leg2, 1e-6);

  // Twice as fast: half the frames. The track's heights taken as EGM96, the terrain's datum: no shift.
  tb::TrackCameraOptions fast;
  fast.time_scale = 2.0;
  fast.height_datum = "egm96";
  const tb::TrackPath f = tb::track_camera_path(t, db, fast, view);
  EXPECT_EQ(f.cameras.size(), 601u);
  EXPECT_EQ(f.shift_min, 0.0);
  EXPECT_EQ(f.shift_max, 0.0);
  EXPECT_EQ(f.cameras[300].z, 1100.0);
  // A window of the track: its frames are the whole replay's from 5 s to 15 s.
  tb::TrackCameraOptions window;
  window.from_s = 5.0, window.to_s = 15.0;
  const tb::TrackPath wp = tb::track_camera_path(t, db, window, view);
  ASSERT_EQ(wp.cameras.size(), 601u);
  EXPECT_EQ(wp.begin_s, 5.0);
  EXPECT_EQ(wp.end_s, 15.0);
  for (std::size_t k : {std::size_t(0), std::size_t(300), std::size_t(600)}) {
    EXPECT_NEAR(wp.cameras[k].x, p.cameras[300 + k].x, 1e-9) << k;
    EXPECT_NEAR(wp.cameras[k].y, p.cameras[300 + k].y, 1e-9) << k;
    EXPECT_NEAR(wp.cameras[k].yaw_deg, p.cameras[300 + k].yaw_deg, 1e-9) << k;
  }
  window.from_s = 20.0, window.to_s = 30.0;
  EXPECT_NE(error_of<std::runtime_error>([&] {
              tb::track_camera_path(t, db, window, view);
            }).find("t.igc: the track lasts 20 s; a replay from 20 s shows none of it"),
            std::string::npos);
  // Without times: flown at speed_mps along the ground.
  t.timed = false;
  tb::TrackCameraOptions slow;
  slow.speed_mps = 100.0;
  const tb::TrackPath u = tb::track_camera_path(t, db, slow, view);
  EXPECT_NEAR(u.duration_s, (leg1 + leg2) / 100.0, 1e-9);
  EXPECT_EQ(u.cameras.size(), std::size_t(std::ceil(u.duration_s * 60.0 - 1e-9)) + 1);
  EXPECT_NEAR(u.cameras.back().x, w[2].first, 1e-6);
}

TEST(FlightTrack, TracksOffTheTerrainOrOverATerrainWithoutCrsAreRefused) {
  const TempDir tmp;
  make_db(tmp / "plain.db", false);
  make_db(tmp / "utm.db", true);
  tb::FlightTrack t;
  t.file = "t.igc";
  t.timed = true;
  t.height_datum = "egm96";
  t.points = {{14.95, 45.05, 1000.0, 0.0}, {14.96, 45.05, 1100.0, 10.0}};
  EXPECT_NE(error_of<tb::GeoError>([&] {
              tb::track_camera_path(t, tb::BlockDatabase::open(tmp / "plain.db"), {}, {});
            }).find("t.igc: the terrain " + tmp / "plain.db" + " has no CRS"),
            std::string::npos);
  const tb::BlockDatabase db = tb::BlockDatabase::open(tmp / "utm.db");
  tb::FlightTrack far = t;
  for (tb::TrackPoint& q : far.points) q.lat -= 1.0;
  EXPECT_NE(error_of<tb::GeoError>([&] {
              tb::track_camera_path(far, db, {}, {});
            }).find("t.igc: no point of the track lies on the terrain"),
            std::string::npos);
  tb::FlightTrack half = t;
  half.points[0].lat -= 1.0;
  EXPECT_EQ(tb::track_camera_path(half, db, {}, {}).outside, 1u);
  tb::TrackCameraOptions few;
  few.max_frames = 100;
  EXPECT_NE(error_of<std::runtime_error>([&] {
              tb::track_camera_path(t, db, few, {});
            }).find("601 frames, more than 100"),
            std::string::npos);
  tb::TrackCameraOptions datum;
  datum.height_datum = "EPSG:999999";
  EXPECT_NE(error_of<tb::GeoError>([&] { tb::track_camera_path(t, db, datum, {}); }).find("t.igc: PROJ"),
            std::string::npos);
}

}  // namespace
