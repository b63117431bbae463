// The DEM writers (blocks/dem_writer.hpp): every file is read back through read_dem and compared
// sample by sample with what it stands for.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

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
