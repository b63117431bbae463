// Topographic texture benchmark: time to build the shading texture of the SRTM tile N44W072
// (1201 x 1201 texels, one per sample) on the CPU with 1 and 2 threads and with OSMesa, with
// and without self-shadowing; median of R runs (default 5), plus the CPU/GPU agreement.
//
// Usage: terralod-bench-shading [--data DIR] [--runs R] [--method lambert|phong|multidirectional|relative]
//                               [--light AZIMUTH,ALTITUDE] [--max-tile N]
//
// One line per configuration: generator, shadows, median / min / max milliseconds, the ratio to
// the 1-thread CPU median of the same shadows setting, and for OSMesa the largest grey-level
// difference to the CPU texture and the share of texels that differ by more than 2 levels.
// The OSMesa context is created once, outside the timings (its creation is printed apart);
// each timed GPU run includes the height upload, shader compilation, drawing and read-back.
// Exit status: 0 (also when the data file is absent: nothing to measure), 1 if anything throws,
// 2 for a bad command line.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "terralod/blocks/dem_reader.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/gpu_shading.hpp"
#include "terralod/render/rgba_image.hpp"
#include "terralod/render/topographic_texture.hpp"
#include "timing.hpp"

namespace {

namespace tr = terralod::render;
using namespace terralod::bench;

void usage(std::FILE* f) {
  std::fprintf(f,
               "usage: terralod-bench-shading [--data DIR] [--runs R] [--method "
               "lambert|phong|multidirectional|relative]\n"
               "                              [--light AZIMUTH,ALTITUDE] [--max-tile N]\n"
               "Times the topographic texture of N44W072.hgt (CPU 1 and 2 threads, OSMesa), with and\n"
               "without shadows; median of R runs (default 5). Light: degrees clockwise from north,\n"
               "degrees above the horizon (default 315,45).\n");
}

struct Timing {
  double median = 0, min = 0, max = 0;
};

template <class F>
Timing time_runs(int runs, F&& f) {
  std::vector<double> t;
  for (int i = 0; i < runs; ++i) {
    const auto t0 = Clock::now();
    f();
    t.push_back(ms_since(t0));
    std::fprintf(stderr, "\r  run %d/%d: %.0f ms   ", i + 1, runs, t.back());
  }
  std::fprintf(stderr, "\r%40s\r", "");
  std::sort(t.begin(), t.end());
  return {t[t.size() / 2], t.front(), t.back()};
}

}  // namespace

int main(int argc, char** argv) {
  std::string data = TERRALOD_DATA_DIR;
  int runs = 5;
  tr::ShadingOptions base;
  tr::GpuShadingOptions gpu;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto next = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        return argv[++i];
      };
      if (a == "--help" || a == "-h") {
        usage(stdout);
        return 0;
      } else if (a == "--data") {
        data = next();
      } else if (a == "--runs") {
        runs = std::stoi(next());
        if (runs < 1) throw std::invalid_argument("--runs must be >= 1");
      } else if (a == "--method") {
        base.method = tr::parse_shading_method(next());
      } else if (a == "--light") {
        const std::string v = next();
        const auto comma = v.find(',');
        if (comma == std::string::npos) throw std::invalid_argument("--light expects AZIMUTH,ALTITUDE");
        base.azimuth_deg = std::stod(v.substr(0, comma));
        base.altitude_deg = std::stod(v.substr(comma + 1));
      } else if (a == "--max-tile") {
        gpu.max_tile = std::stoi(next());
      } else {
        throw std::invalid_argument("unknown argument " + a);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod-bench-shading: %s\n", e.what());
    usage(stderr);
    return 2;
  }
  const std::filesystem::path path = std::filesystem::path(data) / "N44W072.hgt";
  if (!std::filesystem::exists(path)) {
    std::printf("%s not found: nothing to measure\n", path.string().c_str());
    return 0;
  }
  try {
    auto t0 = Clock::now();
    const terralod::pm::Heightfield hf = terralod::blocks::read_dem(path.string());
    std::printf("read %s: %d x %d samples, %.0f ms\n", path.string().c_str(), hf.width(), hf.height(),
                ms_since(t0));
    t0 = Clock::now();
    auto ctx = tr::create_offscreen_context({/*width=*/16, /*height=*/16});
    std::printf("OSMesa context: %s, %.0f ms (not in the timings)\n", ctx->info().renderer.c_str(),
                ms_since(t0));
    std::printf("method %s, light %.1f,%.1f, %d runs each; hardware threads %u\n",
                tr::shading_method_name(base.method), base.azimuth_deg, base.altitude_deg, runs,
                std::thread::hardware_concurrency());
    std::printf("%-10s %-8s %10s %10s %10s %8s %10s %12s\n", "generator", "shadows", "median_ms", "min_ms",
                "max_ms", "ratio", "max_grey", "texels>2");
    for (bool shadows : {false, true}) {
      if (shadows && base.method == tr::ShadingMethod::RelativeHeight) continue;
      tr::ShadingOptions o = base;
      o.shadows = shadows;
      tr::FloatRaster cpu;
      double ref = 0;
      for (int threads : {1, 2}) {
        o.threads = threads;
        const Timing t = time_runs(runs, [&] { cpu = tr::shade_terrain(hf, o); });
        if (threads == 1) ref = t.median;
        std::printf("%-10s %-8s %10.1f %10.1f %10.1f %8.2f %10s %12s\n", threads == 1 ? "cpu-1" : "cpu-2",
                    shadows ? "on" : "off", t.median, t.min, t.max, t.median / ref, "-", "-");
      }
      tr::FloatRaster g;
      tr::GpuShadingReport rep;
      const Timing t = time_runs(runs, [&] { g = tr::shade_terrain_gpu(hf, o, {}, gpu, ctx.get(), &rep); });
      int max_grey = 0;
      std::size_t over = 0;
      for (std::size_t i = 0; i < cpu.v.size(); ++i) {
        const int d = std::abs(int(tr::grey_level(cpu.v[i])) - int(tr::grey_level(g.v[i])));
        max_grey = std::max(max_grey, d);
        over += d > 2;
      }
      char share[32];
      std::snprintf(share, sizeof share, "%.4f%%", 100.0 * double(over) / double(cpu.v.size()));
      std::printf("%-10s %-8s %10.1f %10.1f %10.1f %8.2f %10d %12s   (%d tile(s) of %d x %d)\n", "osmesa",
                  shadows ? "on" : "off", t.median, t.min, t.max, t.median / ref, max_grey, share, rep.tiles,
                  rep.tile_width, rep.tile_height);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod-bench-shading: %s\n", e.what());
    return 1;
  }
  return 0;
}
