// terralod texture add of a georeferenced image: an orthophoto in longitude/latitude over part of
// a UTM terrain is warped into the terrain's frame and placed where it lies, checked texel by
// texel against the image's own georeference through OGR/PROJ (an independent path); a plain
// image still covers the terrain; an image beside the terrain is refused naming it.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "cli_utm_database.hpp"
#include "run_command.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/render/texture_store.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;
using namespace terralod::render;
using terralod::test::quote;

const terralod::test::CliRunner cli{TERRALOD_CLI};

// The test terrain: UTM 33N, 65 x 65 samples of 30 m from (500000, 5000000): sample centres
// 500015..501935 east, 5000015..5001935 north.
constexpr double kEast0 = 500000.0, kNorth0 = 5000000.0, kSide = 65 * 30.0;

struct Deleter {
  void operator()(OGRCoordinateTransformation* t) const { OGRCoordinateTransformation::DestroyCT(t); }
};
using Transform = std::unique_ptr<OGRCoordinateTransformation, Deleter>;

Transform transform(int from, int to) {
  OGRSpatialReference a, b;
  a.importFromEPSG(from);
  b.importFromEPSG(to);
  a.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  b.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return Transform(OGRCreateCoordinateTransformation(&a, &b));
}

/// Places `ds` on (west..east, south..north) degrees by four ground control points at its corners
/// and no geotransform, as a scanned map placed by hand is.
void place_by_corners(GDALDataset& ds, double west, double south, double east, double north) {
  const int w = ds.GetRasterXSize(), h = ds.GetRasterYSize();
  OGRSpatialReference wgs84;
  wgs84.importFromEPSG(4326);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::vector<GDAL_GCP> g(4);
  GDALInitGCPs(4, g.data());
  for (int k = 0; k < 4; ++k) {
    g[k].dfGCPPixel = (k & 1) ? w : 0, g[k].dfGCPLine = (k & 2) ? h : 0;
    g[k].dfGCPX = (k & 1) ? east : west, g[k].dfGCPY = (k & 2) ? south : north;
  }
  ASSERT_EQ(ds.SetGCPs(4, g.data(), &wgs84), CE_None);
  GDALDeinitGCPs(4, g.data());
}

/// An RGB GeoTIFF in longitude/latitude: red west of `split`, blue east of it; with 4 bands the
/// fourth (near infrared, not alpha) is 255 west of the split and 0 east of it; with 5 the fifth
/// is 128 west of it and 255 east.
/// With `gcps`, the georeference is four ground control points at the corners instead of a
/// geotransform (as a scanned map placed by hand has it).
void write_ortho(const fs::path& path, double west, double south, double east, double north, double split,
                 int bands = 3, bool gcps = false) {
  constexpr int w = 120, h = 90;
  GDALAllRegister();
  GDALDatasetUniquePtr ds(
      GetGDALDriverManager()->GetDriverByName("GTiff")->Create(path.c_str(), w, h, bands, GDT_Byte, nullptr));
  ASSERT_TRUE(ds);
  double gt[6] = {west, (east - west) / w, 0, north, 0, -(north - south) / h};
  OGRSpatialReference wgs84;
  wgs84.importFromEPSG(4326);
  if (gcps) {
    place_by_corners(*ds, west, south, east, north);
  } else {
    ds->SetGeoTransform(gt);
    ds->SetSpatialRef(&wgs84);
  }
  for (int b = 1; b <= bands; ++b) {
    std::vector<std::uint8_t> v(std::size_t(w) * h);
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c) {
        const bool red = west + (c + 0.5) * gt[1] < split;
        v[std::size_t(r) * w + c] = std::uint8_t(b == 5             ? (red ? 128 : 255)
                                                 : b == 1 || b == 4 ? (red ? 255 : 0)
                                                 : b == 3           ? (red ? 0 : 255)
                                                                    : 0);
      }
    ASSERT_EQ(ds->GetRasterBand(b)->RasterIO(GF_Write, 0, 0, w, h, v.data(), w, h, GDT_Byte, 0, 0), CE_None);
  }
}

/// write_ortho's RGB ortho (bands = 3) in a deeper `type`: `lo` where write_ortho has 0 and `hi`
/// where it has 255 (green is (lo + hi) / 2 everywhere), and its first `void_rows` rows nodata
/// (`nodata` in every band).
void write_deep_ortho(const fs::path& path, GDALDataType type, double lo, double hi, double nodata,
                      int void_rows, double west, double south, double east, double north, double split) {
  constexpr int w = 120, h = 90;
  GDALAllRegister();
  GDALDatasetUniquePtr ds(
      GetGDALDriverManager()->GetDriverByName("GTiff")->Create(path.c_str(), w, h, 3, type, nullptr));
  ASSERT_TRUE(ds);
  double gt[6] = {west, (east - west) / w, 0, north, 0, -(north - south) / h};
  OGRSpatialReference wgs84;
  wgs84.importFromEPSG(4326);
  ds->SetGeoTransform(gt);
  ds->SetSpatialRef(&wgs84);
  for (int b = 1; b <= 3; ++b) {
    ASSERT_EQ(ds->GetRasterBand(b)->SetNoDataValue(nodata), CE_None);
    std::vector<double> v(std::size_t(w) * h);
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c) {
        const bool red = west + (c + 0.5) * gt[1] < split;
        v[std::size_t(r) * w + c] = r < void_rows     ? nodata
                                    : b == 2          ? 0.5 * (lo + hi)
                                    : (b == 1) == red ? hi
                                                      : lo;
      }
    ASSERT_EQ(ds->GetRasterBand(b)->RasterIO(GF_Write, 0, 0, w, h, v.data(), w, h, GDT_Float64, 0, 0),
              CE_None);
  }
}

TEST(TextureGeoref, AnOrthophotoInLonLatLiesWhereItsGeoreferenceSays) {
  terralod::test::TempDir dir("texture-georef");
  const fs::path d = dir.path();
  terralod::test::build_utm_cli_database(cli, d);
  if (HasFatalFailure()) return;
  const std::string db = quote((d / "t.db").string());

  // The ortho covers the terrain's north-east part and beyond: its south-west corner is the
  // terrain's centre, its north-east corner 1 km past the terrain's.
  const Transform to_lonlat = transform(32633, 4326), to_utm = transform(4326, 32633);
  double x[2] = {kEast0 + kSide / 2, kEast0 + kSide + 1000},
         y[2] = {kNorth0 + kSide / 2, kNorth0 + kSide + 1000};
  ASSERT_TRUE(to_lonlat->Transform(2, x, y));
  const double west = x[0], south = y[0], east = x[1], north = y[1];
  const double split = 0.5 * (west + east);
  write_ortho(d / "ortho.tif", west, south, east, north, split);
  std::string text;
  ASSERT_EQ(
      cli.run("texture add " + db + " --layer ortho --image " + quote((d / "ortho.tif").string()), &text), 0);
  EXPECT_NE(text.find("warp "), std::string::npos) << text;

  const tb::BlockDatabase opened = tb::BlockDatabase::open((d / "t.db").string());
  const LayerRecord rec = read_layer_record(opened, "ortho");
  const RgbaImage img = read_layer_level(opened, rec, 0);
  // Placed over the terrain's part of the ortho: from about the terrain's centre (the ortho's
  // south-west corner; its west and south edges bow by well under a texel over 1 km) to the
  // terrain's north-east corner.
  const double texel = rec.georef.width() / img.width;
  EXPECT_NEAR(rec.georef.minx, kEast0 + kSide / 2, 2 * texel);
  EXPECT_NEAR(rec.georef.miny, kNorth0 + kSide / 2, 2 * texel);
  EXPECT_NEAR(rec.georef.maxx, kEast0 + kSide, 1e-6);
  EXPECT_NEAR(rec.georef.maxy, kNorth0 + kSide, 1e-6);
  // Every texel: red west of the split, blue east of it, transparent outside the ortho; texels
  // within 1.5 texels of an edge are not judged (bilinear blends them).
  int judged = 0, wrong = 0;
  const double lon_texel = 1.5 * texel / (111320.0 * std::cos(south * M_PI / 180.0));
  const double lat_texel = 1.5 * texel / 110574.0;
  for (int r = 0; r < img.height; ++r)
    for (int c = 0; c < img.width; ++c) {
      double px = rec.georef.minx + (c + 0.5) * rec.georef.width() / img.width;
      double py = rec.georef.maxy - (r + 0.5) * rec.georef.height() / img.height;
      ASSERT_TRUE(to_lonlat->Transform(1, &px, &py));
      const bool inside =
          px > west + lon_texel && px < east - lon_texel && py > south + lat_texel && py < north - lat_texel;
      const bool outside = px < west - lon_texel || py < south - lat_texel;
      if (!inside && !outside) continue;
      if (inside && std::abs(px - split) < lon_texel) continue;
      const auto v = img.get(c, r);
      const bool ok =
          outside ? v[3] == 0
                  : v[3] == 255 && (px < split ? (v[0] == 255 && v[2] == 0) : (v[0] == 0 && v[2] == 255));
      ++judged;
      if (!ok && ++wrong <= 5)
        ADD_FAILURE() << "texel " << c << ", " << r << " at lon " << px << ", lat " << py << ": rgba "
                      << int(v[0]) << " " << int(v[1]) << " " << int(v[2]) << " " << int(v[3]);
    }
  EXPECT_GT(judged, img.width * img.height / 2);
  EXPECT_EQ(wrong, 0);

  // The same ortho with a near-infrared fourth band: it is not taken as alpha (that would make
  // the blue half transparent), the layer is the same.
  write_ortho(d / "rgbi.tif", west, south, east, north, split, 4);
  ASSERT_EQ(cli.run("texture add " + db + " --layer rgbi --image " + quote((d / "rgbi.tif").string())), 0);
  const LayerRecord rgbi = read_layer_record(tb::BlockDatabase::open((d / "t.db").string()), "rgbi");
  EXPECT_EQ(rgbi.georef, rec.georef);
  EXPECT_EQ(read_layer_level(tb::BlockDatabase::open((d / "t.db").string()), rgbi, 0), img);

  // RGB, near infrared and an alpha band marked so, fifth: the alpha is that band (the red half
  // translucent), wherever it stands; the colour stays the first three.
  write_ortho(d / "rgbia.tif", west, south, east, north, split, 5);
  {
    GDALDatasetUniquePtr ds(GDALDataset::Open((d / "rgbia.tif").c_str(), GDAL_OF_RASTER | GDAL_OF_UPDATE));
    ASSERT_TRUE(ds);
    ASSERT_EQ(ds->GetRasterBand(5)->SetColorInterpretation(GCI_AlphaBand), CE_None);
  }
  ASSERT_EQ(cli.run("texture add " + db + " --layer rgbia --image " + quote((d / "rgbia.tif").string())), 0);
  const LayerRecord rgbia = read_layer_record(tb::BlockDatabase::open((d / "t.db").string()), "rgbia");
  EXPECT_EQ(rgbia.georef, rec.georef);
  const RgbaImage with_alpha = read_layer_level(tb::BlockDatabase::open((d / "t.db").string()), rgbia, 0);
  ASSERT_EQ(with_alpha.width, img.width);
  ASSERT_EQ(with_alpha.height, img.height);
  int red = 0, misread = 0;
  for (int r = 0; r < img.height; ++r)
    for (int c = 0; c < img.width; ++c) {
      const auto a = img.get(c, r), b = with_alpha.get(c, r);
      if (a != std::array<std::uint8_t, 4>{255, 0, 0, 255}) continue;
      ++red;
      misread += b[0] != 255 || b[1] != 0 || b[2] != 0 || std::abs(int(b[3]) - 128) > 1;
    }
  EXPECT_GT(red, img.width * img.height / 8);
  EXPECT_EQ(misread, 0);

  // The same ortho placed by ground control points at its corners: it was taken for a plain image
  // and stretched over the whole terrain. It lies where the other does (read through a warp
  // north-up first, so resampled twice: texels may differ along the colour split and the edges).
  write_ortho(d / "gcps.tif", west, south, east, north, split, 3, /*gcps=*/true);
  ASSERT_EQ(cli.run("texture add " + db + " --layer gcps --image " + quote((d / "gcps.tif").string())), 0);
  const LayerRecord by_gcps = read_layer_record(tb::BlockDatabase::open((d / "t.db").string()), "gcps");
  EXPECT_NEAR(by_gcps.georef.minx, rec.georef.minx, 2 * texel);
  EXPECT_NEAR(by_gcps.georef.miny, rec.georef.miny, 2 * texel);
  EXPECT_NEAR(by_gcps.georef.maxx, rec.georef.maxx, 2 * texel);
  EXPECT_NEAR(by_gcps.georef.maxy, rec.georef.maxy, 2 * texel);
  const RgbaImage gcp_img = read_layer_level(tb::BlockDatabase::open((d / "t.db").string()), by_gcps, 0);
  int differ = 0;
  for (int r = 0; r < std::min(img.height, gcp_img.height); ++r)
    for (int c = 0; c < std::min(img.width, gcp_img.width); ++c) {
      const auto a = img.get(c, r), b = gcp_img.get(c, r);
      differ += std::abs(int(a[0]) - int(b[0])) > 64 || std::abs(int(a[2]) - int(b[2])) > 64 ||
                std::abs(int(a[3]) - int(b[3])) > 64;
    }
  EXPECT_LT(differ, img.width * img.height / 20) << "of " << img.width * img.height << " texels";

  // A colour-indexed scan placed by ground control points (a scanned map with a palette): GDAL's
  // warp north-up keeps no colour table, so it would come out as grey indices; it is refused,
  // naming the file and what to do.
  {
    const fs::path indexed = d / "indexed.tif";
    constexpr int w = 120, h = 90;
    GDALDatasetUniquePtr ds(GetGDALDriverManager()->GetDriverByName("GTiff")->Create(indexed.c_str(), w, h, 1,
                                                                                     GDT_Byte, nullptr));
    ASSERT_TRUE(ds);
    GDALColorTable table;
    const GDALColorEntry none{0, 0, 0, 255}, red{255, 0, 0, 255}, green{0, 255, 0, 255}, blue{0, 0, 255, 255};
    for (const auto& [i, e] : {std::pair{0, none}, {1, red}, {2, green}, {3, blue}})
      table.SetColorEntry(i, &e);
    GDALRasterBand* band = ds->GetRasterBand(1);
    band->SetColorInterpretation(GCI_PaletteIndex);
    ASSERT_EQ(band->SetColorTable(&table), CE_None);
    std::vector<std::uint8_t> v(std::size_t(w) * h);
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c)
        v[std::size_t(r) * w + c] = west + (c + 0.5) * (east - west) / w < split ? 1 : 3;
    ASSERT_EQ(band->RasterIO(GF_Write, 0, 0, w, h, v.data(), w, h, GDT_Byte, 0, 0), CE_None);
    place_by_corners(*ds, west, south, east, north);
  }
  EXPECT_EQ(
      cli.run("texture add " + db + " --layer indexed --image " + quote((d / "indexed.tif").string()), &text),
      1);
  EXPECT_NE(
      text.find((d / "indexed.tif").string() + ": is a colour-indexed image placed by ground control points"),
      std::string::npos)
      << text;
  EXPECT_NE(text.find("gdal_translate -expand rgb"), std::string::npos) << text;

  // A plain image (no georeference) still covers the terrain, one texel per sample.
  write_layer_image(RgbaImage(65, 65), (d / "plain.png").string());
  ASSERT_EQ(cli.run("texture add " + db + " --layer plain --image " + quote((d / "plain.png").string())), 0);
  EXPECT_EQ(read_layer_record(tb::BlockDatabase::open((d / "t.db").string()), "plain").georef,
            grid_georef(opened.info().transform, 65, 65));

  // An ortho 10 km east of the terrain is refused, naming it; the database keeps its layers.
  double fx[2] = {kEast0 + 10000, kEast0 + 11000}, fy[2] = {kNorth0, kNorth0 + 1000};
  ASSERT_TRUE(to_lonlat->Transform(2, fx, fy));
  write_ortho(d / "far.tif", fx[0], fy[0], fx[1], fy[1], fx[0]);
  EXPECT_EQ(cli.run("texture add " + db + " --layer far --image " + quote((d / "far.tif").string()), &text),
            1);
  EXPECT_NE(text.find((d / "far.tif").string() + ": does not overlap the terrain"), std::string::npos)
      << text;
  EXPECT_EQ(stored_layers(tb::BlockDatabase::open((d / "t.db").string())).size(), 5u);
  EXPECT_FALSE(fs::exists(d / "t.db.texture-far.tx.warp.tif"));
}

TEST(TextureGeoref, DeepOrthophotosAreStretchedAndTheirNodataIsTransparent) {
  terralod::test::TempDir dir("texture-georef-deep");
  const fs::path d = dir.path();
  terralod::test::build_utm_cli_database(cli, d);
  if (HasFatalFailure()) return;
  const std::string db = quote((d / "t.db").string());
  const Transform to_lonlat = transform(32633, 4326);
  double x[2] = {kEast0 + kSide / 2, kEast0 + kSide + 1000},
         y[2] = {kNorth0 + kSide / 2, kNorth0 + kSide + 1000};
  ASSERT_TRUE(to_lonlat->Transform(2, x, y));
  const double west = x[0], south = y[0], east = x[1], north = y[1], split = 0.5 * (west + east);
  // The 8-bit ortho, and the same in 16 bits of 12-bit values (1000 and 3000) and in floating
  // point (0.1 and 0.3 reflectance): each band's 2 % cut spans its two values, so the bytes
  // warped are the 8-bit ortho's (green, one value, is 0 in both), and the layers are the same.
  write_ortho(d / "ortho.tif", west, south, east, north, split);
  write_deep_ortho(d / "u16.tif", GDT_UInt16, 1000, 3000, 0, 0, west, south, east, north, split);
  write_deep_ortho(d / "f32.tif", GDT_Float32, 0.1, 0.3, -9999, 0, west, south, east, north, split);
  std::string text;
  ASSERT_EQ(
      cli.run("texture add " + db + " --layer ortho --image " + quote((d / "ortho.tif").string()), &text), 0);
  EXPECT_EQ(text.find("stretch "), std::string::npos) << text;  // 8 bits: as they are
  ASSERT_EQ(cli.run("texture add " + db + " --layer u16 --image " + quote((d / "u16.tif").string()), &text),
            0);
  EXPECT_NE(text.find("stretch " + (d / "u16.tif").string() + " (2 % cut): R 1000..3000, G 2000.."),
            std::string::npos)
      << text;
  ASSERT_EQ(cli.run("texture add " + db + " --layer f32 --image " + quote((d / "f32.tif").string()), &text),
            0);
  const tb::BlockDatabase opened = tb::BlockDatabase::open((d / "t.db").string());
  const RgbaImage eight = read_layer_level(opened, read_layer_record(opened, "ortho"), 0);
  EXPECT_EQ(read_layer_level(opened, read_layer_record(opened, "u16"), 0), eight);
  EXPECT_EQ(read_layer_level(opened, read_layer_record(opened, "f32"), 0), eight);

  // Nodata in the northern two thirds of a 16-bit ortho (1,317 m of its 1,975, the northern
  // 317 m of its part over the terrain): no histogram counts it (else 0 would be its 2 % point
  // and the colours half as bright), and it is transparent, where the 8-bit ortho's texels are
  // opaque.
  write_deep_ortho(d / "void.tif", GDT_UInt16, 1000, 3000, 0, 60, west, south, east, north, split);
  ASSERT_EQ(cli.run("texture add " + db + " --layer void --image " + quote((d / "void.tif").string()), &text),
            0);
  EXPECT_NE(text.find("R 1000..3000"), std::string::npos) << text;
  const tb::BlockDatabase again = tb::BlockDatabase::open((d / "t.db").string());
  const RgbaImage holed = read_layer_level(again, read_layer_record(again, "void"), 0);
  ASSERT_EQ(holed.width, eight.width);
  ASSERT_EQ(holed.height, eight.height);
  int transparent = 0, same = 0, opaque = 0;
  for (int r = 0; r < eight.height; ++r)
    for (int c = 0; c < eight.width; ++c) {
      const auto a = eight.get(c, r), b = holed.get(c, r);
      if (a[3] != 255) continue;
      ++opaque;
      transparent += b[3] == 0;
      same += a == b;
    }
  // A third of the texels void, most of the rest as the 8-bit ortho's.
  EXPECT_GT(transparent, opaque / 5) << opaque;
  EXPECT_GT(same, opaque / 2) << opaque;
  EXPECT_GT(transparent + same, opaque * 9 / 10) << opaque;

  // --stretch: values given, and a bad form refused as a usage error naming the option.
  ASSERT_EQ(cli.run("texture add " + db + " --layer given --stretch 0,4000 --image " +
                        quote((d / "u16.tif").string()),
                    &text),
            0);
  EXPECT_NE(text.find("(values 0..4000): R 0..4000, G 0..4000, B 0..4000 -> 0..255"), std::string::npos)
      << text;
  const tb::BlockDatabase third = tb::BlockDatabase::open((d / "t.db").string());
  const RgbaImage given = read_layer_level(third, read_layer_record(third, "given"), 0);
  int red = 0;
  for (int r = 0; r < given.height; ++r)
    for (int c = 0; c < given.width; ++c)
      if (eight.get(c, r) == std::array<std::uint8_t, 4>{255, 0, 0, 255}) {
        ++red;
        EXPECT_EQ(given.get(c, r), (std::array<std::uint8_t, 4>{191, 128, 64, 255})) << c << ", " << r;
      }
  EXPECT_GT(red, 0);
  EXPECT_EQ(
      cli.run("texture add " + db + " --layer bad --stretch 98% --image " + quote((d / "u16.tif").string()),
              &text),
      2);
  EXPECT_NE(text.find("--stretch '98%'"), std::string::npos) << text;
}

}  // namespace
