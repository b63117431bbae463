// DemOptions::crs: true distances over large geographic DEMs ("auto"), a CRS named by the user,
// holes outside the warped footprint, and the errors of bad CRSs. Distances are checked on an
// independent path: lon/lat -> the Heightfield's CRS through OGR/PROJ -> samples through
// crs_transform -> world through transform, against geodesics on WGS 84 (PROJ's geodesic.h).
#include <gdal_priv.h>
#include <gdal_utils.h>
#include <geodesic.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "geographic_tiff.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/dem_writer.hpp"
#include "terralod/blocks/geo_grid.hpp"
#include "terralod/blocks/ground_scale.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
using terralod::pm::Heightfield;

const double kNaN = std::numeric_limits<double>::quiet_NaN();

fs::path temp_dir() {
  const fs::path d = fs::temp_directory_path() / ("terralod_dem_crs_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

/// A smooth height (metres) at (lon, lat) degrees.
double smooth_height(double lon, double lat) {
  return 1000.0 + 400.0 * std::sin(0.7 * lon) * std::cos(0.9 * lat);
}

/// A geographic (EPSG:4326) GeoTIFF of cols x rows samples, `step` degrees apart, whose south-west
/// sample centre is at (lon0, lat0); heights smooth_height, NaN (nodata) where in_void(lon, lat).
fs::path write_geographic(const std::string& name, double lon0, double lat0, int cols, int rows, double step,
                          const std::function<bool(double, double)>& in_void) {
  const fs::path path = temp_dir() / name;
  terralod::test::write_geographic_tiff(
      path.string(), lon0, lat0 + (rows - 1) * step, cols, rows, step,
      [&](double lon, double lat) { return in_void(lon, lat) ? kNaN : smooth_height(lon, lat); });
  return path;
}

/// The same, NaN inside `void_box` (col0, row0, col1, row1, inclusive) when given.
fs::path write_geographic(const std::string& name, double lon0, double lat0, int cols, int rows, double step,
                          std::array<int, 4> void_box = {-1, -1, -1, -1}) {
  const double north = lat0 + (rows - 1) * step;
  return write_geographic(name, lon0, lat0, cols, rows, step, [&](double lon, double lat) {
    const int c = int(std::lround((lon - lon0) / step)), r = int(std::lround((north - lat) / step));
    return c >= void_box[0] && c <= void_box[2] && r >= void_box[1] && r <= void_box[3];
  });
}

/// The same, n x n samples.
fs::path write_geographic(const std::string& name, double lon0, double lat0, int n, double step,
                          std::array<int, 4> void_box = {-1, -1, -1, -1}) {
  return write_geographic(name, lon0, lat0, n, n, step, void_box);
}

/// lon/lat (WGS 84) -> world (x, y) of hf, through hf.crs_wkt, crs_transform and transform.
class WorldOf {
 public:
  explicit WorldOf(const Heightfield& hf) : hf_(hf) {
    OGRSpatialReference wgs84, crs;
    wgs84.SetWellKnownGeogCS("WGS84");
    wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    EXPECT_EQ(crs.importFromWkt(hf.crs_wkt.c_str()), OGRERR_NONE);
    crs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    ct_.reset(OGRCreateCoordinateTransformation(&wgs84, &crs));
    EXPECT_TRUE(ct_);
  }
  /// (col, row) of hf's samples.
  std::pair<double, double> samples(double lon, double lat) const {
    double x = lon, y = lat;
    EXPECT_TRUE(ct_->Transform(1, &x, &y));
    const auto& t = *hf_.crs_transform;
    const double det = t.xc * t.yr - t.xr * t.yc, dx = x - t.x0, dy = y - t.y0;
    return {(t.yr * dx - t.xr * dy) / det, (t.xc * dy - t.yc * dx) / det};
  }
  std::pair<double, double> operator()(double lon, double lat) const {
    const auto [c, r] = samples(lon, lat);
    return hf_.transform.to_world(c, r);
  }

 private:
  struct Deleter {
    void operator()(OGRCoordinateTransformation* t) const { OGRCoordinateTransformation::DestroyCT(t); }
  };
  const Heightfield& hf_;
  std::unique_ptr<OGRCoordinateTransformation, Deleter> ct_;
};

/// hf built, on one thread in blocks of block_size, into a fresh database `name` in the test folder.
fs::path built_database(const Heightfield& hf, const std::string& name, int block_size) {
  const fs::path db = temp_dir() / name;
  fs::remove(db);
  tb::DatabaseBuildOptions bo;
  bo.block_size = block_size;
  bo.threads = 1;
  tb::build_database(hf, db.string(), bo);
  return db;
}

/// The largest |distance / geodesic - 1| of the view about an eye at (lon, lat), whose ground
/// scale is G (seen), and of the world frame itself (world), over geodesics of the given lengths
/// in 16 directions from the eye; kept as maxima across calls.
struct ViewErrors {
  double seen = 0.0, world = 0.0;
  void add(const WorldOf& to_world, double lon, double lat, const terralod::pm::GroundScale& G,
           std::initializer_list<double> lengths) {
    geod_geodesic g;
    geod_init(&g, 6378137.0, 1.0 / 298.257223563);
    const auto [x, y] = to_world(lon, lat);
    for (double s : lengths)
      for (int k = 0; k < 16; ++k) {
        double la2 = 0.0, lo2 = 0.0;
        geod_direct(&g, lat, lon, 22.5 * k, s, &la2, &lo2, nullptr);
        const auto [x2, y2] = to_world(lo2, la2);
        const terralod::pm::Vec3 d = G.apply(terralod::pm::Vec3{x2 - x, y2 - y, 0.0});
        seen = std::max(seen, std::abs(std::hypot(d.x, d.y) / s - 1.0));
        world = std::max(world, std::abs(std::hypot(x2 - x, y2 - y) / s - 1.0));
      }
  }
};

/// The largest |world distance / geodesic distance - 1| over seeded random pairs in the box
/// [lon0, lon1] x [lat0, lat1]: 3000 short pairs (2-6 km, anywhere, corners included) and 1000
/// long ones (any two points).
struct DistanceErrors {
  double short_pairs = 0.0, long_pairs = 0.0;
  double all() const { return std::max(short_pairs, long_pairs); }
};

DistanceErrors distance_errors(const Heightfield& hf, double lon0, double lon1, double lat0, double lat1) {
  geod_geodesic g;
  geod_init(&g, 6378137.0, 1.0 / 298.257223563);
  const WorldOf world(hf);
  constexpr unsigned kSeed = 20261202;
  std::mt19937 rng(kSeed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  DistanceErrors worst;
  auto pair = [&](double& into, double la1, double lo1, double la2, double lo2) {
    double s = 0.0;
    geod_inverse(&g, la1, lo1, la2, lo2, &s, nullptr, nullptr);
    const auto [x1, y1] = world(lo1, la1);
    const auto [x2, y2] = world(lo2, la2);
    into = std::max(into, std::abs(std::hypot(x2 - x1, y2 - y1) / s - 1.0));
  };
  for (int i = 0; i < 3000; ++i) {
    // Every fourth short pair starts at a corner of the box.
    double lon = lon0 + (lon1 - lon0) * u(rng), lat = lat0 + (lat1 - lat0) * u(rng);
    if (i % 4 == 0) lon = (i / 4) % 2 ? lon0 : lon1, lat = (i / 8) % 2 ? lat0 : lat1;
    double la2 = 0.0, lo2 = 0.0;
    geod_direct(&g, lat, lon, 360.0 * u(rng), 2000.0 + 4000.0 * u(rng), &la2, &lo2, nullptr);
    la2 = std::clamp(la2, lat0, lat1), lo2 = std::clamp(lo2, lon0, lon1);
    if (la2 != lat || lo2 != lon) pair(worst.short_pairs, lat, lon, la2, lo2);
  }
  for (int i = 0; i < 1000; ++i)
    pair(worst.long_pairs, lat0 + (lat1 - lat0) * u(rng), lon0 + (lon1 - lon0) * u(rng),
         lat0 + (lat1 - lat0) * u(rng), lon0 + (lon1 - lon0) * u(rng));
  std::printf(
      "seed %u: worst |world / geodesic - 1| = %.5f %% (2-6 km pairs %.5f %%, any two points %.5f %%)\n",
      kSeed, worst.all() * 100.0, worst.short_pairs * 100.0, worst.long_pairs * 100.0);
  return worst;
}

double worst_distance_error(const Heightfield& hf, double lon0, double lon1, double lat0, double lat1) {
  return distance_errors(hf, lon0, lon1, lat0, lat1).all();
}

/// The scale error stated at the end of hf.frame, as a fraction.
double stated_scale_error(const Heightfield& hf) {
  const std::string key = "scale error within +-";
  const std::size_t at = hf.frame.find(key);
  EXPECT_NE(at, std::string::npos) << hf.frame;
  return at == std::string::npos ? kNaN : std::stod(hf.frame.substr(at + key.size())) / 100.0;
}

// 8 x 8 degrees, 401 x 401 samples 0.02 degrees apart, on the equator and at 56..64 N.
class EightDegrees : public ::testing::TestWithParam<double> {};

TEST_P(EightDegrees, AutoKeepsDistancesTrueWithinATenthOfAPercent) {
  const double lat0 = GetParam(), lon0 = -72.0;
  const fs::path path =
      write_geographic("eight_" + std::to_string(int(lat0)) + ".tif", lon0, lat0, 401, 0.02);
  tb::DemOptions o;
  o.crs = "auto";
  const Heightfield hf = tb::read_dem(path.string(), o);
  std::printf("%s\n", hf.frame.c_str());
  const double worst = worst_distance_error(hf, lon0, lon0 + 8.0, lat0, lat0 + 8.0);
  EXPECT_LE(worst, 0.001);
  // The measured scale error bounds every distance error and is what the frame states.
  const std::optional<double> scale = tb::frame_scale_error(hf);
  ASSERT_TRUE(scale);
  EXPECT_LE(*scale, 0.001);
  EXPECT_LE(worst, *scale + 1e-5);
  EXPECT_NEAR(stated_scale_error(hf), *scale, 0.5e-5);
  EXPECT_NE(hf.frame.find("azimuthal equidistant"), std::string::npos) << hf.frame;
  // Cells of the source's ground spacings at the centre, east-west and north-south apart (0.02
  // degrees of the parallel and of the meridian there), times k0 < 1: about its sample count.
  const double c_lat = (lat0 + 4.0) * std::numbers::pi / 180.0;
  EXPECT_NEAR(hf.transform.xc, 0.02 * 111320.0 * std::cos(c_lat), 0.012 * hf.transform.xc);
  EXPECT_NEAR(-hf.transform.yr, 0.02 * 110574.0 * (1.0 + 0.0034 * std::sin(c_lat) * std::sin(c_lat)),
              0.012 * hf.transform.xc);

  // The native frame of the same file fails the bound: the test can fail.
  const Heightfield native = tb::read_dem(path.string());
  const double native_worst = worst_distance_error(native, lon0, lon0 + 8.0, lat0, lat0 + 8.0);
  EXPECT_GT(native_worst, 0.001);
  EXPECT_NEAR(stated_scale_error(native), *tb::frame_scale_error(native), 0.5e-5);
  EXPECT_LE(native_worst, *tb::frame_scale_error(native) + 1e-5);
}

INSTANTIATE_TEST_SUITE_P(Latitudes, EightDegrees, ::testing::Values(-4.0, 56.0));

// Strips too long for one azimuthal equidistant frame (40 degrees one way, 6 the other): auto
// picks the projection whose scale depends only on the short direction (the azimuthal frame would
// be off by 0.6 to 1.1 %), and every distance of up to a few kilometres stays true within 0.1 %
// over the whole strip. Between points thousands of kilometres apart the straight line of a flat
// frame is not the geodesic: it stays within 0.1 % where the projection keeps long geodesics
// nearly straight (the central meridian of the transverse Mercator, the equator of the Mercator),
// and is up to 0.13 % short across the 40 degrees of the conic's strip at 45 N, whose
// geodesics bow toward the pole.
struct Strip {
  const char* name;
  double lon0, lat0, width, height;  // degrees
  const char* projection;            // the one auto must pick
  double long_bound;                 // of |world / geodesic - 1| between any two points
};

class LongStrips : public ::testing::TestWithParam<Strip> {};

TEST_P(LongStrips, AutoPicksAProjectionThatKeepsDistancesTrueWithinATenthOfAPercent) {
  const Strip& s = GetParam();
  constexpr double step = 0.05;
  const int cols = int(std::lround(s.width / step)) + 1, rows = int(std::lround(s.height / step)) + 1;
  const fs::path path = write_geographic(std::string(s.name) + ".tif", s.lon0, s.lat0, cols, rows, step);
  tb::DemOptions o;
  o.crs = "auto";
  const Heightfield hf = tb::read_dem(path.string(), o);
  std::printf("%s\n", hf.frame.c_str());
  EXPECT_EQ(hf.frame.rfind(s.projection, 0), 0u) << hf.frame;
  EXPECT_NE(hf.frame.find("against the azimuthal equidistant frame's"), std::string::npos) << hf.frame;
  const DistanceErrors worst = distance_errors(hf, s.lon0, s.lon0 + s.width, s.lat0, s.lat0 + s.height);
  EXPECT_LE(worst.short_pairs, 0.001);
  EXPECT_LE(worst.long_pairs, s.long_bound);
  const std::optional<double> scale = tb::frame_scale_error(hf);
  ASSERT_TRUE(scale);
  EXPECT_LE(*scale, 0.001);
  EXPECT_LE(worst.short_pairs, *scale + 1e-5);
  EXPECT_NEAR(stated_scale_error(hf), *scale, 0.5e-5);
  EXPECT_EQ(hf.frame.find("over 0.1 %"), std::string::npos) << hf.frame;
}

INSTANTIATE_TEST_SUITE_P(
    Strips, LongStrips,
    ::testing::Values(Strip{"north_south", -72.0, -50.0, 6.0, 40.0, "transverse Mercator", 0.001},
                      Strip{"east_west_45n", -100.0, 42.0, 40.0, 6.0, "Lambert conformal conic", 0.0015},
                      Strip{"east_west_equator", 10.0, -3.0, 40.0, 6.0, "Mercator", 0.001}),
    [](const ::testing::TestParamInfo<Strip>& info) { return std::string(info.param.name); });

// A continent (30 x 30 degrees) is beyond every projection auto tries: the frame is the best of
// them and says that it is over 0.1 %.
TEST(DemCrs, AutoSaysWhenAContinentIsBeyondATenthOfAPercent) {
  const fs::path path = write_geographic("continent.tif", 0.0, 30.0, 121, 0.25);
  tb::DemOptions o;
  o.crs = "auto";
  const Heightfield hf = tb::read_dem(path.string(), o);
  std::printf("%s\n", hf.frame.c_str());
  const std::optional<double> scale = tb::frame_scale_error(hf);
  ASSERT_TRUE(scale);
  EXPECT_GT(*scale, 0.001);
  EXPECT_NE(hf.frame.find("over 0.1 %: the best of the projections auto tries"), std::string::npos)
      << hf.frame;
  EXPECT_LE(distance_errors(hf, 0.0, 30.0, 30.0, 60.0).short_pairs, *scale + 1e-5);
}

// No flat frame keeps a continent's distances within 0.1 % (above), so the runtime's view does
// it where the camera is: TerrainRuntime::fit_camera sets the camera's ground scale G at the eye,
// and the view shows eye + G (p - eye). Checked at 49 eyes over the 30 x 30 degrees (corners
// included), against geodesics of 1 to 300 km in 16 directions from each: |G (q - p)| is the
// geodesic within 0.1 %, where the world distance |q - p| is off by more than 0.5 % somewhere.
TEST(DemCrs, AContinentsViewIsTrueWithinATenthOfAPercentAroundTheCamera) {
  const fs::path path = write_geographic("continent_view.tif", 0.0, 30.0, 121, 0.25);
  tb::DemOptions o;
  o.crs = "auto";
  const Heightfield hf = tb::read_dem(path.string(), o);
  tb::TerrainRuntime rt(built_database(hf, "continent_view.db", 65).string());
  const tb::GroundScaleMap map = tb::GroundScaleMap::of(hf);
  EXPECT_TRUE(map.georeferenced());
  const WorldOf world(hf);
  ViewErrors errors;
  for (int i = 0; i <= 6; ++i)
    for (int j = 0; j <= 6; ++j) {
      const double lon = 30.0 * i / 6.0, lat = 30.0 + 30.0 * j / 6.0;
      const auto [x, y] = world(lon, lat);
      terralod::pm::Camera cam;
      cam.x = x, cam.y = y, cam.z = 3000.0;
      rt.fit_camera(cam);
      const terralod::pm::GroundScale& G = cam.ground;
      EXPECT_EQ(G, rt.ground_scale(x, y));
      EXPECT_EQ(G, map.at(x, y)) << "a single mesh's view (GroundScaleMap::of) is the runtime's";
      EXPECT_NO_THROW(terralod::pm::View{cam});
      errors.add(world, lon, lat, G, {1000.0, 20000.0, 70000.0, 300000.0});
    }
  std::printf("worst |distance / geodesic - 1| within 300 km of the eye: seen %.5f %%, world %.5f %%\n",
              errors.seen * 100.0, errors.world * 100.0);
  EXPECT_GT(errors.world, 0.005);
  EXPECT_LE(errors.seen, 0.001);
  // What it costs a frame (information, not a test: four points through PROJ).
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < 1000; ++k) {
    terralod::pm::Camera cam;
    cam.x = 1000.0 * k, cam.y = 0.0;
    rt.fit_camera(cam);
  }
  std::printf(
      "fit_camera: %.1f us a call\n",
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count() / 1000.0);
  // Without a CRS the view is the world itself.
  Heightfield plain = hf;
  plain.crs_wkt.clear();
  plain.crs_transform.reset();
  EXPECT_EQ(tb::TerrainRuntime(built_database(plain, "continent_view_plain.db", 65).string())
                .ground_scale(0.0, 0.0),
            terralod::pm::GroundScale{});
  EXPECT_FALSE(tb::GroundScaleMap::of(plain).georeferenced());
  EXPECT_EQ(tb::GroundScaleMap::of(plain).at(0.0, 0.0), terralod::pm::GroundScale{});
}

// A global DEM (every longitude, pole to pole) is beyond every flat frame: the azimuthal one had
// k0 = 1.1e-5 and turned 720 x 360 samples into 2 x 723. Auto keeps such a DEM in its own grid,
// says why, and the runtime's view keeps distances true around the camera, as it does for a
// continent (above). A hemisphere still gets its azimuthal frame.
TEST(DemCrs, AutoKeepsAGlobalDemInItsOwnGridAndItsViewTrue) {
  const fs::path path = write_geographic("globe.tif", -177.5, -87.5, 72, 36, 5.0);
  tb::DemOptions o;
  o.crs = "auto";
  const Heightfield hf = tb::read_dem(path.string(), o);
  tb::DemOptions n;
  n.crs = "native";
  const Heightfield native = tb::read_dem(path.string(), n);
  std::printf("%s\n", hf.frame.c_str());
  ASSERT_EQ(hf.width(), 72);
  ASSERT_EQ(hf.height(), 36);
  EXPECT_NE(hf.frame.find("--crs auto keeps the DEM's own grid"), std::string::npos) << hf.frame;
  EXPECT_EQ(hf.samples(), native.samples());
  EXPECT_EQ(hf.transform.xc, native.transform.xc);
  EXPECT_EQ(hf.transform.yr, native.transform.yr);
  // Window by window, as the build reads it.
  const std::unique_ptr<tb::DemSource> src = tb::open_dem_source(path.string(), o);
  ASSERT_EQ(src->grid().width, 72);
  ASSERT_EQ(src->grid().height, 36);
  EXPECT_EQ(src->grid().frame, hf.frame);
  EXPECT_EQ(src->read(tb::SampleRect{0, 0, 71, 35}).samples(), native.samples());

  const Heightfield hemisphere =
      tb::read_dem(write_geographic("hemisphere.tif", -87.5, -87.5, 36, 5.0).string(), o);
  EXPECT_NE(hemisphere.frame.find("azimuthal equidistant (auto)"), std::string::npos) << hemisphere.frame;
  EXPECT_NEAR(hemisphere.width(), 36, 2);
  EXPECT_NEAR(hemisphere.height(), 36, 2);

  // The view about eyes from 60 S to 60 N: distances of 1 to 20 km within 0.1 % of geodesics.
  tb::TerrainRuntime rt(built_database(hf, "globe.db", 33).string());
  const WorldOf world(hf);
  ViewErrors errors;
  for (const double lat : {-60.0, -20.0, 0.0, 45.0, 60.0})
    for (const double lon : {-120.0, 0.0, 150.0}) {
      const auto [x, y] = world(lon, lat);
      terralod::pm::Camera cam;
      cam.x = x, cam.y = y, cam.z = 3000.0;
      rt.fit_camera(cam);
      errors.add(world, lon, lat, cam.ground, {1000.0, 20000.0});
    }
  std::printf("worst |distance / geodesic - 1| within 20 km of the eye: seen %.5f %%, world %.5f %%\n",
              errors.seen * 100.0, errors.world * 100.0);
  EXPECT_GT(errors.world, 0.5);
  EXPECT_LE(errors.seen, 0.001);
}

// A geographic DEM whose last row lies on a pole (global and Arctic mosaics reach 90 degrees):
// its pixel edges lie half a pixel beyond the pole, and measuring the frames' scale there made
// every projection fail ("GDAL cannot make any of the projections"). Auto now skips what lies
// within 0.1 degree of the pole, as it always did for the measurement itself, and keeps
// distances true within 0.1 % below it.
class AtAPole : public ::testing::TestWithParam<double> {};

TEST_P(AtAPole, AutoMakesAFrameAndKeepsDistancesTrue) {
  const double lat0 = GetParam(), lon0 = 10.0;  // 4 x 2 degrees, a row on the pole
  const fs::path path =
      write_geographic("pole_" + std::to_string(int(lat0)) + ".tif", lon0, lat0, 81, 41, 0.05);
  tb::DemOptions o;
  o.crs = "auto";
  const Heightfield hf = tb::read_dem(path.string(), o);
  std::printf("%s\n", hf.frame.c_str());
  EXPECT_NE(hf.frame.find("azimuthal equidistant"), std::string::npos) << hf.frame;
  const std::optional<double> scale = tb::frame_scale_error(hf);
  ASSERT_TRUE(scale);
  EXPECT_LE(*scale, 0.001);
  const double lat_lo = lat0 < 0 ? -89.9 : lat0, lat_hi = lat0 < 0 ? lat0 + 2.0 : 89.9;
  EXPECT_LE(worst_distance_error(hf, lon0, lon0 + 4.0, lat_lo, lat_hi), 0.001);
  std::size_t valid = 0;
  for (std::size_t i = 0; i < hf.size(); ++i) valid += hf.valid(i) ? 1 : 0;
  EXPECT_GT(valid, hf.size() / 4) << "the warped grid holds the DEM's samples";
}

INSTANTIATE_TEST_SUITE_P(NorthAndSouth, AtAPole, ::testing::Values(88.0, -90.0));

// A strip along a great circle at 45 degrees (30 degrees long, 5 wide) inside a 30 x 30 degree
// raster whose other samples are voids, kept as holes: auto judges the frame by the valid
// samples (the raster's mask) and takes the oblique Mercator along the strip. Every distance of
// a few kilometres within the strip is true within 0.1 %; the azimuthal frame over the raster
// would be off by about 0.9 %.
TEST(DemCrs, AutoFollowsADiagonalStripThroughItsValidSamples) {
  constexpr double kLon = 10.0, kLat = 40.0, kAzimuth = 45.0, kHalfWidth = 2.5, kHalfLength = 15.0;
  geod_geodesic g;
  geod_init(&g, 6378137.0, 1.0 / 298.257223563);
  // The strip's pole on the unit sphere: the cross product of the centre and the heading there.
  const double d = std::numbers::pi / 180.0;
  const double cx = std::cos(kLat * d) * std::cos(kLon * d), cy = std::cos(kLat * d) * std::sin(kLon * d),
               cz = std::sin(kLat * d);
  const double east[3] = {-std::sin(kLon * d), std::cos(kLon * d), 0.0};
  const double north[3] = {-std::sin(kLat * d) * std::cos(kLon * d), -std::sin(kLat * d) * std::sin(kLon * d),
                           std::cos(kLat * d)};
  double t[3], n[3];
  for (int k = 0; k < 3; ++k) t[k] = std::sin(kAzimuth * d) * east[k] + std::cos(kAzimuth * d) * north[k];
  n[0] = cy * t[2] - cz * t[1], n[1] = cz * t[0] - cx * t[2], n[2] = cx * t[1] - cy * t[0];
  const auto in_strip = [&](double lon, double lat) {
    const double v[3] = {std::cos(lat * d) * std::cos(lon * d), std::cos(lat * d) * std::sin(lon * d),
                         std::sin(lat * d)};
    const double across = std::asin(std::abs(v[0] * n[0] + v[1] * n[1] + v[2] * n[2])) / d;
    const double along =
        std::atan2(v[0] * t[0] + v[1] * t[1] + v[2] * t[2], v[0] * cx + v[1] * cy + v[2] * cz) / d;
    return across <= kHalfWidth && std::abs(along) <= kHalfLength;
  };
  const fs::path path = write_geographic("diagonal.tif", kLon - 15.0, kLat - 15.0, 301, 301, 0.1,
                                         [&](double lon, double lat) { return !in_strip(lon, lat); });
  tb::DemOptions o;
  o.crs = "auto";
  o.fill_voids = false;
  const Heightfield hf = tb::read_dem(path.string(), o);
  std::printf("%s\n", hf.frame.c_str());
  EXPECT_EQ(hf.frame.rfind("oblique Mercator", 0), 0u) << hf.frame;
  EXPECT_NE(hf.frame.find("over the covered part of the footprint"), std::string::npos) << hf.frame;
  const std::optional<double> scale = tb::frame_scale_error(hf);
  ASSERT_TRUE(scale);
  EXPECT_LE(*scale, 0.001);
  EXPECT_NEAR(stated_scale_error(hf), *scale, 0.5e-5);
  // Short pairs (2-6 km) in the strip, against geodesics on an independent path.
  const WorldOf world(hf);
  std::mt19937 rng(20261204);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double worst = 0.0;
  int pairs = 0;
  for (int i = 0; i < 3000; ++i) {
    double la = 0.0, lo = 0.0, az = 0.0, la1 = 0.0, lo1 = 0.0, la2 = 0.0, lo2 = 0.0;
    geod_direct(&g, kLat, kLon, kAzimuth, (2.0 * u(rng) - 1.0) * kHalfLength * 111000.0, &la, &lo, &az);
    geod_direct(&g, la, lo, az + 90.0, (2.0 * u(rng) - 1.0) * kHalfWidth * 111000.0, &la1, &lo1, nullptr);
    geod_direct(&g, la1, lo1, 360.0 * u(rng), 2000.0 + 4000.0 * u(rng), &la2, &lo2, nullptr);
    if (!in_strip(lo1, la1) || !in_strip(lo2, la2)) continue;
    double s = 0.0;
    geod_inverse(&g, la1, lo1, la2, lo2, &s, nullptr, nullptr);
    const auto [x1, y1] = world(lo1, la1);
    const auto [x2, y2] = world(lo2, la2);
    worst = std::max(worst, std::abs(std::hypot(x2 - x1, y2 - y1) / s - 1.0));
    ++pairs;
  }
  std::printf("%d pairs in the strip: worst |world / geodesic - 1| = %.5f %%\n", pairs, worst * 100.0);
  EXPECT_GT(pairs, 2000);
  EXPECT_LE(worst, 0.001);
  EXPECT_LE(worst, *scale + 1e-5);
}

/// A VRT of ten 2 x 2 degree tiles of n x n samples (NaN nodata) on the diagonal of a 20 x 20
/// degree extent.
fs::path write_diagonal_mosaic(const std::string& name, int n) {
  std::vector<std::string> tiles;
  for (int k = 0; k < 10; ++k)
    tiles.push_back(write_geographic(name + "_" + std::to_string(k) + ".tif", 2.0 * k, 2.0 * k, n, n,
                                     2.0 / (n - 1), [](double, double) { return false; })
                        .string());
  const fs::path vrt = temp_dir() / (name + ".vrt");
  std::vector<const char*> names;
  for (const std::string& t : tiles) names.push_back(t.c_str());
  int usage = 0;
  GDALDatasetH ds = GDALBuildVRT(vrt.c_str(), int(names.size()), nullptr, names.data(), nullptr, &usage);
  EXPECT_NE(ds, nullptr);
  GDALClose(ds);
  return vrt;
}

// The same judgement through GDAL's data coverage, as the build reads a mosaic: a VRT of ten
// 2 x 2 degree tiles on the diagonal of a 20 x 20 degree extent, opened window by window with
// its voids kept. The empty cells are known without reading them, and the frame follows the tiles.
TEST(DemCrs, AutoFollowsTheTilesOfAMosaicThroughGdalsDataCoverage) {
  const fs::path vrt = write_diagonal_mosaic("diag", 41);
  tb::DemOptions o;
  o.crs = "auto";
  o.fill_voids = false;
  const std::unique_ptr<tb::DemSource> src = tb::open_dem_source(vrt.string(), o);
  const tb::DemGrid& grid = src->grid();
  std::printf("%s\n", grid.frame.c_str());
  EXPECT_FALSE(src->in_memory());
  EXPECT_NE(grid.frame.find("over the covered part of the footprint"), std::string::npos) << grid.frame;
  ASSERT_TRUE(grid.scale_error);
  EXPECT_LE(*grid.scale_error, 0.001) << grid.frame;
  // The frame read whole (read_dem, the grid's mask) makes the same choice.
  const Heightfield hf = tb::read_dem(vrt.string(), o);
  EXPECT_EQ(hf.frame.substr(0, hf.frame.find(" (unit factor")),
            grid.frame.substr(0, grid.frame.find(" (unit factor")));
  // With its voids filled, the gaps between the tiles (under 4096 x 4096 samples) become
  // samples: the frame is judged by the whole rectangle, and says that it is over 0.1 %. (A
  // coarser mosaic, 0.2 degree samples: the fill of its gaps is what this costs.)
  tb::DemOptions filled;
  filled.crs = "auto";
  const std::unique_ptr<tb::DemSource> whole =
      tb::open_dem_source(write_diagonal_mosaic("diag_coarse", 11).string(), filled);
  std::printf("%s\n", whole->grid().frame.c_str());
  EXPECT_EQ(whole->grid().frame.rfind("azimuthal equidistant (auto)", 0), 0u) << whole->grid().frame;
  EXPECT_EQ(whole->grid().frame.find("covered part"), std::string::npos) << whole->grid().frame;
  ASSERT_TRUE(whole->grid().scale_error);
  EXPECT_GT(*whole->grid().scale_error, 0.001);
}

/// Bilinear interpolation of the source file's samples at fractional (col, row).
double bilinear(const std::vector<double>& z, int n, double c, double r) {
  const int c0 = std::clamp(int(std::floor(c)), 0, n - 2), r0 = std::clamp(int(std::floor(r)), 0, n - 2);
  const double fc = c - c0, fr = r - r0;
  auto at = [&](int cc, int rr) { return z[std::size_t(rr) * n + cc]; };
  return (1 - fr) * ((1 - fc) * at(c0, r0) + fc * at(c0 + 1, r0)) +
         fr * ((1 - fc) * at(c0, r0 + 1) + fc * at(c0 + 1, r0 + 1));
}

TEST(DemCrs, CellsOutsideTheFootprintAndInKeptVoidsAreHolesOthersAreBilinear) {
  // 2 x 2 degrees at 60 N, 101 x 101 samples; a 9 x 9 void at cols/rows 40..48, kept as holes.
  const int n = 101;
  const double lon0 = 10.0, lat0 = 60.0, step = 0.02;
  const fs::path path = write_geographic("holes.tif", lon0, lat0, n, step, {40, 40, 48, 48});
  tb::DemOptions o;
  o.crs = "auto";
  o.fill_voids = false;
  const Heightfield hf = tb::read_dem(path.string(), o);
  ASSERT_TRUE(hf.has_holes());
  EXPECT_EQ(hf.voids.voids, 81u);
  EXPECT_EQ(hf.voids.filled, 0u);
  std::vector<double> z(std::size_t(n) * n);
  const double north = lat0 + (n - 1) * step;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) z[std::size_t(r) * n + c] = smooth_height(lon0 + c * step, north - r * step);
  // Warped positions are within 1e-3 samples of the exact ones (dem_frame.hpp), so a warped height
  // is within 2e-3 of the largest step between neighbouring samples of the bilinear one, plus
  // its rounding to 1/64 m.
  double steepest = 0.0;
  for (int r = 0; r + 1 < n; ++r)
    for (int c = 0; c + 1 < n; ++c) {
      const double v = z[std::size_t(r) * n + c];
      steepest = std::max({steepest, std::abs(z[std::size_t(r) * n + c + 1] - v),
                           std::abs(z[std::size_t(r + 1) * n + c] - v)});
    }

  OGRSpatialReference crs, wgs84;
  crs.importFromWkt(hf.crs_wkt.c_str());
  crs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  wgs84.SetWellKnownGeogCS("WGS84");
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> to_lonlat(OGRCreateCoordinateTransformation(&crs, &wgs84));
  ASSERT_TRUE(to_lonlat);
  std::size_t outside = 0, inside = 0, in_void = 0;
  double worst = 0.0;
  for (int r = 0; r < hf.height(); ++r)
    for (int c = 0; c < hf.width(); ++c) {
      auto [x, y] = hf.crs_transform->to_world(c, r);
      ASSERT_TRUE(to_lonlat->Transform(1, &x, &y));
      const double sc = (x - lon0) / step, sr = (north - y) / step;  // source (col, row)
      if (sc < -1.0 || sr < -1.0 || sc > n || sr > n) {  // over half a pixel outside the footprint
        EXPECT_FALSE(hf.valid(c, r)) << c << ", " << r;
        ++outside;
      } else if (sc >= 39.0 + 1.5 && sc <= 49.0 - 1.5 && sr >= 39.0 + 1.5 && sr <= 49.0 - 1.5) {
        EXPECT_FALSE(hf.valid(c, r)) << "deep in the kept void: " << c << ", " << r;
        ++in_void;
      } else if (sc >= 0.0 && sr >= 0.0 && sc <= n - 1 && sr <= n - 1 &&
                 (sc < 39.0 || sc > 49.0 || sr < 39.0 || sr > 49.0)) {  // bilinear cell fully valid
        ASSERT_TRUE(hf.valid(c, r)) << c << ", " << r;
        worst =
            std::max(worst, std::abs(hf.at(c, r) - bilinear(z, n, sc, sr)) / (2e-3 * steepest + 1.0 / 128));
        EXPECT_EQ(hf.at(c, r), std::round(hf.at(c, r) * 64.0) / 64.0) << "not a multiple of 1/64 m";
        ++inside;
      }
    }
  std::printf(
      "%zu cells outside, %zu in the void, %zu inside: worst |warped - bilinear| / bound = %.3g "
      "(bound 2e-3 x %.3g m + 1/128 m)\n",
      outside, in_void, inside, worst, steepest);
  EXPECT_GT(outside, 100u);
  EXPECT_GT(in_void, 4u);
  EXPECT_GT(inside, std::size_t(n) * n / 2);
  EXPECT_LE(worst, 1.0);
  EXPECT_GT(worst, 0.0);  // positions are interpolated between exact ones here, not all exact
}

TEST(DemCrs, NamedCrsWarpsAndReportsItsScaleError) {
  // 1 x 1 degree in UTM zone 19N (central meridian 69 W).
  const fs::path path = write_geographic("utm.tif", -70.0, 44.0, 61, 1.0 / 60.0);
  tb::DemOptions o;
  o.crs = "EPSG:32619";
  const Heightfield hf = tb::read_dem(path.string(), o);
  std::printf("%s\n", hf.frame.c_str());
  EXPECT_NE(hf.frame.find("UTM zone 19N"), std::string::npos) << hf.frame;
  const std::optional<double> scale = tb::frame_scale_error(hf);
  ASSERT_TRUE(scale);
  EXPECT_GT(*scale, 0.0003);  // UTM's k0 = 0.9996 near its central meridian
  EXPECT_LT(*scale, 0.0005);
  EXPECT_NEAR(stated_scale_error(hf), *scale, 0.5e-5);
  const double worst = worst_distance_error(hf, -70.0, -69.0, 44.0, 45.0);
  EXPECT_LE(worst, *scale + 1e-5);
  // World coordinates are UTM metres: the centre lies near easting 460 km, northing 4.93e6 m.
  const auto [x, y] = WorldOf(hf)(-69.5, 44.5);
  EXPECT_NEAR(x, 460300.0, 1000.0);
  EXPECT_NEAR(y, 4928000.0, 2000.0);
  EXPECT_EQ(hf.vertical_datum, "");
}

TEST(DemCrs, SrtmTileKeepsItsVerticalDatumAndStatesItsScaleError) {
  // A 61 x 61 .hgt tile (1 x 1 degree at 44 N), heights 100 + col.
  const fs::path path = temp_dir() / "N44W070.hgt";
  {
    std::vector<unsigned char> bytes;
    for (int r = 0; r < 61; ++r)
      for (int c = 0; c < 61; ++c) bytes.push_back(0), bytes.push_back((unsigned char)(100 + c));
    std::FILE* f = std::fopen(path.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    ASSERT_EQ(std::fwrite(bytes.data(), 1, bytes.size(), f), bytes.size());
    std::fclose(f);
  }
  tb::DemOptions o;
  for (const std::string crs : {"native", "auto", "EPSG:32619"}) {
    o.crs = crs;
    const Heightfield hf = tb::read_dem(path.string(), o);
    EXPECT_EQ(hf.vertical_datum, "EGM96") << crs;
    const double stated = stated_scale_error(hf);
    EXPECT_NEAR(stated, *tb::frame_scale_error(hf), 0.5e-5) << crs;
    // Native: the equirectangular frame is off by up to cos(44)/cos(44.5) - 1 = 0.6 % east-west,
    // and more north-south (a sphere of the mean radius for the meridian's radius of curvature);
    // auto: c_max = 0.64 degrees, d = c_max^2 / 12 = 1e-5 %.
    const double low = crs == "native" ? 0.006 : 0.0, high = crs == "native" ? 1.0
                                                             : crs == "auto" ? 2e-5
                                                                             : 5e-4;
    EXPECT_GE(stated, low) << crs;
    EXPECT_LT(stated, high) << crs;
  }
}

// A DEM in a 3D CRS (EPSG:4979: WGS 84 with ellipsoidal heights, as GDAL writes and reads it)
// states its heights' datum by its third axis. Before, it read as stating none, and the exporters
// took its heights as EGM96 and added the geoid again: 28 m too low here.
TEST(DemCrs, HeightsOfA3dCrsAreEllipsoidalAndExportAsTheyAre) {
  const fs::path path = temp_dir() / "ellipsoidal.tif";
  const auto height = [](double lon, double lat) {
    return 500.0 + 100.0 * std::sin(lon * 7.0) * std::cos(lat * 5.0);
  };
  ASSERT_NO_FATAL_FAILURE(
      terralod::test::write_tiff(path.string(), 4979, -72.0, 45.0, 31, 31, 0.01, GDT_Float64, height));
  tb::DemOptions o;
  o.crs = "native";
  const Heightfield hf = tb::read_dem(path.string(), o);
  EXPECT_EQ(hf.vertical_datum, "WGS 84 ellipsoidal height");
  const tb::GeoGrid g = tb::make_geo_grid(hf, "", path.string());
  EXPECT_EQ(g.vertical_datum, "WGS 84 ellipsoid");
  EXPECT_FALSE(g.heights_converted);
  ASSERT_EQ(g.width, 31);
  for (int r = 0; r < 31; ++r)  // as they are, in the grid's floats
    for (int c = 0; c < 31; ++c) ASSERT_EQ(g.z(c, r), double(float(hf.at(c, r)))) << c << ", " << r;
  // Written back (the extract of a database) it keeps its 3D CRS, and so its datum.
  const fs::path copy = temp_dir() / "ellipsoidal_copy.tif";
  tb::write_geotiff(hf, copy.string());
  EXPECT_EQ(tb::read_dem(copy.string(), o).vertical_datum, "WGS 84 ellipsoidal height");
}

// A projected DEM whose CRS names its vertical datum (UTM + EGM96 height, as national DEMs state
// theirs) is warped to longitude/latitude for the exporters, and then its heights are converted to
// the ellipsoid once. GDALWarp shifts heights itself when the source names a vertical datum and
// the target does not: the geoid was subtracted twice, 28 m too low here.
TEST(DemCrs, AProjectedDemWithAVerticalDatumIsConvertedToTheEllipsoidOnce) {
  const fs::path path = temp_dir() / "utm_egm96.tif";
  ASSERT_NO_FATAL_FAILURE(terralod::test::write_tiff(path.string(), 32619, 460000.0, 4930000.0, 41, 41, 90.0,
                                                     GDT_Float64, [](double, double) { return 500.0; }));
  {
    GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
    ASSERT_TRUE(ds);
    OGRSpatialReference compound;
    ASSERT_EQ(compound.SetFromUserInput("EPSG:32619+5773"), OGRERR_NONE);
    ASSERT_EQ(ds->SetSpatialRef(&compound), CE_None);
  }
  tb::DemOptions o;
  o.crs = "native";
  const Heightfield hf = tb::read_dem(path.string(), o);
  EXPECT_EQ(hf.vertical_datum, "EGM96 height");
  const tb::GeoGrid g = tb::make_geo_grid(hf, "", path.string());
  EXPECT_TRUE(g.heights_converted);
  std::vector<double> lon, lat, z;
  for (int r = 0; r < g.height; ++r)
    for (int c = 0; c < g.width; ++c)
      if (g.valid(c, r)) lon.push_back(g.lon(c)), lat.push_back(g.lat(r)), z.push_back(g.z(c, r));
  ASSERT_GT(z.size(), 1000u);
  const std::vector<double> n = tb::geoid_undulations("egm96", lon, lat, path.string());
  double worst = 0.0;
  for (std::size_t i = 0; i < z.size(); ++i) worst = std::max(worst, std::abs(z[i] - (500.0 + n[i])));
  EXPECT_NEAR(n[0], -27.5, 1.5);
  // Within the grid's floats: one unit in the last place at 472 m is 2^-15 m.
  EXPECT_LT(worst, 0x1p-15) << "metres from 500 m above EGM96";
}

TEST(DemCrs, BadCrsIsAnErrorNamingTheFileAndTheOption) {
  const fs::path path = write_geographic("bad.tif", 0.0, 0.0, 11, 0.01);
  tb::DemOptions o;
  for (const std::string bad : {"EPSG:999999", "not a crs", "EPSG:4326"}) {
    o.crs = bad;
    try {
      tb::read_dem(path.string(), o);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const tb::DemError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path.string()), std::string::npos) << what;
      EXPECT_NE(what.find("'" + bad + "'"), std::string::npos) << what;
      EXPECT_NE(what.find("--crs"), std::string::npos) << what;
    }
  }
  o.crs = "";
  EXPECT_THROW(tb::read_dem(path.string(), o), std::invalid_argument);
}

// A 2 x 2 geographic DEM warped to its auto frame keeps no whole cell (the frame's cells outside
// the input are holes): the build's refusal says that the warp emptied it and what builds it.
TEST(DemCrs, ADemTheWarpLeavesEmptyIsRefusedNamingTheWarpAndTheWayOut) {
  const fs::path path = write_geographic("tiny_2x2.tif", -72.0, 45.0 - 1.0 / 1200, 2, 1.0 / 1200);
  const fs::path db = temp_dir() / "tiny_2x2.db";
  fs::remove(db);
  tb::DemOptions automatic;
  automatic.crs = "auto";
  try {
    tb::build_database(*tb::open_dem_source(path.string(), automatic), db.string(), {});
    ADD_FAILURE() << "an empty warp was built";
  } catch (const tb::BuildError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path.string() + ": no triangle of valid samples"), std::string::npos) << what;
    EXPECT_NE(what.find("warped to (azimuthal equidistant)"), std::string::npos) << what;
    EXPECT_NE(what.find("--crs native"), std::string::npos) << what;
  }
  EXPECT_FALSE(fs::exists(db));
  // Its own grid (the library's default frame) builds.
  EXPECT_GT(tb::build_database(*tb::open_dem_source(path.string()), db.string(), {}).samples, 0u);
}

// A geographic DEM across the antimeridian (longitudes 179.6 to 180.4, as GDAL writes a grid of
// Fiji): PROJ gives the warp's source positions in [-180, 180], and east of 180 they fell outside
// the source, so half the terrain was holes. It keeps as many samples as the same grid a degree
// west, and its heights east of 180 are the file's.
TEST(DemCrs, AutoWarpsAGridAcrossTheAntimeridian) {
  tb::DemOptions o;
  o.crs = "auto";
  auto valid = [](const Heightfield& hf) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < hf.size(); ++i) n += hf.valid(i);
    return n;
  };
  const Heightfield across =
      tb::read_dem(write_geographic("antimeridian.tif", 179.6, -17.4, 101, 0.008).string(), o);
  const Heightfield west =
      tb::read_dem(write_geographic("before_it.tif", 178.6, -17.4, 101, 0.008).string(), o);
  EXPECT_EQ(across.size(), west.size());
  EXPECT_NEAR(double(valid(across)), double(valid(west)), 0.01 * double(valid(west)));
  const WorldOf world(across);
  for (const double lon : {179.7, 180.1, 180.3}) {
    const auto [c, r] = world.samples(lon, -17.0);
    const std::size_t i =
        std::size_t(std::lround(r)) * std::size_t(across.width()) + std::size_t(std::lround(c));
    ASSERT_TRUE(across.valid(i)) << "longitude " << lon << " is a hole";
    // Within a sample's change (0.008 degrees of a 400 m sine of period 9 degrees: 2.2 m).
    EXPECT_NEAR(across[i], smooth_height(lon, -17.0), 2.5) << "longitude " << lon;
  }
}

TEST(DemCrs, AutoLeavesProjectedAndUnreferencedInputsNative) {
  const fs::path path = temp_dir() / "projected.tif";
  {
    GDALAllRegister();
    GDALDatasetUniquePtr ds(GetGDALDriverManager()->GetDriverByName("GTiff")->Create(path.c_str(), 5, 4, 1,
                                                                                     GDT_Float64, nullptr));
    double gt[6] = {500000.0, 30.0, 0.0, 4900000.0, 0.0, -30.0};
    ds->SetGeoTransform(gt);
    OGRSpatialReference srs;
    srs.importFromEPSG(32619);
    ds->SetSpatialRef(&srs);
    std::vector<double> z(20, 5.0);
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 5, 4, z.data(), 5, 4, GDT_Float64, 0, 0),
              CE_None);
  }
  tb::DemOptions o;
  o.crs = "auto";
  const Heightfield a = tb::read_dem(path.string(), o);
  const Heightfield n = tb::read_dem(path.string());
  EXPECT_EQ(a.frame, n.frame);
  EXPECT_EQ(a.transform.x0, 500015.0);
  EXPECT_EQ(a.width(), 5);
  EXPECT_FALSE(a.has_holes());
}

}  // namespace

// N44W072.hgt (1201 x 1201 samples, 1 x 1 degree at 44 N) under "auto": the warped grid keeps
// about the source's sample count (cells of its east-west and north-south spacings, not square
// cells of the smaller one: those gave 41 % more), and what the exporters see of it, the auto
// grid warped back to longitude/latitude (make_geo_grid), against the DEM's own samples: the two
// bilinear resamplings the README states for exports of an "auto" database.
TEST(DemCrs, N44W072UnderAutoKeepsItsSampleCountAndExportsResampleTwice) {
  const std::string path = std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt";
  if (!fs::exists(path)) GTEST_SKIP() << path << " is absent";
  tb::DemOptions o;
  o.crs = "native";
  const auto tn = std::chrono::steady_clock::now();
  const Heightfield native = tb::read_dem(path, o);
  const double native_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tn).count();
  o.crs = "auto";
  const auto t0 = std::chrono::steady_clock::now();
  const Heightfield aeqd = tb::read_dem(path, o);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double ratio = double(aeqd.size()) / double(native.size());
  std::printf(
      "N44W072 auto: %d x %d samples (%.3f x the source's), read and warped in %.2f s (read "
      "natively in %.2f s); %s\n",
      aeqd.width(), aeqd.height(), ratio, seconds, native_seconds, aeqd.frame.c_str());
  EXPECT_LT(ratio, 1.05) << aeqd.width() << " x " << aeqd.height();
  EXPECT_GT(ratio, 0.95) << aeqd.width() << " x " << aeqd.height();
  const double sx = aeqd.transform.spacing_x(), sy = aeqd.transform.spacing_y();
  EXPECT_NEAR(sx / sy, native.transform.spacing_x() / native.transform.spacing_y(), 0.01)
      << sx << " x " << sy;

  const tb::GeoGrid a = tb::make_geo_grid(aeqd, "ellipsoid", path);
  double worst = 0, sum = 0, signed_sum = 0;
  std::size_t n = 0;
  for (int r = 0; r < native.height(); r += 3)
    for (int c = 0; c < native.width(); c += 3) {
      const auto [lon, lat] = native.crs_transform->to_world(c, r);
      const double gc = (lon - a.west) / a.dlon, gr = (a.north - lat) / a.dlat;
      const int c0 = int(std::floor(gc)), r0 = int(std::floor(gr));
      if (c0 < 0 || r0 < 0 || c0 + 1 >= a.width || r0 + 1 >= a.height) continue;
      if (!a.valid(c0, r0) || !a.valid(c0 + 1, r0) || !a.valid(c0, r0 + 1) || !a.valid(c0 + 1, r0 + 1))
        continue;
      const double u = gc - c0, v = gr - r0;
      const double z = (1 - v) * ((1 - u) * a.z(c0, r0) + u * a.z(c0 + 1, r0)) +
                       v * ((1 - u) * a.z(c0, r0 + 1) + u * a.z(c0 + 1, r0 + 1));
      const double d = std::abs(z - native.at(c, r));
      worst = std::max(worst, d), sum += d, signed_sum += z - native.at(c, r), ++n;
    }
  std::printf(
      "exported heights of the auto frame (DEM -> aeqd -> lon/lat) against the DEM's samples: "
      "mean %.2f m (signed %+.2f m), largest %.2f m over %zu samples; the native frame's scale error %.3f "
      "%%\n",
      sum / double(n), signed_sum / double(n), worst, n, *tb::frame_scale_error(native) * 100.0);
  EXPECT_GT(n, native.size() / 12);
  EXPECT_GT(worst, 0.0);  // resampled, not the samples themselves
  // Bilinear twice smooths peaks and cliffs by tens of metres on 66 x 93 m cells of mountains,
  // metres on average, with no shift (the signed mean near 0).
  EXPECT_LT(sum / double(n), 3.0);
  EXPECT_LT(std::abs(signed_sum / double(n)), 0.5);
  EXPECT_LT(worst, 60.0);
}
