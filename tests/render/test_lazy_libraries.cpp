// OpenImageIO and OSMesa are loaded on the first call of one of their functions
// (cmake/lazy/lazy_library.cmake), not when a process starts: a process that reads a GeoTIFF DEM
// maps neither; reading a PNG heightmap maps OpenImageIO and reads the heights exactly; four
// threads making that first call at once all get the same heights (the resolver stores each
// function once, whoever comes first); making an offscreen context maps OSMesa, which then
// draws. Each check lives in one test body: ctest runs every test in a process of its own, which
// is what makes "not yet loaded" observable.
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/render/gl_context.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;

// Whether a library whose file name contains `name` is mapped into this process.
bool mapped(const char* name) {
  std::ifstream maps("/proc/self/maps");
  for (std::string line; std::getline(maps, line);)
    if (line.find(name) != std::string::npos) return true;
  return false;
}
bool openimageio_mapped() { return mapped("libOpenImageIO"); }
bool osmesa_mapped() { return mapped("libOSMesa"); }

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(TERRALOD_TEST_TMP) / ("lazy_openimageio_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A w x h grid of UInt16 heights, h(i, j) = 7 i + 13 j + 100, written through GDAL (never
// OpenImageIO) as `driver` ("GTiff" or "PNG").
void write_grid(const fs::path& path, const char* driver, int w, int h) {
  GDALAllRegister();
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  GDALDatasetUniquePtr src(mem->Create("", w, h, 1, GDT_UInt16, nullptr));
  std::vector<std::uint16_t> z(std::size_t(w) * h);
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) z[std::size_t(j) * w + i] = std::uint16_t(7 * i + 13 * j + 100);
  ASSERT_EQ(src->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, w, h, z.data(), w, h, GDT_UInt16, 0, 0), CE_None);
  if (std::string(driver) == "GTiff") {
    const double gt[6] = {500000, 30, 0, 4900000, 0, -30};
    src->SetGeoTransform(const_cast<double*>(gt));
  }
  GDALDriver* out = GetGDALDriverManager()->GetDriverByName(driver);
  ASSERT_NE(out, nullptr) << driver;
  GDALDatasetUniquePtr dst(out->CreateCopy(path.c_str(), src.get(), FALSE, nullptr, nullptr, nullptr));
  ASSERT_TRUE(dst) << path;
}

void expect_grid(const terralod::pm::Heightfield& hf, int w, int h, const std::string& what) {
  ASSERT_EQ(hf.width(), w) << what;
  ASSERT_EQ(hf.height(), h) << what;
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i)
      ASSERT_EQ(hf.at(i, j), 7.0 * i + 13.0 * j + 100.0) << what << " at " << i << "," << j;
}

// Whether the process started with either library mapped (linked outright): read while the
// executable's statics are made, before any test.
const bool kOpenImageIOAtStart = openimageio_mapped(), kOSMesaAtStart = osmesa_mapped();

// Fails when the library came with the process although this build loads it lazily; a test run
// after another in the same process (the executable run by hand) may find it loaded by that one
// and then has nothing to observe. A build that links it outright (TERRALOD_LAZY_* = 0, set by
// tests/render/CMakeLists.txt) has nothing to observe either.
bool already_loaded(bool lazy, bool at_start, bool now, const char* library) {
  if (!lazy) return true;
  EXPECT_FALSE(at_start) << library << " was loaded when the process started";
  return at_start || now;
}
constexpr const char* kAlone =
    "linked outright in this build, or loaded already (then run this test in a process of its own)";

TEST(LazyLibraries, OpenImageIOOnlyWhenAnImageIsRead) {
  if (already_loaded(TERRALOD_LAZY_OPENIMAGEIO, kOpenImageIOAtStart, openimageio_mapped(), "OpenImageIO"))
    GTEST_SKIP() << kAlone;
  const fs::path dir = scratch("read");
  write_grid(dir / "a.tif", "GTiff", 9, 6);
  write_grid(dir / "a.png", "PNG", 9, 6);
  expect_grid(tb::read_dem((dir / "a.tif").string()), 9, 6, "GeoTIFF");
  EXPECT_FALSE(openimageio_mapped()) << "a GeoTIFF DEM (GDAL) loaded OpenImageIO";
  tb::DemOptions opt;
  opt.heightmap_spacing = 30.0;
  expect_grid(tb::read_dem((dir / "a.png").string(), opt), 9, 6, "PNG heightmap");
  EXPECT_TRUE(openimageio_mapped()) << "a PNG heightmap was read without OpenImageIO?";
  EXPECT_FALSE(osmesa_mapped()) << "reading a DEM loaded OSMesa";
}

TEST(LazyLibraries, OpenImageIOFirstCalledFromFourThreadsAtOnce) {
  const fs::path dir = scratch("threads");
  if (already_loaded(TERRALOD_LAZY_OPENIMAGEIO, kOpenImageIOAtStart, openimageio_mapped(), "OpenImageIO"))
    GTEST_SKIP() << kAlone;
  write_grid(dir / "b.png", "PNG", 17, 11);
  tb::DemOptions opt;
  opt.heightmap_spacing = 10.0;
  std::vector<terralod::pm::Heightfield> got(4);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] { got[t] = tb::read_dem((dir / "b.png").string(), opt); });
  for (auto& t : threads) t.join();
  for (int t = 0; t < 4; ++t) expect_grid(got[t], 17, 11, "thread " + std::to_string(t));
  EXPECT_TRUE(openimageio_mapped());
  EXPECT_FALSE(osmesa_mapped()) << "reading an image loaded OSMesa";
}

TEST(LazyLibraries, OSMesaOnlyWhenAnOffscreenContextIsMade) {
  if (already_loaded(TERRALOD_LAZY_OSMESA, kOSMesaAtStart, osmesa_mapped(), "OSMesa")) GTEST_SKIP() << kAlone;
  std::unique_ptr<terralod::render::GlContext> ctx;
  try {
    ctx = terralod::render::create_offscreen_context({16, 8});
  } catch (const terralod::render::RenderError& e) {
    GTEST_SKIP() << "no OSMesa context: " << e.what();
  }
  EXPECT_TRUE(osmesa_mapped());
  EXPECT_EQ(ctx->framebuffer_width(), 16);
  EXPECT_EQ(ctx->framebuffer_height(), 8);
}

}  // namespace
