// Tests for blocks::open_dem_source: windowed reads of GeoTIFFs, VRT mosaics and .hgt tiles give
// exactly block_heightfield(read_dem(...)), bit for bit, filled or not, from any window and any
// number of threads, warped to a projected frame or not; heightmap images decoded once to a
// temporary file; errors.
#include <OpenImageIO/imageio.h>
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <latch>
#include <limits>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/blocks/tree_builder.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
using terralod::pm::Heightfield;

const double kNaN = std::numeric_limits<double>::quiet_NaN();

fs::path temp_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() /
                       ("terralod_dem_source_" + name + "_" + std::to_string(std::random_device{}()));
  fs::create_directories(dir);
  return dir;
}

/// A w x h terrain (smooth hills plus a ripple) with voids (NaN): single samples, a blob crossing
/// many windows, a long thin snake (whose box grows a window far), and samples on every grid edge.
std::vector<double> terrain(int w, int h) {
  std::vector<double> z(std::size_t(w) * h);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c)
      z[std::size_t(r) * w + c] = std::round(4.0 * (300.0 + 80.0 * std::sin(c * 0.05) * std::cos(r * 0.04) +
                                                    7.0 * std::sin(c * 0.9 + r * 0.7))) /
                                  4.0;
  auto hole = [&](int c, int r) {
    if (c >= 0 && r >= 0 && c < w && r < h) z[std::size_t(r) * w + c] = kNaN;
  };
  for (int k = 0; k < 40; ++k) hole((k * 37) % w, (k * 53 + 7) % h);  // single samples
  for (int r = 40; r < 95; ++r)                                       // a blob, ragged
    for (int c = 60; c < 130; ++c)
      if ((c - 95) * (c - 95) / 1225.0 + (r - 67) * (r - 67) / 729.0 < 1.0 - 0.1 * std::sin(c * 0.7))
        hole(c, r);
  for (int c = 10; c < w - 20; ++c) hole(c, 150 + int(20 * std::sin(c * 0.05)));  // a snake
  for (int c = 150; c < 175; ++c) hole(c, 0), hole(c, 1);                         // north edge
  for (int r = 30; r < 60; ++r) hole(0, r), hole(w - 1, r + 100);                 // west, east edges
  for (int c = 0; c < 12; ++c) hole(c, h - 1);                                    // south-west corner
  return z;
}

/// A GeoTIFF through GDAL: tiled 32 x 32, Float32 with NaN voids or Int16 with nodata -32768
/// (then band scale 0.25, offset 100, unit feet); `epsg` 0: no CRS.
void write_geotiff(const fs::path& path, int w, int h, const std::vector<double>& z, GDALDataType type,
                   const std::array<double, 6>& gt, int epsg) {
  GDALAllRegister();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  ASSERT_NE(driver, nullptr);
  const char* options[] = {"TILED=YES", "BLOCKXSIZE=32", "BLOCKYSIZE=32", "COMPRESS=DEFLATE", nullptr};
  GDALDatasetUniquePtr ds(driver->Create(path.c_str(), w, h, 1, type, const_cast<char**>(options)));
  ASSERT_TRUE(ds) << CPLGetLastErrorMsg();
  std::array<double, 6> g = gt;
  ASSERT_EQ(ds->SetGeoTransform(g.data()), CE_None);
  if (epsg != 0) {
    OGRSpatialReference srs;
    ASSERT_EQ(srs.importFromEPSG(epsg), OGRERR_NONE);
    ASSERT_EQ(ds->SetSpatialRef(&srs), CE_None);
  }
  GDALRasterBand* band = ds->GetRasterBand(1);
  std::vector<double> raw = z;
  if (type == GDT_Int16) {
    ASSERT_EQ(band->SetNoDataValue(-32768), CE_None);
    band->SetScale(0.25);
    band->SetOffset(100.0);
    band->SetUnitType("ft");
    for (double& v : raw) v = std::isfinite(v) ? std::round((v - 200.0) * 4.0) : -32768.0;
  }
  ASSERT_EQ(band->RasterIO(GF_Write, 0, 0, w, h, raw.data(), w, h, GDT_Float64, 0, 0), CE_None);
}

/// SRTM .hgt: big-endian int16, -32768 for voids.
void write_hgt(const fs::path& path, const std::vector<double>& z) {
  std::vector<char> bytes;
  for (double v : z) {
    const auto u = std::uint16_t(std::int16_t(std::isfinite(v) ? std::lround(v) : -32768));
    bytes.push_back(char(u >> 8));
    bytes.push_back(char(u & 0xff));
  }
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
}

void expect_same_grid(const tb::DemGrid& a, const tb::DemGrid& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.transform.x0, b.transform.x0);
  EXPECT_EQ(a.transform.xc, b.transform.xc);
  EXPECT_EQ(a.transform.xr, b.transform.xr);
  EXPECT_EQ(a.transform.y0, b.transform.y0);
  EXPECT_EQ(a.transform.yc, b.transform.yc);
  EXPECT_EQ(a.transform.yr, b.transform.yr);
  EXPECT_EQ(a.crs_wkt, b.crs_wkt);
  ASSERT_EQ(a.crs_transform.has_value(), b.crs_transform.has_value());
  if (a.crs_transform) {
    EXPECT_EQ(a.crs_transform->x0, b.crs_transform->x0);
    EXPECT_EQ(a.crs_transform->xc, b.crs_transform->xc);
    EXPECT_EQ(a.crs_transform->y0, b.crs_transform->y0);
    EXPECT_EQ(a.crs_transform->yr, b.crs_transform->yr);
  }
  EXPECT_EQ(a.vertical_datum, b.vertical_datum);
  EXPECT_EQ(a.source, b.source);
  EXPECT_EQ(a.frame, b.frame);
}

/// Same samples (bits), mask and transform; `metadata`: also crs_wkt, source and frame.
::testing::AssertionResult same_block(const Heightfield& a, const Heightfield& b, bool metadata = true) {
  if (a.width() != b.width() || a.height() != b.height())
    return ::testing::AssertionFailure() << "size differs";
  if (std::memcmp(a.samples().data(), b.samples().data(), a.size() * sizeof(double)) != 0) {
    for (std::size_t i = 0; i < a.size(); ++i)
      if (std::memcmp(&a.samples()[i], &b.samples()[i], sizeof(double)) != 0)
        return ::testing::AssertionFailure()
               << "sample " << i << ": " << a.samples()[i] << " vs " << b.samples()[i];
  }
  if (a.mask() != b.mask()) return ::testing::AssertionFailure() << "masks differ";
  const auto &s = a.transform, &t = b.transform;
  if (s.x0 != t.x0 || s.y0 != t.y0 || s.xc != t.xc || s.xr != t.xr || s.yc != t.yc || s.yr != t.yr)
    return ::testing::AssertionFailure() << "transforms differ";
  if (metadata && (a.crs_wkt != b.crs_wkt || a.source != b.source || a.frame != b.frame))
    return ::testing::AssertionFailure() << "crs_wkt, source or frame differ";
  return ::testing::AssertionSuccess();
}

/// Windows of a w x h grid: 1 x 1 ones, the full grid, edge rows and columns, block-sized and random.
std::vector<tb::SampleRect> windows(int w, int h, int random, unsigned seed) {
  std::vector<tb::SampleRect> out = {
      {0, 0, w - 1, h - 1},     {0, 0, 0, 0},     {w - 1, h - 1, w - 1, h - 1}, {0, 0, w - 1, 0},
      {0, h - 1, w - 1, h - 1}, {0, 0, 0, h - 1}, {w - 1, 0, w - 1, h - 1}};
  if (w > 200 && h > 200)
    out.insert(out.end(), {{95, 67, 95, 67}, {100, 150, 100, 150}});  // in a blob, a snake
  const tb::BlockLayout layout = tb::partition(w, h, 33);
  for (const tb::BlockKey& k : layout.keys()) out.push_back(layout.rect(k));
  std::mt19937 rng(seed);
  for (int i = 0; i < random; ++i) {
    const int c0 = int(rng() % unsigned(w)), r0 = int(rng() % unsigned(h));
    const int c1 = std::min(w - 1, c0 + int(rng() % 70u)), r1 = std::min(h - 1, r0 + int(rng() % 70u));
    out.push_back({c0, r0, c1, r1});
  }
  return out;
}

/// open_dem_source(path, options) against read_dem: grid, every window, samples_crc.
void expect_like_read_dem(const std::string& path, const tb::DemOptions& options, bool in_memory) {
  const Heightfield hf = tb::read_dem(path, options);
  const auto src = tb::open_dem_source(path, options);
  EXPECT_EQ(src->in_memory(), in_memory);
  expect_same_grid(src->grid(), tb::DemGrid::of(hf));
  // Through read_counting_voids (read() with the count; a warped frame's is read() itself),
  // which also counts the window's voids in the file (in the DEM's own grid; a warped frame's
  // cells count none).
  tb::DemOptions keep = options;
  keep.fill_voids = false;
  keep.crs = "native";
  const Heightfield file = tb::read_dem(path, keep);
  for (const tb::SampleRect& r : windows(hf.width(), hf.height(), 60, 7)) {
    const std::string at = path + " window " + std::to_string(r.col0) + "," + std::to_string(r.row0) + " - " +
                           std::to_string(r.col1) + "," + std::to_string(r.row1);
    std::size_t voids = 12345, want = 0;
    EXPECT_TRUE(same_block(src->read_counting_voids(r, voids), tb::block_heightfield(hf, r))) << at;
    for (int row = r.row0; !src->grid().warped && row <= r.row1; ++row)
      for (int col = r.col0; col <= r.col1; ++col) want += file.valid(col, row) ? 0 : 1;
    EXPECT_EQ(voids, want) << at;
  }
  EXPECT_EQ(src->samples_crc(), tb::heightfield_source(hf)->samples_crc());
}

constexpr int kW = 300, kH = 220;
// UTM zone 19N, 10 m cells: a projected CRS, so the frame carries a measured scale error.
constexpr std::array<double, 6> kUtm = {300000.0, 10.0, 0.0, 4900000.0, 0.0, -10.0};
// WGS 84 longitude and latitude, 3 arc-second cells at 44 N: warped by the "auto" frame.
constexpr std::array<double, 6> kGeographic = {-71.25, 1.0 / 1200.0, 0.0, 44.5, 0.0, -1.0 / 1200.0};

class DemSourceTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name()); }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(DemSourceTest, GeoTiffWindowsAreReadDemBlocksFilledOrNot) {
  const fs::path f32 = dir_ / "f32.tif", i16 = dir_ / "i16.tif", plain = dir_ / "plain.tif";
  const std::vector<double> z = terrain(kW, kH);
  write_geotiff(f32, kW, kH, z, GDT_Float32, kUtm, 32619);
  write_geotiff(i16, kW, kH, z, GDT_Int16, kUtm, 32619);                 // nodata, scale, offset, feet
  write_geotiff(plain, kW, kH, z, GDT_Float32, {0, 2, 0, 0, 0, -2}, 0);  // no CRS
  for (const fs::path& p : {f32, i16, plain})
    for (const bool fill : {true, false})
      for (const char* crs : {"native", "auto"}) {
        SCOPED_TRACE(p.string() + (fill ? " filled " : " holes ") + crs);
        tb::DemOptions o;
        o.fill_voids = fill;
        o.crs = crs;
        expect_like_read_dem(p.string(), o, false);
      }
}

/// A mosaic of 2 x 2 GeoTIFF tiles cut through voids (a VRT, as DemInputs makes) against the same
/// grid in one file, read with o.crs = `crs`: the same windows, CRC and database, filled or not.
void expect_vrt_same_as_one_file(const fs::path& dir, const std::array<double, 6>& gt, int epsg,
                                 const std::string& crs) {
  const std::vector<double> z = terrain(kW, kH);
  const fs::path whole = dir / "whole.tif";
  write_geotiff(whole, kW, kH, z, GDT_Float32, gt, epsg);
  // 2 x 2 tiles split through the blob, the snake and the edge voids.
  const int cs = 97, rs = 70;
  std::vector<std::string> tiles;
  for (const auto& [c0, c1] : {std::pair{0, cs}, std::pair{cs, kW}})
    for (const auto& [r0, r1] : {std::pair{0, rs}, std::pair{rs, kH}}) {
      std::vector<double> t;
      for (int r = r0; r < r1; ++r)
        for (int c = c0; c < c1; ++c) t.push_back(z[std::size_t(r) * kW + c]);
      const fs::path p = dir / ("tile_" + std::to_string(r0) + "_" + std::to_string(c0) + ".tif");
      write_geotiff(p, c1 - c0, r1 - r0, t, GDT_Float32,
                    {gt[0] + c0 * gt[1], gt[1], 0, gt[3] + r0 * gt[5], 0, gt[5]}, epsg);
      tiles.push_back(p.string());
    }
  const tb::DemInputs vrt(tiles);
  for (const bool fill : {true, false}) {
    tb::DemOptions o;
    o.fill_voids = fill;
    o.crs = crs;
    expect_like_read_dem(vrt.path(), o, false);
    const auto a = tb::open_dem_source(vrt.path(), o), b = tb::open_dem_source(whole.string(), o);
    const tb::DemGrid& g = a->grid();
    for (const tb::SampleRect& r : windows(g.width, g.height, 40, 11))
      EXPECT_TRUE(same_block(a->read(r), b->read(r), false));
    EXPECT_EQ(a->samples_crc(), b->samples_crc());
    if (!fill) continue;
    // And so the same database: every block, the tree and the stand-ins, byte for byte.
    // (A PM records its source's name: both get the same, as two builds of one input would.)
    a->set_source("mosaic");
    b->set_source("mosaic");
    tb::DatabaseBuildOptions opt;
    opt.block_size = 33;
    opt.threads = 2;
    const std::string da = (dir / "vrt.db").string(), db = (dir / "whole.db").string();
    tb::build_database(*a, da, opt);
    tb::build_database(*b, db, opt);
    const tb::BlockDatabase x = tb::BlockDatabase::open(da), y = tb::BlockDatabase::open(db);
    EXPECT_EQ(x.info().build_parameters, y.info().build_parameters);
    ASSERT_EQ(x.blocks(), y.blocks());
    for (const tb::BlockKey k : x.blocks())
      EXPECT_EQ(x.read_block(k), y.read_block(k)) << k.col << "," << k.row;
    for (const char* blob : {"tree", "block_summaries"}) {
      ASSERT_TRUE(x.read_blob(blob).has_value()) << blob;
      EXPECT_EQ(x.read_blob(blob), y.read_blob(blob)) << blob;
    }
  }
}

TEST_F(DemSourceTest, VrtOfTilesIsTheSameMosaicAsOneFile) {
  expect_vrt_same_as_one_file(dir_, kUtm, 32619, "auto");
}

// A geographic mosaic in the "auto" frame is warped window by window: the voids cut by the tiles'
// edges are filled in the native grid, then every warped window is the same as the one-file one's.
TEST_F(DemSourceTest, WarpedVrtOfGeographicTilesIsTheSameMosaicAsOneFile) {
  expect_vrt_same_as_one_file(dir_, kGeographic, 4326, "auto");
}

// An all-void DEM: read_dem refuses it at once. A windowed source refuses it when a read grows
// to the whole grid (filling voids: at open when it measures the frame, else in the first block), or
// the build does after its blocks (voids kept); either way no database is left.
TEST_F(DemSourceTest, AllVoidDemIsRefusedAndLeavesNoDatabase) {
  const std::vector<double> z(std::size_t(40) * 30, std::numeric_limits<double>::quiet_NaN());
  const fs::path dem = dir_ / "void.tif";
  for (const int epsg : {32619, 0})  // with a CRS the frame is measured at open; without, not
    for (const bool fill : {true, false}) {
      write_geotiff(dem, 40, 30, z, GDT_Float32, kUtm, epsg);
      tb::DemOptions o;
      o.fill_voids = fill;
      EXPECT_THROW(tb::read_dem(dem.string(), o), tb::DemError);
      const std::string db = (dir_ / "void.db").string();
      try {
        const auto src = tb::open_dem_source(dem.string(), o);
        EXPECT_FALSE(src->in_memory());
        tb::DatabaseBuildOptions opt;
        opt.block_size = 17;
        tb::build_database(*src, db, opt);
        ADD_FAILURE() << "an all-void DEM was built";
      } catch (const std::exception& e) {
        EXPECT_NE(std::string(e.what()).find("void"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("void.tif"), std::string::npos) << e.what();
      }
      EXPECT_FALSE(fs::exists(db)) << "fill " << fill << ", EPSG " << epsg;
    }
}

TEST_F(DemSourceTest, HgtIsWindowedNativeOrWarped) {
  const int n = 201;
  std::vector<double> z = terrain(n, n);
  for (double& v : z) v = std::isfinite(v) ? std::round(v) : v;
  const fs::path hgt = dir_ / "N44W072.hgt";
  write_hgt(hgt, z);
  for (const bool fill : {true, false}) {
    tb::DemOptions o;
    o.fill_voids = fill;
    expect_like_read_dem(hgt.string(), o, false);
    o.crs = "auto";  // geographic: warped, window by window too
    expect_like_read_dem(hgt.string(), o, false);
  }
  const fs::path real = "/work/shared/data/N44W072.hgt";
  if (fs::exists(real)) expect_like_read_dem(real.string(), {}, false);
}

/// Writes `px` (w x h pixels of `channels` values of `type`) with OpenImageIO; tiled when `tile` > 0.
template <typename T>
void write_image(const fs::path& path, int w, int h, int channels, OIIO::TypeDesc type,
                 const std::vector<T>& px, int tile = 0) {
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out) << path;
  OIIO::ImageSpec spec(w, h, channels, type);
  if (channels == 2) spec.alpha_channel = 1;
  spec.tile_width = spec.tile_height = tile;
  ASSERT_TRUE(out->open(path.string(), spec)) << out->geterror();
  ASSERT_TRUE(out->write_image(type, px.data())) << out->geterror();
  ASSERT_TRUE(out->close());
}

// Every kind of heightmap the windowed source reads as read_dem does: grey and alpha, integer
// types that floats hold exactly and those they do not (32-bit: kept as doubles), floats, half
// floats, and tiled files whose size is no multiple of the tile (read a row of tiles at a time).
TEST_F(DemSourceTest, HeightmapsOfEveryKindAreReadLikeReadDem) {
  constexpr int w = 150, h = 97;
  std::vector<std::uint16_t> grey_alpha(2 * w * h);
  std::vector<std::int32_t> big(w * h);
  std::vector<float> floats(w * h);
  for (int i = 0; i < w * h; ++i) {
    const int x = i % w, y = i / w;
    grey_alpha[2 * i] = std::uint16_t(1000 + 30 * x + 7 * y);
    grey_alpha[2 * i + 1] = (x - 60) * (x - 60) + (y - 40) * (y - 40) < 100 || x == w - 1 ? 0 : 65535;
    big[i] = 123456789 + 1001 * x - 997 * y;  // over 2^24: not a float
    floats[i] = (x * y) % 17 == 3 ? kNaN : 0.25f * float(x) - 0.125f * float(y);
  }
  write_image(dir_ / "alpha.png", w, h, 2, OIIO::TypeDesc::UINT16, grey_alpha);
  write_image(dir_ / "big.tif", w, h, 1, OIIO::TypeDesc::INT32, big);
  write_image(dir_ / "tiled.tif", w, h, 1, OIIO::TypeDesc::FLOAT, floats, 32);
  write_image(dir_ / "half.exr", w, h, 1, OIIO::TypeDesc::HALF, floats);
  tb::DemOptions o;
  o.vertical_scale = 0.001;  // millimetres: the int32 heights' last digits count
  o.vertical_offset = -100.0;
  for (const char* name : {"alpha.png", "big.tif", "tiled.tif", "half.exr"}) {
    SCOPED_TRACE(name);
    for (const bool fill : {true, false}) {
      o.fill_voids = fill;
      expect_like_read_dem((dir_ / name).string(), o, false);
    }
  }
  // No temporary folder: an error that names the image, the folder and the variable that sets it.
  {
    const char* was = std::getenv("TMPDIR");
    const std::string saved = was != nullptr ? was : "";
    ASSERT_EQ(setenv("TMPDIR", (dir_ / "no such folder").c_str(), 1), 0);
    try {
      tb::open_dem_source((dir_ / "alpha.png").string(), o);
      ADD_FAILURE() << "no error without a temporary folder";
    } catch (const tb::DemError& e) {
      EXPECT_EQ(e.path(), (dir_ / "alpha.png").string());
      EXPECT_NE(e.problem().find("temporary file in " + (dir_ / "no such folder").string()),
                std::string::npos)
          << e.what();
      EXPECT_NE(e.problem().find("TMPDIR"), std::string::npos) << e.what();
    }
    if (was != nullptr) {
      setenv("TMPDIR", saved.c_str(), 1);
    } else {
      unsetenv("TMPDIR");
    }
  }

  // The int32 heights are kept to the millimetre (as floats they would be off by up to 4 m).
  o.fill_voids = true;
  const auto src = tb::open_dem_source((dir_ / "big.tif").string(), o);
  const Heightfield b = src->read({0, 0, w - 1, h - 1});
  EXPECT_EQ(b.at(1, 2), double(123456789 + 1001 - 2 * 997) * 0.001 - 100.0);
}

// An Esri ASCII grid is decoded once too: over 1 MiB of text, so that values straddle the reader's
// buffer; voids by NODATA_value; metric (UTM .prj) and geographic (warped by "auto").
TEST_F(DemSourceTest, AsciiGridsAreDecodedOnceAndReadLikeReadDem) {
  constexpr int w = 400, h = 300;
  const std::vector<double> z = terrain(w, h);
  for (const bool geographic : {false, true}) {
    SCOPED_TRACE(geographic ? "geographic" : "UTM");
    const fs::path asc = dir_ / (geographic ? "geo.asc" : "utm.asc");
    {
      std::ofstream out(asc);
      out << "ncols " << w << "\nnrows " << h << "\n"
          << (geographic ? "xllcenter -71.25\nyllcenter 44.25\ncellsize 0.000833333333333\n"
                         : "xllcorner 300000\nyllcorner 4900000\ncellsize 10\n")
          << "NODATA_value -9999\n";
      out.precision(12);
      for (int r = 0; r < h; ++r) {
        for (int c = 0; c < w; ++c) {
          const double v = z[std::size_t(r) * w + std::size_t(c)];
          out << (std::isfinite(v) ? v + 0.123456789 : -9999.0) << (c + 1 < w ? " " : "\n");
        }
      }
    }
    ASSERT_GT(fs::file_size(asc), std::uintmax_t(1) << 20);
    OGRSpatialReference srs;
    ASSERT_EQ(srs.importFromEPSG(geographic ? 4326 : 32619), OGRERR_NONE);
    char* wkt = nullptr;
    srs.exportToWkt(&wkt);
    std::ofstream(fs::path(asc).replace_extension(".prj")) << wkt;
    CPLFree(wkt);
    tb::DemOptions o;
    o.crs = "auto";
    for (const bool fill : {true, false}) {
      o.fill_voids = fill;
      expect_like_read_dem(asc.string(), o, false);
    }
  }
}

TEST_F(DemSourceTest, HeightmapsAreDecodedOnceNamedCrsIsWindowed) {
  const fs::path png = dir_ / "island.png";
  std::vector<std::uint16_t> px(64 * 48);
  for (std::size_t i = 0; i < px.size(); ++i) px[i] = std::uint16_t((i * 7919) % 4000);
  auto out = OIIO::ImageOutput::create(png.string());
  ASSERT_TRUE(out);
  ASSERT_TRUE(out->open(png.string(), OIIO::ImageSpec(64, 48, 1, OIIO::TypeDesc::UINT16)));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT16, px.data()));
  out->close();
  tb::DemOptions o;
  o.vertical_scale = 0.1;
  expect_like_read_dem(png.string(), o, false);

  // A .tif without georeference is a heightmap (OpenImageIO), decoded once like a PNG.
  const fs::path bare = dir_ / "bare.tif";
  GDALAllRegister();
  {
    GDALDatasetUniquePtr ds(GetGDALDriverManager()->GetDriverByName("GTiff")->Create(bare.c_str(), 40, 30, 1,
                                                                                     GDT_UInt16, nullptr));
    ASSERT_TRUE(ds);
    std::vector<std::uint16_t> v(40 * 30, 7);
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 40, 30, v.data(), 40, 30, GDT_UInt16, 0, 0),
              CE_None);
  }
  expect_like_read_dem(bare.string(), {}, false);

  const fs::path tif = dir_ / "utm.tif";
  write_geotiff(tif, kW, kH, terrain(kW, kH), GDT_Float32, kUtm, 32619);
  tb::DemOptions named;
  named.crs = "EPSG:32619";  // a named CRS warps, even to the DEM's own
  expect_like_read_dem(tif.string(), named, false);
  named.crs = "EPSG:32618";  // the next zone west: cells outside the footprint
  expect_like_read_dem(tif.string(), named, false);
  const auto src = tb::heightfield_source(tb::read_dem(tif.string(), named));

  // set_source renames what every read gives, in memory as windowed (a PM records it: a mosaic's
  // blocks are named after its description, not the VRT's in-memory path).
  const auto windowed = tb::open_dem_source(tif.string());
  ASSERT_FALSE(windowed->in_memory());
  for (tb::DemSource* s : {src.get(), windowed.get()}) {
    s->set_source("mosaic of 2 files");
    EXPECT_EQ(s->grid().source, "mosaic of 2 files");
    EXPECT_EQ(s->read({3, 4, 20, 30}).source, "mosaic of 2 files");
  }
}

// A void region whose box is over VoidFillOptions::max_region_cells (4096 x 4096, which read_dem
// does not let a caller change): a 4-connected staircase from corner to corner. It stays a hole in
// every window, however the window meets it, and a small void beside it is filled.
TEST_F(DemSourceTest, RegionOverTheCapStaysAHoleInEveryWindow) {
  const int n = 4100;
  std::vector<double> z(std::size_t(n) * n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) z[std::size_t(r) * n + c] = double((c / 64 + r / 64) % 7);
  for (int i = 0; i + 1 < n; ++i) z[std::size_t(i) * n + i] = z[std::size_t(i) * n + i + 1] = kNaN;
  z[std::size_t(3000) * n + 100] = kNaN;
  for (int r = 500; r < 530; ++r)  // a blob away from the staircase
    for (int c = 3000; c < 3030; ++c) z[std::size_t(r) * n + c] = kNaN;
  const fs::path tif = dir_ / "stairs.tif";
  write_geotiff(tif, n, n, z, GDT_Float32, {0, 1, 0, 0, 0, -1}, 0);
  const Heightfield hf = tb::read_dem(tif.string());
  ASSERT_TRUE(hf.has_holes());
  ASSERT_FALSE(hf.valid(2000, 2000));
  ASSERT_TRUE(hf.valid(100, 3000));
  const auto src = tb::open_dem_source(tif.string());
  expect_same_grid(src->grid(), tb::DemGrid::of(hf));
  std::vector<tb::SampleRect> rects = {
      {2000, 2000, 2000, 2000}, {1990, 2000, 2010, 2010}, {90, 2990, 110, 3010}, {4000, 4090, 4099, 4099}};
  const tb::BlockLayout layout = tb::partition(n, n, 257);
  for (int k = 0; k < layout.blocks_x; ++k)
    rects.push_back(layout.rect(tb::BlockKey{k, k}));  // the staircase
  rects.push_back({3010, 510, 3020, 520});  // cutting the blob, once the staircase is known as capped
  rects.push_back({2990, 520, 3015, 540});
  for (const tb::SampleRect& r : rects)
    EXPECT_TRUE(same_block(src->read(r), tb::block_heightfield(hf, r))) << r.col0 << "," << r.row0;
  EXPECT_EQ(src->samples_crc(), tb::heightfield_source(hf)->samples_crc());
}

// A large void region is solved by the first read that holds it; later reads take its values
// (the same bits) instead of growing to hold it and solving it again. Small voids are solved by
// every read that meets them. Counted through void_fill_work, native and warped.
TEST_F(DemSourceTest, LargeFilledRegionsAreSolvedOnceAndReused) {
  std::vector<double> z(std::size_t(kW) * kH);
  for (int r = 0; r < kH; ++r)
    for (int c = 0; c < kW; ++c)
      z[std::size_t(r) * kW + c] = 200.0 + 0.5 * c + 0.25 * r + 3.0 * std::sin(c * 0.3);
  for (int r = 60; r < 160; ++r)  // a 120 x 100 void across many 33-sample blocks
    for (int c = 90; c < 210; ++c) z[std::size_t(r) * kW + c] = kNaN;
  z[std::size_t(20) * kW + 20] = kNaN;  // and a single one, below the size that is kept
  const fs::path tif = dir_ / "gap.tif", geo = dir_ / "gap_geo.tif";
  write_geotiff(tif, kW, kH, z, GDT_Float32, kUtm, 32619);
  write_geotiff(geo, kW, kH, z, GDT_Float32, kGeographic, 4326);
  for (const fs::path& p : {tif, geo}) {
    SCOPED_TRACE(p.string());
    const Heightfield hf = tb::read_dem(p.string());
    const auto src = tb::open_dem_source(p.string());
    ASSERT_FALSE(src->in_memory());
    const tb::DemSource::VoidFillWork opened = src->void_fill_work();  // measuring the frame reads some
    const tb::BlockLayout layout = tb::partition(hf.width(), hf.height(), 33);
    for (int pass = 0; pass < 2; ++pass)
      for (const tb::BlockKey& k : layout.keys())
        EXPECT_TRUE(same_block(src->read(layout.rect(k)), tb::block_heightfield(hf, layout.rect(k))))
            << k.col << "," << k.row;
    const tb::DemSource::VoidFillWork w = src->void_fill_work();
    // The gap once in all (at open or by the first block meeting it), the single void once per
    // read meeting it (one block of the native grid, one or two of the warped one, in each pass).
    const std::size_t large = (opened.solved_samples >= 12000 ? 0 : 1);
    EXPECT_GE(w.solved - opened.solved, large + 2);
    EXPECT_LE(w.solved - opened.solved, large + 8);
    EXPECT_LT(w.solved_samples, 2 * 12000 + 50) << "the gap was solved twice";
    EXPECT_GE(w.reused, 2 * 9) << "every later block meeting the gap reuses it";
  }
}

// A cache smaller than the gaps met: regions leave it, least recently used first, and are solved
// again when met again, with the same bits; with no cache every read meeting a gap solves it.
TEST_F(DemSourceTest, FilledRegionsLeaveASmallCacheAndAreSolvedAgainTheSame) {
  std::vector<double> z(std::size_t(kW) * kH);
  for (int r = 0; r < kH; ++r)
    for (int c = 0; c < kW; ++c)
      z[std::size_t(r) * kW + c] = 80.0 + 0.3 * c + 0.2 * r + 4.0 * std::cos(c * 0.11);
  for (int g = 0; g < 6; ++g)  // six 40 x 40 gaps (1,600 samples, 12.8 kB of values each)
    for (int r = 20 + 100 * (g / 3); r < 60 + 100 * (g / 3); ++r)
      for (int c = 20 + 95 * (g % 3); c < 60 + 95 * (g % 3); ++c) z[std::size_t(r) * kW + c] = kNaN;
  const fs::path tif = dir_ / "gaps.tif";
  write_geotiff(tif, kW, kH, z, GDT_Float32, {0, 1, 0, 0, 0, -1}, 0);
  const Heightfield hf = tb::read_dem(tif.string());
  // A window inside each gap, read round and round: gaps 0, 1, ..., 5, 0, 1, ...
  std::vector<tb::SampleRect> inside;
  for (int g = 0; g < 6; ++g) {
    const int c = 35 + 95 * (g % 3), r = 35 + 100 * (g / 3);
    inside.push_back({c, r, c + 9, r + 9});
  }
  for (const std::size_t budget : {std::size_t(0), std::size_t(30000), std::size_t(1) << 20}) {
    SCOPED_TRACE(budget);
    tb::DemOptions o;
    o.filled_void_cache_bytes = budget;
    const auto src = tb::open_dem_source(tif.string(), o);
    for (int round = 0; round < 3; ++round)
      for (const tb::SampleRect& r : inside)
        for (int twice = 0; twice < 2; ++twice)
          EXPECT_TRUE(same_block(src->read(r), tb::block_heightfield(hf, r)));
    const tb::DemSource::VoidFillWork w = src->void_fill_work();
    EXPECT_EQ(w.solved + w.reused, 36u);
    // 0: nothing kept; 30 kB: two gaps at most, so each is gone before the round comes back to
    // it, but read again at once it is there; 1 MiB: all kept.
    EXPECT_EQ(w.solved, budget == 0 ? 36u : budget == 30000 ? 18u : 6u);
  }
}

// A read meeting a kept gap and a new wide one takes the first once (the count says so) and
// solves the second.
TEST_F(DemSourceTest, AKeptGapBesideANewOneIsReusedOnceAndTheOtherSolved) {
  std::vector<double> z(std::size_t(kW) * kH);
  for (int r = 0; r < kH; ++r)
    for (int c = 0; c < kW; ++c) z[std::size_t(r) * kW + c] = 10.0 + 0.2 * c + 0.1 * r + std::sin(r * 0.3);
  for (int r = 40; r < 120; ++r)  // two 80 x 80 gaps (boxes over 64 x 64), two columns apart
    for (int c = 40; c < 120; ++c) z[std::size_t(r) * kW + c] = z[std::size_t(r) * kW + c + 82] = kNaN;
  const fs::path tif = dir_ / "two_gaps.tif";
  write_geotiff(tif, kW, kH, z, GDT_Float32, {0, 1, 0, 0, 0, -1}, 0);
  const Heightfield hf = tb::read_dem(tif.string());
  const auto src = tb::open_dem_source(tif.string());
  const tb::SampleRect first{30, 30, 120, 130}, both{30, 30, 210, 130};  // first: A and its ring
  EXPECT_TRUE(same_block(src->read(first), tb::block_heightfield(hf, first)));
  EXPECT_TRUE(same_block(src->read(both), tb::block_heightfield(hf, both)));
  const tb::DemSource::VoidFillWork w = src->void_fill_work();
  EXPECT_EQ(w.solved, 2u);
  EXPECT_EQ(w.solved_samples, 2u * 80 * 80);
  EXPECT_EQ(w.reused, 1u);
}

// Readers meeting a wide gap at once: one solves it, the others wait and take its values (the
// solver holds about 115 bytes a void sample: readers solving one gap together multiply that).
TEST_F(DemSourceTest, ReadersMeetingAGapAtOnceSolveItOnce) {
  const int n = 1000;
  std::vector<double> z(std::size_t(n) * n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c)
      z[std::size_t(r) * n + c] = 50.0 + 0.1 * c - 0.05 * r + 2.0 * std::sin(r * 0.2);
  for (int r = 150; r < 850; ++r)  // 700 x 700 samples: about half a second to solve
    for (int c = 150; c < 850; ++c) z[std::size_t(r) * n + c] = kNaN;
  const fs::path tif = dir_ / "wide_gap.tif";
  write_geotiff(tif, n, n, z, GDT_Float32, {0, 1, 0, 0, 0, -1}, 0);  // no CRS: no reads at open
  const Heightfield hf = tb::read_dem(tif.string());
  const auto src = tb::open_dem_source(tif.string());
  ASSERT_EQ(src->void_fill_work().solved, 0u);
  std::latch start(4);
  std::vector<int> failures(4, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      const tb::SampleRect inside{300 + 100 * t, 400, 364 + 100 * t, 464},
          across{100 + 200 * t, 120, 164 + 200 * t, 184};
      start.arrive_and_wait();
      for (const tb::SampleRect& r : {inside, across})
        if (!same_block(src->read(r), tb::block_heightfield(hf, r))) ++failures[std::size_t(t)];
    });
  for (std::thread& t : threads) t.join();
  for (int f : failures) EXPECT_EQ(f, 0);
  const tb::DemSource::VoidFillWork w = src->void_fill_work();
  EXPECT_EQ(w.solved_samples, std::size_t(700 * 700)) << "readers solved the gap together";
  EXPECT_EQ(w.reused, 7u);  // the seven other reads, each once
}

// A wide gap takes a second or more to fill, during which a read (opening a mosaic, a block) is
// silent: DemOptions::on_large_void tells before and after each solve of 2^20 samples or more,
// whole-grid reads and windowed sources alike, and nothing of smaller regions or of reuses.
TEST_F(DemSourceTest, WideGapsAreToldBeforeAndAfterTheirSolve) {
  const int w = 1100, h = 1060;
  std::vector<double> z(std::size_t(w) * h);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c)
      z[std::size_t(r) * w + c] = 120.0 + 0.2 * c + 0.1 * r + 5.0 * std::sin(c * 0.05);
  const tb::SampleRect gap{30, 20, 1052, 1045};  // 1023 x 1026 = 1,049,598 samples, just over 2^20
  for (int r = gap.row0; r <= gap.row1; ++r)
    for (int c = gap.col0; c <= gap.col1; ++c) z[std::size_t(r) * w + c] = kNaN;
  for (int r = 2; r < 12; ++r)  // and a small one, filled without a word
    for (int c = 2; c < 12; ++c) z[std::size_t(r) * w + c] = kNaN;
  const fs::path tif = dir_ / "told_gap.tif";
  write_geotiff(tif, w, h, z, GDT_Float32, {0, 1, 0, 0, 0, -1}, 0);  // no CRS: no reads at open
  std::mutex m;
  std::vector<tb::VoidSolveNotice> told;
  tb::DemOptions o;
  o.on_large_void = [&](const tb::VoidSolveNotice& n) {
    std::lock_guard lock(m);
    told.push_back(n);
  };
  const auto expect_one_solve_told = [&] {
    ASSERT_EQ(told.size(), 2u);
    EXPECT_LT(told[0].seconds, 0.0) << "told first before the solve";
    EXPECT_GT(told[1].seconds, 0.0) << "then after it, with its time";
    for (const tb::VoidSolveNotice& n : told) {
      EXPECT_EQ(n.extent, gap);
      EXPECT_EQ(n.samples, gap.samples());
    }
  };
  const Heightfield hf = tb::read_dem(tif.string(), o);
  expect_one_solve_told();
  told.clear();
  const auto src = tb::open_dem_source(tif.string(), o);
  EXPECT_TRUE(told.empty());
  const tb::SampleRect inside{500, 500, 532, 532}, beside{1040, 1000, 1072, 1032};
  for (const tb::SampleRect& r : {inside, beside, inside})  // then reused: nothing more to tell
    EXPECT_TRUE(same_block(src->read(r), tb::block_heightfield(hf, r)));
  expect_one_solve_told();
  EXPECT_EQ(src->void_fill_work().reused, 2u);
}

TEST_F(DemSourceTest, ConcurrentReadersGetTheSameBlocks) {
  const fs::path tif = dir_ / "c.tif";
  write_geotiff(tif, kW, kH, terrain(kW, kH), GDT_Int16, kUtm, 32619);
  const fs::path geo = dir_ / "g.tif";  // warped: a pool of coordinate transformations
  write_geotiff(geo, kW, kH, terrain(kW, kH), GDT_Int16, kGeographic, 4326);
  for (const fs::path& p : {tif, geo}) {
    const Heightfield hf = tb::read_dem(p.string());
    const auto src = tb::open_dem_source(p.string());
    ASSERT_FALSE(src->in_memory());
    std::vector<int> failures(4, 0);
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
      threads.emplace_back([&, t] {
        for (const tb::SampleRect& r : windows(hf.width(), hf.height(), 150, 100 + unsigned(t)))
          if (!same_block(src->read(r), tb::block_heightfield(hf, r))) ++failures[std::size_t(t)];
      });
    for (std::thread& t : threads) t.join();
    for (int f : failures) EXPECT_EQ(f, 0) << p;
  }
}

TEST_F(DemSourceTest, GdalCacheIsCappedWhileOpen) {
  if (CPLGetConfigOption("GDAL_CACHEMAX", nullptr) != nullptr) GTEST_SKIP() << "GDAL_CACHEMAX is set";
  const fs::path tif = dir_ / "cache.tif";
  write_geotiff(tif, kW, kH, terrain(kW, kH), GDT_Float32, kUtm, 32619);
  const GIntBig before = GDALGetCacheMax64();
  {
    const auto src = tb::open_dem_source(tif.string());
    EXPECT_LE(GDALGetCacheMax64(), GIntBig(64) << 20);
  }
  EXPECT_EQ(GDALGetCacheMax64(), before);
}

// A GeoPackage with two elevation tables (NetCDF files with several variables and HDF5 files are
// alike): the file itself has no band, and the error names the rasters in it by the names GDAL
// opens them by; such a name is read like a file. The name was refused as "no such file", and
// the file as having "0 bands".
TEST_F(DemSourceTest, RastersInsideAFileAreNamedAndReadByTheirNames) {
  const fs::path tif = dir_ / "utm.tif", gpkg = dir_ / "two.gpkg";
  write_geotiff(tif, kW, kH, terrain(kW, kH), GDT_Float32, kUtm, 32619);
  GDALDatasetUniquePtr src(GDALDataset::Open(tif.c_str(), GDAL_OF_RASTER));
  ASSERT_TRUE(src);
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (driver == nullptr) GTEST_SKIP() << "GDAL has no GeoPackage driver";
  for (const char* table : {"first", "second"}) {
    const std::string name = std::string("RASTER_TABLE=") + table;
    const char* options[] = {name.c_str(), "TILE_FORMAT=TIFF", "APPEND_SUBDATASET=YES", nullptr};
    GDALDatasetUniquePtr out(
        driver->CreateCopy(gpkg.c_str(), src.get(), FALSE, const_cast<char**>(options), nullptr, nullptr));
    ASSERT_TRUE(out) << CPLGetLastErrorMsg();
  }
  const std::string second = "GPKG:" + gpkg.string() + ":second";
  try {
    tb::open_dem_source(gpkg.string());
    ADD_FAILURE() << "a file of two rasters was read as one";
  } catch (const tb::DemError& e) {
    EXPECT_NE(e.problem().find("holds 2 rasters"), std::string::npos) << e.what();
    EXPECT_NE(e.problem().find("'" + second + "'"), std::string::npos) << e.what();
  }
  tb::DemOptions holes;
  holes.fill_voids = false;
  for (const tb::DemOptions& o : {tb::DemOptions{}, holes}) {
    const Heightfield from_tif = tb::read_dem(tif.string(), o), from_table = tb::read_dem(second, o);
    EXPECT_TRUE(same_block(from_table, from_tif, /*metadata=*/false));
    expect_like_read_dem(second, o, false);
  }
  EXPECT_THROW(tb::read_dem("GPKG:" + gpkg.string() + ":third"), tb::DemError);
}

TEST_F(DemSourceTest, FileRemovedOrTruncatedAfterOpeningIsAnError) {
  const fs::path hgt = dir_ / "N10E010.hgt", tif = dir_ / "gone.tif";
  write_hgt(hgt, std::vector<double>(101 * 101, 5.0));
  write_geotiff(tif, kW, kH, terrain(kW, kH), GDT_Float32, kUtm, 32619);
  const auto h = tb::open_dem_source(hgt.string()), g = tb::open_dem_source(tif.string());
  fs::resize_file(hgt, 101 * 50 * 2);
  fs::remove(tif);
  auto expect_error = [](const tb::DemSource& s, const fs::path& p) {
    try {
      s.read({0, 90, 5, 99});
      ADD_FAILURE() << "no error for " << p;
    } catch (const tb::DemError& e) {
      EXPECT_EQ(e.path(), p.string());
      EXPECT_FALSE(e.problem().empty());
    }
  };
  expect_error(*h, hgt);
  expect_error(*g, tif);
  fs::remove(hgt);
  expect_error(*h, hgt);
}

}  // namespace
