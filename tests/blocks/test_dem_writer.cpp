// The DEM writers (blocks/dem_writer.hpp): every file is read back through read_dem and compared
// sample by sample with what it stands for.
#include <cpl_vsi.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "geographic_tiff.hpp"
#include "run_command.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/dem_writer.hpp"
#include "terralod/blocks/tree_builder.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace fs = std::filesystem;

namespace {

const fs::path& tmp() { return terralod::test::process_temp_dir("dem-writer"); }

tb::DemOptions keep_voids() {
  tb::DemOptions o;
  o.fill_voids = false;
  return o;
}

// A small geographic source with voids, two of them reaching its east and south edges (so that
// in a mirror mosaic they cross the tile borders).
pm::Heightfield geographic_source() {
  pm::Heightfield hf(37, 25);
  for (int r = 0; r < hf.height(); ++r)
    for (int c = 0; c < hf.width(); ++c)
      hf.at(c, r) = 100.0 + 3.0 * c - 2.0 * r + 0.25 * ((c * 7 + r * 3) % 5);
  hf.crs_wkt =
      R"(GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]])";
  hf.crs_transform = pm::GridTransform::north_up(7.0, 46.0, 1.0 / 36.0, 1.0 / 24.0);  // degrees
  std::vector<std::uint8_t> mask(hf.size(), 1);
  for (auto [c, r] :
       {std::pair{35, 10}, std::pair{36, 10}, std::pair{12, 23}, std::pair{12, 24}, std::pair{5, 5}})
    mask[std::size_t(r) * std::size_t(hf.width()) + std::size_t(c)] = 0;
  hf.set_mask(std::move(mask));
  return hf;
}

}  // namespace

TEST(FractalDem, ReadBackEqualsTheFieldAtEverySample) {
  pm::FractalField::Options o;
  o.width = 301, o.height = 517;  // strips of 256 rows: two full, one partial
  o.seed = 9;
  const pm::FractalField field(o);
  const fs::path file = tmp() / "fractal.tif";
  double last = -1;
  tb::write_fractal_dem(field, file.string(), 2, [&](double f) {
    EXPECT_GT(f, last);
    last = f;
  });
  EXPECT_EQ(last, 1.0);
  const pm::Heightfield hf = tb::read_dem(file.string());
  ASSERT_EQ(hf.width(), 301);
  ASSERT_EQ(hf.height(), 517);
  EXPECT_EQ(hf.transform, field.transform());
  double lo = 1e300, hi = -1e300;
  for (int r = 0; r < hf.height(); ++r)
    for (int c = 0; c < hf.width(); ++c) {
      ASSERT_EQ(hf.at(c, r), field.at(c, r)) << c << "," << r;  // 1/16 m steps: exact in float
      lo = std::min(lo, hf.at(c, r)), hi = std::max(hi, hf.at(c, r));
    }
  EXPECT_GE(lo, 0.0);
  EXPECT_LE(hi, o.relief);
  EXPECT_GT(hi - lo, 0.25 * o.relief) << "a terrain, not a plain";
  EXPECT_FALSE(fs::exists(file.string() + ".tmp.tif"));
}

TEST(FractalDem, AnySampleAnyOrderAndSeedsDiffer) {
  pm::FractalField::Options o;
  o.width = o.height = 1025;
  const pm::FractalField a(o);
  o.seed = 2;
  const pm::FractalField b(o);
  EXPECT_EQ(a.octaves(), 10);  // wavelengths 1024 .. 2
  int same = 0;
  for (int k = 0; k < 100; ++k) {
    const int c = (k * 97) % 1025, r = (k * 389) % 1025;
    EXPECT_EQ(a.at(c, r), a.at(c, r));
    same += a.at(c, r) == b.at(c, r);
  }
  EXPECT_LT(same, 5);
  EXPECT_THROW(pm::FractalField({.width = 0}), std::invalid_argument);
  EXPECT_THROW(pm::FractalField({.roughness = 1.0}), std::invalid_argument);
}

TEST(MirrorMosaic, TilesAreMirroredContinuousAndPlacedInTheSourceCrs) {
  const pm::Heightfield src = geographic_source();
  const fs::path source = tmp() / "source.tif", dir = tmp() / "mosaic";
  tb::write_geotiff(src, source.string());
  const tb::MosaicReport m = tb::write_mirror_mosaic(source.string(), 3, 2, dir.string());
  EXPECT_EQ(m.width, 3 * 36 + 1);
  EXPECT_EQ(m.height, 2 * 24 + 1);
  EXPECT_EQ(m.tiles, 6);
  const pm::Heightfield mos = tb::read_dem(m.vrt, keep_voids());
  ASSERT_EQ(mos.width(), m.width);
  ASSERT_EQ(mos.height(), m.height);
  // Placed in the source's CRS: the same origin and spacing, in degrees.
  ASSERT_TRUE(mos.crs_transform.has_value());
  EXPECT_NEAR(mos.crs_transform->x0, 7.0, 1e-9);
  EXPECT_NEAR(mos.crs_transform->y0, 46.0, 1e-9);
  EXPECT_NEAR(mos.crs_transform->xc, 1.0 / 36.0, 1e-12);
  EXPECT_NEAR(mos.crs_transform->yr, -1.0 / 24.0, 1e-12);
  // Every sample is the source's, mirrored in odd tiles; voids stay voids.
  for (int r = 0; r < mos.height(); ++r)
    for (int c = 0; c < mos.width(); ++c) {
      const int i = std::min(c / 36, 2), j = std::min(r / 24, 1);
      const int lc = c - 36 * i, lr = r - 24 * j;
      const int sc = i % 2 ? 36 - lc : lc, sr = j % 2 ? 24 - lr : lr;
      ASSERT_EQ(mos.valid(c, r), src.valid(sc, sr)) << c << "," << r;
      if (src.valid(sc, sr)) {
        ASSERT_EQ(mos.at(c, r), float(src.at(sc, sr))) << c << "," << r;
      }
    }
  // The void on the source's east edge lies on the border of tiles 0 and 1: both tiles have it.
  EXPECT_FALSE(mos.valid(36, 10));
  EXPECT_FALSE(tb::read_dem((dir / "tile_0_1.tif").string(), keep_voids()).valid(0, 10));
}

// The heights' vertical datum is written as a compound CRS and read back, by the source file,
// every tile of its mirror mosaic and the VRT over them: an SRTM tile's mosaic stays above EGM96.
TEST(MirrorMosaic, TilesKeepTheVerticalDatum) {
  for (const auto& [datum, read_back] : {std::pair<std::string, std::string>{"EGM96", "EGM96 height"},
                                         {"EGM2008", "EGM2008 height"},
                                         {"local survey datum", "local survey datum"},
                                         {"", ""}}) {
    SCOPED_TRACE(datum);
    pm::Heightfield src = geographic_source();
    src.vertical_datum = datum;
    const fs::path source = tmp() / "datum.tif", dir = tmp() / "datum_mosaic";
    fs::remove_all(dir);
    tb::write_geotiff(src, source.string());
    EXPECT_EQ(tb::read_dem(source.string(), keep_voids()).vertical_datum, read_back);
    const tb::MosaicReport m = tb::write_mirror_mosaic(source.string(), 2, 1, dir.string());
    EXPECT_EQ(tb::read_dem(m.vrt, keep_voids()).vertical_datum, read_back);
    EXPECT_EQ(tb::read_dem((dir / "tile_0_1.tif").string(), keep_voids()).vertical_datum, read_back);
    // Placed as before: the datum changes nothing horizontal.
    const pm::Heightfield mos = tb::read_dem(m.vrt, keep_voids());
    ASSERT_TRUE(mos.crs_transform.has_value());
    EXPECT_NEAR(mos.crs_transform->x0, 7.0, 1e-9);
    EXPECT_NEAR(mos.crs_transform->yr, -1.0 / 24.0, 1e-12);
  }
}

TEST(GeoTiffWriter, UncommittedLeavesNothingAndErrorsNameTheFile) {
  const fs::path file = tmp() / "never.tif";
  {
    tb::GeoTiffWriter w(file.string(), 10, 10, pm::GridTransform::identity());
    const std::vector<float> rows(20, 1.0f);
    w.write_rows(0, 2, rows.data());
    EXPECT_THROW(w.write_rows(9, 2, rows.data()), std::invalid_argument);  // past the last row
  }
  EXPECT_FALSE(fs::exists(file));
  EXPECT_FALSE(fs::exists(file.string() + ".tmp.tif"));
  try {
    tb::GeoTiffWriter w((tmp() / "no" / "such" / "dir.tif").string(), 4, 4, pm::GridTransform::identity());
    FAIL() << "created a GeoTIFF in a missing folder";
  } catch (const tb::DemError& e) {
    EXPECT_NE(std::string(e.what()).find("dir.tif"), std::string::npos) << e.what();
  }
  EXPECT_THROW(tb::write_mirror_mosaic((tmp() / "missing.tif").string(), 2, 2, (tmp() / "m2").string()),
               tb::DemError);
}

// `terralod build --input FOLDER` (or the tiles as repeated --input): the tiles are read as one
// mosaic, voids that cross their borders are filled on the mosaic, and the database is the one
// built from the same mosaic in a single file.
TEST(DemInputs, TilesWithVoidsAcrossTheirBordersBuildAsTheMosaicInOneFile) {
  const fs::path source = tmp() / "inputs_source.tif", dir = tmp() / "inputs_mosaic", one = tmp() / "one.tif";
  tb::write_geotiff(geographic_source(), source.string());
  const tb::MosaicReport m = tb::write_mirror_mosaic(source.string(), 3, 2, dir.string());
  tb::write_geotiff(tb::read_dem(m.vrt, keep_voids()), one.string());  // voids as NaN

  const tb::DemInputs folder({dir.string()});
  EXPECT_EQ(folder.files(), 6u);  // the tiles, not mosaic.vrt
  EXPECT_NE(folder.description().find("mosaic of 6 files"), std::string::npos) << folder.description();
  std::vector<std::string> tiles;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 3; ++i)
      tiles.push_back((dir / ("tile_" + std::to_string(j) + "_" + std::to_string(i) + ".tif")).string());
  const tb::DemInputs listed(tiles), single({one.string()});
  EXPECT_EQ(single.path(), one.string());

  tb::DatabaseBuildOptions opt;
  opt.block_size = 17;
  opt.threads = 2;
  opt.tree.levels = {tb::StrategyChoice::Grid, tb::StrategyChoice::Tin};
  std::vector<fs::path> dbs;
  for (const tb::DemInputs* in : {&single, &folder, &listed}) {
    pm::Heightfield hf = tb::read_dem(in->path());
    EXPECT_GE(hf.voids.filled, 8u);  // the voids, crossing the borders, are filled
    hf.source = "mosaic";            // the same source text, so that only the samples could differ
    dbs.push_back(tmp() / ("inputs_" + std::to_string(dbs.size()) + ".db"));
    tb::build_database(hf, dbs.back().string(), opt);
  }
  const tb::BlockDatabase want = tb::BlockDatabase::open(dbs[0].string());
  for (std::size_t k = 1; k < dbs.size(); ++k) {
    const tb::BlockDatabase got = tb::BlockDatabase::open(dbs[k].string());
    ASSERT_EQ(got.blocks(), want.blocks());
    for (tb::BlockKey b : want.blocks()) EXPECT_EQ(got.read_block(b), want.read_block(b));
    for (const std::string& blob : want.blob_names())
      EXPECT_EQ(got.read_blob(blob), want.read_blob(blob)) << blob;
    EXPECT_EQ(got.info(), want.info());
  }
  // Errors name the folder or file.
  fs::create_directories(tmp() / "empty");
  try {
    tb::DemInputs none({(tmp() / "empty").string()});
    FAIL() << "an empty folder was accepted";
  } catch (const tb::DemError& e) {
    EXPECT_NE(std::string(e.what()).find("empty"), std::string::npos) << e.what();
  }
  EXPECT_THROW(tb::DemInputs({tiles[0], (tmp() / "missing.tif").string()}), tb::DemError);
}

// Geographic tiles on both sides of the antimeridian (as S17E179 and S17W180 hold Fiji's Taveuni):
// their mosaic joins them east of 180 degrees, 2 degrees wide with every sample the tiles', instead
// of a raster around the whole Earth (432001 columns of void: 'opening...' ran for over 10 minutes).
TEST(DemInputs, TilesAcrossTheAntimeridianJoinEastOf180) {
  constexpr int kN = 120;
  constexpr double kStep = 1.0 / kN;
  const auto height = [](double lon, double lat) {
    const double east = lon < 0.0 ? lon + 360.0 : lon;  // continuous across 180
    return 300.0 + 200.0 * std::sin((east - 179.0) * 3.0) * std::cos((lat + 16.5) * 5.0);
  };
  const std::string west_tile = (tmp() / "S17E179.tif").string(),
                    east_tile = (tmp() / "S17W180.tif").string();
  ASSERT_NO_FATAL_FAILURE(terralod::test::write_geographic_tiff(west_tile, 179.0 + 0.5 * kStep,
                                                                -16.0 - 0.5 * kStep, kN, kN, kStep, height));
  ASSERT_NO_FATAL_FAILURE(terralod::test::write_geographic_tiff(east_tile, -180.0 + 0.5 * kStep,
                                                                -16.0 - 0.5 * kStep, kN, kN, kStep, height));
  const tb::DemInputs in({east_tile, west_tile});
  EXPECT_NE(in.description().find("S17W180.tif"), std::string::npos) << in.description();
  tb::DemOptions native;
  native.crs = "native";
  const pm::Heightfield hf = tb::read_dem(in.path(), native);
  ASSERT_EQ(hf.width(), 2 * kN);
  ASSERT_EQ(hf.height(), kN);
  ASSERT_TRUE(hf.crs_transform.has_value());
  EXPECT_NEAR(hf.crs_transform->x0, 179.0 + 0.5 * kStep, 1e-9);
  EXPECT_FALSE(hf.has_holes());
  for (int c = 0; c < 2 * kN; c += 7)
    for (int r = 0; r < kN; r += 11)
      ASSERT_NEAR(hf.at(c, r), height(179.0 + (c + 0.5) * kStep, -16.0 - (r + 0.5) * kStep), 1e-9)
          << "column " << c << ", row " << r;
  // The auto frame warps the joined tiles whole: about their samples.
  tb::DemOptions automatic;
  automatic.crs = "auto";
  const pm::Heightfield warped = tb::read_dem(in.path(), automatic);
  EXPECT_NEAR(double(warped.width()), 2.0 * kN, 0.05 * kN);
  EXPECT_NEAR(double(warped.height()), double(kN), 0.05 * kN);
}

// A folder of SRTM tiles as they are downloaded, zipped (N44W072.hgt.zip): `--input FOLDER` reads
// them through GDAL, which opens .hgt.zip files directly.
TEST(DemInputs, AFolderOfZippedSrtmTilesIsReadAsItsTiles) {
  const fs::path dir = tmp() / "zipped";
  fs::create_directories(dir);
  constexpr int kN = 1201;
  const std::string inner = "/vsizip/" + (dir / "N44W072.hgt.zip").string() + "/N44W072.hgt";
  {
    std::vector<std::uint8_t> bytes(std::size_t(kN) * kN * 2);
    for (int r = 0; r < kN; ++r)
      for (int c = 0; c < kN; ++c) {  // big-endian int16
        const int h = 100 + (r * 7 + c * 3) % 900;
        bytes[(std::size_t(r) * kN + c) * 2] = std::uint8_t(h >> 8);
        bytes[(std::size_t(r) * kN + c) * 2 + 1] = std::uint8_t(h & 0xff);
      }
    VSILFILE* f = VSIFOpenL(inner.c_str(), "wb");
    ASSERT_NE(f, nullptr) << inner;
    ASSERT_EQ(VSIFWriteL(bytes.data(), 1, bytes.size(), f), bytes.size());
    ASSERT_EQ(VSIFCloseL(f), 0);
  }
  const tb::DemInputs in({dir.string()});
  EXPECT_EQ(in.files(), 1u);
  const pm::Heightfield hf = tb::read_dem(in.path());
  ASSERT_EQ(hf.width(), kN);
  ASSERT_EQ(hf.height(), kN);
  for (int r = 0; r < kN; r += 97)
    for (int c = 0; c < kN; c += 89) ASSERT_EQ(hf.at(c, r), 100 + (r * 7 + c * 3) % 900) << c << ", " << r;
}

namespace {

// A smooth terrain around 44 N, 72 W (waves of 0.25 degrees, about 20 km): bilinear resampling
// at 90 m moves it by under 0.05 m.
double rolling(double lon, double lat) {
  return 800.0 + 300.0 * std::sin(lon * 2.0 * M_PI / 0.25) * std::cos(lat * 2.0 * M_PI / 0.2);
}

// A point of EPSG:`from` in EPSG:`to` (geographic ones as (lon, lat)). Each pair's transformation
// is made once: making one costs about a millisecond.
std::pair<double, double> transform(int from, int to, double x, double y) {
  static std::map<std::pair<int, int>, std::unique_ptr<OGRCoordinateTransformation>> made;
  auto& t = made[{from, to}];
  if (!t) {
    OGRSpatialReference a, b;
    a.importFromEPSG(from);
    b.importFromEPSG(to);
    a.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    b.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    t.reset(OGRCreateCoordinateTransformation(&a, &b));
  }
  EXPECT_TRUE(t && t->Transform(1, &x, &y));
  return {x, y};
}

}  // namespace

// Tiles of a national DEM in two UTM zones (west of 72 W in zone 18, east of it in zone 19):
// GDALBuildVRT refused them ("heterogeneous projection"). The zone-19 tile, with fewer samples, is
// warped to zone 18 on the zone-18 tile's cells, and the mosaic is the terrain everywhere, across
// the zone line too.
TEST(DemInputs, TilesInTwoUtmZonesJoinInTheCrsOfMostSamples) {
  constexpr double kStep = 90.0;
  struct Tile {
    int epsg;
    double x0, y0;  // the north-west sample
    int cols, rows;
    double west, east;  // longitudes it holds
    // Whether (lon, lat) lies inside it, a sample's width from its edges.
    bool holds(double lon, double lat) const {
      const auto [x, y] = transform(4326, epsg, lon, lat);
      return lon > west + 0.002 && lon < east - 0.002 && x > x0 + kStep && x < x0 + (cols - 2) * kStep &&
             y < y0 - kStep && y > y0 - (rows - 2) * kStep;
    }
    std::string write(const std::string& name) const {
      const std::string path = (tmp() / name).string();
      terralod::test::write_tiff(path, epsg, x0, y0, cols, rows, kStep, GDT_Float32, [&](double x, double y) {
        const auto [lon, lat] = transform(epsg, 4326, x, y);
        return lon >= west && lon <= east ? rolling(lon, lat) : std::nan("");
      });
      return path;
    }
  };
  // Zone 18 (central meridian 75 W): 72.4 W to 72 W is x = 738 to 771 km at 44.1 N; zone 19
  // (69 W): 72.02 W to 71.75 W is x = 259 to 282 km. They overlap a little at the zone line, as
  // such tiles do.
  const Tile z18{32618, 738000.0, 4893000.0, 380, 120, -72.4, -71.99};
  const Tile z19{32619, 259000.0, 4893000.0, 260, 130, -72.02, -71.75};
  const tb::DemInputs in({z19.write("z19.tif"), z18.write("z18.tif")});
  EXPECT_NE(in.description().find("1 warped to WGS 84 / UTM zone 18N"), std::string::npos)
      << in.description();
  const pm::Heightfield hf = tb::read_dem(in.path());
  ASSERT_TRUE(hf.crs_transform.has_value());
  EXPECT_NE(hf.crs_wkt.find("UTM zone 18N"), std::string::npos);
  EXPECT_NEAR(hf.crs_transform->spacing_x(), kStep, 1e-9);
  EXPECT_NEAR(hf.crs_transform->spacing_y(), kStep, 1e-9);
  // The zone-18 tile's samples are where they were: its cells are the mosaic's.
  const double fc = (z18.x0 - hf.crs_transform->x0) / kStep, fr = (hf.crs_transform->y0 - z18.y0) / kStep;
  EXPECT_NEAR(fc, std::round(fc), 1e-9);
  EXPECT_NEAR(fr, std::round(fr), 1e-9);
  std::size_t checked = 0, across = 0;
  double worst = 0.0;
  for (int r = 0; r < hf.height(); ++r)
    for (int c = 0; c < hf.width(); ++c) {
      const auto [x, y] = hf.crs_transform->to_world(c, r);
      const auto [lon, lat] = transform(32618, 4326, x, y);
      if (!z18.holds(lon, lat) && !z19.holds(lon, lat)) continue;
      ++checked;
      across += lon > -72.01 && lon < -71.995;
      worst = std::max(worst, std::abs(hf.at(c, r) - rolling(lon, lat)));
    }
  EXPECT_GT(checked, 25000u);
  EXPECT_GT(across, 100u);
  EXPECT_LT(worst, 0.1) << "metres, over " << checked << " samples";
}

// SRTM's Int16 tiles beside Float32 ones (Copernicus GLO-30 is Float32): GDALBuildVRT refused them
// ("heterogeneous band data type"). The Int16 tile is read as Float32, and the mosaic, with a
// void across the tiles' shared edge (-32768 in one, NaN in the other), reads as the same
// terrain written as one Float32 file.
TEST(DemInputs, Int16AndFloat32TilesReadAsOneFloat32File) {
  constexpr double kStep = 1.0 / 1200.0;
  constexpr double kWest = -72.1 + 0.5 * kStep, kNorth = 44.2 - 0.5 * kStep;
  const auto height = [&](double lon, double lat) {
    const double gap = std::hypot((lon + 72.0) / kStep, (lat - 44.15) / kStep);  // void: 3 samples
    return gap < 3.0 ? std::nan("") : std::round(rolling(lon, lat));
  };
  const std::string west = (tmp() / "int16.tif").string(), east = (tmp() / "float32.tif").string(),
                    one = (tmp() / "one_float32.tif").string();
  ASSERT_NO_FATAL_FAILURE(
      terralod::test::write_tiff(west, 4326, kWest, kNorth, 120, 100, kStep, GDT_Int16, height));
  ASSERT_NO_FATAL_FAILURE(terralod::test::write_tiff(east, 4326, kWest + 120 * kStep, kNorth, 120, 100, kStep,
                                                     GDT_Float32, height));
  ASSERT_NO_FATAL_FAILURE(
      terralod::test::write_tiff(one, 4326, kWest, kNorth, 240, 100, kStep, GDT_Float32, height));
  const tb::DemInputs in({west, east});
  EXPECT_NE(in.description().find("1 read as Float32"), std::string::npos) << in.description();
  const pm::Heightfield got = tb::read_dem(in.path()), want = tb::read_dem(one);
  ASSERT_EQ(got.width(), want.width());
  ASSERT_EQ(got.height(), want.height());
  EXPECT_GE(want.voids.filled, 20u);
  EXPECT_EQ(got.voids.filled, want.voids.filled);
  for (int r = 0; r < want.height(); ++r)
    for (int c = 0; c < want.width(); ++c) ASSERT_EQ(got.at(c, r), want.at(c, r)) << c << ", " << r;
}

// An SRTM .hgt tile beside a GeoTIFF of the same type and spacing (a void-filled tile from
// elsewhere, say): GDALBuildVRT refused them, because the .hgt band's colour interpretation is
// Undefined and the GeoTIFF's Gray. The mosaic is the one-file terrain, sample for sample.
TEST(DemInputs, HgtTileBesideAGeoTiffJoinsIt) {
  constexpr int n = 1201;  // a size GDAL's SRTM driver knows
  constexpr double kStep = 1.0 / (n - 1);
  const auto height = [](double lon, double lat) { return std::round(rolling(lon, lat)); };
  const std::string hgt = (tmp() / "N44W073.hgt").string(), east = (tmp() / "east.tif").string(),
                    one = (tmp() / "one.tif").string();
  {
    std::string bytes;
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        const auto v = std::uint16_t(std::int16_t(height(-73.0 + c * kStep, 45.0 - r * kStep)));
        bytes += char(v >> 8);
        bytes += char(v & 0xff);
      }
    std::ofstream(hgt, std::ios::binary) << bytes;
  }
  ASSERT_NO_FATAL_FAILURE(
      terralod::test::write_tiff(east, 4326, -72.0 + kStep, 45.0, n - 1, n, kStep, GDT_Int16, height));
  ASSERT_NO_FATAL_FAILURE(
      terralod::test::write_tiff(one, 4326, -73.0, 45.0, 2 * n - 1, n, kStep, GDT_Int16, height));
  const tb::DemInputs in({hgt, east});
  const pm::Heightfield got = tb::read_dem(in.path()), want = tb::read_dem(one);
  ASSERT_EQ(got.width(), want.width());
  ASSERT_EQ(got.height(), want.height());
  for (int r = 0; r < want.height(); ++r)
    for (int c = 0; c < want.width(); ++c) ASSERT_EQ(got.at(c, r), want.at(c, r)) << c << ", " << r;
}

// A tile whose voids are an alpha band (gdalwarp -dstalpha writes heights so) beside a tile
// without one: GDALBuildVRT refused the two band counts. The alpha tile's heights are read with
// its alpha band as their mask: the mosaic, voids kept, is the one-file terrain whose voids are
// nodata, sample for sample and void for void.
TEST(DemInputs, ATileWithAnAlphaBandJoinsTilesWithout) {
  constexpr double kStep = 1.0 / 1200.0;
  constexpr double kWest = -72.1 + 0.5 * kStep, kNorth = 44.2 - 0.5 * kStep;
  const auto height = [&](double lon, double lat) {
    const double gap = std::hypot((lon + 72.05) / kStep, (lat - 44.15) / kStep);  // void: 5 samples
    return gap < 5.0 ? std::nan("") : std::round(rolling(lon, lat));
  };
  const std::string west = (tmp() / "alpha.tif").string(), east = (tmp() / "plain.tif").string(),
                    one = (tmp() / "one.tif").string();
  {
    GDALAllRegister();
    GDALDatasetUniquePtr ds(GetGDALDriverManager()->GetDriverByName("GTiff")->Create(west.c_str(), 120, 100,
                                                                                     2, GDT_Int16, nullptr));
    ASSERT_TRUE(ds);
    double gt[6] = {kWest - 0.5 * kStep, kStep, 0.0, kNorth + 0.5 * kStep, 0.0, -kStep};
    ds->SetGeoTransform(gt);
    OGRSpatialReference srs;
    srs.importFromEPSG(4326);
    ds->SetSpatialRef(&srs);
    std::vector<double> z(120 * 100), alpha(120 * 100);
    for (int r = 0; r < 100; ++r)
      for (int c = 0; c < 120; ++c) {
        const double h = height(kWest + c * kStep, kNorth - r * kStep);
        z[std::size_t(r) * 120 + std::size_t(c)] = std::isnan(h) ? 0.0 : h;
        alpha[std::size_t(r) * 120 + std::size_t(c)] = std::isnan(h) ? 0.0 : 32767.0;
      }
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 120, 100, z.data(), 120, 100, GDT_Float64, 0, 0),
              CE_None);
    ASSERT_EQ(
        ds->GetRasterBand(2)->RasterIO(GF_Write, 0, 0, 120, 100, alpha.data(), 120, 100, GDT_Float64, 0, 0),
        CE_None);
    ds->GetRasterBand(2)->SetColorInterpretation(GCI_AlphaBand);
  }
  ASSERT_NO_FATAL_FAILURE(terralod::test::write_tiff(east, 4326, kWest + 120 * kStep, kNorth, 120, 100, kStep,
                                                     GDT_Int16, height));
  ASSERT_NO_FATAL_FAILURE(
      terralod::test::write_tiff(one, 4326, kWest, kNorth, 240, 100, kStep, GDT_Int16, height));
  const tb::DemInputs in({west, east});
  EXPECT_NE(in.description().find("1 with its alpha band read as voids"), std::string::npos)
      << in.description();
  tb::DemOptions holes;
  holes.fill_voids = false;
  const pm::Heightfield got = tb::read_dem(in.path(), holes), want = tb::read_dem(one, holes);
  ASSERT_EQ(got.width(), want.width());
  ASSERT_EQ(got.height(), want.height());
  EXPECT_GE(want.voids.voids, 60u);
  EXPECT_EQ(got.voids.voids, want.voids.voids);
  for (std::size_t i = 0; i < want.size(); ++i) {
    ASSERT_EQ(got.valid(i), want.valid(i)) << i;
    if (want.valid(i)) {
      ASSERT_EQ(got.samples()[i], want.samples()[i]) << i;
    }
  }
}

// SRTM at 1 second beside tiles at 3 seconds, or any two spacings: GDALBuildVRT put them all on
// their mean spacing, dropping detail from the finer ones. The finest is kept, with its samples
// as they are, and the coarser tile is resampled bilinearly (not into steps).
TEST(DemInputs, TilesOfDifferentSpacingsKeepTheFinest) {
  constexpr double kStep = 1.0 / 1200.0;
  constexpr double kWest = -72.1 + 0.5 * kStep, kNorth = 44.2 - 0.5 * kStep;
  const std::string fine = (tmp() / "fine.tif").string(), coarse = (tmp() / "coarse.tif").string();
  const auto height = [](double lon, double lat) { return rolling(lon, lat); };
  ASSERT_NO_FATAL_FAILURE(
      terralod::test::write_tiff(fine, 4326, kWest, kNorth, 120, 100, kStep, GDT_Float32, height));
  // Cells of two fine ones, east of the fine tile: its first sample is 1.5 fine steps east of the
  // fine tile's last.
  ASSERT_NO_FATAL_FAILURE(terralod::test::write_tiff(
      coarse, 4326, kWest + 120.5 * kStep, kNorth - 0.5 * kStep, 60, 50, 2 * kStep, GDT_Float32, height));
  const tb::DemInputs in({fine, coarse});
  EXPECT_NE(in.description().find("finest sample spacing"), std::string::npos) << in.description();
  tb::DemOptions native;
  const pm::Heightfield hf = tb::read_dem(in.path(), native);
  ASSERT_EQ(hf.width(), 240);
  ASSERT_EQ(hf.height(), 100);
  ASSERT_TRUE(hf.crs_transform.has_value());
  EXPECT_NEAR(hf.crs_transform->x0, kWest, 1e-12);
  EXPECT_NEAR(hf.crs_transform->spacing_x(), kStep, 1e-15);
  double worst = 0.0;
  for (int r = 0; r < 100; ++r)
    for (int c = 0; c < 240; ++c) {
      const double lon = kWest + c * kStep, lat = kNorth - r * kStep;
      if (c < 120) {
        ASSERT_EQ(hf.at(c, r), double(float(rolling(lon, lat)))) << c << ", " << r;
      } else if (c >= 122 && c < 238 && r >= 2 && r < 98) {
        worst = std::max(worst, std::abs(hf.at(c, r) - rolling(lon, lat)));
      }
    }
  // Steps (nearest) would be up to 4 m off on these slopes.
  EXPECT_LT(worst, 0.3) << "metres";
}
