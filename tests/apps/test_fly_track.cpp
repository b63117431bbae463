// Flight tracks end to end: `terralod build` of a small geographic DEM (an .asc with a .prj of
// EPSG:4326, so the default frame is terralod's own azimuthal equidistant one), then an IGC log
// replayed by `terralod fly` and a GPX track by `terralod-fly --headless`. The drawn cameras are
// checked against PROJ's geodesics (distances between fixes within 0.1 %) and the heights'
// datum (IGC's ellipsoidal heights lose the geoid's ~50 m over the Alps; GPX's EGM96 heights,
// the terrain's datum, are kept); usage errors are exit status 2.
#include <geodesic.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "run_command.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;
namespace tt = terralod::test;

const fs::path& tmp() { return tt::process_temp_dir("fly_track"); }

// 65 x 65 samples 0.0005 degrees apart, lower-left corner at 7 E, 46 N (about 39 x 56 m cells).
constexpr int kN = 65;
constexpr double kCell = 0.0005, kWest = 7.0, kSouth = 46.0;

const fs::path& database() {
  static const fs::path db = [] {
    const fs::path asc = tmp() / "alps.asc", out = tmp() / "alps.db";
    pm::TerrainOptions o;
    o.width = o.height = kN;
    o.seed = 5;
    o.relief = 800;
    o.quantize_to_metres = true;
    const pm::Heightfield g = pm::generate_terrain(o);
    {
      std::ofstream f(asc);
      f << "ncols " << kN << "\nnrows " << kN << "\nxllcorner " << kWest << "\nyllcorner " << kSouth
        << "\ncellsize " << kCell << "\n";
      for (int r = 0; r < kN; ++r)
        for (int c = 0; c < kN; ++c) f << 1000.0 + g.at(c, r) << (c + 1 < kN ? " " : "\n");
    }
    std::ofstream(tmp() / "alps.prj") << "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS "
                                         "84\",6378137,298.257223563]],PRIMEM[\"Greenwich\",0],"
                                         "UNIT[\"degree\",0.0174532925199433],AUTHORITY[\"EPSG\",\"4326\"]]";
    const tt::CommandResult r =
        tt::run_tool(TERRALOD_CLI, "build --input " + tt::quote(asc.string()) + " --out " +
                                       tt::quote(out.string()) + " --block-size 33 --threads 1");
    EXPECT_EQ(r.status, 0) << r.out << r.err;
    return out;
  }();
  return db;
}

// Fixes of the test flight: 2 s apart, over the terrain.
struct Fix {
  double lat, lon;
};
const std::vector<Fix> kFixes = {{46.004, 7.004}, {46.020, 7.012}, {46.024, 7.026}};

// The log, at GNSS altitude `gnss` (ellipsoidal metres) and pressure altitude `pressure`.
std::string igc_text(int gnss = 3000, int pressure = 2900) {
  std::string s = "AXXX001\r\nHFDTE010726\r\nHFALGALTGPS:ELL\r\n";
  for (std::size_t i = 0; i < kFixes.size(); ++i) {
    const long la = std::lround(kFixes[i].lat * 60000.0), lo = std::lround(kFixes[i].lon * 60000.0);
    char buf[96];
    std::snprintf(buf, sizeof buf, "B1200%02zu%02ld%05ldN%03ld%05ldEA%05d%05d\r\n", 2 * i, la / 60000,
                  la % 60000, lo / 60000, lo % 60000, pressure, gnss);
    s += buf;
  }
  return s;
}

std::string gpx_text() {
  std::string s =
      "<?xml version=\"1.0\"?>\n<gpx version=\"1.1\" creator=\"t\" "
      "xmlns=\"http://www.topografix.com/GPX/1/1\"><trk><trkseg>\n";
  for (std::size_t i = 0; i < kFixes.size(); ++i) {
    std::ostringstream p;
    p.precision(17);
    p << "<trkpt lat=\"" << kFixes[i].lat << "\" lon=\"" << kFixes[i].lon
      << "\"><ele>3000</ele><time>2026-07-01T12:00:0" << 2 * i << "Z</time></trkpt>\n";
    s += p.str();
  }
  return s + "</trkseg></trk></gpx>\n";
}

struct Frames {
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;
  double at(std::size_t row, const std::string& name) const {
    for (std::size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return rows.at(row).at(i);
    ADD_FAILURE() << "no column " << name;
    return 0;
  }
};

Frames read_frames(const fs::path& csv) {
  Frames f;
  std::istringstream in(tt::slurp(csv));
  std::string line;
  std::getline(in, line);
  for (std::stringstream h(line); std::getline(h, line, ',');) f.header.push_back(line);
  while (std::getline(in, line)) {
    std::vector<double> row;
    std::stringstream r(line);
    for (std::string cell; std::getline(r, cell, ',');) row.push_back(std::atof(cell.c_str()));
    f.rows.push_back(row);
  }
  return f;
}

double geodesic_m(const Fix& a, const Fix& b) {
  geod_geodesic g;
  geod_init(&g, 6378137.0, 1.0 / 298.257223563);
  double s = 0;
  geod_inverse(&g, a.lat, a.lon, b.lat, b.lon, &s, nullptr, nullptr);
  return s;
}

TEST(FlyTrack, IgcReplayedByTerralodFlyLandsWhereItWasFlown) {
  const fs::path igc = tmp() / "flight.igc", out = tmp() / "igc_out";
  std::ofstream(igc, std::ios::binary) << igc_text();
  const tt::CommandResult r = tt::run_tool(
      TERRALOD_CLI, "fly --db " + tt::quote(database().string()) + " --path " + tt::quote(igc.string()) +
                        " --out " + tt::quote(out.string()) + " --speed-factor 0 --size 160x120");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("flight.igc: IGC, 3 points, 4.0 s"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("241 frames at 60 fps"), std::string::npos) << r.out;
  const Frames f = read_frames(out / "frames.csv");
  ASSERT_EQ(f.rows.size(), 241u);
  // Distances between the fixes as drawn: the geodesic's within 0.1 %.
  for (const auto& [a, b] : std::vector<std::pair<std::size_t, std::size_t>>{{0, 1}, {1, 2}, {0, 2}}) {
    const double d =
        std::hypot(f.at(120 * b, "x") - f.at(120 * a, "x"), f.at(120 * b, "y") - f.at(120 * a, "y"));
    EXPECT_NEAR(d / geodesic_m(kFixes[a], kFixes[b]), 1.0, 1e-3) << a << " -> " << b;
  }
  // Ellipsoidal 3000 m is about 3000 - 49 m above EGM96 over the western Alps.
  for (std::size_t k : {std::size_t(0), std::size_t(120), std::size_t(240)}) {
    EXPECT_GT(f.at(k, "z"), 3000.0 - 60.0) << k;
    EXPECT_LT(f.at(k, "z"), 3000.0 - 40.0) << k;
  }
  // Looking along the first leg: north-north-east (the frame's north is true north at its centre).
  EXPECT_NEAR(f.at(60, "yaw"), 19.0, 3.0);
  EXPECT_EQ(f.at(60, "pitch"), -10.0);
}

// A log whose heights lie under the terrain (1000 to 1800 m there). terralod-fly --headless
// (every frame waits for its loads; the first is drawn once beforehand) keeps the eye 2 m
// above the terrain's samples in every frame; terralod fly (which never waits) does as soon as
// the ground under the eye is known, and with --track-clearance 0 flies the log's heights.
TEST(FlyTrack, TheEyeStaysAboveTheGroundUnlessTold) {
  const fs::path igc = tmp() / "low.igc";
  std::ofstream(igc, std::ios::binary) << igc_text(1, 0);
  const fs::path out = tmp() / "low_headless";
  const tt::CommandResult h = tt::run_tool(TERRALOD_FLY,
                                           "--headless --db " + tt::quote(database().string()) + " --path " +
                                               tt::quote(igc.string()) + " --out " + tt::quote(out.string()) +
                                               " --frames 4 --size 64x48",
                                           {.merge_stderr = false, .no_display = true});
  ASSERT_EQ(h.status, 0) << h.out << h.err;
  EXPECT_NE(h.out.find("lifted to 2 m above the ground in 4 of 4 frames"), std::string::npos) << h.out;
  const Frames hf = read_frames(out / "frames.csv");
  ASSERT_EQ(hf.rows.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) EXPECT_GT(hf.at(k, "z"), 1000.0 + 2.0) << "frame " << k;
  for (const bool clear : {true, false}) {
    const fs::path o = tmp() / (clear ? "low_fly" : "low_fly_0");
    const tt::CommandResult r = tt::run_tool(
        TERRALOD_CLI, "fly --db " + tt::quote(database().string()) + " --path " + tt::quote(igc.string()) +
                          " --out " + tt::quote(o.string()) + " --size 160x120" +
                          (clear ? "" : " --track-clearance 0 --speed-factor 0"));
    ASSERT_EQ(r.status, 0) << r.out << r.err;
    const Frames f = read_frames(o / "frames.csv");
    ASSERT_EQ(f.rows.size(), 241u);
    std::size_t above = 0;
    for (std::size_t k = 0; k < f.rows.size(); ++k) {
      const double z = f.at(k, "z");
      // Where the eye was not lifted it is where the log puts it (about -50 m).
      EXPECT_TRUE(z < -40.0 || (clear && z > 1000.0)) << "frame " << k << ": " << z;
      above += z > 1000.0;
    }
    if (clear) {
      EXPECT_NE(r.out.find("lifted to 2 m above the ground in " + std::to_string(above) + " of 241 frames"),
                std::string::npos)
          << r.out;
      EXPECT_GT(above, 120u) << "the ground under the eye was known late";  // it arrives within a second
    } else {
      EXPECT_EQ(above, 0u);
      EXPECT_EQ(r.out.find("lifted"), std::string::npos) << r.out;
    }
  }
}

TEST(FlyTrack, GpxReplayedByTheFlightDemoKeepsHeightsInTheTerrainsDatum) {
  const fs::path gpx = tmp() / "flight.gpx", out = tmp() / "gpx_out";
  std::ofstream(gpx) << gpx_text();
  const tt::CommandResult r =
      tt::run_tool(TERRALOD_FLY,
                   "--headless --db " + tt::quote(database().string()) + " --path " +
                       tt::quote(gpx.string()) + " --out " + tt::quote(out.string()) +
                       " --frames 3 --size 64x48 --track-pitch -20 --track-time-scale 2 --track-from 1",
                   {.merge_stderr = false, .no_display = true});
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("flight.gpx: GPX, 3 points"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("91 frames at 60 fps (time scale 2, from 1.0 s to 4.0 s of it)"), std::string::npos)
      << r.out;
  const Frames f = read_frames(out / "frames.csv");
  ASSERT_EQ(f.rows.size(), 3u);
  EXPECT_EQ(f.at(0, "z"), 3000.0);
  EXPECT_EQ(f.at(0, "pitch"), -20.0);
  EXPECT_NE(r.out.find("lifted to 2 m above the ground in 0 of 3 frames"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(out / "frame_00002.png"));
}

TEST(FlyTrack, TrackOptionsAndTracksWithoutADatabaseAreUsageErrors) {
  const fs::path igc = tmp() / "usage.igc";
  std::ofstream(igc, std::ios::binary) << igc_text();
  const tt::CommandResult no_db = tt::run_tool(TERRALOD_FLY,
                                               "--headless --path " + tt::quote(igc.string()) + " --out " +
                                                   tt::quote((tmp() / "u1").string()) + " --frames 2",
                                               {.merge_stderr = false, .no_display = true});
  EXPECT_EQ(no_db.status, 2) << no_db.out << no_db.err;
  EXPECT_NE(no_db.err.find("usage.igc needs --db"), std::string::npos) << no_db.err;
  const fs::path csv = tmp() / "p.csv";
  std::ofstream(csv) << "x,y,z,yaw,pitch,fovy\n0,0,3000,0,-10,60\n";
  const tt::CommandResult csv_pitch = tt::run_tool(
      TERRALOD_CLI, "fly --db " + tt::quote(database().string()) + " --path " + tt::quote(csv.string()) +
                        " --out " + tt::quote((tmp() / "u2").string()) + " --track-pitch 5");
  EXPECT_EQ(csv_pitch.status, 2) << csv_pitch.out << csv_pitch.err;
  EXPECT_NE(csv_pitch.err.find("--track-pitch is for a GPX or IGC path"), std::string::npos) << csv_pitch.err;
  const tt::CommandResult bad_pitch = tt::run_tool(
      TERRALOD_CLI, "fly --db " + tt::quote(database().string()) + " --path " + tt::quote(igc.string()) +
                        " --out " + tt::quote((tmp() / "u3").string()) + " --track-pitch 95");
  EXPECT_EQ(bad_pitch.status, 2) << bad_pitch.err;
  EXPECT_NE(bad_pitch.err.find("'--track-pitch' must be in -90..90"), std::string::npos) << bad_pitch.err;
}

}  // namespace
