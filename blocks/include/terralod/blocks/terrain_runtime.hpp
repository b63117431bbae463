// The one per-frame terrain runtime over a block database: the approximation tree traversed from
// its root over the whole terrain (frustum culling, coarse grid / TIN / non-regular-grid nodes
// where their error on screen meets tau), PM blocks below them refined by view-dependent
// selective refinement, background loading by priority with flight-path prefetch inside a
// memory budget, watertight seams between any two selected patches, geomorphs, and a bound
// that holds for the mesh exactly as it is drawn.
//
// Usage:
//   terralod::blocks::RuntimeOptions opt;
//   opt.tolerance_px = 1.0;                    // tau: what is drawn stays within it
//   opt.morph_seconds = 0.5;                   // geomorphs; 0 pops
//   terralod::blocks::TerrainRuntime rt("terrain.db", opt);
//   for (int f = 0;; ++f) {
//     terralod::pm::Camera cam = ...;                       // any pose, any altitude
//     rt.fit_camera(cam);                              // clip planes, ground scale at the eye
//     const auto& s = rt.update(terralod::pm::View(cam), f / 60.0);
//     const terralod::blocks::DrawnMesh& m = rt.drawn_mesh();   // within s.bound_px, as drawn
//     // s.missing_in_view == 0  =>  s.bound_px <= s.tolerance_px
//   }
//   opt.tolerance_px = 2.0;  rt.set_options(opt);           // next frame; nothing is read again
//
// Papers: seeds/approximation-tree.txt sections 3-4 and 6 and
// seeds/multiresolution-geometry-and-texture.txt (the tree drives the frame: culling, visual
// error alpha, patches of any strategy); seeds/view-dependent-pm-dynamic-loading.txt section 4
// (PM blocks, the active region b = a cot(theta), flight-path prefetch, seams by
// re-triangulation, Fig. 6); Hoppe 1998 (geomorphs within the error budget).
//
// Per frame, update(view, t):
//   1. Loads: finished blocks are taken from the background loader (never waiting). The loader
//      thread also builds each block's SelectiveRefinement and runs its first update (from the
//      base mesh to the view of the latest update() to start: the largest one), so an arrival
//      costs the frame thread only the change since then. That view is set as update() starts,
//      before step 3 queues anything: a block queued and decoded within one frame is refined
//      for that frame's own view, whichever moment it is decoded at.
//   2. Selection: from the root, a node whose box is outside the frustum is culled with its
//      subtree. A coarse node (any strategy but PmBlock) is drawn with its own surface when
//      View::vertical_error_px(box, error) <= tau / 2 (half of tau: the seams may add as much
//      again, see the bound) or when it is a leaf; otherwise its children are visited. A PmBlock
//      leaf reached this way is first tried as its stand-in (the block's TIN of at most 64
//      samples in the database's block summaries, exact error per triangle; read from the
//      database when a frame first tries it, see blocks/src/summary_store.hpp):
//      when that meets tau / 2 the block is drawn with it and need not be loaded. Otherwise the
//      block is needed, with the coarsest leaf error that meets tau / 2 over its box (its
//      floor: tau / 2 over View::vertical_error_px(box, 1 m)). When resident it is drawn by its
//      SelectiveRefinement at tau / 2 (for the same reason); a resident copy whose leaves are
//      coarser than the floor (a partial block, see 3) is drawn too, with its true bound, and
//      counted missing until a finer copy replaces it. When not resident it is missing, and its
//      nearest ancestor (always resident: every coarse node is) is drawn in place of that
//      ancestor's whole subtree, with its true bound.
//      A PmBlock root with no ancestor is drawn as its stand-in (BlockSummary) instead. A
//      database without block summaries (its blocks have voids) has no stand-ins: no block is
//      drawn as one, and a missing PmBlock root leaves its terrain undrawn (and counted missing).
//   3. Residency: the loader's queue is replaced by the needed blocks (missing in view first,
//      largest screen error first), then the blocks of the active region around the eye
//      (active_region(), b = a cot(theta)), then (prefetch on) for each predicted eye position,
//      nearest in time first, the blocks the view from there needs (the camera moved there and
//      turned along the motion) and the active region around it; the queue stops where the blocks' memory
//      (estimated from their vertex counts) would exceed the budget. Each block is read down to
//      its floor divided by partial_load_factor (the finest floor any of these views asks): its
//      DAG skips the PM's collapses below that (CollapseDag DagOptions::skip), so a far block
//      holds only the coarse end of its PM. A finer copy, once read, replaces a coarser one,
//      blending in from what the coarser one drew (as a block arriving over its stand-in does).
//      Blocks not needed are
//      evicted least-recently-used first whenever the resident bytes would pass the budget, and
//      a block that arrives without room is dropped: resident_bytes <= budget_bytes at the end
//      of every frame. resident_bytes is measured from what is held (the capacities of the
//      arrays): the tree, the summaries, each block's DAG, refinement, displayed mesh and blend
//      state (a block counts at least the reservation it was admitted with, its refinement at
//      full resolution), the frame's patches, seam buffers, height index and drawn mesh, and
//      what the loader holds (each block being read at its estimate, finished blocks not yet
//      taken, each connection's SQLite cache limit and structures), which the queue's plan
//      counts as spent. Not counted: malloc's headers; test_terrain_runtime checks the heap the
//      process gains against resident_bytes after every frame of a flight.
//   4. Seams: stitch_seams() (seam_stitch.hpp) over every selected patch: coarse node beside
//      coarse node of any strategy and level, beside a PM block's front, PM beside PM. Every
//      patch gets the border vertices of its neighbours; a terrain sample is one vertex of the
//      drawn mesh with one displayed height, so the union is watertight and shared vertices
//      are bit-identical, during geomorphs too.
//   5. Geomorphs: the refinements morph heights (pm::MorphMode::Vertical: plan positions stay
//      on the samples, so nothing folds); a PM block that arrives blends from the surface drawn
//      there before (its ancestor's) over morph_seconds. The displayed offset of a vertex from
//      its true height is then clamped so that every triangle around it stays within tau
//      (below): geomorphs use the slack left between a triangle's own error and tau, and never
//      more. With morph_seconds = 0 nothing is clamped (nothing moves).
//
// The bound (RuntimeFrameStats::bound_px): for the drawn mesh as drawn. A drawn triangle T has
//   - its logical error e_T, metres: the error of the node it belongs to (coarse nodes: the
//     node's exact error), or the error of the collapse that created it (PM faces;
//     collapse_dag.hpp, point 3; the error SelectiveRefinement bounds its faces with), plus, for a piece made
//     by the stitch from an original triangle T0, max |z(p) - S0(p)| over the inserted vertices p among its
//     corners, S0 the plane of T0 (the stitched surface is S0 plus hat functions of those differences:
//     seam_stitch.hpp);
//   - its morph offset m_T: the largest |displayed z - true z| of its three corners. The
//     displayed surface differs from the logical one by the linear interpolation of those
//     offsets, so it is within e_T + m_T of every sample under T;
//   - its box: T's plan rectangle x the heights of its displayed corners and of the samples
//     under it (within e_T0 of the true plane of T0, the triangle T was cut from, itself when
//     not stitched, and inside the node's sample range), which holds every vertical segment
//     from the displayed surface to a sample under T. It lies in T0's prism.
// bound_px = max over triangles whose box is not outside the view of
// View::vertical_error_px(box_T, e_T + m_T). Triangles with no inserted corner and no offset
// are covered at once by their patch's own bound (SelectiveRefinement's FrameStats::bound_px,
// the node's vertical_error_px over its box), so only stitched and moving triangles are
// evaluated one by one. Why it meets tau when nothing needed is missing: every selected patch
// is within tau / 2 at rest (coarse nodes by their box, PM faces by their prisms), and a
// stitched piece of T0 has e <= 2 e_T0 (|z(p) - S0(p)| <= e_T0 at a sample p under T0) in a
// box inside T0's prism, so it projects to <= 2 x tau / 2. The clamp then keeps every moving
// triangle within tau: offsets use exactly the slack between a triangle's own error and tau
// (a face at tau / 2 may move by as much again; a stitched piece at tau not at all).
//
// Contract: the database is a complete blocked database (require_complete_build), opened
// read-only on the constructor's thread and by each loader thread; DatabaseError /
// TreeFormatError / BuildError name the file; a budget_bytes under what the tree and the
// summaries need resident is a DatabaseError saying both sizes (stats() before the first frame
// reports that need as resident_bytes). Options are checked by the constructor and
// set_options (std::invalid_argument). update() times must not decrease (std::invalid_argument);
// a loader error (corrupt block) is rethrown by update() as std::runtime_error naming the file
// and the block. Not thread-safe: one frame thread; the loader threads are internal.
// Memory: the tree (approximation_tree.hpp), every block's summary fields (176 bytes a block
// with its record's place), one SQLite connection for the stand-ins (under 0.2 MB), the
// stand-ins the last frames looked at (about 3.5 kB each), the resident blocks (at least
// LoadedBlock::memory_bytes each: DAG and refinement at full resolution, about 30 MB for
// 257 x 257 samples read whole, in proportion to the collapses kept for a partial block, plus
// about 30 bytes a sample), the drawn mesh (~40 bytes per vertex, 20 per triangle) and the
// per-patch meshes of the frame (about as much again); all of it is in resident_bytes (step 3).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "terralod/blocks/active_region.hpp"
#include "terralod/blocks/approximation_tree.hpp"
#include "terralod/blocks/block_cache.hpp"
#include "terralod/blocks/block_loader.hpp"
#include "terralod/blocks/drawn_mesh.hpp"
#include "terralod/blocks/flight_predictor.hpp"
#include "terralod/blocks/ground_scale.hpp"
#include "terralod/pm/selective_refinement.hpp"

namespace terralod::blocks {

namespace detail {
class SummaryStore;  // summary_store.hpp
}  // namespace detail

struct RuntimeOptions {
  double tolerance_px = 1.0;  ///< tau, pixels, > 0: the bound of what is drawn (start value in budget mode)
  /// Triangle-budget mode when > 0: tau is regulated frame to frame (factor (triangles /
  /// target)^1, clamped to [1/2, 2] per frame and to [min, max]) to hold about this many.
  std::size_t target_triangles = 0;
  double min_tolerance_px = 0.1, max_tolerance_px = 256.0;  ///< budget-mode range, 0 < min <= max
  double morph_seconds = 0.5;                               ///< geomorph duration, seconds, >= 0; 0 = pop
  std::size_t budget_bytes = std::size_t(512) << 20;        ///< resident memory, bytes (everything loaded)
  /// A needed block is loaded only down to the error its view needs, divided by this factor
  /// (>= 1): its DAG skips the PM's collapses below that (CollapseDag::floor_error), so a far block
  /// holds only the coarse end of its PM, and serves until the eye is this many times closer;
  /// then a finer copy is loaded and replaces it (with a blend). 0 loads every block whole
  /// (N44W072 in blocks of 257 at tau = 1 and 512 MB, terralod-bench-fly: 67 frames with a block
  /// missing with 4, 958 with 0). Which inner update of update_until_loaded a copy arrives in
  /// does not change what a replayed frame draws (FlyDb.HeadlessIsDeterministic runs with it).
  double partial_load_factor = 4.0;
  /// Threads that read and decode blocks (>= 1), each with its own database connection. Fixed
  /// when the runtime opens: set_options refuses another value (std::invalid_argument). Two
  /// by default: one decodes a whole blob per read and was the limit of many-block flights
  /// (N44W072 as above: 119 frames with a block missing with one thread, 67 with two).
  int loader_threads = 2;
  bool prefetch = true;  ///< queue the blocks around the predicted path
  PredictorOptions predictor;
  double prefetch_horizon_s = 3.0;  ///< seconds ahead, >= 0
  double prefetch_step_s = 0.25;    ///< spacing of predicted points, seconds, > 0
  /// The region kept ready around the eye (Eq. 2, b = a cot(theta)); p is not used (the tree
  /// draws everything beyond the blocks).
  ActiveRegionOptions region;
};

/// What one frame did and guarantees. Counters named *_total are cumulative.
struct RuntimeFrameStats {
  std::uint64_t frame = 0;
  double time_s = 0;
  double tolerance_px = 0;  ///< tau used (regulated in budget mode)
  double bound_px = 0;      ///< guaranteed screen-space error of the drawn mesh, as drawn
  std::size_t triangles = 0, vertices = 0;
  std::size_t nodes_visited = 0, nodes_culled = 0;
  std::size_t coarse_nodes = 0;    ///< selected nodes drawn with their own surface (incl. fallbacks)
  std::size_t pm_blocks = 0;       ///< PM blocks drawn by selective refinement
  std::size_t standin_blocks = 0;  ///< PM blocks drawn as their stand-ins (within tau / 2, not loaded)
  std::size_t needed_in_view = 0;  ///< PM blocks the selection needs
  /// Of those, not resident (an ancestor is drawn), or resident with leaves coarser than the
  /// view needs (it is drawn, its bound above tau / 2, while a finer copy loads).
  std::size_t missing_in_view = 0;
  std::size_t fallback_nodes = 0;  ///< ancestors drawn for missing blocks
  std::size_t nodes_resident = 0;  ///< tree nodes in memory (all of them)
  std::size_t blocks_resident = 0, blocks_loading = 0, blocks_evicted = 0, evicted_total = 0;
  std::size_t dropped_total = 0;          ///< arrived blocks dropped for lack of room
  std::size_t partial_blocks = 0;         ///< resident blocks holding only the coarse end of their PM
  std::size_t reloads_total = 0;          ///< resident blocks replaced by a finer copy
  std::size_t prefetch_hits_total = 0;    ///< blocks resident when they became needed
  std::size_t prefetch_misses_total = 0;  ///< blocks needed before they were resident
  std::uint64_t bytes_read = 0, bytes_read_total = 0;  ///< blob bytes this frame / in total
  std::size_t resident_bytes = 0, peak_resident_bytes = 0;
  /// Stand-in surfaces held (read from the database when a frame first looks at their block,
  /// dropped some frames after its last look), and read so far.
  std::size_t standins_held = 0, standin_reads_total = 0;
  std::size_t morphing_blocks = 0;          ///< PM blocks with vertices still moving (incl. swap-in blends)
  std::size_t moving_vertices = 0;          ///< drawn vertices off their true height
  std::size_t clamped_vertices = 0;         ///< of those, held back by the bound
  std::size_t seam_triangles = 0;           ///< triangles made by the stitch
  double update_ms = 0, update_cpu_ms = 0;  ///< wall and thread CPU time of update()
  /// Wall time of update()'s steps: selection (with taking loads), the loader's queue, the
  /// refinements and patch meshes, the seams with the bound and the drawn mesh.
  double select_ms = 0, residency_ms = 0, refine_ms = 0, seams_ms = 0;
};

class TerrainRuntime {
 public:
  /// Opens `db_path` (see the contract) and starts the loader. `blocks` (optional) is where
  /// the loader reads the block blobs from instead of the database (e.g. a remote store or a
  /// test's source with latency); the tree and the summaries always come from the database.
  explicit TerrainRuntime(const std::string& db_path, const RuntimeOptions& options = {},
                          BlockSourceFactory blocks = {});
  ~TerrainRuntime();
  TerrainRuntime(const TerrainRuntime&) = delete;
  TerrainRuntime& operator=(const TerrainRuntime&) = delete;

  /// New tau, budget mode, geomorph time, memory budget: in force at the next update;
  /// no block is read again (refinements keep their state).
  void set_options(const RuntimeOptions& options);
  const RuntimeOptions& options() const { return opt_; }

  const RuntimeFrameStats& update(const pm::View& view, double time_s);
  /// For tools, tests and headless runs that must be reproducible: update(view, time_s), then
  /// the same view and time again until the loader has nothing left for this frame (two quiet
  /// updates in a row: a read that finished just after one update's take is picked up by the
  /// next). Returns the first update's statistics (the frame's work; the later updates only
  /// pick up loads); stats() is the last one's. std::runtime_error naming the database when
  /// the loads take longer than timeout_s.
  RuntimeFrameStats update_until_loaded(const pm::View& view, double time_s, double timeout_s = 600);
  const RuntimeFrameStats& stats() const { return stats_; }
  const DrawnMesh& drawn_mesh() const { return mesh_; }

  /// Fits the camera to the terrain; call it before every frame's View. Sets camera.ground to
  /// the world frame's ground scale at the eye (pm/view.hpp; at the nearest point of the
  /// terrain's box when the eye is outside it), so that what the view shows near the camera is
  /// in ground metres wherever the camera is, even in a frame that spans a continent: the
  /// identity when the database has no CRS. Then camera.near_m and far_m from the terrain's box
  /// as seen: far beyond its farthest corner (so whatever terrain is in the frustum is drawn,
  /// at any altitude), near half the distance to the box (clamped to [0.05, 1000] m).
  void fit_camera(pm::Camera& camera) const;
  /// The ground scale fit_camera sets at world (x, y) (ground_scale.hpp): the identity without
  /// a CRS.
  pm::GroundScale ground_scale(double x, double y) const { return ground_.at(x, y); }
  /// True while the loader has requests queued or in flight, or finished blocks that the next
  /// update() takes (set_queue never asks again for those: counting them is what keeps a
  /// caller waiting for a block that finished between update()'s take and its queue).
  bool loading() const;
  /// Waits (up to timeout_s) until the loader finishes a request or has none; for headless
  /// runs that must be reproducible. Returns whether requests are still queued or in flight
  /// (finished blocks wait for update(), so `while (wait_for_loader(1.0)) {}` ends).
  bool wait_for_loader(double timeout_s) const;

  const ApproximationTree& tree() const { return tree_; }
  const BlockGrid& grid() const { return grid_; }
  const std::string& path() const { return path_; }
  /// World box of the whole terrain (x, y of the grid corners, z the sample height range).
  const pm::Box& terrain_box() const { return tree_.root().bbox; }
  /// Height of the drawn surface under world (x, y) (NaN outside what is drawn). The first
  /// call after an update indexes the drawn triangles in a bucket grid (O(triangles)); each
  /// call then tests one bucket's triangles. Not thread-safe (the frame thread's).
  double drawn_height(double x, double y) const;
  /// The drawn triangles (indices into drawn_mesh().triangles, sorted, each once) that may meet
  /// the world box [x0, x1] x [y0, y1] (corners in any order): those of the buckets of
  /// drawn_height's index over the box, a superset of the triangles meeting it. Empty when the
  /// box misses the terrain. Same index and thread rule as drawn_height.
  void drawn_triangles_in(double x0, double y0, double x1, double y1, std::vector<std::uint32_t>& out) const;
  /// The highest sample of the smallest tree node over world (x, y) (clamped to the terrain):
  /// a height at or above the terrain there, known without loading anything. O(tree depth).
  double max_height_at(double x, double y) const;
  /// The terrain itself under world (x, y), whatever is drawn there: the bilinear surface of the
  /// samples (pm::bilinear_height) of the resident block holding (x, y), which keeps all its
  /// samples however much of its PM it holds; NaN outside the terrain, where that block is not
  /// resident, or over holes. O(log blocks).
  double terrain_height(double x, double y) const;

 private:
  struct Block;    // a resident block with its refinement
  struct Patch;    // one selected node's mesh this frame
  struct Eval;     // a drawn triangle evaluated on its own
  struct Scratch;  // assemble()'s buffers, reused
  struct Need {    // a PM leaf the selection needs
    std::int64_t id;
    double parent_px;  // its parent's error on screen
    double floor_m;    // the coarsest leaf error that meets tau / 2 over its box
  };
  struct Selection {  // what step 2 chose (node ids)
    std::vector<std::int64_t> coarse, pms, standins;
    std::vector<Need> needed;
  };
  struct Want {    // a block the view from a predicted point needs
    double order;  // lower first
    BlockKey key;
    double floor_m;
    bool operator<(const Want& o) const { return order < o.order || (order == o.order && key < o.key); }
  };
  bool visit(const pm::View& view, double tau, std::int64_t id, Selection& sel, double parent_px);
  void queue_loads(const pm::View& view, const std::vector<Need>& needed);
  void needed_at(const pm::View& view, double tau, std::int64_t id, double parent_px,
                 std::vector<Want>& out) const;
  bool covers(const Block& b, double floor_m) const;
  void take_loads();
  void make_room(std::size_t bytes, const std::set<BlockKey>& keep);
  std::size_t block_bytes(const Block& b) const;  // what b holds, or was admitted with when more
  std::size_t frame_bytes() const;                // the frame's buffers: meshes, seams, indexes, sets
  std::size_t resident_bytes() const;             // fixed_bytes_ + frame_bytes() + every block's
  void assemble(const pm::View& view, double tau, std::size_t patch_count, RuntimeFrameStats& s);
  std::size_t estimate_bytes(BlockKey k) const;

  std::string path_;
  RuntimeOptions opt_;
  BlockGrid grid_;
  ApproximationTree tree_;
  std::unique_ptr<detail::SummaryStore> sums_;  // every block's fields; stand-ins on demand
  GroundScaleMap ground_;                       // the frame's ground scale (identity without a CRS)
  std::vector<std::uint64_t> block_vertices_;   // per block index: PM vertices (from the build's meta)
  std::size_t fixed_bytes_ = 0;  // the tree, the summaries' fields and the vertex counts, at opening
  // Bytes per PM vertex of a decoded whole block, learnt from the whole blocks loaded so far:
  // a ratio of sums, so that it does not depend on the order the loader threads finish in.
  double loaded_bytes_ = 0, loaded_vertices_ = 0;
  std::map<BlockKey, std::unique_ptr<Block>> blocks_;
  std::unique_ptr<BlockLoader> loader_;
  FlightPredictor predictor_;
  std::set<BlockKey> needed_prev_, missing_;
  std::map<std::int64_t, std::int64_t> drawn_as_;  // PM node -> node drawn over it last frame
  std::set<std::int64_t> standins_prev_;           // PM nodes drawn as their stand-ins last frame
  double tau_ = 1.0;
  double time_ = 0;
  bool started_ = false;
  std::uint64_t frame_ = 0;
  RuntimeFrameStats stats_;
  DrawnMesh mesh_;
  struct HeightIndex {  // drawn_height's bucket grid over mesh_ (sample space)
    std::uint64_t frame = ~std::uint64_t(0);
    int nx = 0, ny = 0;
    double cell_w = 1, cell_h = 1;
    std::vector<std::uint32_t> start, tris;  // bucket b's triangles: tris[start[b], start[b+1])
    std::vector<std::array<double, 4>> box;  // per triangle: min col, max col, min row, max row
    std::vector<std::uint32_t> fill;         // building scratch: next slot per bucket
  };
  mutable HeightIndex height_index_;
  const HeightIndex& height_index() const;  // height_index_, built for this frame
  std::vector<Patch> patches_;              // the frame's patches (a pool: the first patch_count are used)
  std::unique_ptr<Scratch> scratch_;
  // What the loader thread needs to prepare an arriving block's refinement (the view, time
  // and refinement options of the latest update() to start), behind its own lock.
  std::mutex prep_mutex_;
  std::optional<pm::View> prep_view_;
  double prep_time_ = 0;
  pm::RefinementOptions prep_options_;
};

}  // namespace terralod::blocks
