// Dynamic-loading benchmark (not a test): a scripted 60-second flight over N44W072 built into
// blocks, replayed in real time through blocks::TerrainSession with flight-path prediction on
// and off: frame time (median, 99th percentile, worst), prefetch misses, peak resident memory,
// bytes read.
//
// Usage: terralod-bench-fly [DB] [--block-size N] [--tau PX]
//   DB: a block database of N44W072 (from 'terralod build'); without it the benchmark builds
//   one (blocks of --block-size samples, default 129) in a temporary folder first.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/dem_reader.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/blocks/terrain_session.hpp"
#include "terralod/pm/pm_io.hpp"

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

std::string build_database(int block_size) {
  const std::string dem = std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt";
  const std::string path = (fs::temp_directory_path() / ("terralod-bench-fly-" + std::to_string(block_size) + ".db")).string();
  if (fs::exists(path)) {
    std::printf("reuse %s\n", path.c_str());
    return path;
  }
  const auto t = Clock::now();
  const pm::Heightfield hf = tb::read_dem(dem);
  tb::DatabaseInfo info;
  info.grid_width = hf.width();
  info.grid_height = hf.height();
  info.transform = hf.transform;
  info.block_size = block_size;
  info.source = dem;
  info.build_parameters = "{\"bench_fly\": true, \"block_size\": " + std::to_string(block_size) + "}";
  const std::string tmp = path + ".partial";
  fs::remove(tmp);
  {
    tb::BlockDatabase db = tb::BlockDatabase::create(tmp, info);
    const tb::BlockLayout layout = tb::partition(hf.width(), hf.height(), block_size);
    const tb::BlockGrid grid = tb::BlockGrid::from_info(info);
    std::vector<tb::BlockSummary> sums(grid.block_count());
    for (tb::BlockKey k : layout.keys()) {
      const pm::ProgressiveMesh p = tb::build_block_pm(hf, layout.rect(k));
      db.put_block(k, pm::encode_pm(p));
      sums[grid.index(k)] = tb::summarize_block(p, k);
      std::fprintf(stderr, "\rbuild blocks: %zu of %zu", grid.index(k) + 1, grid.block_count());
    }
    db.put_blob(tb::kBlockSummariesBlob, tb::encode_block_summaries(grid, sums));
  }
  for (const char* ext : {"", "-wal", "-shm"})
    if (fs::exists(tmp + ext)) fs::rename(tmp + ext, path + ext);
  std::fprintf(stderr, "\n");
  std::printf("build %s: %d x %d samples in blocks of %d, %.1f s\n", path.c_str(), hf.width(), hf.height(), block_size,
              std::chrono::duration<double>(Clock::now() - t).count());
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
  double tau = 1.0;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--block-size") && i + 1 < argc) block_size = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--tau") && i + 1 < argc) tau = std::atof(argv[++i]);
    else if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h")) {
      std::puts("usage: terralod-bench-fly [DB] [--block-size N] [--tau PX]\n"
                "Replays a scripted 60 s flight over N44W072 in real time with prediction on and off.");
      return 0;
    } else db_path = argv[i];
  }
  if (db_path.empty()) {
    if (!fs::exists(std::string(TERRALOD_DATA_DIR) + "/N44W072.hgt")) {
      std::printf("skip: N44W072.hgt not in %s\n", TERRALOD_DATA_DIR);
      return 0;
    }
    db_path = build_database(block_size);
  }
  const tb::BlockDatabase db = tb::BlockDatabase::open(db_path);
  const tb::BlockGrid grid = tb::BlockGrid::from_info(db.info());
  const std::vector<tb::BlockSummary> sums = tb::read_block_summaries(db, grid);

  // The flight: 60 s at 60 fps, 400 m/s, an S-curve across the tile (a right then a left
  // turn of radius 12 km), 700 m above the highest sample, looking ahead 20 deg down.
  double zmax = 0;
  for (const tb::BlockSummary& s : sums) zmax = std::max(zmax, s.zmax);
  const auto [xa, ya] = grid.transform().to_world(0, grid.grid_height() - 1);
  const auto [xb, yb] = grid.transform().to_world(grid.grid_width() - 1, 0);
  const double w = std::abs(xb - xa), h = std::abs(yb - ya), x_lo = std::min(xa, xb), y_lo = std::min(ya, yb);
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
    c.yaw_deg = heading * 180 / M_PI;
    c.pitch_deg = -20;
    c.fovy_deg = 60;
    c.width_px = 1280;
    c.height_px = 720;
    c.near_m = 1;
    c.far_m = 2e5;
    path.push_back(c);
  }
  std::printf("flight: %zu frames (%.0f s) at %.0f m/s, %.0f m up, over %s (%d x %d blocks of %d samples), tau %g px\n",
              path.size(), path.size() / 60.0, speed, zmax + 700, db_path.c_str(), grid.cols(), grid.rows(),
              grid.block_size(), tau);
  for (bool prefetch : {true, false}) {
    tb::SessionOptions opt;
    opt.prefetch = prefetch;
    opt.refinement.tolerance_px = tau;
    opt.refinement.morph_seconds = 0.5;
    opt.cache.budget_bytes = std::size_t(256) << 20;
    tb::TerrainSession s(tb::database_source(db_path), grid, sums, opt);
    std::vector<double> ms, bounds;
    std::size_t cold_misses = 0, cold_needed = 0;  // the first 2 s: every block is missing then
    std::size_t over_budget_frames = 0, triangles = 0, missing_frames = 0;
    double bound = 0;
    const auto t0 = Clock::now();
    for (std::size_t f = 0; f < path.size(); ++f) {
      std::this_thread::sleep_until(t0 + std::chrono::duration<double>(double(f) / 60.0));
      const tb::SessionFrameStats& st = s.update(pm::View(path[f]), double(f) / 60.0);
      ms.push_back(st.update_ms);
      if (st.update_ms > 1000.0 / 60) ++over_budget_frames;
      if (st.missing_in_view > 0) ++missing_frames;
      triangles = std::max(triangles, st.triangles);
      bound = std::max(bound, st.bound_px);
      bounds.push_back(st.bound_px);
      if (f + 1 == 120) {
        cold_misses = st.prefetch_misses_total;
        cold_needed = st.prefetch_misses_total + st.prefetch_hits_total;
      }
    }
    const tb::SessionFrameStats& st = s.stats();
    struct rusage ru {};
    getrusage(RUSAGE_SELF, &ru);
    std::printf("prediction %-3s: frame median %.2f ms, p99 %.2f ms, worst %.2f ms, %zu frames over 16.7 ms; "
                "prefetch misses %zu of %zu blocks needed in view (after the first 2 s: %zu of %zu), %zu frames "
                "with a stand-in in view; peak resident %.1f MB (budget %.0f MB), %.1f MB read, %zu evicted; max %zu "
                "triangles, bound median %.1f px, max %.1f px; process peak RSS %.0f MB\n",
                prefetch ? "on" : "off", pct(ms, 0.5), pct(ms, 0.99), pct(ms, 1.0), over_budget_frames,
                st.prefetch_misses_total, st.prefetch_hits_total + st.prefetch_misses_total,
                st.prefetch_misses_total - cold_misses, st.prefetch_hits_total + st.prefetch_misses_total - cold_needed,
                missing_frames, st.peak_resident_bytes / 1e6, opt.cache.budget_bytes / 1e6, st.bytes_read_total / 1e6,
                st.evicted_total, triangles, pct(bounds, 0.5), bound, ru.ru_maxrss / 1024.0);
  }
  return 0;
}
