// Draped-line benchmark (not a test): R random roads of V vertices over N44W072 in a block
// database, draped every frame on the drawn terrain (blocks::drape_lines) along a scripted
// flight at 1280 x 720: thread CPU time of the drape per frame (median, p99), with the pieces,
// drawn triangles tested and ribbon triangles made, beside the drawn-height index build that
// the frame's first query pays (shared with everything else that asks for heights).
//
// Usage: terralod-bench-drape [--roads R] [--vertices V] [--frames F]
//   Builds (or reuses) a database of N44W072 (blocks of 129 samples) in the temporary folder.
//   Roads (fixed seed 1): random walks from uniform random points of the tile, 100 m steps whose
//   heading turns by up to 30 degrees a step, 8 m wide.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "object_bench.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/object_drape.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/timing.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;

int main(int argc, char** argv) {
  long roads = 1000, vertices = 50, frames = 120;
  if (const auto status = terralod::bench::parse_options(
          argc, argv, {{"--roads", &roads}, {"--vertices", &vertices}, {"--frames", &frames}},
          "usage: terralod-bench-drape [--roads R] [--vertices V] [--frames F]\n"
          "Drapes R random roads (default 1000) of V vertices (default 50), 8 m wide, over N44W072\n"
          "every frame of an F-frame flight (default 120) at 1280x720 and prints the drape's thread\n"
          "CPU time per frame."))
    return *status;
  if (roads < 1 || vertices < 2 || frames < 1) {
    std::fprintf(stderr, "terralod-bench-drape: need --roads >= 1, --vertices >= 2 and --frames >= 1\n");
    return 2;
  }
  if (terralod::bench::skipped_without_n44w072()) return 0;
  try {
    const std::string path = terralod::bench::n44w072_database(tb::read_dem(terralod::bench::n44w072_path()));
    tb::RuntimeOptions opt;
    opt.morph_seconds = 0.5;
    tb::TerrainRuntime rt(path, opt);
    const tb::BlockGrid& grid = rt.grid();
    const auto [xa, ya] = grid.transform().to_world(0, grid.grid_height() - 1);
    const auto [xb, yb] = grid.transform().to_world(grid.grid_width() - 1, 0);
    const double x0 = std::min(xa, xb), x1 = std::max(xa, xb), y0 = std::min(ya, yb), y1 = std::max(ya, yb);
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> ux(x0, x1), uy(y0, y1),
        turn(-std::numbers::pi / 6, std::numbers::pi / 6), dir(0, 2 * std::numbers::pi);
    std::vector<std::vector<tb::WorldPoint>> points(static_cast<std::size_t>(roads));
    std::vector<tb::DrapedLine> lines;
    for (long r = 0; r < roads; ++r) {
      auto& p = points[std::size_t(r)];
      double x = ux(rng), y = uy(rng), a = dir(rng);
      for (long v = 0; v < vertices; ++v, a += turn(rng), x += 100 * std::cos(a), y += 100 * std::sin(a))
        p.push_back({x, y});
      lines.push_back({p, 8.0, std::uint32_t(r)});
    }
    // The flight of terralod-bench-objects: 400 m/s along an arc (radius 12 km), 700 m above the
    // highest sample, looking ahead and 20 degrees down; every frame waits for its loads.
    terralod::bench::ArcFlight flight{x0 + 0.1 * (x1 - x0), y0 + 0.1 * (y1 - y0), 0.2, 400, 12000, 700,
                                      rt.terrain_box().hi.z};
    std::vector<double> drape_ms, index_ms, pieces, tested, made, drawn;
    tb::ObjectMesh mesh;
    for (long f = 0; f < frames; ++f) {
      pm::Camera c = flight.next();
      rt.fit_camera(c);
      rt.update_until_loaded(pm::View(c), double(f) / 60.0);
      double t0 = pm::thread_cpu_ms();
      rt.drawn_height(c.x, c.y);  // the frame's first height query builds the bucket index
      index_ms.push_back(pm::thread_cpu_ms() - t0);
      mesh.clear();
      t0 = pm::thread_cpu_ms();
      const tb::DrapeStats s = tb::drape_lines(rt, lines, mesh);
      drape_ms.push_back(pm::thread_cpu_ms() - t0);
      pieces.push_back(double(s.pieces));
      tested.push_back(double(s.drawn_triangles_tested));
      made.push_back(double(s.triangles));
      drawn.push_back(double(rt.drawn_mesh().triangles.size()));
    }
    std::printf(
        "%ld frames at 1280x720, %ld roads of %ld vertices (8 m wide): drape thread CPU median %.3f ms, p99 "
        "%.3f ms (pieces %.0f, drawn triangles tested median %.0f, ribbon triangles median %.0f, %.0f "
        "triangles drawn); drawn-height index build median %.3f ms\n",
        frames, roads, vertices, pm::median(drape_ms), pm::quantile(drape_ms, 0.99), pm::median(pieces),
        pm::median(tested), pm::median(made), pm::median(drawn), pm::median(index_ms));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod-bench-drape: %s\n", e.what());
    return 1;
  }
  return 0;
}
