// Dynamic-loading benchmark (not a test): a scripted 60-second flight over a block database of
// N44W072, replayed in real time through blocks::TerrainRuntime with flight-path prediction on
// and off: frame time (median, 99th percentile, worst), prefetch misses, peak resident memory
// (and how far the heap the process gained ever was above it: glibc's mallinfo2), bytes read.
//
// Usage: terralod-bench-fly [DB] [--block-size N] [--tau PX] [--budget MB] [--partial F]
//                           [--loader-threads N]
//   DB: a block database of N44W072 (from 'terralod build'); without it the benchmark builds
//   one with build_database (blocks of --block-size samples, default 129, the default tree and
//   stand-ins) in a temporary folder first, and reuses it on later runs.
//   --budget: the runtime's memory budget, megabytes (default 1024: the flight at tau = 1 px
//   peaks near 710 MB with the default 129-sample blocks; below what a frame needs, blocks stay
//   missing).
//   --partial: RuntimeOptions::partial_load_factor (default 4: far blocks hold only the coarse
//   end of their PM; 0 loads every block whole).
//   --loader-threads: RuntimeOptions::loader_threads (default 2).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/timing.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

// Builds (or, when a complete one with the same parameters is there, reuses) the database.
std::string build_database(int block_size) {
  const std::string dem = std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt";
  const std::string path =
      (fs::temp_directory_path() / ("terralod-bench-fly-runtime-" + std::to_string(block_size) + ".db"))
          .string();
  const pm::Heightfield hf = tb::read_dem(dem);
  tb::DatabaseBuildOptions o;
  o.block_size = block_size;
  o.threads = int(std::max(1u, std::thread::hardware_concurrency()));
  o.progress = [](double f, double) { std::fprintf(stderr, "\rbuild blocks: %3.0f %%", 100 * f); };
  const tb::DatabaseSummary s = tb::build_database(hf, path, o);
  if (s.blocks_built.value_or(0) > 0) std::fprintf(stderr, "\n");
  std::printf("%s %s: %d x %d samples in %zu blocks of %d (%zu built now), tree of %zu nodes, %.1f s\n",
              s.blocks_built.value_or(0) == 0 ? "reuse" : "build", path.c_str(), s.grid_width, s.grid_height,
              s.blocks, s.block_size, s.blocks_built.value_or(0), s.nodes, s.seconds);
  return path;
}

double pct(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(q * double(v.size() - 1) + 0.5))];
}

}  // namespace

int main(int argc, char** argv) {
  std::string db_path;
  int block_size = 129;
  double tau = 1.0, budget_mb = 1024.0, partial = tb::RuntimeOptions{}.partial_load_factor;
  int loader_threads = tb::RuntimeOptions{}.loader_threads;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--block-size") && i + 1 < argc)
      block_size = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--tau") && i + 1 < argc)
      tau = std::atof(argv[++i]);
    else if (!std::strcmp(argv[i], "--budget") && i + 1 < argc)
      budget_mb = std::atof(argv[++i]);
    else if (!std::strcmp(argv[i], "--partial") && i + 1 < argc)
      partial = std::atof(argv[++i]);
    else if (!std::strcmp(argv[i], "--loader-threads") && i + 1 < argc)
      loader_threads = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h")) {
      std::puts(
          "usage: terralod-bench-fly [DB] [--block-size N] [--tau PX] [--budget MB] [--partial F]\n"
          "                          [--loader-threads N]\n"
          "Replays a scripted 60 s flight over N44W072 in real time through the terrain runtime\n"
          "with prediction on and off. Without DB, builds one (blocks of N samples, default 129).\n"
          "--budget: resident memory of the runtime, megabytes (default 1024).\n"
          "--partial: load a needed block only down to the error its view needs divided by F\n"
          "(default 4); 0 loads every block whole.\n"
          "--loader-threads: threads reading and decoding blocks (default 2).");
      return 0;
    } else
      db_path = argv[i];
  }
  if (!(tau > 0) || !(budget_mb > 0) || block_size < 3 || !(partial == 0 || partial >= 1) ||
      loader_threads < 1) {
    std::fprintf(
        stderr,
        "terralod-bench-fly: need --tau > 0, --budget > 0, --block-size >= 3, --partial 0 or >= 1 and "
        "--loader-threads >= 1\n");
    return 2;
  }
  try {
    if (db_path.empty()) {
      if (!fs::exists(std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt")) {
        std::printf("skip: N44W072.hgt not in %s\n", TERRALOD_DATA_DIR);
        return 0;
      }
      db_path = build_database(block_size);
    }
    const tb::BlockDatabase db = tb::BlockDatabase::open(db_path);
    const tb::BlockGrid grid = tb::BlockGrid::from_info(db.info());
    // The highest sample: the top of the tree root's box (its surface's heights are samples), not
    // a decode of every block summary, which would hold them all outside the runtime's count.
    const auto tree_blob = db.read_blob("tree");
    if (!tree_blob) throw tb::DatabaseError(db_path, "no approximation tree (blob 'tree')");
    const double zmax = tb::decode_tree(*tree_blob, db_path + ": tree").root().bbox.hi.z;

    // The flight: 60 s at 60 fps, 400 m/s, an S-curve across the tile (a right then a left
    // turn of radius 12 km), 700 m above the highest sample, looking ahead 20 deg down.
    const auto [xa, ya] = grid.transform().to_world(0, grid.grid_height() - 1);
    const auto [xb, yb] = grid.transform().to_world(grid.grid_width() - 1, 0);
    const double w = std::abs(xb - xa), h = std::abs(yb - ya), x_lo = std::min(xa, xb),
                 y_lo = std::min(ya, yb);
    std::vector<pm::Camera> path;
    double x = x_lo + 0.1 * w, y = y_lo + 0.1 * h, heading = 0.2;  // radians clockwise from north
    const double speed = 400, radius = 12000;
    for (int f = 0; f < 3600; ++f) {
      const double turn = (f < 1800 ? 1 : -1) * speed / radius;
      heading += turn / 60;
      x += speed / 60 * std::sin(heading);
      y += speed / 60 * std::cos(heading);
      pm::Camera c;
      c.x = x;
      c.y = y;
      c.z = zmax + 700;
      c.yaw_deg = heading * 180 / std::numbers::pi;
      c.pitch_deg = -20;
      c.fovy_deg = 60;
      c.width_px = 1280;
      c.height_px = 720;
      path.push_back(c);
    }
    std::printf(
        "flight: %zu frames (%.0f s) at %.0f m/s, %.0f m up, over %s (%d x %d blocks of %d samples), tau %g "
        "px\n",
        path.size(), double(path.size()) / 60.0, speed, zmax + 700, db_path.c_str(), grid.cols(), grid.rows(),
        grid.block_size(), tau);
    for (bool prefetch : {true, false}) {
      tb::RuntimeOptions opt;
      opt.prefetch = prefetch;
      opt.tolerance_px = tau;
      opt.morph_seconds = 0.5;
      opt.budget_bytes = std::size_t(budget_mb * 1e6);
      opt.partial_load_factor = partial;
      opt.loader_threads = loader_threads;
      // The heap the process gains while the runtime is open, against what it counts
      // (resident_bytes): sampled after every frame, so blocks being decoded are caught midway.
      const double heap0 = pm::heap_in_use_bytes();
      double heap_over = -1e300;
      tb::TerrainRuntime rt(db_path, opt);
      std::vector<double> ms, bounds;
      std::size_t cold_misses = 0, cold_needed = 0;  // the first 2 s: every block is missing then
      std::size_t slow_frames = 0, triangles = 0, missing_frames = 0, standins = 0;
      const double fixed_mb = double(rt.stats().resident_bytes) / 1e6;  // before a frame: what opening holds
      double bound = 0;
      const auto t0 = Clock::now();
      for (std::size_t f = 0; f < path.size(); ++f) {
        std::this_thread::sleep_until(t0 + std::chrono::duration<double>(double(f) / 60.0));
        pm::Camera cam = path[f];
        rt.fit_camera(cam);
        const tb::RuntimeFrameStats& st = rt.update(pm::View(cam), double(f) / 60.0);
        ms.push_back(st.update_ms);
        heap_over = std::max(heap_over, pm::heap_in_use_bytes() - heap0 - double(st.resident_bytes));
        if (st.update_ms > 1000.0 / 60) ++slow_frames;
        if (st.missing_in_view > 0) ++missing_frames;
        triangles = std::max(triangles, st.triangles);
        standins = std::max(standins, st.standins_held);
        bound = std::max(bound, st.bound_px);
        bounds.push_back(st.bound_px);
        if (f + 1 == 120) {
          cold_misses = st.prefetch_misses_total;
          cold_needed = st.prefetch_misses_total + st.prefetch_hits_total;
        }
        if (f % 60 == 59)
          std::fprintf(stderr, "\rfly (prediction %s): %2zu of %zu s", prefetch ? "on" : "off", (f + 1) / 60,
                       path.size() / 60);
      }
      std::fprintf(stderr, "\n");
      const tb::RuntimeFrameStats& st = rt.stats();
      std::printf(
          "prediction %-3s: frame median %.2f ms, p99 %.2f ms, worst %.2f ms, %zu frames over 16.7 ms; "
          "prefetch misses %zu of %zu blocks needed in view (after the first 2 s: %zu of %zu), %zu frames "
          "with a block missing in view; peak resident %.1f MB (budget %.0f MB), %.1f MB read, %zu evicted, "
          "%zu dropped, %zu reloaded finer; "
          "max %zu triangles, bound median %.2f px, max %.2f px; process peak RSS %.0f MB, heap at most "
          "%.2f MB above resident; held from opening %.2f MB, stand-ins held at most %zu, %zu read\n",
          prefetch ? "on" : "off", pct(ms, 0.5), pct(ms, 0.99), pct(ms, 1.0), slow_frames,
          st.prefetch_misses_total, st.prefetch_hits_total + st.prefetch_misses_total,
          st.prefetch_misses_total - cold_misses,
          st.prefetch_hits_total + st.prefetch_misses_total - cold_needed, missing_frames,
          double(st.peak_resident_bytes) / 1e6, double(opt.budget_bytes) / 1e6,
          double(st.bytes_read_total) / 1e6, st.evicted_total, st.dropped_total, st.reloads_total, triangles,
          pct(bounds, 0.5), bound, double(pm::peak_resident_bytes()) / (1024.0 * 1024.0), heap_over / 1e6,
          fixed_mb, standins, st.standin_reads_total);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "terralod-bench-fly: %s\n", e.what());
    return 1;
  }
  return 0;
}
