// libFuzzer target for blocks::read_dem: arbitrary file contents under each supported extension
// must give either a sound Heightfield or a DemError naming the file.
//
// Input layout: byte 0 picks the case, the rest is the file's contents.
//   bits 0-1: extension  0 .hgt (named N10E020.hgt, so that the name is a valid tile)
//                        1 .asc   2 .png   3 .tif (GDAL, or OpenImageIO when not georeferenced)
//   bit 2:    1 = keep voids as holes (fill_voids = false), 0 = fill them
// The file is written to a private temporary folder and read with Format::Auto.
//
// A finding is anything but a DemError whose message starts with the path: a crash, a
// sanitizer report, another exception type (including std::bad_alloc: the readers must check
// sizes against the file before allocating), a non-finite height or transform, sizes that do
// not match, or a run past libFuzzer's -timeout.
//
// Bounded work: the GDAL and OpenImageIO decoders legitimately accept tiny files that declare
// huge rasters (sparse or compressed); those are skipped when the header declares more than
// 2^20 samples, before read_dem runs, by asking the same library for the size. The .hgt and
// .asc parsers are ours and get no such help.
#include <OpenImageIO/imageio.h>
#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal_priv.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "fuzz_support.hpp"
#include "terralod/blocks/dem_reader.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;

constexpr std::uint64_t kMaxForeignSamples = std::uint64_t(1) << 20;

[[noreturn]] void finding(const std::string& what) { terralod::fuzz::finding("fuzz_dem_reader", what); }
#define REQUIRE(cond)                                 \
  do {                                                \
    if (!(cond)) finding("invariant broken: " #cond); \
  } while (0)

fs::path scratch_dir;

/// Declared raster size of a file the foreign libraries decode; 0 when they cannot open it.
std::uint64_t declared_samples(const std::string& path, bool gdal) {
  std::uint64_t n = 0;
  if (gdal) {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    if (GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly)) {
      n = std::uint64_t(GDALGetRasterXSize(ds)) * std::uint64_t(GDALGetRasterYSize(ds));
      GDALClose(ds);
    }
    CPLPopErrorHandler();
  }
  // .tif files without georeferencing go to OpenImageIO too; ask it as well.
  if (auto in = OIIO::ImageInput::open(path)) {
    const OIIO::ImageSpec& s = in->spec();
    n = std::max<std::uint64_t>(n, std::uint64_t(std::max(s.width, 0)) *
                                       std::uint64_t(std::max(s.height, 0)) *
                                       std::uint64_t(std::max(s.depth, 1)));
  } else {
    (void)OIIO::geterror();  // clear the thread's error message
  }
  return n;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  char tmpl[] = "/tmp/fuzz_dem_reader.XXXXXX";
  if (const char* d = ::mkdtemp(tmpl))
    scratch_dir = d;
  else
    finding("cannot create a temporary folder");
  // Keep GDAL's block cache small, so that libFuzzer's RSS limit measures the reader.
  CPLSetConfigOption("GDAL_CACHEMAX", "32");
  GDALAllRegister();
  std::atexit([] {
    std::error_code ec;
    fs::remove_all(scratch_dir, ec);
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return -1;
  static constexpr const char* kNames[4] = {"N10E020.hgt", "grid.asc", "image.png", "raster.tif"};
  const int kind = data[0] & 3;
  const bool fill = (data[0] & 4) == 0;
  const std::string path = (scratch_dir / kNames[kind]).string();
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data + 1), std::streamsize(size - 1));
    if (!out) finding("cannot write " + path);
  }
  if ((kind == 2 || kind == 3) && declared_samples(path, kind == 3) > kMaxForeignSamples) return -1;

  tb::DemOptions options;
  options.fill_voids = fill;
  try {
    const terralod::pm::Heightfield hf = tb::read_dem(path, options);
    REQUIRE(hf.width() >= 2 && hf.height() >= 2);
    REQUIRE(hf.size() == std::size_t(hf.width()) * std::size_t(hf.height()));
    REQUIRE(hf.samples().size() == hf.size());
    for (std::size_t i = 0; i < hf.size(); ++i) REQUIRE(std::isfinite(hf[i]));
    const terralod::pm::GridTransform& t = hf.transform;
    for (double v : {t.x0, t.xc, t.xr, t.y0, t.yc, t.yr}) REQUIRE(std::isfinite(v));
    REQUIRE(std::isfinite(t.determinant()) && t.determinant() != 0.0);
    REQUIRE(hf.voids.voids < hf.size());
    REQUIRE(hf.source == path);
    if (fill) {
      REQUIRE(!hf.has_holes() && hf.voids.filled == hf.voids.voids);
    } else {
      REQUIRE(hf.voids.filled == 0);
      REQUIRE(hf.has_holes() == (hf.voids.voids > 0));
      if (hf.has_holes()) {
        REQUIRE(hf.mask().size() == hf.size());
        std::size_t holes = 0;
        for (std::size_t i = 0; i < hf.size(); ++i) {
          REQUIRE(hf.mask()[i] <= 1);
          if (!hf.mask()[i]) {
            ++holes;
            REQUIRE(hf[i] == 0.0);
          }
        }
        REQUIRE(holes == hf.voids.voids);
      }
    }
  } catch (const tb::DemError& e) {
    const std::string_view what = e.what();
    REQUIRE(what.starts_with(path + ": "));
    REQUIRE(e.path() == path && !e.problem().empty());
  } catch (const std::exception& e) {
    finding(std::string("unexpected exception: ") + e.what());
  }
  return 0;
}
