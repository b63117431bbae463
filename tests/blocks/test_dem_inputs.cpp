// DemInputs (blocks/dem_reader.hpp): several DEM files, or a folder of them, read as one mosaic.
// Each mosaic is compared sample by sample with the same terrain in one file, or with each of its
// tiles read alone. (Mosaics the mirror writer makes are tested with the writers.)
#include <cpl_vsi.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "geographic_tiff.hpp"
#include "run_command.hpp"
#include "terralod/blocks/dem_reader.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace fs = std::filesystem;

namespace {

const fs::path& tmp() { return terralod::test::process_temp_dir("dem-inputs"); }

tb::DemOptions keep_voids() {
  tb::DemOptions o;
  o.fill_voids = false;
  return o;
}

}  // namespace

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

namespace {

// Two 1 x 1 degree tiles at 30" (121 x 121 samples, sharing the column at 72 W, as SRTM's and
// DTED's tiles do) and the same terrain in one file, in integer metres.
constexpr double kTileStep = 1.0 / 120.0;
double tile_height(double lon, double lat) { return std::round(rolling(lon, lat)); }
void write_tile(const fs::path& path, int west, GDALDataType type = GDT_Int16) {
  fs::create_directories(path.parent_path());
  ASSERT_NO_FATAL_FAILURE(
      terralod::test::write_tiff(path.string(), 4326, west, 45.0, 121, 121, kTileStep, type, tile_height));
}
void expect_the_two_tiles(const tb::DemInputs& in) {
  const std::string one = (tmp() / "two_tiles_in_one.tif").string();
  ASSERT_NO_FATAL_FAILURE(
      terralod::test::write_tiff(one, 4326, -73.0, 45.0, 241, 121, kTileStep, GDT_Int16, tile_height));
  EXPECT_EQ(in.files(), 2u) << in.description();
  const pm::Heightfield got = tb::read_dem(in.path()), want = tb::read_dem(one);
  ASSERT_EQ(got.width(), want.width());
  ASSERT_EQ(got.height(), want.height());
  for (int r = 0; r < want.height(); ++r)
    for (int c = 0; c < want.width(); ++c) ASSERT_EQ(got.at(c, r), want.at(c, r)) << c << ", " << r;
}

}  // namespace

// Copernicus DEM keeps each tile in a folder of its own, its heights in DEM/ and its masks (on
// the same cells) in AUXFILES/; ASTER GDEM puts each tile's count of scenes beside its heights.
// Before, the first folder was "a folder that holds no elevation file" and the second mosaicked
// the counts over the heights, silently. Now the tree is read as its tiles, the masks and counts
// left out and said so.
TEST(DemInputs, FoldersOfTileFoldersAndTilesWithQualityLayersAreReadAsTheirTiles) {
  const fs::path cop = tmp() / "copernicus";
  for (const int west : {-73, -72}) {
    const std::string tile = "Copernicus_DSM_10_N44_00_W0" + std::to_string(-west) + "_00";
    ASSERT_NO_FATAL_FAILURE(write_tile(cop / tile / "DEM" / (tile + "_DEM.tif"), west, GDT_Float32));
    for (const char* mask : {"_EDM", "_FLM", "_WBM", "_HEM"}) {
      fs::create_directories(cop / tile / "AUXFILES");
      ASSERT_NO_FATAL_FAILURE(terralod::test::write_tiff(
          (cop / tile / "AUXFILES" / (tile + mask + ".tif")).string(), 4326, west, 45.0, 121, 121, kTileStep,
          GDT_Byte, [](double, double) { return 1.0; }));
    }
  }
  {
    const tb::DemInputs in({cop.string()});
    ASSERT_NO_FATAL_FAILURE(expect_the_two_tiles(in));
    EXPECT_NE(in.description().find("8 quality layers beside the tiles left out"), std::string::npos)
        << in.description();
  }
  const fs::path aster = tmp() / "aster";
  for (const int west : {-73, -72}) {
    const std::string tile = "ASTGTMV003_N44W0" + std::to_string(-west);
    ASSERT_NO_FATAL_FAILURE(write_tile(aster / (tile + "_dem.tif"), west));
    ASSERT_NO_FATAL_FAILURE(terralod::test::write_tiff((aster / (tile + "_num.tif")).string(), 4326, west,
                                                       45.0, 121, 121, kTileStep, GDT_Int16,
                                                       [](double, double) { return 7.0; }));
  }
  const tb::DemInputs in({aster.string()});
  ASSERT_NO_FATAL_FAILURE(expect_the_two_tiles(in));
  EXPECT_NE(in.description().find("2 quality layers"), std::string::npos) << in.description();
}

// DTED comes as a tree of one folder per longitude (dted/w073/n44.dt0), in a format of its own.
// A folder's own elevation files are its tiles; its subfolders are then not searched (they may
// hold other versions of the same tiles), and the description says so instead of leaving them
// out silently.
TEST(DemInputs, AFolderWithTilesOfItsOwnSaysItsSubfoldersWereNotSearched) {
  const fs::path dir = tmp() / "own_and_sub";
  ASSERT_NO_FATAL_FAILURE(write_tile(dir / "N44W073.tif", -73));
  ASSERT_NO_FATAL_FAILURE(write_tile(dir / "more" / "N44W072.tif", -72));
  ASSERT_NO_FATAL_FAILURE(write_tile(dir / "older" / "N44W073.tif", -73));
  fs::create_directories(dir / ".cache");
  const tb::DemInputs in({dir.string()});
  EXPECT_EQ(in.files(), 1u);
  EXPECT_NE(in.description().find("; 2 subfolders not searched"), std::string::npos) << in.description();
  // Without tiles of its own, the tiles of its subfolders are its tiles.
  fs::remove(dir / "N44W073.tif");
  fs::remove_all(dir / "older");
  const tb::DemInputs sub({dir.string()});
  EXPECT_EQ(sub.files(), 1u);
  EXPECT_EQ(sub.description().find("not searched"), std::string::npos) << sub.description();
}

TEST(DemInputs, ADtedTreeIsReadAsItsTiles) {
  GDALAllRegister();  // GetDriverByName finds only registered drivers
  GDALDriver* dted = GetGDALDriverManager()->GetDriverByName("DTED");
  if (dted == nullptr) GTEST_SKIP() << "GDAL has no DTED driver";
  const fs::path tree = tmp() / "dted";
  for (const int west : {-73, -72}) {
    const fs::path tif = tmp() / ("dted_source" + std::to_string(-west) + ".tif");
    ASSERT_NO_FATAL_FAILURE(write_tile(tif, west));
    GDALDatasetUniquePtr src(GDALDataset::Open(tif.c_str(), GDAL_OF_RASTER));
    ASSERT_TRUE(src);
    const fs::path dt0 = tree / ("w0" + std::to_string(-west)) / "n44.dt0";
    fs::create_directories(dt0.parent_path());
    GDALDatasetUniquePtr out(dted->CreateCopy(dt0.c_str(), src.get(), TRUE, nullptr, nullptr, nullptr));
    ASSERT_TRUE(out) << dt0 << ": " << CPLGetLastErrorMsg();
  }
  ASSERT_NO_FATAL_FAILURE(expect_the_two_tiles(tb::DemInputs({tree.string()})));
}

// Two files on the same cells are no mosaic: the later one would hide the other whole. Refused,
// naming both, whether a folder or the inputs hold them.
TEST(DemInputs, TwoFilesOnTheSameCellsAreRefusedByName) {
  const fs::path dir = tmp() / "same_cells";
  ASSERT_NO_FATAL_FAILURE(write_tile(dir / "heights.tif", -73));
  ASSERT_NO_FATAL_FAILURE(write_tile(dir / "slope.tif", -73, GDT_Float32));
  ASSERT_NO_FATAL_FAILURE(write_tile(dir / "east.tif", -72));
  const auto refused = [&](const std::vector<std::string>& inputs, const std::string& named) {
    try {
      const tb::DemInputs in(inputs);
      ADD_FAILURE() << "accepted: " << in.description();
    } catch (const tb::DemError& e) {
      EXPECT_EQ(e.path(), named);
      const std::string heights = (dir / "heights.tif").string(), slope = (dir / "slope.tif").string();
      EXPECT_NE(e.problem().find(heights + " and " + slope + " cover the same cells"), std::string::npos)
          << e.what();
    }
  };
  refused({dir.string()}, dir.string());
  refused({(dir / "heights.tif").string(), (dir / "east.tif").string(), (dir / "slope.tif").string()},
          (dir / "slope.tif").string());
}

namespace {

// A 1 x 1 degree tile at 30" (as write_tile) of `type` whose nodata value is `nodata` (none when
// NaN), with the samples where void(col, row) written as that value.
void write_tile_with_nodata(const fs::path& path, int west, GDALDataType type, double nodata,
                            const std::function<bool(int, int)>& is_void, double sea = 0.0) {
  ASSERT_NO_FATAL_FAILURE(write_tile(path, west, type));
  GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
  ASSERT_TRUE(ds) << path;
  GDALRasterBand* band = ds->GetRasterBand(1);
  if (std::isnan(nodata))
    band->DeleteNoDataValue();
  else
    band->SetNoDataValue(nodata);
  std::vector<double> z(121 * 121);
  ASSERT_EQ(band->RasterIO(GF_Read, 0, 0, 121, 121, z.data(), 121, 121, GDT_Float64, 0, 0), CE_None);
  for (int r = 0; r < 121; ++r)
    for (int c = 0; c < 121; ++c) {
      double& v = z[std::size_t(r) * 121 + std::size_t(c)];
      if (is_void(c, r))
        v = nodata;
      else if (r > 100 && c > 20 && c < 100)
        v = sea;  // a bay at the south edge, at `sea` metres
    }
  ASSERT_EQ(band->RasterIO(GF_Write, 0, 0, 121, 121, z.data(), 121, 121, GDT_Float64, 0, 0), CE_None);
}

}  // namespace

// GDALBuildVRT gives a mosaic its first file's nodata value: where files' nodata values differ, a
// height of one file that equals it became a void (a bay at 0 m beside a tile whose voids are 0),
// and where the first file has none, another's voids read as 0 m pits. The mosaic now keeps every
// file's voids, and only them, as a one-file read of each tile does.
TEST(DemInputs, TilesWhoseNodataValuesDifferKeepTheirHeightsAndTheirVoids) {
  const auto west_voids = [](int c, int r) { return c > 10 && c < 20 && r > 30 && r < 40; };
  const auto east_voids = [](int c, int r) { return c > 50 && c < 60 && r > 60 && r < 64; };
  struct Case {
    const char* name;
    GDALDataType west_type;
    double west_nodata;  // NaN: none
    GDALDataType east_type;
    double east_nodata;
  };
  const double none = std::numeric_limits<double>::quiet_NaN();
  for (const Case& k : {Case{"zero_and_min", GDT_Int16, 0.0, GDT_Int16, -32768.0},
                        Case{"none_and_min", GDT_Float32, none, GDT_Int16, -32768.0},
                        Case{"none_and_float", GDT_Int16, none, GDT_Float32, -9999.0}}) {
    SCOPED_TRACE(k.name);
    const fs::path dir = tmp() / "nodata" / k.name;
    const fs::path west = dir / "a_west.tif", east = dir / "b_east.tif";
    // The west tile has no voids where it has no nodata value.
    ASSERT_NO_FATAL_FAILURE(write_tile_with_nodata(
        west, -73, k.west_type, k.west_nodata,
        [&](int c, int r) { return !std::isnan(k.west_nodata) && west_voids(c, r); }, 1.0));
    ASSERT_NO_FATAL_FAILURE(write_tile_with_nodata(east, -72, k.east_type, k.east_nodata, east_voids));
    const tb::DemInputs in({dir.string()});
    EXPECT_NE(in.description().find("nodata values differ"), std::string::npos) << in.description();
    const pm::Heightfield got = tb::read_dem(in.path(), keep_voids()),
                          w = tb::read_dem(west.string(), keep_voids()),
                          e = tb::read_dem(east.string(), keep_voids());
    ASSERT_EQ(got.width(), 241);
    ASSERT_EQ(got.height(), 121);
    std::size_t voids = 0;
    for (int r = 0; r < 121; ++r)
      for (int c = 0; c < 241; ++c) {
        // The shared column is the east tile's (later names win).
        const pm::Heightfield& tile = c < 120 ? w : e;
        const int tc = c < 120 ? c : c - 120;
        ASSERT_EQ(got.valid(c, r), tile.valid(tc, r)) << c << ", " << r;
        if (tile.valid(tc, r)) {
          ASSERT_EQ(got.at(c, r), tile.at(tc, r)) << c << ", " << r;
        }
        voids += !got.valid(c, r);
      }
    EXPECT_EQ(voids, (std::isnan(k.west_nodata) ? 0u : 9u * 9u) + 9u * 3u);
  }
}

// GDALBuildVRT keeps no band scale, offset or vertical unit: a mosaic of tiles in feet read as
// metres (3.28 times too high), one of tiles in metres and in feet mixed the two, and tiles of
// scaled integers read as their raw integers. Each mosaic now reads every tile as read_dem reads
// it alone.
TEST(DemInputs, TilesInFeetOrScaledAreReadInMetres) {
  const auto tile = [](const fs::path& path, int west, GDALDataType type, double scale, double offset,
                       const char* unit) {
    ASSERT_NO_FATAL_FAILURE(write_tile(path, west, GDT_Float64));
    GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
    ASSERT_TRUE(ds) << path;
    std::vector<double> z(121 * 121);
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, 121, 121, z.data(), 121, 121, GDT_Float64, 0, 0),
              CE_None);
    ds.reset();
    fs::remove(path);
    GDALDatasetUniquePtr out(
        GetGDALDriverManager()->GetDriverByName("GTiff")->Create(path.c_str(), 121, 121, 1, type, nullptr));
    ASSERT_TRUE(out) << path;
    double gt[6] = {west - 0.5 * kTileStep, kTileStep, 0.0, 45.0 + 0.5 * kTileStep, 0.0, -kTileStep};
    out->SetGeoTransform(gt);
    OGRSpatialReference srs;
    srs.importFromEPSG(4326);
    out->SetSpatialRef(&srs);
    GDALRasterBand* band = out->GetRasterBand(1);
    const double metres_per_unit = std::string(unit) == "ft" ? 0.3048 : 1.0;
    for (double& v : z) v = std::round((v / metres_per_unit - offset) / scale);  // stored samples
    ASSERT_EQ(band->RasterIO(GF_Write, 0, 0, 121, 121, z.data(), 121, 121, GDT_Float64, 0, 0), CE_None);
    if (scale != 1.0) band->SetScale(scale);
    if (offset != 0.0) band->SetOffset(offset);
    band->SetUnitType(unit);
  };
  struct Case {
    const char* name;
    GDALDataType west_type;
    double west_scale, west_offset;
    const char* west_unit;
    GDALDataType east_type;
    double east_scale, east_offset;
    const char* east_unit;
    const char* note;  // in the description; "" for none
  };
  for (const Case& k : {Case{"feet", GDT_Int16, 1.0, 0.0, "ft", GDT_Int16, 1.0, 0.0, "ft", ""},
                        Case{"metres_and_feet", GDT_Int16, 1.0, 0.0, "", GDT_Float32, 1.0, 0.0, "ft",
                             "heights of 1 converted"},
                        Case{"scaled", GDT_UInt16, 0.1, -100.0, "", GDT_UInt16, 0.1, -100.0, "", ""},
                        Case{"scaled_and_not", GDT_Int16, 1.0, 0.0, "m", GDT_UInt16, 0.1, -100.0, "",
                             "heights of 1 converted"}}) {
    SCOPED_TRACE(k.name);
    const fs::path dir = tmp() / "units" / k.name;
    const fs::path west = dir / "a_west.tif", east = dir / "b_east.tif";
    ASSERT_NO_FATAL_FAILURE(tile(west, -73, k.west_type, k.west_scale, k.west_offset, k.west_unit));
    ASSERT_NO_FATAL_FAILURE(tile(east, -72, k.east_type, k.east_scale, k.east_offset, k.east_unit));
    const tb::DemInputs in({dir.string()});
    if (*k.note) {
      EXPECT_NE(in.description().find(k.note), std::string::npos) << in.description();
    }
    const pm::Heightfield got = tb::read_dem(in.path(), keep_voids()),
                          w = tb::read_dem(west.string(), keep_voids()),
                          e = tb::read_dem(east.string(), keep_voids());
    ASSERT_EQ(got.width(), 241);
    ASSERT_EQ(got.height(), 121);
    double worst = 0.0;
    for (int r = 0; r < 121; ++r)
      for (int c = 0; c < 241; ++c) {
        const double want = c < 120 ? w.at(c, r) : e.at(c - 120, r);  // the shared column is east's
        ASSERT_NEAR(want, tile_height(-73.0 + c * kTileStep, 45.0 - r * kTileStep), 0.2) << c << ", " << r;
        worst = std::max(worst, std::abs(got.at(c, r) - want));
      }
    // Exact but for the VRT's scaling by an offset (one rounding of the scale ratio).
    EXPECT_LT(worst, 1e-9) << "metres";
  }
}

// Tiles in another vertical datum than the mosaic's: GDALWarp converts their heights where PROJ
// has the transformation (ellipsoidal heights to EGM96 through proj-data's egm96_15.gtx) and
// leaves them as they are where it has none (EGM2008 to EGM96 needs egm08_25.gtx, which Debian's
// proj-data lacks). Before, the description said "warped to WGS 84 + EGM96 height" either way,
// and a tile whose CRS names no vertical datum was taken as ellipsoidal and shifted 28 m below
// the EGM96 tile beside it. Heights are checked against PROJ's own transformation of them.
TEST(DemInputs, TilesInAnotherVerticalDatumSayWhetherTheirHeightsWereConverted) {
  struct Case {
    const char* name;
    const char* west_crs;  // the mosaic's CRS (the first file's, on a tie of samples)
    const char* east_crs;
    const char* note;   // of the east tile, in the description; "?" for "converted" or "read as"
    const char* datum;  // the mosaic's vertical datum
  };
  for (const Case& k :
       {Case{"ellipsoidal", "EPSG:4326+5773", "EPSG:4979", "heights of 1 in WGS 84 ellipsoidal height ?",
             "EGM96 height"},
        Case{"egm2008", "EPSG:4326+5773", "EPSG:4326+3855", "heights of 1 in EGM2008 height ?",
             "EGM96 height"},
        Case{"none", "EPSG:4326+5773", "EPSG:4326",
             "heights of 1 without a vertical datum read as EGM96 height", "EGM96 height"},
        Case{"to_none", "EPSG:4326", "EPSG:4326+5773",
             "heights of 1 in EGM96 height read unconverted (WGS 84 names no vertical datum)", ""}}) {
    SCOPED_TRACE(k.name);
    const fs::path dir = tmp() / "datums" / k.name;
    const fs::path west = dir / "a_west.tif", east = dir / "b_east.tif";
    ASSERT_NO_FATAL_FAILURE(write_tile(west, -73));
    ASSERT_NO_FATAL_FAILURE(write_tile(east, -72));
    OGRSpatialReference to, from;
    ASSERT_EQ(to.SetFromUserInput(k.west_crs), OGRERR_NONE);
    ASSERT_EQ(from.SetFromUserInput(k.east_crs), OGRERR_NONE);
    for (const auto& [path, srs] : {std::pair{west, &to}, std::pair{east, &from}}) {
      GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
      ASSERT_TRUE(ds) << path;
      ASSERT_EQ(ds->SetSpatialRef(srs), CE_None) << path;
    }
    // PROJ's transformation of the east tile's heights (lon, lat order on both sides), where both
    // tiles name their datum; else the heights stay.
    to.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    from.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    const std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&from, &to));
    ASSERT_TRUE(ct);
    const bool both =
        (to.IsCompound() || to.GetAxesCount() == 3) && (from.IsCompound() || from.GetAxesCount() == 3);
    const auto converted = [&](double lon, double lat, double h) {
      double x = lon, y = lat, z = h;
      EXPECT_TRUE(ct->Transform(1, &x, &y, &z));
      return both ? z : h;
    };
    const bool shifts = converted(-71.5, 44.5, 0.0) != 0.0;
    EXPECT_EQ(shifts, std::string(k.name) == "ellipsoidal") << "PROJ's grids here";  // the case's premise
    const tb::DemInputs in({dir.string()});
    std::string note = k.note;
    if (note.ends_with("?"))
      note.replace(note.size() - 1, 1,
                   shifts ? "converted to EGM96 height" : "read as EGM96 height unconverted");
    EXPECT_NE(in.description().find(note), std::string::npos) << in.description();
    const pm::Heightfield got = tb::read_dem(in.path(), keep_voids()),
                          e = tb::read_dem(east.string(), keep_voids());
    EXPECT_EQ(got.vertical_datum, k.datum);
    ASSERT_EQ(got.width(), 241);  // not widened by a column of void: the tiles share their cells
    double worst = 0.0, moved = 0.0;
    for (int r = 0; r < 121; ++r)
      for (int c = 120; c < 241; ++c) {
        const double want = converted(-72.0 + (c - 120) * kTileStep, 45.0 - r * kTileStep, e.at(c - 120, r));
        worst = std::max(worst, std::abs(got.at(c, r) - want));
        moved = std::max(moved, std::abs(got.at(c, r) - e.at(c - 120, r)));
      }
    EXPECT_LT(worst, 1e-3) << "metres from PROJ's heights";  // Float32 samples
    if (shifts) {
      EXPECT_GT(moved, 20.0) << "metres";  // EGM96 lies about 28 m below the ellipsoid here
    } else {
      EXPECT_EQ(moved, 0.0) << "metres";
    }
  }
}

namespace {

// Copies the file at `from` into the zip archive `zip` as `member` (GDAL writes zips: a new
// member is added to the archive that is there).
void add_to_zip(const fs::path& from, const fs::path& zip, const std::string& member) {
  std::ifstream in(from, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string inner = "/vsizip/" + zip.string() + "/" + member;
  VSILFILE* f = VSIFOpenL(inner.c_str(), "wb");
  ASSERT_NE(f, nullptr) << inner;
  ASSERT_EQ(VSIFWriteL(bytes.data(), 1, bytes.size(), f), bytes.size());
  ASSERT_EQ(VSIFCloseL(f), 0);
}

}  // namespace

// Tiles come as they are downloaded: ASTER GDEM as one zip per tile (its _dem.tif and _num.tif),
// Copernicus DEM from ESA as one tar per tile (its DEM and AUXFILES folders). Before, a zip was
// "no raster" and a folder of zips held "no elevation file". An archive given as an input, or
// found in a folder, is read in place (GDAL's /vsizip/ and /vsitar/) as its tiles, without the
// quality layers.
TEST(DemInputs, ArchivesAreReadInPlaceAsTheirTiles) {
  const fs::path zips = tmp() / "aster_zips", tars = tmp() / "copernicus_tars", work = tmp() / "archive_work";
  fs::create_directories(zips);
  fs::create_directories(tars);
  for (const int west : {-73, -72}) {
    const std::string tile = "ASTGTMV003_N44W0" + std::to_string(-west);
    const fs::path dem = work / (tile + "_dem.tif"), num = work / (tile + "_num.tif");
    ASSERT_NO_FATAL_FAILURE(write_tile(dem, west));
    ASSERT_NO_FATAL_FAILURE(terralod::test::write_tiff(num.string(), 4326, west, 45.0, 121, 121, kTileStep,
                                                       GDT_Int16, [](double, double) { return 7.0; }));
    ASSERT_NO_FATAL_FAILURE(add_to_zip(dem, zips / (tile + ".zip"), dem.filename().string()));
    ASSERT_NO_FATAL_FAILURE(add_to_zip(num, zips / (tile + ".zip"), num.filename().string()));
    // The same tile as ESA's tar of a Copernicus tile (tar, gzipped for the second).
    const std::string cop = "Copernicus_DSM_10_N44_00_W0" + std::to_string(-west) + "_00";
    fs::create_directories(work / cop / "DEM");
    fs::create_directories(work / cop / "AUXFILES");
    fs::copy_file(dem, work / cop / "DEM" / (cop + "_DEM.tif"), fs::copy_options::overwrite_existing);
    fs::copy_file(num, work / cop / "AUXFILES" / (cop + "_EDM.tif"), fs::copy_options::overwrite_existing);
    const std::string tar = (tars / (cop + (west == -73 ? ".tar" : ".tar.gz"))).string();
    const auto made = terralod::test::run_command("tar -C " + terralod::test::quote(work.string()) +
                                                  (west == -73 ? " -cf " : " -czf ") +
                                                  terralod::test::quote(tar) + " " + cop);
    ASSERT_EQ(made.status, 0) << made.err;
  }
  {
    const tb::DemInputs in({zips.string()});
    ASSERT_NO_FATAL_FAILURE(expect_the_two_tiles(in));
    EXPECT_NE(in.description().find("2 quality layers"), std::string::npos) << in.description();
  }
  {
    const tb::DemInputs in(
        {zips.string() + "/ASTGTMV003_N44W073.zip", zips.string() + "/ASTGTMV003_N44W072.zip"});
    ASSERT_NO_FATAL_FAILURE(expect_the_two_tiles(in));
  }
  const tb::DemInputs in({tars.string()});
  ASSERT_NO_FATAL_FAILURE(expect_the_two_tiles(in));
  EXPECT_NE(in.description().find("2 quality layers"), std::string::npos) << in.description();
  // An archive without elevation files names itself and what it looked for.
  const fs::path only_num = zips / "only_num.zip";
  ASSERT_NO_FATAL_FAILURE(
      add_to_zip(work / "ASTGTMV003_N44W073_num.tif", only_num, "ASTGTMV003_N44W073_num.tif"));
  try {
    const tb::DemInputs bad({only_num.string()});
    ADD_FAILURE() << "accepted: " << bad.description();
  } catch (const tb::DemError& e) {
    EXPECT_EQ(e.path(), only_num.string());
    EXPECT_NE(e.problem().find("the archive holds no elevation file"), std::string::npos) << e.what();
    EXPECT_NE(e.problem().find("other than 1 quality layer)"), std::string::npos) << e.what();
  }
}
