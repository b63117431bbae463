// Windowed DEM reads against read_dem: time and peak RSS (getrusage) of reading every 257-sample
// block of a DEM through open_dem_source or through read_dem + block_heightfield, then samples_crc. One mode
// per process, so that each peak RSS is its own.
//   terralod-bench-dem-source FILE source|read_dem [THREADS]
//   (FILE e.g. from `terralod testdem --fractal 8193x8193 --out /tmp/x.tif`)
#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/partition.hpp"

namespace tb = terralod::blocks;

int main(int argc, char** argv) {
  if (argc < 3 || (std::string(argv[2]) != "source" && std::string(argv[2]) != "read_dem")) {
    std::fprintf(stderr, "usage: %s FILE source|read_dem [THREADS]\n", argv[0]);
    return 2;
  }
  const std::string path = argv[1], mode = argv[2];
  const int threads = argc > 3 ? std::max(1, std::atoi(argv[3])) : 1;
  const auto t0 = std::chrono::steady_clock::now();
  std::unique_ptr<tb::DemSource> src;
  std::unique_ptr<terralod::pm::Heightfield> hf;
  if (mode == "source") {
    src = tb::open_dem_source(path);
  } else {
    hf = std::make_unique<terralod::pm::Heightfield>(tb::read_dem(path));
    src = tb::heightfield_source(*hf);
  }
  const double open_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const tb::BlockLayout layout = tb::partition(src->grid().width, src->grid().height, 257);
  const std::vector<tb::BlockKey> keys = layout.keys();
  std::atomic<std::size_t> next{0};
  std::atomic<std::uint64_t> holes{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&] {
      for (std::size_t i; (i = next++) < keys.size();)
        if (src->read(layout.rect(keys[i])).has_holes()) ++holes;
    });
  for (std::thread& t : pool) t.join();
  const double total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto t1 = std::chrono::steady_clock::now();
  const std::uint32_t crc = src->samples_crc();
  const double crc_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  std::printf(
      "%s: %d x %d samples, %zu blocks of 257, %d thread(s): open %.2f s, all blocks %.2f s, "
      "samples_crc %08x in %.2f s; peak RSS %.1f MiB (blocks with holes: %llu)\n",
      mode.c_str(), src->grid().width, src->grid().height, keys.size(), threads, open_s, total_s, crc, crc_s,
      double(ru.ru_maxrss) / 1024.0, (unsigned long long)holes.load());
  return 0;
}
