// The out-of-core build (issue 17): a DEM with four times the samples of another builds with a
// peak resident set within 1.25x of the smaller one's. Both builds run in this process, one after
// the other; before each, the kernel's peak counter (VmHWM) is reset to the current resident set
// by writing 5 to /proc/self/clear_refs, so each peak is that build's own. The DEMs are tiled
// GeoTIFFs read window by window (open_dem_source); a reader that held the whole raster would
// need 32 MiB of doubles for the small one and 128 MiB for the large one and fails the bound.
// GDAL's block cache is a constant (64 MiB by default while a windowed source is open) that the
// small DEM's 16 MiB of floats never fill; the test caps it at 8 MiB (GDAL_CACHEMAX) so that both
// builds fill it and the comparison sees what grows with the DEM.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <string>

#include "run_command.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/dem_writer.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;

namespace {

/// The kernel's peak resident set of this process, bytes (VmHWM of /proc/self/status).
std::uint64_t peak_resident() {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6)) * 1024u;
  ADD_FAILURE() << "/proc/self/status has no VmHWM line";
  return 0;
}

/// Resets VmHWM to the current resident set (Linux >= 4.0).
void reset_peak() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  ASSERT_TRUE(out.good()) << "/proc/self/clear_refs: cannot reset the peak resident set";
}

}  // namespace

TEST(BuildMemory, FourTimesTheSamplesWithinAQuarterMoreMemory) {
  ASSERT_EQ(setenv("GDAL_CACHEMAX", "8", 1), 0);
  const terralod::test::TempDir dir("build-memory");
  auto peak_of_build = [&](int size) {
    const std::string dem = (dir.path() / ("fractal" + std::to_string(size) + ".tif")).string();
    tb::write_fractal_dem(pm::FractalField({.width = size, .height = size, .seed = 5}), dem, 2);
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
}
