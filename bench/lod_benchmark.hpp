// The run-time-versus-error benchmark of terrain LOD strategies at the same screen-space
// guarantee (issue 8, point 4): PM blocks (ours), Ulrich's chunked LOD, TIN nodes,
// non-regular-grid nodes and the full-resolution grid, flown along fixed scripted flights.
//
// Usage:
//   terralod::bench::LodBenchmarkOptions o;           // N44W072 at 1280 x 720, tau 0.5..8 px
//   o.dem_path = "/data/N44W072.hgt";                  // empty: a generated terrain
//   o.log = [](const std::string& s) { std::fprintf(stderr, "%s\n", s.c_str()); };
//   terralod::bench::LodBenchmarkResult r = terralod::bench::run_lod_benchmark(o);
//   terralod::bench::write_csv(r, "bench.csv");
//   terralod::bench::write_plots(r, "out/");             // error_vs_time.png, error_vs_triangles.png
//   std::string md = terralod::bench::summary_markdown(r);   // table + PASS/FAIL lines
//
// The strategies, each selected so that its screen-space error is guaranteed <= tau pixels
// (every selection bound is pm::View::vertical_error_px, a conservative bound; trees have exact
// leaves, error 0, so a selection can always meet tau):
//   pm_blocks    the one runtime, blocks::TerrainRuntime, over a block database built from the
//                terrain (build_database's defaults: grid levels of (P+1)^2 = 25 points above one
//                PmBlock leaf per block_size block, 64-point TIN stand-ins): coarse nodes and PM
//                blocks at tau / 2, stitched seams, the bound of the mesh as drawn; no geomorphs.
//   chunked_lod  Ulrich's chunked LOD: a regular-grid quadtree of (chunk_patch+1)^2 chunks whose
//                children halve the spacing, down to the full resolution.
//   tin          greedy-insertion TIN nodes of at most node_points points (default 1089, the
//                chunks' budget), k-d children, exact leaves.
//   nonregular   non-regular-grid nodes (rows and columns through the point of largest error),
//                at most node_points points, k-d children, exact leaves.
//   full_grid    every triangle of the grid, no LOD (the same for every tau).
// Only pm_blocks stitches its seams (the tree baselines leave cracks between patches of different
// resolution, as in their papers; stitching can double a patch's error, which is why the runtime
// selects at tau / 2); none geomorphs, so the popping metric compares like with like.
//
// Measured per strategy and tau, over the frames of the flights (60 frames per second of flight):
//   triangles     drawn per frame (median, max);
//   update        LOD update wall time: tree selection plus, for PM blocks, the refinement of
//                 every selected block (median, p99), one thread, as wall-clock time and
//                 as the thread's CPU time (which a shared machine's preemption does not
//                 inflate; the update-time target is checked on it);
//   draw          OSMesa wall time of uploading the frame's index list and drawing it at
//                 width x height with glFinish, on every draw_every-th frame (median, p99);
//   frame         update + draw on the drawn frames (median, p99);
//   guaranteed    the largest bound the selection reported (<= tau by construction);
//   measured      the largest screen-space error found by the independent brute-force checker
//                 (tests/support/screen_error_checker) on every check_every-th frame, over the
//                 union of the drawn triangles (all vertices are terrain samples);
//   popping       the largest per-frame change of the displayed surface at the samples, each
//                 change projected as a vertical segment with that frame's camera, in pixels
//                 (as tests/pm/test_geomorph.cpp measures it), between each checked frame and
//                 the frame before it: a sample, which misses rare switches (changed_frames
//                 counts every frame whose triangle list differs from the previous one).
// Each flight starts with one untimed update at its first pose (the state of a running
// application), so start-up refinement is not counted as a frame.
//
// Contract: options are checked (std::invalid_argument naming the option); a DEM that cannot be
// read throws blocks::DemError naming the file; a missing GL (OSMesa) throws the renderer's
// RenderError. Memory: the terrain (8 bytes per sample), the four trees (chunked: ~45 bytes per
// sample; TIN / non-regular with exact leaves: ~100 bytes per sample), the block PMs with their
// collapse DAGs and refiners (~200 bytes per sample), and the drawing copy of the terrain on the
// GPU (28 bytes per sample) plus one index list of the frame.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/terrain_generator.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::bench {

struct LodBenchmarkOptions {
  std::string dem_path;  ///< DEM to fly over; empty = generate `generated`
  /// The strategies to run (names of strategy_names(), in any order); empty = all of them.
  std::vector<std::string> strategies;
  pm::TerrainOptions generated{.width = 513, .height = 513, .seed = 8, .spacing = 30.0, .relief = 1200.0};
  int frames = 600;                                      ///< frames in all, split over the two flights, >= 2
  int width_px = 1280, height_px = 720;                  ///< viewport, >= 16 x 16
  std::vector<double> taus = {0.5, 1.0, 2.0, 4.0, 8.0};  ///< screen-space tolerances, px, > 0
  int block_size = 257;                                  ///< PM blocks: samples per block side, 2^k + 1
  /// PM blocks: the runtime's resident memory budget, bytes (> 0).
  std::size_t memory_budget_bytes = std::size_t(2) << 30;
  int chunk_patch = 32;  ///< chunked LOD: chunks of (P+1)^2 samples, P >= 1
  /// s of TIN and non-regular nodes, >= 4; default (32+1)^2, the chunks' point budget (the trees'
  /// s = 25 default would make exact-leaf trees of ~2 nodes per sample: gigabytes for N44W072).
  std::size_t node_points = 1089;
  int check_every = 20;      ///< error and popping checked on every k-th frame, >= 1
  int draw_every = 10;       ///< LOD strategies drawn on every k-th frame, >= 1
  int full_draw_every = 30;  ///< the full grid drawn on every k-th frame, >= 1
  int build_threads = 2;     ///< threads for building trees and PMs (offline), >= 1
  /// One line per stage (progress); may be empty.
  std::function<void(const std::string&)> log;
};

/// One strategy at one tau.
struct StrategyRow {
  std::string strategy;  ///< pm_blocks | chunked_lod | tin | nonregular | full_grid
  double tau_px = 0;
  std::size_t frames = 0, drawn_frames = 0, checked_frames = 0;
  double nodes_median = 0;  ///< selected nodes (PM: blocks and grid nodes)
  double triangles_median = 0, triangles_max = 0;
  double update_median_ms = 0, update_p99_ms = 0;          ///< wall clock
  double update_cpu_median_ms = 0, update_cpu_p99_ms = 0;  ///< thread CPU time (no preemption)
  /// PM blocks: median of the part of update spent in the seams and the bound of what is drawn
  /// (RuntimeFrameStats::seams_ms); 0 for the other strategies.
  double update_bound_median_ms = 0;
  /// PM blocks: frames with a needed block not resident (their bound may exceed tau), and the
  /// runtime's peak resident memory; 0 for the other strategies.
  std::size_t missing_frames = 0;
  std::size_t peak_resident_bytes = 0;
  double draw_median_ms = 0, draw_p99_ms = 0;
  double frame_median_ms = 0, frame_p99_ms = 0;
  double guaranteed_px = 0;        ///< largest bound reported by the selection
  double measured_worst_px = 0;    ///< largest error found by the independent checker
  double popping_px = 0;           ///< largest per-frame change of the surface, px
  std::size_t changed_frames = 0;  ///< frames whose triangles differ from the previous frame's
};

struct LodBenchmarkResult {
  std::string terrain;  ///< the DEM's path or "generated WxH seed S"
  int grid_width = 0, grid_height = 0;
  int frames = 0, width_px = 0, height_px = 0;
  std::string renderer;                                         ///< the GL renderer string (llvmpipe ...)
  std::vector<std::string> flights;                             ///< one line describing each flight
  std::vector<std::pair<std::string, double>> build_seconds;    ///< per strategy, offline
  std::vector<std::pair<std::string, std::size_t>> tree_nodes;  ///< per tree strategy
  std::vector<StrategyRow> rows;                                ///< strategy-major, taus in the given order
  const StrategyRow* find(const std::string& strategy, double tau_px) const;
};

/// The options of `terralod bench --short`: a generated 129 x 129 terrain in 33-sample blocks,
/// chunks of 9 x 9 samples and TIN / non-regular nodes of 81 points, 40 frames, everything
/// checked and drawn on every 5th frame (a few seconds).
LodBenchmarkOptions short_benchmark_options();

/// The folder with the real elevation data this build was configured with (TERRALOD_DATA_DIR).
std::string default_data_dir();

/// The strategy names in the order rows are produced.
const std::vector<std::string>& strategy_names();

/// The fixed scripted flights over hf: a low terrain-following circle (150 m above the highest
/// ground ahead, 120 m/s, 15 degrees down) and a high diagonal pass (1500 m above the highest
/// sample, 400 m/s, 30 degrees down), frames / 2 and frames - frames / 2 poses, 60 per second.
std::vector<std::vector<pm::Camera>> benchmark_flights(const pm::Heightfield& hf, int frames, int width_px,
                                                       int height_px);

/// Runs everything (see the header comment); progress goes to options.log.
LodBenchmarkResult run_lod_benchmark(const LodBenchmarkOptions& options);

/// bench.csv: a header and one row per strategy x tau, every column filled.
void write_csv(const LodBenchmarkResult& result, const std::string& path);
/// error_vs_time.png and error_vs_triangles.png in `folder` (log axes, one line per strategy).
void write_plots(const LodBenchmarkResult& result, const std::string& folder);

/// A target of issue 8 and whether the run met it.
struct TargetCheck {
  std::string name;
  bool pass = false;
  std::string detail;
};
std::vector<TargetCheck> check_targets(const LodBenchmarkResult& result);
/// summary.md: the table with ratios to chunked_lod and the PASS/FAIL lines.
std::string summary_markdown(const LodBenchmarkResult& result);

}  // namespace terralod::bench
