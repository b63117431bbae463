// Benchmark (not a test) of the windowed surface scan (blocks/src/surface_scan.hpp, issue 17): the
// exact error of a root-sized node surface streamed through a DemSource in windows, against
// surface_error over the whole heightfield in memory (the same bits; checked here too).
//
// Usage: terralod-bench-scan [--size N] [--patch P] [--window W] [--threads T]
//   --size     side of the generated fractal terrain, samples (default 4097)
//   --patch    grid strategy P of the surface (default 4)
//   --window   window side, samples (default 257: windows of 257 x 257)
//   --threads  threads of the windowed scan (default 0: all cores); it also runs with 1
// Each time is the fastest of 5 runs. Memory: the terrain (8 bytes/sample) plus one window per thread.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "surface_scan.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/node_strategy.hpp"
#include "terralod/pm/parallel.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "timing.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace bench = terralod::bench;

int main(int argc, char** argv) {
  int size = 4097, patch = 4, window = 257, threads = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "terralod-bench-scan: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return std::atoi(argv[++i]);
    };
    if (a == "--size")
      size = value();
    else if (a == "--patch")
      patch = value();
    else if (a == "--window")
      window = value();
    else if (a == "--threads")
      threads = value();
    else {
      std::fprintf(stderr, "usage: terralod-bench-scan [--size N] [--patch P] [--window W] [--threads T]\n");
      return a == "--help" ? 0 : 2;
    }
  }
  if (size < 2 || patch < 1 || window < 2) {
    std::fprintf(stderr, "terralod-bench-scan: --size and --window must be >= 2, --patch >= 1\n");
    return 2;
  }
  const auto t = bench::Clock::now();
  pm::TerrainOptions to;
  to.width = to.height = size;
  const pm::Heightfield hf = pm::generate_terrain(to);
  std::printf("terrain %d x %d generated: %.0f ms\n", size, size, bench::ms_since(t));
  const tb::SampleRect domain{0, 0, size - 1, size - 1};
  const tb::NodeSurface s = tb::make_grid_strategy(patch)->approximate(hf, domain);
  const tb::NodeSurface* one[] = {&s};
  const auto src = tb::heightfield_source(hf);
  // Each time is the fastest of `runs` (the machine may be shared).
  const int runs = 5;
  auto fastest = [&](auto&& f) {
    double best = 1e300;
    for (int k = 0; k < runs; ++k) {
      const auto t0 = bench::Clock::now();
      f();
      best = std::min(best, bench::ms_since(t0));
    }
    return best;
  };
  double zlo = 0.0, zhi = 0.0;  // the domain box's z range in memory (no holes here)
  const double z_ms = fastest([&] {
    zlo = hf.at(0, 0), zhi = zlo;
    for (double z : hf.samples()) zlo = std::min(zlo, z), zhi = std::max(zhi, z);
  });
  std::printf("z range in memory: %.2f .. %.2f, %.1f ms\n", zlo, zhi, z_ms);
  int failures = 0;
  for (pm::ErrorMetric m : {pm::ErrorMetric::Samples, pm::ErrorMetric::Continuous}) {
    const char* name = m == pm::ErrorMetric::Samples ? "samples" : "continuous";
    double want = 0.0;
    const double base_ms = fastest([&] { want = tb::surface_error(hf, s, m); });
    std::printf("%-10s surface_error in memory, %zu triangles: %.4f m, %.1f ms\n", name, s.triangles.size(),
                want, base_ms);
    for (int th : {1, threads}) {
      tb::detail::SurfaceScan got;
      const double ms = fastest([&] {
        got = tb::detail::scan_surfaces(*src, domain, one, m, std::size_t(window) * std::size_t(window), th);
      });
      const bool same =
          std::memcmp(&got.errors[0], &want, sizeof want) == 0 && got.zlo == zlo && got.zhi == zhi;
      failures += !same;
      std::printf(
          "%-10s scan + z range, windows %d^2, threads %d: %.4f m, z %.2f .. %.2f (%s), %.1f ms; "
          "ratio to surface_error %.2f, to surface_error + z range %.2f\n",
          name, window, pm::thread_count(th), got.errors[0], got.zlo, got.zhi,
          same ? "same bits" : "DIFFERENT", ms, ms / base_ms, ms / (base_ms + z_ms));
    }
  }
  return failures ? 1 : 0;
}
