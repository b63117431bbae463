// The out-of-core build (issue 17): a DEM with four times the samples of another builds with a
// peak resident set within 1.25x of the smaller one's. Both builds run in this process, one after
// the other; before each, the kernel's peak counter (VmHWM) is reset to the current resident set
// by writing 5 to /proc/self/clear_refs, so each peak is that build's own. The DEMs are tiled
// GeoTIFFs read window by window (open_dem_source); a reader that held the whole raster would
// need 32 MiB of doubles for the small one and 128 MiB for the large one and fails the bound.
// HeightmapImagesAreNotHeldWhole does the same for a PNG heightmap's windows.
// Then each database's shading texture (what `terralod texture shade --shadows` computes) is
// written as an image pyramid window by window (terrain_windows.hpp), and its growth over the
// resident set is measured the same way, after one unmeasured run (the first one maps about
// 100 MiB of libraries and thread arenas once): held whole, the terrain (8 bytes a sample), its
// shade (4) and the RGBA texture (4) grew by 64 MiB for the small database and 256 MiB for the
// large one.
// GDAL's block cache is a constant (64 MiB by default while a windowed source is open) that the
// small DEM's 16 MiB of floats never fill; the test caps it at 8 MiB (GDAL_CACHEMAX) so that both
// builds fill it and the comparison sees what grows with the DEM.
// The fractals are terraced in 16 m steps (height_quantum): a flat terrace's rings are not
// measured (the PM builder's flat_box), so the builds take 0.64x the time (52 s instead of 82 s
// for both, alone on this 2-core machine; 0.67x for PeakGrowsByLittle) and the CI run is shorter,
// while every block is still read, built, written and summarised as on any terrain.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <malloc.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "gdal_warp.hpp"  // blocks/src: the exporters' warp
#include "geographic_tiff.hpp"
#include "peak_memory.hpp"
#include "run_command.hpp"
#include "terralod/blocks/database_extract.hpp"
#include "terralod/blocks/database_terrain.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/dem_writer.hpp"
#include "terralod/blocks/geo_grid.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/render/terrain_windows.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace tr = terralod::render;

using terralod::test::current_resident;
using terralod::test::peak_resident;
using terralod::test::reset_peak;

TEST(BuildMemory, FourTimesTheSamplesWithinAQuarterMoreMemory) {
  ASSERT_EQ(setenv("GDAL_CACHEMAX", "8", 1), 0);
  const terralod::test::TempDir dir("build-memory");
  auto peak_of_build = [&](int size) {
    const std::string dem = (dir.path() / ("fractal" + std::to_string(size) + ".tif")).string();
    tb::write_fractal_dem(
        pm::FractalField({.width = size, .height = size, .seed = 5, .height_quantum = 16.0}), dem, 2);
    tb::DatabaseBuildOptions opt;
    opt.threads = 2;
    reset_peak();
    const std::uint64_t before = peak_resident();
    {
      const std::unique_ptr<tb::DemSource> src = tb::open_dem_source(dem);
      EXPECT_FALSE(src->in_memory()) << dem << " should be read window by window";
      const tb::DatabaseSummary s =
          tb::build_database(*src, (dir.path() / (std::to_string(size) + ".db")).string(), opt);
      EXPECT_TRUE(s.complete);
      EXPECT_EQ(s.samples, std::uint64_t(size) * std::uint64_t(size));
    }
    const std::uint64_t peak = peak_resident();
    std::printf("%d x %d samples: resident %.1f MiB before the build, peak %.1f MiB\n", size, size,
                double(before) / 1048576.0, double(peak) / 1048576.0);
    return peak;
  };
  const std::uint64_t small = peak_of_build(2049);
  const std::uint64_t large = peak_of_build(4097);
  EXPECT_LE(double(large), 1.25 * double(small))
      << "4x the samples took " << double(large) / double(small) << "x the peak resident set";

  // The shading texture of each database, window by window, through a 16 MiB block cache.
  auto growth_of_shading = [&](int size) {
    malloc_trim(0);
    reset_peak();
    const std::uint64_t before = current_resident();
    {
      const auto db = tb::BlockDatabase::open((dir.path() / (std::to_string(size) + ".db")).string());
      tb::DatabaseTerrain terrain(db, {.cache_bytes = std::size_t(16) << 20, .threads = 2});
      const tr::TerrainWindows t = tr::terrain_windows(terrain);
      tr::ShadingOptions o;
      o.shadows = true;
      o.threads = 2;
      const std::string pyramid = (dir.path() / (std::to_string(size) + ".tx")).string();
      const auto band = [&](int y, int n) {
        return tr::grey_to_rgba(tr::shade_terrain(t, o, {0, y, -1, n, 1}));
      };
      tr::convert_by_bands(t, band, pyramid, {});
      EXPECT_EQ(tr::ImagePyramid(pyramid).level(0), (tr::LevelSize{size, size}));
    }
    const std::uint64_t growth = peak_resident() - before;
    std::printf("%d x %d samples: the shading texture's pyramid grew the resident set by %.1f MiB\n", size,
                size, double(growth) / 1048576.0);
    return growth;
  };
  growth_of_shading(2049);  // the first run's one-time costs
  const std::uint64_t small_shade = growth_of_shading(2049), large_shade = growth_of_shading(4097);
  // 12.6 M more samples: 16 bytes each (192 MiB) if anything held them whole.
  EXPECT_LE(double(large_shade), double(small_shade) + 24.0 * 1048576.0)
      << "4x the samples grew the shading's resident set by "
      << (double(large_shade) - double(small_shade)) / 1048576.0 << " MiB more";
}

// A 16-bit PNG heightmap (the usual game and tool export) with four times the pixels of another:
// opening it and reading every block's window peaks within 1.25x. The image is decoded once into
// a temporary file and read back window by window; held whole as doubles it took 32 MiB for the
// small one and 128 MiB for the large one.
TEST(BuildMemory, HeightmapImagesAreNotHeldWhole) {
  const terralod::test::TempDir dir("heightmap-memory");
  auto peak_of_reads = [&](int size) {
    const std::string png = (dir.path() / ("fractal" + std::to_string(size) + ".png")).string();
    {
      std::vector<std::uint16_t> px(std::size_t(size) * std::size_t(size));
      for (int r = 0; r < size; ++r)
        for (int c = 0; c < size; ++c)
          px[std::size_t(r) * std::size_t(size) + std::size_t(c)] = std::uint16_t(
              20000.0 + 3000.0 * std::sin(c * 0.013) * std::cos(r * 0.011) + (c * 7 + r * 13) % 50);
      auto out = OIIO::ImageOutput::create(png);
      EXPECT_TRUE(out && out->open(png, OIIO::ImageSpec(size, size, 1, OIIO::TypeDesc::UINT16))) << png;
      EXPECT_TRUE(out->write_image(OIIO::TypeDesc::UINT16, px.data()) && out->close()) << out->geterror();
    }
    reset_peak();
    const std::uint64_t before = peak_resident();
    double sum = 0.0;
    {
      const std::unique_ptr<tb::DemSource> src = tb::open_dem_source(png);
      EXPECT_FALSE(src->in_memory()) << png << " should be read window by window";
      const tb::BlockLayout layout = tb::partition(size, size, 257);
      for (const tb::BlockKey& k : layout.keys()) sum += src->read(layout.rect(k)).at(0, 0);
    }
    EXPECT_GT(sum, 0.0);
    const std::uint64_t peak = peak_resident();
    std::printf("%d x %d PNG: resident %.1f MiB before opening it, peak %.1f MiB\n", size, size,
                double(before) / 1048576.0, double(peak) / 1048576.0);
    return peak;
  };
  const std::uint64_t small = peak_of_reads(2049);
  const std::uint64_t large = peak_of_reads(4097);
  EXPECT_LE(double(large), 1.25 * double(small))
      << "4x the pixels took " << double(large) / double(small) << "x the peak resident set";
}

// Memory that grows with the number of blocks, with the samples fixed: one 2049^2 DEM built by
// `terralod build` in blocks of 129 (256 blocks) and of 33 (4,096 blocks), each in its own
// process, whose peak resident set is the one it reports ('memory peak resident', the kernel's
// VmHWM). Per block the build keeps the size of its summary record (4 bytes), its base error (8
// bytes) and its share of the tree (a grid node per three blocks, its encoding and the copy
// summarize_database decodes: about 1 kB in all); the stand-in records go through the database
// into the block_summaries blob. A build that held every block's summary until the end (for
// these 64-point TIN stand-ins the summary, its encoding, the joined blob and the copy read back:
// 8.4 kB a block) grew by 32 MB here; the bound is 3 kB a block (11.5 MB).
TEST(BuildMemory, PeakGrowsByLittleWithTheNumberOfBlocks) {
#ifndef TERRALOD_BINARY
  GTEST_SKIP() << "needs the terralod command-line tool";
#else
  ASSERT_EQ(setenv("GDAL_CACHEMAX", "8", 1), 0);  // the builds inherit it: both fill the cache
  const terralod::test::TempDir dir("build-memory-blocks");
  const std::string dem = (dir.path() / "fractal2049.tif").string();
  tb::write_fractal_dem(pm::FractalField({.width = 2049, .height = 2049, .seed = 6, .height_quantum = 16.0}),
                        dem, 2);
  auto peak_of_build = [&](int block_size) -> double {
    const std::string db = (dir.path() / (std::to_string(block_size) + ".db")).string();
    const terralod::test::CommandResult r = terralod::test::run_tool(
        TERRALOD_BINARY, "build --input '" + dem + "' --out '" + db + "' --threads 2 --block-size " +
                             std::to_string(block_size));
    EXPECT_EQ(r.status, 0) << r.out << r.err;
    const std::size_t at = r.out.find("memory peak resident ");
    if (at == std::string::npos) {
      ADD_FAILURE() << "no 'memory peak resident' line in:\n" << r.out;
      return 0;
    }
    double v = 0;
    char unit[8] = "";
    EXPECT_EQ(std::sscanf(r.out.c_str() + at, "memory peak resident %lf %7s", &v, unit), 2);
    const double bytes = v * (std::string(unit) == "GB" ? 1e9 : std::string(unit) == "MB" ? 1e6 : 1e3);
    std::printf("blocks of %d: peak %.1f MB\n", block_size, bytes / 1e6);
    return bytes;
  };
  const double few = peak_of_build(129);
  const double many = peak_of_build(33);
  const double per_block = (many - few) / double(4096 - 256);
  std::printf("%.2f kB more a block\n", per_block / 1e3);
  EXPECT_LE(per_block, 3000.0) << "the peak grew by " << per_block << " bytes a block";
#endif
}

// The exporters' longitude/latitude grid (geo_grid.hpp: make_geo_grid, from a DatabaseTerrain as
// the export makes it) holds 4 bytes a sample (floats; 5 with holes) and nothing else that grows
// with the terrain's rows: the database is read a row of blocks at a time (a window of up to 16
// blocks, decoded, and its doubles: costs that follow the width, bounded), and the geoid
// undulations are computed in bands of rows. Two geographic DEMs of one width (EGM96 heights, so
// every sample is converted), 2049 x 257 and 2049 x 1281 samples, are built, then read back and
// made into grids one after the other in this process (2.1 M samples apart: the resident set's
// noise, a few MB from PROJ's grids and malloc's arenas, hid the 4 bytes a sample of 1025 x 513
// against 1025 x 1025). Before each, freed memory is returned to
// the system (malloc_trim) and VmHWM reset, so each grid's growth over the resident set is its
// own. Copying the samples into the grid and holding the whole grid's coordinates and
// undulations for PROJ (before) took 55 bytes a sample more for the larger one; the database
// read whole into doubles that moved into the grid, about 9.
TEST(ExportMemory, GeoGridHoldsAboutFourBytesASample) {
  const terralod::test::TempDir dir("export-memory");
  constexpr int kWidth = 2049, kFew = 257, kMany = 1281;
  const pm::FractalField field({.width = kWidth, .height = kMany, .seed = 8, .height_quantum = 16.0});
  auto db_of = [&](int rows) {
    const std::string tif = (dir.path() / ("geo" + std::to_string(rows) + ".tif")).string();
    const std::string db = (dir.path() / ("geo" + std::to_string(rows) + ".db")).string();
    constexpr double kStep = 1.0 / 1200;  // SRTM's 3 arc-seconds, near 46 N
    terralod::test::write_tiff(tif, 4326, 10.0, 46.5, kWidth, rows, kStep, GDT_Float32,
                               [&](double x, double y) {
                                 return field.at(std::int64_t(std::lround((x - 10.0) / kStep)),
                                                 std::int64_t(std::lround((46.5 - y) / kStep)));
                               });
    tb::DatabaseBuildOptions opt;
    opt.threads = 2;
    tb::build_database(*tb::open_dem_source(tif), db, opt);
    return db;
  };
  const std::string small_db = db_of(kFew), large_db = db_of(kMany);
  auto growth_of_grid = [&](const std::string& db, int rows) -> double {
    const tb::BlockDatabase handle = tb::BlockDatabase::open(db, tb::BlockDatabase::Mode::ReadOnly);
    malloc_trim(0);
    reset_peak();
    const std::uint64_t before = peak_resident();
    {
      tb::DatabaseTerrain terrain(handle, {.cache_bytes = 0, .threads = 1});
      const tb::GeoGrid g = tb::make_geo_grid(terrain, "", db);
      EXPECT_TRUE(g.heights_converted) << "EGM96 heights are converted to the ellipsoid";
      EXPECT_EQ(g.heights.size(), std::size_t(kWidth) * std::size_t(rows)) << "the DEM's own samples";
    }
    const std::uint64_t peak = peak_resident();
    std::printf("%d x %d samples: resident %.1f MiB before, peak %.1f MiB\n", kWidth, rows,
                double(before) / 1048576.0, double(peak) / 1048576.0);
    return double(peak) - double(before);
  };
  const double small = growth_of_grid(small_db, kFew), large = growth_of_grid(large_db, kMany);
  const double per_sample = (large - small) / (double(kWidth) * double(kMany - kFew));
  std::printf("%.1f bytes a sample more\n", per_sample);
  EXPECT_LE(per_sample, 6.0) << "the grid's peak grew by " << per_sample << " bytes a sample";
}

// A terrain in a projected frame (what `terralod build` makes by default) reaches the exporters
// through a warp to longitude/latitude (gdal_warp.hpp) that reads its source window by window:
// a 4097 x 2049 grid in UTM zone 32N (30 m spacing), computed by its reader, is warped and the
// process grows by the warped grid (4 bytes a sample, floats) and GDAL's chunks (8 MiB each, two at
// once, and its threads' buffers: 14 to 37 MiB in all here, as the process's arenas were warm
// or not), not by the source. The source held whole, as the exporters' warp did before, adds its
// 64 MiB (and a copy of the output another 50 MiB); the bound leaves 48 MiB for the chunks. The
// reader is never asked for more than a quarter of the source at once, and every row is read.
// Every warped sample is the one a warp in a single chunk gives: GDAL widens the bilinear kernel
// of a chunk whose source window is larger than its output, and took each chunk's own ratio, so
// corner chunks (where the UTM rectangle fills little of the longitude/latitude box) came out
// smoothed otherwise (by up to 2.7 m on a 3690 x 3613 terrain) and the grid depended on the chunks.
TEST(ExportMemory, AWarpReadsItsSourceWindowByWindow) {
  constexpr int kW = 4097, kH = 2049;
  constexpr double kStep = 30.0;
  std::size_t largest = 0;
  std::vector<std::uint8_t> row_read(kH, 0);
  tb::detail::WarpSource src;
  src.width = kW;
  src.height = kH;
  src.gt = {440000.0, kStep, 0.0, 5200000.0, 0.0, -kStep};
  src.read = [&](int col0, int row0, int cols, int rows, double* out) {
    largest = std::max(largest, std::size_t(cols) * std::size_t(rows));
    for (int r = 0; r < rows; ++r) {
      row_read[std::size_t(row0 + r)] = 1;
      for (int c = 0; c < cols; ++c)
        *out++ = 1000.0 + 300.0 * std::sin((col0 + c) * 0.01) * std::cos((row0 + r) * 0.013);
    }
  };
  const std::string src_wkt = terralod::test::epsg_wkt(32632),
                    dst_wkt = terralod::test::epsg_wkt(4326);  // UTM 32N to lon/lat
  malloc_trim(0);
  reset_peak();
  const std::uint64_t before = peak_resident();
  std::string error;
  const tb::detail::WarpGrid w = tb::detail::warp_grid(src, src_wkt, dst_wkt, error);
  const std::uint64_t growth = peak_resident() - before;
  ASSERT_TRUE(error.empty()) << error;
  const double grid_bytes = double(w.z.size()) * sizeof(w.z[0]);
  std::printf(
      "warped %d x %d -> %d x %d: grew by %.1f MiB (the warped grid %.1f MiB), largest read %.1f %% "
      "of the source\n",
      kW, kH, w.width, w.height, double(growth) / 1048576.0, grid_bytes / 1048576.0,
      100.0 * double(largest) / (double(kW) * kH));
  EXPECT_LE(double(growth), grid_bytes + 48.0 * 1048576.0);
  EXPECT_LE(largest, std::size_t(kW) * kH / 4);
  EXPECT_EQ(std::count(row_read.begin(), row_read.end(), 0), 0) << "rows the warp never read";
  std::size_t valid = 0;
  for (double z : w.z) valid += std::isfinite(z) ? 1 : 0;
  EXPECT_GT(valid, w.z.size() * 8 / 10) << "a UTM rectangle covers most of its longitude/latitude box";

  // The same warp in one chunk of 1 GiB, after the measurement: the same samples, bit for bit.
  src.chunk_mib = 1024;
  const tb::detail::WarpGrid one = tb::detail::warp_grid(src, src_wkt, dst_wkt, error);
  ASSERT_TRUE(error.empty()) << error;
  ASSERT_EQ(one.z.size(), w.z.size());
  std::size_t differ = 0;
  for (std::size_t i = 0; i < w.z.size(); ++i)
    differ += !(w.z[i] == one.z[i] || (std::isnan(w.z[i]) && std::isnan(one.z[i])));
  EXPECT_EQ(differ, 0u) << "samples that depend on the chunks";
}

// A reader that fails (a corrupt block of the database, a file gone) stops the warp, and its
// exception comes out of warp_grid as it was thrown (export_terrain's callers see the
// DatabaseError naming the file, not a GDAL "read error" that says nothing of it).
TEST(WarpSource, AReaderThatFailsStopsTheWarpWithItsException) {
  tb::detail::WarpSource src;
  src.width = 300;
  src.height = 200;
  src.gt = {440000.0, 30.0, 0.0, 5200000.0, 0.0, -30.0};
  int calls = 0;
  src.read = [&](int, int, int, int, double*) {
    ++calls;
    throw std::out_of_range("terrain.db: block (0, 0) is corrupt");
  };
  const std::string src_wkt = terralod::test::epsg_wkt(32632),
                    dst_wkt = terralod::test::epsg_wkt(4326);  // UTM 32N to lon/lat
  std::string error;
  try {
    (void)tb::detail::warp_grid(src, src_wkt, dst_wkt, error);
    ADD_FAILURE() << "no exception; error: " << error;
  } catch (const std::out_of_range& e) {
    EXPECT_STREQ(e.what(), "terrain.db: block (0, 0) is corrupt");
  }
  EXPECT_EQ(calls, 1) << "a failed reader is not asked again";
}
