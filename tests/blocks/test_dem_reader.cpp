// Tests for blocks::read_dem: one grid through every format, void filling, bad input, real SRTM tiles.
#include <OpenImageIO/imageio.h>
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/dem_source.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
using terralod::pm::GridTransform;
using terralod::pm::Heightfield;
using Format = tb::DemOptions::Format;

constexpr double kR = 6371008.8;
constexpr double kDeg = std::numbers::pi / 180.0;
const double kNaN = std::numeric_limits<double>::quiet_NaN();

// ------------------------------------------------------------------------------------------
// Fixtures

// Grid A, 7 x 5, integer heights (metres); row 0 is north.
//
//          col: 0   1   2   3   4   5   6
//   row 0 (N): 10  12  15  20  18  14  11
//   row 1:     11  14  19  27  23  16  12
//   row 2:     12  15  22  35  30  20  13      <- peak 35 at (col 3, row 2)
//   row 3:     10  13  18  25  21  15  11
//   row 4 (S):  9  10  12  15  13  11  10      <- south-west sample 9 at (0, 4)
constexpr int kAW = 7, kAH = 5;
const std::vector<int> kGridA = {
    10, 12, 15, 20, 18, 14, 11,  //
    11, 14, 19, 27, 23, 16, 12,  //
    12, 15, 22, 35, 30, 20, 13,  //
    10, 13, 18, 25, 21, 15, 11,  //
    9,  10, 12, 15, 13, 11, 10,
};

// Grid B, 5 x 5 (square, so it can be an .hgt tile), a round hill.
//
//   row 0 (N): 100 110 120 110 100
//   row 1:     110 130 150 130 110
//   row 2:     120 150 200 150 120
//   row 3:     110 130 150 130 110
//   row 4 (S): 100 110 120 110 101      <- 101 marks the south-east corner
constexpr int kBN = 5;
const std::vector<int> kGridB = {
    100, 110, 120, 110, 100,  //
    110, 130, 150, 130, 110,  //
    120, 150, 200, 150, 120,  //
    110, 130, 150, 130, 110,  //
    100, 110, 120, 110, 101,
};

// Grid C, 8 x 6 with voids (*), for the fill tests. Void regions (4-connected) and the range of
// the valid samples 4-adjacent to each, derived by hand:
//
//          col: 0   1   2   3   4   5   6   7
//   row 0:     50  52  55  57  60  62  64  66
//   row 1:     51   *   *  58  61   *  65  67     A = {(1,1),(2,1),(1,2),(2,2)}: [51, 59]
//   row 2:     52   *   *  59  62  64  66  68     B = {(5,1)}: 61,62,64,65 -> exactly 63
//   row 3:     53  55  57   *   *   *  67  69     C = {(3,3),(4,3),(5,3),(4,4)}: [57, 67]
//   row 4:     54  56  58  60   *  66  68  70     D = {(0,5)}: 54,57 -> exactly 55.5
//   row 5:      *  57  59  61  63  65  69   *     E = {(7,5)}: 70,69 -> exactly 69.5
constexpr int kCW = 8, kCH = 6;
constexpr int V = -9999;
const std::vector<int> kGridC = {
    50, 52, 55, 57, 60, 62, 64, 66,  //
    51, V,  V,  58, 61, V,  65, 67,  //
    52, V,  V,  59, 62, 64, 66, 68,  //
    53, 55, 57, V,  V,  V,  67, 69,  //
    54, 56, 58, 60, V,  66, 68, 70,  //
    V,  57, 59, 61, 63, 65, 69, V,
};
constexpr std::size_t kGridCVoids = 11;

/// A fresh, empty scratch folder for the current test.
fs::path scratch() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(TERRALOD_TEST_TMP) /
                       (std::string("dem_reader_") + info->test_suite_name() + "_" + info->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void write_bytes(const fs::path& path, const std::vector<unsigned char>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

/// SRTM .hgt: big-endian int16, row-major, north row first.
void write_hgt(const fs::path& path, const std::vector<int>& z) {
  std::vector<unsigned char> bytes;
  for (int v : z) {
    const auto u = std::uint16_t(std::int16_t(v));
    bytes.push_back((unsigned char)(u >> 8));
    bytes.push_back((unsigned char)(u & 0xff));
  }
  write_bytes(path, bytes);
}

/// A GeoTIFF through GDAL. `epsg` 0 writes no CRS; an empty `gt` writes no geotransform.
void write_geotiff(const fs::path& path, int w, int h, const std::vector<double>& z, GDALDataType type,
                   std::vector<double> gt, int epsg, std::optional<double> nodata = std::nullopt,
                   int bands = 1) {
  GDALAllRegister();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  ASSERT_NE(driver, nullptr);
  GDALDatasetUniquePtr ds(driver->Create(path.c_str(), w, h, bands, type, nullptr));
  ASSERT_TRUE(ds) << CPLGetLastErrorMsg();
  if (!gt.empty()) {
    ASSERT_EQ(ds->SetGeoTransform(gt.data()), CE_None);
  }
  if (epsg != 0) {
    OGRSpatialReference srs;
    ASSERT_EQ(srs.importFromEPSG(epsg), OGRERR_NONE);
    srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    ASSERT_EQ(ds->SetSpatialRef(&srs), CE_None);
  }
  for (int b = 1; b <= bands; ++b) {
    GDALRasterBand* band = ds->GetRasterBand(b);
    if (nodata) {
      ASSERT_EQ(band->SetNoDataValue(*nodata), CE_None);
    }
    std::vector<double> copy = z;
    ASSERT_EQ(band->RasterIO(GF_Write, 0, 0, w, h, copy.data(), w, h, GDT_Float64, 0, 0), CE_None);
  }
}

/// An image through OpenImageIO, `channels` interleaved channels of `type`.
template <typename T>
void write_image(const fs::path& path, int w, int h, int channels, const std::vector<T>& pixels,
                 OIIO::TypeDesc type) {
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out) << OIIO::geterror();
  OIIO::ImageSpec spec(w, h, channels, type);
  ASSERT_TRUE(out->open(path.string(), spec)) << out->geterror();
  ASSERT_TRUE(out->write_image(type, pixels.data())) << out->geterror();
  ASSERT_TRUE(out->close());
}

std::string asc_text(int w, int h, const std::vector<int>& z, const std::string& header) {
  std::string s = "ncols " + std::to_string(w) + "\nnrows " + std::to_string(h) + "\n" + header;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) s += std::to_string(z[std::size_t(r) * w + c]) + (c + 1 < w ? " " : "\n");
  }
  return s;
}

std::string wgs84_wkt() {
  OGRSpatialReference srs;
  srs.SetWellKnownGeogCS("WGS84");
  char* text = nullptr;
  srs.exportToWkt(&text);
  std::string s = text;
  CPLFree(text);
  return s;
}

void expect_heights(const Heightfield& hf, int w, int h, const std::vector<int>& z, const std::string& what) {
  ASSERT_EQ(hf.width(), w) << what;
  ASSERT_EQ(hf.height(), h) << what;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      EXPECT_EQ(hf.at(c, r), double(z[std::size_t(r) * w + c])) << what << " at col " << c << " row " << r;
    }
  }
  EXPECT_FALSE(hf.has_holes()) << what;
  EXPECT_EQ(hf.voids.voids, 0u) << what;
}

void expect_transform_near(const GridTransform& a, const GridTransform& b, double tol,
                           const std::string& what) {
  EXPECT_NEAR(a.x0, b.x0, tol) << what;
  EXPECT_NEAR(a.xc, b.xc, tol) << what;
  EXPECT_NEAR(a.xr, b.xr, tol) << what;
  EXPECT_NEAR(a.y0, b.y0, tol) << what;
  EXPECT_NEAR(a.yc, b.yc, tol) << what;
  EXPECT_NEAR(a.yr, b.yr, tol) << what;
}

/// Expects read_dem(path, options) to throw DemError whose message starts with "path: " and
/// contains `needle`.
void expect_dem_error(const fs::path& path, const std::string& needle, tb::DemOptions options = {}) {
  try {
    (void)tb::read_dem(path.string(), options);
    ADD_FAILURE() << "no DemError for " << path;
  } catch (const tb::DemError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(path.string() + ": ", 0), 0u) << "message does not start with the path: " << msg;
    EXPECT_NE(msg.find(needle), std::string::npos) << "message lacks '" << needle << "': " << msg;
    EXPECT_EQ(e.path(), path.string());
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type for " << path << ": " << e.what();
  }
}

/// Independent check of the fill bound: for each 4-connected region of void samples in
/// `original` (NaN = void), every filled value in `filled` is finite and within [min, max] of
/// the valid samples 4-adjacent to the region. Returns the number of regions.
std::size_t expect_fill_within_region_bounds(const std::vector<double>& original, const Heightfield& filled) {
  const int w = filled.width(), h = filled.height();
  std::vector<int> seen(original.size(), 0);
  std::size_t regions = 0;
  for (std::size_t seed = 0; seed < original.size(); ++seed) {
    if (!std::isnan(original[seed]) || seen[seed]) continue;
    ++regions;
    std::vector<std::size_t> stack = {seed}, members;
    seen[seed] = 1;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    while (!stack.empty()) {
      const std::size_t i = stack.back();
      stack.pop_back();
      members.push_back(i);
      const int c = int(i % w), r = int(i / w);
      const int dc[4] = {-1, 1, 0, 0}, dr[4] = {0, 0, -1, 1};
      for (int k = 0; k < 4; ++k) {
        const int cc = c + dc[k], rr = r + dr[k];
        if (cc < 0 || rr < 0 || cc >= w || rr >= h) continue;
        const std::size_t j = std::size_t(rr) * w + cc;
        if (!std::isnan(original[j])) {
          lo = std::min(lo, original[j]);
          hi = std::max(hi, original[j]);
        } else if (!seen[j]) {
          seen[j] = 1;
          stack.push_back(j);
        }
      }
    }
    for (std::size_t i : members) {
      const double v = filled[i];
      EXPECT_TRUE(std::isfinite(v)) << "sample " << i;
      EXPECT_GE(v, lo) << "spike below the region's border at sample " << i;
      EXPECT_LE(v, hi) << "spike above the region's border at sample " << i;
    }
  }
  return regions;
}

std::vector<double> with_nan(const std::vector<int>& z, int void_value) {
  std::vector<double> out;
  for (int v : z) out.push_back(v == void_value ? kNaN : double(v));
  return out;
}

// ------------------------------------------------------------------------------------------
// One grid, every format

TEST(dem_reader_formats, SameGridFromGeoTiffPngAndAsciiGrid) {
  const fs::path dir = scratch();
  // Projected frame: UTM 19N, cells of 30 m, lower-left corner at (500000, 4900000).
  // Sample centres: (0,0) -> (500015, 4900135); the south-west sample (0,4) -> (500015, 4900015).
  const GridTransform expected = GridTransform::north_up(500015.0, 4900135.0, 30.0, 30.0);

  const fs::path tif = dir / "a.tif";
  write_geotiff(tif, kAW, kAH, std::vector<double>(kGridA.begin(), kGridA.end()), GDT_Int16,
                {500000.0, 30.0, 0.0, 4900150.0, 0.0, -30.0}, 32619);
  const Heightfield from_tif = tb::read_dem(tif.string());
  expect_heights(from_tif, kAW, kAH, kGridA, "GeoTIFF");
  expect_transform_near(from_tif.transform, expected, 1e-9, "GeoTIFF transform");
  EXPECT_NE(from_tif.crs_wkt.find("UTM zone 19N"), std::string::npos) << from_tif.crs_wkt;
  EXPECT_EQ(from_tif.source, tif.string());

  const fs::path asc = dir / "a.asc";
  write_text(asc, asc_text(kAW, kAH, kGridA, "xllcorner 500000\nyllcorner 4900000\ncellsize 30\n"));
  const Heightfield from_asc = tb::read_dem(asc.string());
  expect_heights(from_asc, kAW, kAH, kGridA, "ASCII grid");
  EXPECT_EQ(from_asc.transform, expected);
  EXPECT_TRUE(from_asc.crs_wkt.empty());

  // The same grid with centre keys, upper-case keys and values spread over lines differently.
  const fs::path asc2 = dir / "a_centre.asc";
  std::string text = "NCOLS 7\nNROWS 5\nXLLCENTER 500015\nYLLCENTER 4900015\nCELLSIZE 30\nNODATA_value -1\n";
  for (int v : kGridA) text += std::to_string(v) + "\n";
  write_text(asc2, text);
  const Heightfield from_asc2 = tb::read_dem(asc2.string());
  expect_heights(from_asc2, kAW, kAH, kGridA, "ASCII grid, centre keys");
  EXPECT_EQ(from_asc2.transform, expected);

  // GDAL exports a float raster whose nodata is NaN with "NODATA_value nan": a void where the
  // values say nan. It was refused as "not a finite number".
  const fs::path asc_nan = dir / "a_nan.asc";
  text = "ncols 7\nnrows 5\nxllcenter 500015\nyllcenter 4900015\ncellsize 30\nNODATA_value  nan\n";
  for (std::size_t i = 0; i < kGridA.size(); ++i)
    text += (i == 3 ? std::string("nan") : std::to_string(kGridA[i])) + " ";
  write_text(asc_nan, text);
  tb::DemOptions keep;
  keep.fill_voids = false;
  const Heightfield from_nan = tb::read_dem(asc_nan.string(), keep);
  EXPECT_EQ(from_nan.voids.voids, 1u);
  EXPECT_FALSE(from_nan.valid(3));
  EXPECT_EQ(from_nan.at(4, 0), double(kGridA[4]));

  // 16-bit PNG: no georeferencing, so the frame is north-up with heightmap_spacing and the
  // south-west sample at (0, 0): (0,0) -> (0, 4 * 30).
  const fs::path png = dir / "a.png";
  write_image(png, kAW, kAH, 1, std::vector<std::uint16_t>(kGridA.begin(), kGridA.end()),
              OIIO::TypeDesc::UINT16);
  tb::DemOptions opt;
  opt.heightmap_spacing = 30.0;
  const Heightfield from_png = tb::read_dem(png.string(), opt);
  expect_heights(from_png, kAW, kAH, kGridA, "16-bit PNG");
  EXPECT_EQ(from_png.transform, GridTransform::north_up(0.0, 120.0, 30.0, 30.0));
  const auto [sx, sy] = from_png.transform.to_world(0, kAH - 1);
  EXPECT_EQ(sx, 0.0);
  EXPECT_EQ(sy, 0.0);

  // The affine maps agree where comparable: same spacing and orientation, shifted origin.
  EXPECT_EQ(from_png.transform.xc, from_tif.transform.xc);
  EXPECT_EQ(from_png.transform.yr, from_tif.transform.yr);
  EXPECT_LT(from_tif.transform.determinant(), 0.0);

  // The hand-drawn peak and south-west corner, to be explicit.
  EXPECT_EQ(from_png.at(3, 2), 35.0);
  EXPECT_EQ(from_tif.at(0, 4), 9.0);
}

TEST(dem_reader_formats, SameSquareGridFromHgtGeographicTiffAndAsciiGridWithPrj) {
  const fs::path dir = scratch();
  // N10E020.hgt, 5 x 5: spacing 1/4 degree, samples on the tile edges, south-west corner
  // (lon 20, lat 10), centre latitude 10.5. Local frame, by hand:
  //   dy = R * pi/180 / 4, dx = R * cos(10.5 deg) * pi/180 / 4,
  //   sample (0,0) (north-west) -> (0, R * pi/180), south-west (0,4) -> (0, 0).
  const double ky = kR * kDeg, kx = kR * std::cos(10.5 * kDeg) * kDeg;
  const GridTransform expected = GridTransform::north_up(0.0, ky, kx / 4, ky / 4);

  const fs::path hgt = dir / "N10E020.hgt";
  write_hgt(hgt, kGridB);
  const Heightfield from_hgt = tb::read_dem(hgt.string());
  expect_heights(from_hgt, kBN, kBN, kGridB, "hgt");
  expect_transform_near(from_hgt.transform, expected, 1e-6, "hgt transform");
  const auto [sx, sy] = from_hgt.transform.to_world(0, kBN - 1);
  EXPECT_NEAR(sx, 0.0, 1e-6);
  EXPECT_NEAR(sy, 0.0, 1e-6);
  const auto [ex, ey] = from_hgt.transform.to_world(kBN - 1, 0);  // north-east sample
  EXPECT_NEAR(ex, kx, 1e-6);
  EXPECT_NEAR(ey, ky, 1e-6);
  EXPECT_NE(from_hgt.crs_wkt.find("WGS"), std::string::npos);
  EXPECT_NE(from_hgt.frame.find("lon0 = 20"), std::string::npos) << from_hgt.frame;
  EXPECT_NE(from_hgt.frame.find("lat0 = 10"), std::string::npos) << from_hgt.frame;
  EXPECT_NE(from_hgt.frame.find("phi_c = 10.5"), std::string::npos) << from_hgt.frame;

  // The same tile as an EPSG:4326 GeoTIFF (GDAL corner convention: half a cell outwards).
  const fs::path tif = dir / "b.tif";
  write_geotiff(tif, kBN, kBN, std::vector<double>(kGridB.begin(), kGridB.end()), GDT_Float32,
                {20.0 - 0.125, 0.25, 0.0, 11.0 + 0.125, 0.0, -0.25}, 4326);
  const Heightfield from_tif = tb::read_dem(tif.string());
  expect_heights(from_tif, kBN, kBN, kGridB, "geographic GeoTIFF");
  expect_transform_near(from_tif.transform, expected, 1e-6, "geographic GeoTIFF transform");

  // And as an ASCII grid with a geographic .prj.
  const fs::path asc = dir / "b.asc";
  write_text(asc, asc_text(kBN, kBN, kGridB, "xllcenter 20\nyllcenter 10\ncellsize 0.25\n"));
  write_text(dir / "b.prj", wgs84_wkt());
  const Heightfield from_asc = tb::read_dem(asc.string());
  expect_heights(from_asc, kBN, kBN, kGridB, "ASCII grid with .prj");
  expect_transform_near(from_asc.transform, expected, 1e-6, "ASCII grid with .prj transform");
  EXPECT_FALSE(from_asc.crs_wkt.empty());
}

TEST(dem_reader_formats, HeightmapScaleOffsetAndUngeoreferencedTiff) {
  const fs::path dir = scratch();
  // Raw 16-bit values up to 65535 stay integers (no normalisation): 65535 * 0.1 - 100 = 6453.5.
  const std::vector<std::uint16_t> raw = {0, 1000, 65535, 30000};
  const fs::path png = dir / "h.png";
  write_image(png, 2, 2, 1, raw, OIIO::TypeDesc::UINT16);
  tb::DemOptions opt;
  opt.vertical_scale = 0.1;
  opt.vertical_offset = -100.0;
  opt.heightmap_spacing = 2.5;
  const Heightfield hf = tb::read_dem(png.string(), opt);
  EXPECT_DOUBLE_EQ(hf.at(0, 0), -100.0);
  EXPECT_DOUBLE_EQ(hf.at(1, 0), 0.0);
  EXPECT_DOUBLE_EQ(hf.at(0, 1), 6453.5);
  EXPECT_DOUBLE_EQ(hf.at(1, 1), 2900.0);
  EXPECT_EQ(hf.transform, GridTransform::north_up(0.0, 2.5, 2.5, 2.5));

  // 8-bit PNG.
  const fs::path png8 = dir / "h8.png";
  write_image(png8, 2, 2, 1, std::vector<std::uint8_t>{0, 7, 255, 128}, OIIO::TypeDesc::UINT8);
  const Heightfield hf8 = tb::read_dem(png8.string());
  EXPECT_EQ(hf8.at(1, 0), 7.0);
  EXPECT_EQ(hf8.at(0, 1), 255.0);

  // 16-bit grey and alpha (GDAL writes a PNG of a DEM with voids so): alpha 0 marks a void. It
  // was refused for having two channels.
  const fs::path ga = dir / "grey_alpha.png";
  {
    std::vector<std::uint16_t> px = {100, 65535, 200, 0, 300, 65535, 400, 65535};  // grey, alpha
    auto out = OIIO::ImageOutput::create(ga.string());
    ASSERT_TRUE(out);
    OIIO::ImageSpec spec(2, 2, 2, OIIO::TypeDesc::UINT16);
    spec.channelnames = {"Y", "A"};
    spec.alpha_channel = 1;
    ASSERT_TRUE(out->open(ga.string(), spec)) << out->geterror();
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT16, px.data())) << out->geterror();
    ASSERT_TRUE(out->close());
  }
  tb::DemOptions holes;
  holes.fill_voids = false;
  const Heightfield hfa = tb::read_dem(ga.string(), holes);
  EXPECT_EQ(hfa.at(0, 0), 100.0);
  EXPECT_FALSE(hfa.valid(1));  // (1, 0): alpha 0
  EXPECT_EQ(hfa.at(0, 1), 300.0);
  EXPECT_EQ(hfa.at(1, 1), 400.0);
  EXPECT_EQ(hfa.voids.voids, 1u);

  // A PNG with a world file beside it (so does GDAL's .aux.xml) is a raster on its georeference,
  // 30 m cells here; it was read as a heightmap of 1 m cells whatever its georeference said.
  const fs::path placed = dir / "placed.png";
  write_image(placed, 2, 2, 1, raw, OIIO::TypeDesc::UINT16);
  std::ofstream(dir / "placed.pgw") << "30\n0\n0\n-30\n500015\n4999985\n";
  // A vertical scale is for heightmaps only: given for this raster, it is refused (it was
  // silently ignored).
  EXPECT_THROW(tb::read_dem(placed.string(), opt), tb::DemError);
  EXPECT_THROW(tb::open_dem_source(placed.string(), opt), tb::DemError);
  const Heightfield hfp = tb::read_dem(placed.string());
  const auto [x0, y0] = hfp.transform.to_world(0, 0);
  const auto [x1, y1] = hfp.transform.to_world(1, 1);
  EXPECT_EQ(x1 - x0, 30.0);
  EXPECT_EQ(y0 - y1, 30.0);
  EXPECT_EQ(hfp.at(1, 0), 1000.0);
  EXPECT_EQ(tb::open_dem_source(placed.string())->grid().transform, hfp.transform);

  // A TIFF without geotransform or CRS is a heightmap under Auto: vertical_scale applies.
  const fs::path tif = dir / "plain.tif";
  write_geotiff(tif, kAW, kAH, std::vector<double>(kGridA.begin(), kGridA.end()), GDT_UInt16, {}, 0);
  tb::DemOptions twice;
  twice.vertical_scale = 2.0;
  const Heightfield hft = tb::read_dem(tif.string(), twice);
  EXPECT_EQ(hft.at(3, 2), 70.0);
  EXPECT_EQ(hft.at(0, 4), 18.0);
  EXPECT_EQ(hft.transform, GridTransform::north_up(0.0, 4.0, 1.0, 1.0));

  // The same TIFF forced through GDAL: a vertical scale is refused (it is for heightmaps).
  tb::DemOptions gdal = twice;
  gdal.format = Format::Gdal;
  try {
    tb::read_dem(tif.string(), gdal);
    ADD_FAILURE() << "a vertical scale was taken for a raster read through GDAL";
  } catch (const tb::DemError& e) {
    EXPECT_NE(e.problem().find("heightmaps only"), std::string::npos) << e.what();
  }
  gdal.vertical_scale = 1.0;
  const Heightfield hfg = tb::read_dem(tif.string(), gdal);
  expect_heights(hfg, kAW, kAH, kGridA, "plain TIFF via GDAL");
  EXPECT_EQ(hfg.transform, GridTransform::north_up(0.0, 4.0, 1.0, 1.0));
}

// A DEM placed by ground control points only, no geotransform (scanned maps, raw products): it
// was read as a heightmap image of 1 m cells. Here its grid is turned 20 degrees from north; it
// is read north-up in the GCPs' CRS, every sample of the terrain where the grid covers it, and
// the frame says so.
TEST(dem_reader_formats, GroundControlPointsPlaceTheGrid) {
  constexpr int kN = 120;
  constexpr double kStep = 1.0 / 1200.0, kTurn = 20.0 * kDeg, kLon0 = 8.0, kLat0 = 46.1;
  const auto height = [](double lon, double lat) {
    return 1500.0 + 400.0 * std::sin((lon - 8.0) * 40.0) * std::cos((lat - 46.0) * 50.0);
  };
  // Pixel/line (corner of the first pixel at (0, 0)) to (lon, lat), and back.
  const auto place = [&](double p, double l) {
    return std::pair{kLon0 + (p * std::cos(kTurn) - l * std::sin(kTurn)) * kStep,
                     kLat0 - (p * std::sin(kTurn) + l * std::cos(kTurn)) * kStep};
  };
  const auto unplace = [&](double lon, double lat) {
    const double x = (lon - kLon0) / kStep, y = (kLat0 - lat) / kStep;
    return std::pair{x * std::cos(kTurn) + y * std::sin(kTurn), -x * std::sin(kTurn) + y * std::cos(kTurn)};
  };
  const fs::path tif = scratch() / "gcps.tif";
  {
    GDALAllRegister();
    GDALDatasetUniquePtr ds(GetGDALDriverManager()->GetDriverByName("GTiff")->Create(tif.c_str(), kN, kN, 1,
                                                                                     GDT_Float32, nullptr));
    ASSERT_TRUE(ds);
    std::vector<GDAL_GCP> gcps(4);
    GDALInitGCPs(4, gcps.data());
    const double corners[4][2] = {{0, 0}, {kN, 0}, {0, kN}, {kN, kN}};
    for (int k = 0; k < 4; ++k) {
      gcps[k].dfGCPPixel = corners[k][0], gcps[k].dfGCPLine = corners[k][1];
      std::tie(gcps[k].dfGCPX, gcps[k].dfGCPY) = place(corners[k][0], corners[k][1]);
    }
    OGRSpatialReference wgs84;
    wgs84.importFromEPSG(4326);
    wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    ASSERT_EQ(ds->SetGCPs(4, gcps.data(), &wgs84), CE_None);
    GDALDeinitGCPs(4, gcps.data());
    std::vector<float> z(std::size_t(kN) * kN);
    for (int l = 0; l < kN; ++l)
      for (int p = 0; p < kN; ++p) {
        const auto [lon, lat] = place(p + 0.5, l + 0.5);
        z[std::size_t(l) * kN + p] = float(height(lon, lat));
      }
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, kN, kN, z.data(), kN, kN, GDT_Float32, 0, 0),
              CE_None);
  }
  tb::DemOptions native;
  native.fill_voids = false;
  const Heightfield hf = tb::read_dem(tif.string(), native);
  ASSERT_TRUE(hf.crs_transform.has_value());
  EXPECT_NE(hf.frame.find("placed north-up by its 4 ground control points"), std::string::npos) << hf.frame;
  EXPECT_EQ(hf.crs_transform->xr, 0.0);  // north-up
  EXPECT_EQ(hf.crs_transform->yc, 0.0);
  EXPECT_GT(hf.width(), kN);  // the turned grid's bounding box
  std::size_t inside = 0, holes = 0;
  double worst = 0.0;
  for (int r = 0; r < hf.height(); ++r)
    for (int c = 0; c < hf.width(); ++c) {
      const auto [lon, lat] = hf.crs_transform->to_world(c, r);
      const auto [p, l] = unplace(lon, lat);
      const bool in = p > 1.0 && p < kN - 1.0 && l > 1.0 && l < kN - 1.0;
      const bool out = p < -1.0 || p > kN + 1.0 || l < -1.0 || l > kN + 1.0;
      const bool valid = hf.valid(std::size_t(r) * std::size_t(hf.width()) + std::size_t(c));
      if (in) {
        ++inside;
        ASSERT_TRUE(valid) << c << ", " << r;
        worst = std::max(worst, std::abs(hf.at(c, r) - height(lon, lat)));
      }
      if (out) {
        ++holes;
        EXPECT_FALSE(valid) << c << ", " << r;
      }
    }
  EXPECT_GT(inside, std::size_t(kN * kN * 9 / 10));
  EXPECT_GT(holes, std::size_t(kN * kN / 10));  // the corners of the bounding box
  EXPECT_LT(worst, 1.0) << "metres (relief 800 m, bilinear at 90 m)";
}

// ------------------------------------------------------------------------------------------
// Voids

TEST(dem_reader_voids, FilledWithinRegionBoundsExactValuesForSingleVoids) {
  const fs::path dir = scratch();
  const fs::path asc = dir / "c.asc";
  write_text(asc, asc_text(kCW, kCH, kGridC, "xllcorner 0\nyllcorner 0\ncellsize 10\nNODATA_value -9999\n"));
  const Heightfield hf = tb::read_dem(asc.string());
  EXPECT_EQ(hf.voids.voids, kGridCVoids);
  EXPECT_EQ(hf.voids.filled, kGridCVoids);
  EXPECT_FALSE(hf.has_holes());
  EXPECT_EQ(expect_fill_within_region_bounds(with_nan(kGridC, V), hf), 5u);
  // Hand-derived: a lone void surrounded by valid samples is exactly their mean.
  EXPECT_DOUBLE_EQ(hf.at(5, 1), 63.0);
  EXPECT_DOUBLE_EQ(hf.at(0, 5), 55.5);
  EXPECT_DOUBLE_EQ(hf.at(7, 5), 69.5);
  // Region bounds by hand (A: [51, 59], C: [57, 67]).
  for (auto [c, r] : {std::pair{1, 1}, {2, 1}, {1, 2}, {2, 2}}) {
    EXPECT_GE(hf.at(c, r), 51.0);
    EXPECT_LE(hf.at(c, r), 59.0);
  }
  for (auto [c, r] : {std::pair{3, 3}, {4, 3}, {5, 3}, {4, 4}}) {
    EXPECT_GE(hf.at(c, r), 57.0);
    EXPECT_LE(hf.at(c, r), 67.0);
  }
  // Valid samples are untouched.
  for (std::size_t i = 0; i < kGridC.size(); ++i) {
    if (kGridC[i] != V) {
      EXPECT_EQ(hf[i], double(kGridC[i]));
    }
  }
}

TEST(dem_reader_voids, RegionOverTheSizeCapStaysAHoleUnderAMask) {
  // A 4102 x 4102 tile, z = (col + row) % 100, with three void regions:
  //   L1: row 1 and column 1, samples 1..4100: bounding box 4100 x 4100 > 4096 x 4096 -> hole;
  //   L2: row 3 and column 3, samples 3..4098: bounding box 4096 x 4096, the cap -> filled;
  //   one void at (10, 10): neighbours 19, 21, 19, 21 -> filled with exactly 20.
  const fs::path dir = scratch();
  const int n = 4102;
  std::vector<int> z(std::size_t(n) * n);
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) z[std::size_t(r) * n + c] = (c + r) % 100;
  }
  const auto at = [&](int c, int r) -> int& { return z[std::size_t(r) * n + c]; };
  for (int k = 1; k <= 4100; ++k) at(k, 1) = at(1, k) = -32768;
  for (int k = 3; k <= 4098; ++k) at(k, 3) = at(3, k) = -32768;
  at(10, 10) = -32768;
  const fs::path path = dir / "N10E010.hgt";
  write_hgt(path, z);
  z.clear();
  const Heightfield hf = tb::read_dem(path.string());
  const std::size_t l1 = 2 * 4100 - 1, l2 = 2 * 4096 - 1;
  EXPECT_EQ(hf.voids.voids, l1 + l2 + 1);
  EXPECT_EQ(hf.voids.filled, l2 + 1);
  ASSERT_TRUE(hf.has_holes());
  EXPECT_EQ(std::size_t(std::count(hf.mask().begin(), hf.mask().end(), 0)), l1);
  for (int k = 1; k <= 4100; ++k) {
    ASSERT_FALSE(hf.valid(k, 1));
    ASSERT_FALSE(hf.valid(1, k));
    ASSERT_EQ(hf.at(k, 1), 0.0);
  }
  for (int k = 3; k <= 4098; ++k) {
    ASSERT_TRUE(hf.valid(k, 3));
    ASSERT_TRUE(hf.valid(3, k));
    ASSERT_TRUE(std::isfinite(hf.at(k, 3)));
  }
  EXPECT_TRUE(hf.valid(10, 10));
  EXPECT_EQ(hf.at(10, 10), 20.0);
}

TEST(dem_reader_voids, KeptAsHolesWhenNotFilling) {
  const fs::path dir = scratch();
  const fs::path asc = dir / "c.asc";
  write_text(asc, asc_text(kCW, kCH, kGridC, "xllcorner 0\nyllcorner 0\ncellsize 10\nNODATA_value -9999\n"));
  tb::DemOptions opt;
  opt.fill_voids = false;
  const Heightfield hf = tb::read_dem(asc.string(), opt);
  EXPECT_EQ(hf.voids.voids, kGridCVoids);
  EXPECT_EQ(hf.voids.filled, 0u);
  ASSERT_TRUE(hf.has_holes());
  ASSERT_EQ(hf.mask().size(), hf.size());
  for (std::size_t i = 0; i < kGridC.size(); ++i) {
    EXPECT_EQ(hf.valid(i), kGridC[i] != V) << i;
    EXPECT_EQ(hf[i], kGridC[i] == V ? 0.0 : double(kGridC[i])) << i;
  }

  // The same voids in an .hgt tile (-32768), and a GeoTIFF with nodata, NaN and +inf.
  std::vector<int> square(36);
  for (int i = 0; i < 36; ++i) square[i] = 100 + i;
  square[7] = square[8] = square[35] = -32768;
  const fs::path hgt = dir / "S01W001.hgt";
  write_hgt(hgt, square);
  const Heightfield hh = tb::read_dem(hgt.string(), opt);
  EXPECT_EQ(hh.voids.voids, 3u);
  EXPECT_FALSE(hh.valid(7));
  EXPECT_FALSE(hh.valid(35));
  EXPECT_TRUE(hh.valid(9));
  // South-west corner of S01W001: lon -1, lat -1.
  EXPECT_NE(hh.frame.find("lon0 = -1,"), std::string::npos) << hh.frame;
  EXPECT_NE(hh.frame.find("lat0 = -1,"), std::string::npos) << hh.frame;

  std::vector<double> z(36, 5.0);
  z[0] = -1.0;  // nodata
  z[14] = kNaN;
  z[20] = std::numeric_limits<double>::infinity();
  const fs::path tif = dir / "v.tif";
  write_geotiff(tif, 6, 6, z, GDT_Float32, {0, 1, 0, 6, 0, -1}, 32633, -1.0);
  const Heightfield ht = tb::read_dem(tif.string(), opt);
  EXPECT_EQ(ht.voids.voids, 3u);
  EXPECT_FALSE(ht.valid(0));
  EXPECT_FALSE(ht.valid(14));
  EXPECT_FALSE(ht.valid(20));
  const Heightfield ht_filled = tb::read_dem(tif.string());
  EXPECT_EQ(ht_filled.voids.filled, 3u);
  for (double v : ht_filled.samples()) EXPECT_EQ(v, 5.0);  // a flat border fills flat
}

// Rasters exported without a nodata tag keep their fill value as a sample: -3.4e38 (the least
// float) most often. No height is 10,000 km from the datum, so every reader takes such values as
// voids; kept, they made a database whose root error was 3.4e38 m. Heights of the deepest trench
// and the highest peak stay heights.
TEST(dem_reader_voids, UndeclaredFloatFillsAreVoids) {
  const fs::path dir = scratch();
  const double fill = -3.4028234663852886e38;
  std::vector<double> z(64, 100.0);
  z[9] = z[10] = fill;
  z[20] = 1e30;
  z[30] = 8848.86;
  z[40] = -10994.0;
  const fs::path tif = dir / "fill.tif";
  write_geotiff(tif, 8, 8, z, GDT_Float32, {500000, 30, 0, 4900000, 0, -30}, 32619);  // no nodata
  tb::DemOptions holes;
  holes.fill_voids = false;
  const auto expect_read = [&](const Heightfield& hf, const std::string& what) {
    std::size_t voids = 0;
    for (std::size_t i = 0; i < hf.size(); ++i) voids += hf.valid(i) ? 0 : 1;
    EXPECT_EQ(voids, 3u) << what;
    for (std::size_t i : {9u, 10u, 20u}) EXPECT_FALSE(hf.valid(i)) << what << " sample " << i;
    EXPECT_TRUE(hf.valid(30)) << what;
    EXPECT_NEAR(hf[30], 8848.86, 1e-3) << what;
    EXPECT_EQ(hf[40], -10994.0) << what;
  };
  expect_read(tb::read_dem(tif.string(), holes), "GeoTIFF read whole");
  // Window by window, as the build reads it.
  const std::unique_ptr<tb::DemSource> src = tb::open_dem_source(tif.string(), holes);
  ASSERT_FALSE(src->in_memory());
  expect_read(src->read(tb::SampleRect{0, 0, 7, 7}), "GeoTIFF window");
  // Filled, every void takes values from its neighbours' range.
  const Heightfield filled = tb::read_dem(tif.string());
  EXPECT_EQ(filled.voids.filled, 3u);
  for (double v : filled.samples()) {
    EXPECT_GE(v, -10994.0);
    EXPECT_LE(v, 8848.87);
  }

  // An ASCII grid without NODATA_value, and a float heightmap image.
  std::string asc = "ncols 8\nnrows 8\nxllcorner 0\nyllcorner 0\ncellsize 10\n";
  for (std::size_t i = 0; i < z.size(); ++i) {
    char v[32];
    std::snprintf(v, sizeof v, "%.9g", z[i]);
    asc += v;
    asc += (i % 8 == 7) ? "\n" : " ";
  }
  write_text(dir / "fill.asc", asc);
  expect_read(tb::read_dem((dir / "fill.asc").string(), holes), "ASCII grid");
  std::vector<float> image(z.begin(), z.end());
  write_image(dir / "fill_image.tif", 8, 8, 1, image, OIIO::TypeDesc::FLOAT);
  expect_read(tb::read_dem((dir / "fill_image.tif").string(), holes), "float heightmap");
}

// gdalwarp -dstalpha writes a DEM as two bands, heights and alpha: the alpha's 0 samples are
// voids, whole and window by window. A second band that is not alpha is still refused.
TEST(dem_reader_voids, AnAlphaBandMarksVoids) {
  const fs::path dir = scratch();
  const fs::path tif = dir / "alpha.tif";
  {
    GDALAllRegister();
    GDALDatasetUniquePtr ds(
        GetGDALDriverManager()->GetDriverByName("GTiff")->Create(tif.c_str(), 6, 5, 2, GDT_Int16, nullptr));
    ASSERT_TRUE(ds);
    double gt[6] = {500000, 30, 0, 4900000, 0, -30};
    ds->SetGeoTransform(gt);
    OGRSpatialReference srs;
    srs.importFromEPSG(32619);
    ds->SetSpatialRef(&srs);
    std::vector<std::int16_t> z(30), a(30, 255);
    for (int i = 0; i < 30; ++i) z[std::size_t(i)] = std::int16_t(200 + i);
    a[7] = a[8] = a[29] = 0;
    z[7] = z[8] = z[29] = 0;  // what gdalwarp leaves under alpha 0
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 6, 5, z.data(), 6, 5, GDT_Int16, 0, 0), CE_None);
    ASSERT_EQ(ds->GetRasterBand(2)->SetColorInterpretation(GCI_AlphaBand), CE_None);
    ASSERT_EQ(ds->GetRasterBand(2)->RasterIO(GF_Write, 0, 0, 6, 5, a.data(), 6, 5, GDT_Int16, 0, 0), CE_None);
  }
  tb::DemOptions holes;
  holes.fill_voids = false;
  const auto expect_read = [](const Heightfield& hf, const std::string& what) {
    for (std::size_t i = 0; i < 30; ++i) {
      const bool void_sample = i == 7 || i == 8 || i == 29;
      EXPECT_EQ(hf.valid(i), !void_sample) << what << " sample " << i;
      if (!void_sample) {
        EXPECT_EQ(hf[i], 200.0 + double(i)) << what << " sample " << i;
      }
    }
  };
  expect_read(tb::read_dem(tif.string(), holes), "read whole");
  const std::unique_ptr<tb::DemSource> src = tb::open_dem_source(tif.string(), holes);
  expect_read(src->read(tb::SampleRect{0, 0, 5, 4}), "window");
  const Heightfield filled = tb::read_dem(tif.string());
  EXPECT_EQ(filled.voids.filled, 3u);
  for (double v : filled.samples()) EXPECT_GE(v, 200.0);

  // The same voids through a GDAL mask band (a per-dataset internal mask, 0 = void).
  const fs::path masked = dir / "masked.tif";
  {
    GDALDatasetUniquePtr ds(GetGDALDriverManager()->GetDriverByName("GTiff")->Create(masked.c_str(), 6, 5, 1,
                                                                                     GDT_Int16, nullptr));
    ASSERT_TRUE(ds);
    double gt[6] = {500000, 30, 0, 4900000, 0, -30};
    ds->SetGeoTransform(gt);
    std::vector<std::int16_t> z(30);
    std::vector<std::uint8_t> m(30, 255);
    for (int i = 0; i < 30; ++i) z[std::size_t(i)] = std::int16_t(200 + i);
    m[7] = m[8] = m[29] = 0;
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 6, 5, z.data(), 6, 5, GDT_Int16, 0, 0), CE_None);
    ASSERT_EQ(ds->CreateMaskBand(GMF_PER_DATASET), CE_None);
    ASSERT_EQ(
        ds->GetRasterBand(1)->GetMaskBand()->RasterIO(GF_Write, 0, 0, 6, 5, m.data(), 6, 5, GDT_Byte, 0, 0),
        CE_None);
  }
  expect_read(tb::read_dem(masked.string(), holes), "mask band, read whole");
  expect_read(tb::open_dem_source(masked.string(), holes)->read(tb::SampleRect{0, 0, 5, 4}),
              "mask band, window");

  const fs::path two = dir / "two.tif";
  write_geotiff(two, 4, 3, std::vector<double>(12, 1.0), GDT_Int16, {0, 1, 0, 3, 0, -1}, 32633, std::nullopt,
                2);
  expect_dem_error(two, "has 2 bands; a DEM must have one (and may have an alpha band besides)");
}

TEST(dem_reader_voids, LargeVoidReproducesDiscreteHarmonicFunction) {
  // z = 300 + 0.5 x + 0.3 y + 0.01 (x^2 - y^2) is discrete-harmonic (the 5-point Laplacian of
  // x^2 - y^2 is 2 - 2 = 0), so the exact harmonic fill of a void inside the grid is z itself.
  // A 100-sample-wide disc plus scattered single voids; checks convergence, bounds and counts.
  const fs::path dir = scratch();
  const int w = 400, h = 300;
  auto truth = [](int c, int r) {
    return 300.0 + 0.5 * c + 0.3 * r + 0.01 * (double(c) * c - double(r) * r);
  };
  std::vector<double> z(std::size_t(w) * h);
  std::vector<double> original(z.size());
  std::mt19937 rng(20240601);
  std::cout << "seed 20240601\n";
  std::size_t voids = 0;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const std::size_t i = std::size_t(r) * w + c;
      const bool in_disc = std::hypot(c - 200.0, r - 150.0) < 50.0;
      const bool scattered = c > 0 && r > 0 && c < w - 1 && r < h - 1 && rng() % 97 == 0;
      const bool is_void = in_disc || scattered;
      z[i] = is_void ? -9999.0 : truth(c, r);
      original[i] = is_void ? kNaN : z[i];
      voids += is_void;
    }
  }
  const fs::path tif = dir / "harmonic.tif";
  write_geotiff(tif, w, h, z, GDT_Float64, {0, 1, 0, double(h), 0, -1}, 0, -9999.0);
  const auto t0 = std::chrono::steady_clock::now();
  const Heightfield hf = tb::read_dem(tif.string());
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::cout << w << " x " << h << ", " << voids << " voids read and filled in " << ms << " ms\n";
  EXPECT_EQ(hf.voids.voids, voids);
  EXPECT_EQ(hf.voids.filled, voids);
  expect_fill_within_region_bounds(original, hf);
  double worst = 0.0;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) worst = std::max(worst, std::abs(hf.at(c, r) - truth(c, r)));
  }
  std::cout << "largest deviation from the harmonic function: " << worst << " m\n";
  EXPECT_LT(worst, 1e-5);
}

// ------------------------------------------------------------------------------------------
// Bad input: each error names the file and the problem.

TEST(dem_reader_errors, MissingFiles) {
  const fs::path dir = scratch();
  expect_dem_error(dir / "N10E020.hgt", "no such file");
  expect_dem_error(dir / "nope.tif", "no such file");
  expect_dem_error(dir / "nope.asc", "no such file");
  expect_dem_error(dir / "nope.png", "no such file");
  expect_dem_error(dir / "nope.dem", "no such file");
  expect_dem_error(dir, "");  // a folder
}

TEST(dem_reader_errors, BadHgtFiles) {
  const fs::path dir = scratch();
  const fs::path wrong = dir / "N10E020.hgt";
  write_bytes(wrong, std::vector<unsigned char>(1000, 0));
  expect_dem_error(wrong, "file size 1000 bytes is not that of a square grid of 16-bit samples");

  // A 1201 x 1201 tile missing its last row.
  const fs::path truncated = dir / "N11E020.hgt";
  write_bytes(truncated, std::vector<unsigned char>(std::size_t(1201) * 1200 * 2, 0));
  expect_dem_error(truncated, "is not that of a square grid");
  // An odd byte count.
  const fs::path odd = dir / "N12E020.hgt";
  write_bytes(odd, std::vector<unsigned char>(49, 0));
  expect_dem_error(odd, "is not that of a square grid");

  const fs::path empty = dir / "N13E020.hgt";
  write_bytes(empty, {});
  expect_dem_error(empty, "empty");

  const fs::path one = dir / "N14E020.hgt";  // 2 bytes: a 1 x 1 grid
  write_bytes(one, {0, 7});
  expect_dem_error(one, "grid is 1 x 1; at least 2 x 2 samples are needed");

  const fs::path unnamed = dir / "tile.hgt";
  write_hgt(unnamed, kGridB);
  expect_dem_error(unnamed, "south-west corner");

  const fs::path all_void = dir / "N15E020.hgt";
  write_hgt(all_void, std::vector<int>(25, -32768));
  expect_dem_error(all_void, "no valid sample");
}

TEST(dem_reader_errors, BadRastersAndImages) {
  const fs::path dir = scratch();
  std::vector<unsigned char> garbage(4096);
  std::mt19937 rng(7);
  for (auto& b : garbage) b = (unsigned char)(rng() & 0xff);
  const fs::path tif = dir / "garbage.tif";
  write_bytes(tif, garbage);
  expect_dem_error(tif, "GDAL cannot read it");
  const fs::path png = dir / "garbage.png";
  write_bytes(png, garbage);
  expect_dem_error(png, "cannot read it as an image");
  tb::DemOptions gdal;
  gdal.format = Format::Gdal;
  expect_dem_error(png, "GDAL cannot read it", gdal);

  const fs::path rgb = dir / "rgb.png";
  write_image(rgb, 4, 3, 3, std::vector<std::uint8_t>(36, 9), OIIO::TypeDesc::UINT8);
  expect_dem_error(rgb, "has 3 channels; a heightmap must have one");

  const fs::path bands = dir / "bands.tif";
  write_geotiff(bands, 4, 3, std::vector<double>(12, 1.0), GDT_Int16, {0, 1, 0, 3, 0, -1}, 32633,
                std::nullopt, 3);
  expect_dem_error(bands, "has 3 bands; a DEM must have one");

  const fs::path tiny = dir / "tiny.tif";
  write_geotiff(tiny, 1, 1, {42.0}, GDT_Int16, {0, 1, 0, 1, 0, -1}, 32633);
  expect_dem_error(tiny, "grid is 1 x 1; at least 2 x 2 samples are needed");

  const fs::path thin = dir / "thin.png";
  write_image(thin, 5, 1, 1, std::vector<std::uint16_t>(5, 1), OIIO::TypeDesc::UINT16);
  expect_dem_error(thin, "grid is 5 x 1; at least 2 x 2 samples are needed");

  const fs::path all_void = dir / "void.tif";
  write_geotiff(all_void, 3, 3, std::vector<double>(9, -5.0), GDT_Int16, {0, 1, 0, 3, 0, -1}, 32633, -5.0);
  expect_dem_error(all_void, "no valid sample");

  // Geographic CRS with latitudes beyond the pole.
  const fs::path pole = dir / "pole.tif";
  write_geotiff(pole, 3, 3, std::vector<double>(9, 1.0), GDT_Int16, {0, 1, 0, 95, 0, -1}, 4326);
  expect_dem_error(pole, "outside [-90, 90]");
}

TEST(dem_reader_errors, BadAsciiGrids) {
  const fs::path dir = scratch();
  struct Case {
    const char* name;
    std::string text;
    const char* needle;
  };
  const std::string head = "ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n";
  const std::vector<Case> cases = {
      {"junk", "this is not a grid\n", "line 1: 'this' is not an Esri ASCII grid header key"},
      {"bad_value", head + "1 2 3\n4 x 6\n", "line 7: 'x' is not a number"},
      {"short", head + "1 2 3\n4 5\n", "data ends after 5 of 3 x 2 = 6 values"},
      {"long", head + "1 2 3\n4 5 6\n7\n", "line 8: more values than ncols x nrows = 6"},
      {"no_ncols", "nrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n3 4\n", "header lacks 'ncols'"},
      {"no_value", "ncols\nnrows 2\n", "line 1: header key 'ncols' has no value"},
      {"bad_header_value", "ncols abc\n", "line 1: value 'abc' of 'ncols' is not a finite number"},
      {"fractional", "ncols 2.5\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n",
       "ncols = 2.5 is not a positive whole number"},
      {"twice", "ncols 2\nncols 2\n", "line 2: header key 'ncols' appears twice"},
      {"both_corners", "ncols 2\nnrows 2\nxllcorner 0\nxllcenter 0\nyllcorner 0\ncellsize 1\n1 2 3 4\n",
       "both 'xllcorner' and 'xllcenter'"},
      {"no_cellsize", "ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\n1 2 3 4\n", "lacks 'cellsize'"},
      {"negative_cell", "ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize -1\n1 2 3 4\n",
       "cell size must be positive"},
      {"one_by_one", "ncols 1\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n5\n",
       "grid is 1 x 1; at least 2 x 2 samples are needed"},
      {"empty", "", "header lacks 'ncols'"},
      {"binary", std::string("ncols 2\0\1\2", 10), "binary file"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const fs::path path = dir / (std::string(c.name) + ".asc");
    write_text(path, c.text);
    expect_dem_error(path, c.needle);
  }
  // A .prj that is not a CRS.
  const fs::path asc = dir / "badprj.asc";
  write_text(asc, head + "1 2 3\n4 5 6\n");
  write_text(dir / "badprj.prj", "not a coordinate system");
  expect_dem_error(asc, "badprj.prj holds no CRS");
}

/// Reads `path`; either a sound Heightfield or a DemError naming the file, nothing else.
void expect_sound_or_dem_error(const fs::path& path, const tb::DemOptions& options = {}) {
  try {
    const Heightfield hf = tb::read_dem(path.string(), options);
    EXPECT_GE(hf.width(), 2);
    EXPECT_GE(hf.height(), 2);
    EXPECT_EQ(hf.size(), std::size_t(hf.width()) * hf.height());
    for (double v : hf.samples()) ASSERT_TRUE(std::isfinite(v)) << path;
    EXPECT_EQ(hf.voids.filled, hf.voids.voids);
  } catch (const tb::DemError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path.string() + ": ", 0), 0u) << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << path << ": unexpected exception " << e.what();
  }
}

TEST(dem_reader_errors, CorruptedFilesGiveSoundResultsOrDemErrors) {
  // Our own parsers (.hgt, .asc) get random byte flips, insertions and truncations; the GDAL and
  // OpenImageIO paths get truncations (flips there could claim gigantic sizes; their decoders
  // are fuzzed upstream).
  const fs::path dir = scratch();
  const unsigned seed = 20240607;
  std::cout << "seed " << seed << "\n";
  std::mt19937 rng(seed);
  auto read_all = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::vector<unsigned char>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const fs::path hgt = dir / "N10E020.hgt";
  std::vector<int> b = kGridB;
  b[12] = -32768;
  write_hgt(hgt, b);
  const fs::path asc = dir / "c.asc";
  write_text(asc, asc_text(kCW, kCH, kGridC, "xllcorner 0\nyllcorner 0\ncellsize 10\nNODATA_value -9999\n"));
  const fs::path tif = dir / "a.tif";
  write_geotiff(tif, kAW, kAH, std::vector<double>(kGridA.begin(), kGridA.end()), GDT_Int16,
                {500000.0, 30.0, 0.0, 4900150.0, 0.0, -30.0}, 32619);
  const fs::path png = dir / "a.png";
  write_image(png, kAW, kAH, 1, std::vector<std::uint16_t>(kGridA.begin(), kGridA.end()),
              OIIO::TypeDesc::UINT16);

  for (const fs::path& original : {hgt, asc}) {
    const std::vector<unsigned char> bytes = read_all(original);
    for (int round = 0; round < 300; ++round) {
      std::vector<unsigned char> m = bytes;
      const int kind = int(rng() % 3);
      if (kind == 0) {
        for (int k = 0, n = 1 + int(rng() % 4); k < n && !m.empty(); ++k)
          m[rng() % m.size()] = (unsigned char)(rng() & 0xff);
      } else if (kind == 1) {
        m.insert(m.begin() + std::ptrdiff_t(rng() % (m.size() + 1)), (unsigned char)(rng() & 0xff));
      } else {
        m.resize(rng() % (m.size() + 1));
      }
      const fs::path mutated = dir / ("m_" + original.filename().string());
      write_bytes(mutated, m);
      SCOPED_TRACE("round " + std::to_string(round) + " of " + original.filename().string());
      expect_sound_or_dem_error(mutated);
    }
  }
  for (const fs::path& original : {tif, png}) {
    const std::vector<unsigned char> bytes = read_all(original);
    for (std::size_t len = 0; len < bytes.size(); len += 1 + bytes.size() / 60) {
      const fs::path cut = dir / ("cut_" + original.filename().string());
      write_bytes(cut, std::vector<unsigned char>(bytes.begin(), bytes.begin() + std::ptrdiff_t(len)));
      SCOPED_TRACE("length " + std::to_string(len) + " of " + original.filename().string());
      expect_sound_or_dem_error(cut);
    }
  }
}

TEST(dem_reader_errors, InvalidOptionsAreRejected) {
  tb::DemOptions opt;
  opt.heightmap_spacing = 0.0;
  EXPECT_THROW((void)tb::read_dem("whatever.png", opt), std::invalid_argument);
  opt = {};
  opt.vertical_scale = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)tb::read_dem("whatever.png", opt), std::invalid_argument);
}

// ------------------------------------------------------------------------------------------
// Real SRTM tiles (skipped when ../shared/data is absent)

fs::path data_file(const char* name) { return fs::path(TERRALOD_DATA_DIR) / name; }

std::vector<double> raw_hgt_with_nan(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<unsigned char> b((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<double> z(b.size() / 2);
  for (std::size_t i = 0; i < z.size(); ++i) {
    const auto v = std::int16_t(std::uint16_t((b[2 * i] << 8) | b[2 * i + 1]));
    z[i] = v == -32768 ? kNaN : double(v);
  }
  return z;
}

double read_ms(const fs::path& path, Heightfield& out, const tb::DemOptions& options = {}) {
  const auto t0 = std::chrono::steady_clock::now();
  out = tb::read_dem(path.string(), options);
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

TEST(dem_reader_real_data, WhiteMountainsTile) {
  const fs::path path = data_file("N44W072.hgt");
  if (!fs::exists(path)) GTEST_SKIP() << path << " absent";
  Heightfield hf;
  const double ms = read_ms(path, hf);
  std::cout << path.filename() << ": read in " << ms << " ms\n";
  ASSERT_EQ(hf.width(), 1201);
  ASSERT_EQ(hf.height(), 1201);
  EXPECT_EQ(hf.voids.voids, 0u);
  EXPECT_FALSE(hf.has_holes());
  const auto [lo, hi] = std::minmax_element(hf.samples().begin(), hf.samples().end());
  EXPECT_EQ(*lo, 115.0);
  EXPECT_EQ(*hi, 1908.0);

  // Spacing: R * pi/180 / 1200 = 92.66 m north-south, times cos(44.5 deg) east-west.
  const double dy = kR * kDeg / 1200.0, dx = dy * std::cos(44.5 * kDeg);
  EXPECT_NEAR(dy, 92.66, 0.01);
  EXPECT_NEAR(hf.transform.spacing_y(), dy, 1e-9);
  EXPECT_NEAR(hf.transform.spacing_x(), dx, 1e-9);
  EXPECT_EQ(hf.transform.xr, 0.0);
  EXPECT_EQ(hf.transform.yc, 0.0);
  EXPECT_LT(hf.transform.yr, 0.0);
  const auto [sx, sy] = hf.transform.to_world(0, 1200);
  EXPECT_NEAR(sx, 0.0, 1e-6);
  EXPECT_NEAR(sy, 0.0, 1e-6);
  EXPECT_NE(hf.frame.find("lon0 = -72"), std::string::npos) << hf.frame;
  EXPECT_NE(hf.frame.find("lat0 = 44"), std::string::npos) << hf.frame;
  EXPECT_NE(hf.frame.find("phi_c = 44.5"), std::string::npos) << hf.frame;
  EXPECT_NE(hf.crs_wkt.find("WGS"), std::string::npos);

  // GDAL's SRTMHGT driver gives the same heights and the same frame.
  tb::DemOptions gdal;
  gdal.format = Format::Gdal;
  Heightfield via_gdal;
  const double gms = read_ms(path, via_gdal, gdal);
  std::cout << path.filename() << ": read through GDAL in " << gms << " ms\n";
  ASSERT_EQ(via_gdal.width(), 1201);
  ASSERT_EQ(via_gdal.height(), 1201);
  EXPECT_TRUE(via_gdal.samples() == hf.samples());
  expect_transform_near(via_gdal.transform, hf.transform, 1e-6, "SRTMHGT vs own reader");
}

TEST(dem_reader_real_data, KauaiTileVoidsFilled) {
  const fs::path path = data_file("N22W160.hgt");
  if (!fs::exists(path)) GTEST_SKIP() << path << " absent";
  Heightfield hf;
  const double ms = read_ms(path, hf);
  std::cout << path.filename() << ": read and filled in " << ms << " ms\n";
  ASSERT_EQ(hf.width(), 1201);
  EXPECT_EQ(hf.voids.voids, 4279u);
  EXPECT_EQ(hf.voids.filled, 4279u);
  EXPECT_FALSE(hf.has_holes());
  const std::vector<double> original = raw_hgt_with_nan(path);
  double lo = 1e300, hi = -1e300;
  for (double v : original) {
    if (!std::isnan(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  }
  EXPECT_EQ(lo, -34.0);
  EXPECT_EQ(hi, 1579.0);
  for (double v : hf.samples()) {
    ASSERT_TRUE(std::isfinite(v));
    ASSERT_GE(v, lo);
    ASSERT_LE(v, hi);
  }
  const std::size_t regions = expect_fill_within_region_bounds(original, hf);
  std::cout << regions << " void regions\n";
  EXPECT_NEAR(hf.transform.spacing_y(), kR * kDeg / 1200.0, 1e-9);
  EXPECT_NEAR(hf.transform.spacing_x(), kR * kDeg / 1200.0 * std::cos(22.5 * kDeg), 1e-9);

  tb::DemOptions holes;
  holes.fill_voids = false;
  Heightfield hh;
  const double hms = read_ms(path, hh, holes);
  std::cout << path.filename() << ": read with holes in " << hms << " ms\n";
  ASSERT_TRUE(hh.has_holes());
  EXPECT_EQ(std::size_t(std::count(hh.mask().begin(), hh.mask().end(), 0)), 4279u);
  EXPECT_EQ(hh.voids.filled, 0u);
}

}  // namespace
