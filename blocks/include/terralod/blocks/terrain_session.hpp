// The per-frame pipeline of dynamic block loading: active region -> background loads and
// prefetch -> per-block view-dependent selective refinement -> watertight seams -> geomorphs
// -> the drawn mesh of the whole active region and its statistics.
//
// Usage:
//   auto db = terralod::blocks::BlockDatabase::open("terrain.db");
//   terralod::blocks::BlockGrid grid = terralod::blocks::BlockGrid::from_info(db.info());
//   std::vector<terralod::blocks::BlockSummary> sums = terralod::blocks::read_block_summaries(db, grid);
//   terralod::blocks::SessionOptions opt;
//   opt.refinement.tolerance_px = 1.0;  opt.refinement.morph_seconds = 0.5;
//   terralod::blocks::TerrainSession session(terralod::blocks::database_source("terrain.db"), grid, sums, opt);
//   for (int f = 0;; ++f) {
//     const terralod::blocks::SessionFrameStats& s = session.update(terralod::pm::View(cam), f / 60.0);
//     const terralod::blocks::DrawnMesh& m = session.drawn_mesh();   // s.bound_px guaranteed
//   }
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 4 (active blocks, Eq. 2,
// re-triangulation of unmatched boundary triangles, Fig. 6) and section 1 (iii)-(iv) (flight
// path prediction, runtime geomorphs when swapping blocks).
//
// Per frame, update(view, t):
//   1. Region: active_region() around the eye; the inner blocks are drawn as view-dependent
//      PMs when resident, every other active block (the outer p rings, and inner blocks not yet
//      resident) as its stand-in (BlockSummary: a TIN, grid, non-regular grid or two-triangle
//      surface on the block's samples, with its exact error).
//   2. Loads: finished blocks are taken from the loader (never waiting); the loader's queue is
//      replaced by: inner blocks in view, other inner blocks, then (prefetch on) the inner
//      blocks of the regions around the predicted eye positions up to prefetch_horizon_s
//      ahead, nearest in time first, capped so that they fit in the memory budget.
//   3. Refinement: each resident inner block runs pm::SelectiveRefinement. A block that was
//      just swapped in (with morph_seconds > 0) is selected at tau at once, and its displayed
//      heights blend from the surface drawn for the block the frame before (its stand-in with
//      the stitched border pieces; the bare stand-in when the block was not drawn) to the
//      refinement's displayed heights: z = s + w (z_ref - s), s the old surface at the vertex's
//      plan position, w = (t - t_swap) / morph_seconds clamped to [0, 1], so the displayed
//      surface is continuous at the swap (each new vertex starts on the old surface) and moves
//      at most |z_ref - s| x dt / morph_seconds per frame (plus the refinement's own morphs).
//   4. Eviction: blocks not inner are evicted least-recently-used first beyond the budget.
//   5. Seams (SeamMode::Stitch, the default; stitch_seams() of seam_stitch.hpp, driven by
//      blocks/src/block_seams.cpp): on every border shared by two active blocks, each side
//      gets the other side's border vertices inserted into its boundary triangles (a fan
//      from the opposite corner; a triangle with unmatched vertices on two borders, at a
//      block corner, is split along the first border, then the piece holding the second
//      border is split again from the first split's last vertex: the order of Fig. 6). Both
//      sides then have the same border vertices, so every border edge is shared by exactly
//      two triangles and the union is watertight with no T-junction. SeamMode::Skirts
//      instead hangs a vertical wall below every shared border edge (for comparison).
//   6. Geomorphs: refinement uses pm::MorphMode::Vertical, so every drawn vertex stays at its
//      sample's plan position (no fold is possible) and only heights move. A border sample
//      present on both sides is drawn at one height: the height of a side where it is
//      morphing (the first such side in block order), else its rest height; an inserted
//      vertex takes its owner's height. So seam vertices are bit-identical and move in step.
//
// The bound (SessionFrameStats::bound_px), a guarantee for the logical mesh (the geomorphing
// display lags it, as in selective_refinement.hpp): the max of
//   - each refined block's FrameStats::bound_px (its selection's guarantee);
//   - each stand-in block's standin_bound_px() (active_region.hpp): the max over its
//     triangles T of View::vertical_error_px(box_T, e_T), T's own error in T's own box;
//   - for each triangle changed by the stitch: its block's bound plus
//     View::vertical_error_px(box of the new pieces, delta), delta = max over the inserted
//     vertices p of |z(p) - S(p)|, S the old triangle's surface at p. The new surface differs
//     from the old by a piecewise-linear function that is 0 at the old corners and z(p) - S(p)
//     at each inserted p, so an error segment from the new surface to a sample splits into
//     the old one (within the block's bound) and one of length <= delta inside that box.
//   Before the stitch, close unmatched border vertices of two neighbours are merged
//   (merge_tolerance_samples; blocks/src/block_seams.hpp, "Sliver merging"): a vertex moves
//   only when the exact error of every triangle it changes projects within its block's bound,
//   so the merge never raises the bound, and the stitch's S is the merged surface.
//
// Contract: the grid and summaries describe the source's blocks (summaries.size() ==
// grid.block_count(); a summary without a stand-in surface gets the two triangles of its
// corners, one with triangles but not one error per triangle is std::invalid_argument); options are checked on construction (std::invalid_argument: morph
// mode Full, theta outside (0, 90), negative p, bad n range, a non-positive horizon step);
// update() times must not decrease (std::invalid_argument). A loader error (missing or
// corrupt block) is rethrown by update() as std::runtime_error with the loader's message
// (it names the file and the block). Not thread-safe: one frame thread; the loader thread is
// internal.
// Memory: the resident blocks (LoadedBlock::memory_bytes, bounded by the budget except for
// the inner blocks in use), the summaries (active_region.hpp: ~2.6 KB per block with 64-point
// stand-ins), the drawn mesh (~40 bytes per vertex, 12 per triangle) and, per block blending
// in, its old surface (72 bytes per triangle) and 16 bytes per vertex.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/block_cache.hpp"
#include "terralod/blocks/block_loader.hpp"
#include "terralod/blocks/drawn_mesh.hpp"
#include "terralod/blocks/flight_predictor.hpp"
#include "terralod/pm/selective_refinement.hpp"

namespace terralod::blocks {

enum class SeamMode : std::uint8_t {
  Stitch = 0,  ///< watertight re-triangulation of the block borders (default)
  Skirts = 1,  ///< vertical walls below shared borders, no re-triangulation
};

struct SessionOptions {
  ActiveRegionOptions region;
  /// tolerance_px, budget mode and morph_seconds apply to every inner block; morph_mode must
  /// be Vertical (see step 6).
  pm::RefinementOptions refinement = [] {
    pm::RefinementOptions r;
    r.morph_mode = pm::MorphMode::Vertical;
    return r;
  }();
  CacheOptions cache;
  bool prefetch = true;            ///< queue the blocks on the predicted path
  PredictorOptions predictor;
  double prefetch_horizon_s = 3.0; ///< how far ahead to predict, seconds, >= 0
  double prefetch_step_s = 0.25;   ///< spacing of the predicted points, seconds, > 0
  SeamMode seams = SeamMode::Stitch;
  double skirt_depth_m = 0.0;      ///< Skirts: wall depth, metres; 0 = the block's tm_error + 1 (>= its stand-in's error + 1 for TIN/grid stand-ins)
  /// Stitch: unmatched border vertices of two neighbours fewer than this many samples apart
  /// merge into one (blocks/src/block_seams.hpp, "Sliver merging"); 0 = off, >= 0.
  double merge_tolerance_samples = 3.0;
};

/// What one frame did and guarantees. Counters named *_total are cumulative.
struct SessionFrameStats {
  std::uint64_t frame = 0;
  double time_s = 0;
  BlockKey centre;
  int n = 0, p = 0;
  std::size_t active = 0, inner = 0;   ///< blocks in the region, of which inner
  std::size_t refined = 0;             ///< inner blocks drawn as view-dependent PMs
  std::size_t stand_ins = 0;           ///< inner blocks drawn as their stand-ins (not resident)
  std::size_t swapped_in = 0;          ///< blocks that started their swap-in geomorph this frame
  std::size_t morphing_blocks = 0;     ///< refined blocks with vertices still moving (incl. swap-in blends)
  std::size_t resident = 0, loading = 0, evicted = 0;  ///< loading: queued + being read
  std::size_t evicted_total = 0;
  std::size_t needed_in_view = 0;      ///< inner blocks whose box is not outside the view
  std::size_t missing_in_view = 0;     ///< of those, not resident (drawn as stand-ins)
  std::size_t prefetch_hits_total = 0;   ///< blocks resident when they became needed in view
  std::size_t prefetch_misses_total = 0; ///< blocks needed in view before they were resident
  std::uint64_t bytes_read_total = 0, bytes_read = 0;  ///< blob bytes, total and this frame
  std::size_t resident_bytes = 0, peak_resident_bytes = 0;
  std::size_t triangles = 0, vertices = 0;
  std::size_t seam_triangles = 0;      ///< triangles replaced by the stitch
  double tolerance_px = 0;             ///< tau used
  double bound_px = 0;                 ///< guaranteed screen-space error (see above)
  double max_stitch_delta_m = 0;       ///< largest |z(p) - S(p)| of an inserted vertex
  double update_ms = 0;                ///< wall time of update()
};

class TerrainSession {
 public:
  TerrainSession(BlockSourceFactory source, const BlockGrid& grid, std::vector<BlockSummary> summaries,
                 const SessionOptions& options = {});
  ~TerrainSession();

  const SessionFrameStats& update(const pm::View& view, double time_s);
  const SessionFrameStats& stats() const { return stats_; }
  const DrawnMesh& drawn_mesh() const { return mesh_; }
  const ActiveRegion& region() const { return region_; }
  const BlockGrid& grid() const { return grid_; }
  const SessionOptions& options() const { return opt_; }
  const std::vector<BlockSummary>& summaries() const { return sums_; }

  /// Resident block k (null when not resident), for tests and tools.
  std::shared_ptr<const LoadedBlock> resident(BlockKey k) const { return cache_.find(k); }
  std::vector<BlockKey> resident_keys() const { return cache_.keys(); }
  /// The selection of an inner block drawn as a PM this frame (null otherwise).
  const pm::SelectiveRefinement* selection(BlockKey k) const;

 private:
  /// A triangle of a block's old surface: block-local (col, row) and displayed height.
  struct OldTriangle {
    std::array<std::array<double, 3>, 3> p;
  };
  struct Refined {
    std::shared_ptr<const LoadedBlock> block;
    std::unique_ptr<pm::SelectiveRefinement> sel;
    bool blending = false;                  ///< swap-in blend from `old` still running
    double blend_t0 = 0;                    ///< time of the swap, seconds
    std::vector<OldTriangle> old;           ///< the block's drawn surface before the swap
    std::unordered_map<std::uint32_t, double> old_z;  ///< old surface at local samples (cache)
  };
  double old_height(Refined& r, BlockKey k, std::uint32_t local_sample, int width) const;
  std::vector<OldTriangle> old_surface(BlockKey k) const;
  void queue_loads(const pm::View& view);
  void build_mesh(const pm::View& view);

  BlockGrid grid_;
  std::vector<BlockSummary> sums_;
  SessionOptions opt_;
  BlockCache cache_;
  FlightPredictor predictor_;
  ActiveRegion region_;
  std::map<BlockKey, Refined> refined_;
  std::set<BlockKey> needed_prev_, missing_;
  std::vector<BlockKey> needed_;
  SessionFrameStats stats_;
  DrawnMesh mesh_;
  double time_ = 0;
  bool started_ = false;
  std::uint64_t frame_ = 0;
  std::unique_ptr<BlockLoader> loader_;  // last: stopped first
};

}  // namespace terralod::blocks
