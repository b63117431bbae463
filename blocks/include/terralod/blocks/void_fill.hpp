// Void filling: harmonic (Laplace) inpainting of DEM voids, one 4-connected void region at a
// time, so a region's filled heights depend only on the samples around it, never on the window
// (or file) that read it.
//
// Usage:
//   #include <terralod/blocks/void_fill.hpp>
//   namespace tb = terralod::blocks;
//   std::vector<double> z = ...;                       // width x height, row-major, NaN = void
//   tb::VoidFillStats s = tb::fill_voids(z, width, height);
//   // s.filled == s.voids unless s.capped_regions > 0 (those stay NaN)
//
//   // Out of core: fill what a window of the grid can close, grow the window for the rest.
//   tb::SampleRect window{/*col0=*/1000, /*row0=*/0, /*col1=*/2999, /*row1=*/1999};
//   std::vector<double> part = ...;                    // window.samples() values, row-major
//   tb::VoidFillStats w = tb::fill_voids_in_window(part, window, width, height);
//   for (const tb::OpenVoidRegion& o : w.open) { /* read a window holding o.extent + 1 ring */ }
//
// The rule: each 4-connected void region R is solved on its box, the bounding box of R grown by
// one sample on every side and cut by the grid edge, in the box's own coordinates, in a fixed
// order, on one thread. Its filled values depend only on the valid samples of that box that are
// 4-adjacent to R, so every window that holds the box gives R the same bits, and so does the
// whole grid. A window holds R's box when no sample of R lies on a window edge that is not also
// a grid edge; a region cut that way is not filled but reported in VoidFillStats::open with the
// extent seen so far. A region whose bounding box (without the ring) has more than
// VoidFillOptions::max_region_cells cells is never filled, in any window: it stays void (NaN).
//
// Each filled sample is the mean of its 4-neighbours inside the grid (valid samples held fixed;
// conjugate gradients preconditioned by aggregation multigrid, to a residual of 1e-10 of the
// region's height scale, max(hi - lo, |hi|, |lo|)), and lies within [lo, hi], the range of the
// valid samples 4-adjacent to its region, exactly (clip plus bound-preserving Gauss-Seidel
// sweeps). A one-sample void is the clipped mean of its neighbours.
//
// Contract:
//   z            row-major values of the grid (fill_voids) or of the window
//                (fill_voids_in_window: window.samples() values, window's first row first);
//                non-finite = void. Filled in place; voids left unfilled keep their value.
//   width/height grid size in samples, >= 1, width * height < 2^32 (a window likewise).
//   window       inclusive sample rectangle inside [0, grid_width) x [0, grid_height).
//   result       counts over the window (see VoidFillStats).
// A region with no valid neighbour (a grid that is all void) is misuse: asserted, left void.
// Cost: about 0.8 us and 115 bytes per void sample of large regions, 4 bytes per window sample
// for the labels and 4 bytes per sample of each region's box while it is solved; regions are
// solved in parallel (VoidFillOptions::threads), with bits that do not depend on the thread
// count.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "terralod/blocks/sample_rect.hpp"

namespace terralod::blocks {

/// A region being solved (VoidFillOptions::on_solve): told before its solve, with seconds < 0,
/// and after it, with the seconds it took.
struct VoidSolveNotice {
  SampleRect extent;        ///< bounding box of its void samples, grid coordinates
  std::size_t samples = 0;  ///< its void samples
  double seconds = -1;      ///< < 0: about to be solved; otherwise the solve's wall time
};

struct VoidFillOptions {
  /// Regions whose bounding box has more cells than this are not filled (they stay holes).
  std::size_t max_region_cells = std::size_t(4096) * 4096;
  /// Threads solving regions; <= 0: all cores. Results are the same for every value.
  int threads = 0;
  /// Regions of at least this many void samples that are filled are also returned, with their
  /// values, in VoidFillStats::kept (0: none), so that a caller reading the grid window by
  /// window can reuse them instead of solving them again.
  std::size_t keep_filled_from = 0;
  /// Called before and after the solve of every region of at least `notify_from` void samples,
  /// on the thread that solves it (regions are solved in parallel: it must be thread-safe).
  /// At about 0.8 us a void sample, the default 2^20 samples tells of every solve that takes
  /// a second or so, so that a caller can show what a long read is doing. Empty: not called.
  std::function<void(const VoidSolveNotice&)> on_solve = {};
  std::size_t notify_from = std::size_t(1) << 20;
};

/// Samples as runs along rows: {row, col0, col1} in grid coordinates, in row-major order.
using SampleRuns = std::vector<std::array<int, 3>>;

/// The runs of the samples of `window` at `cells`: row-major indices into the window, ascending.
SampleRuns runs_of(const std::vector<std::uint32_t>& cells, SampleRect window);

/// A filled region (see VoidFillOptions::keep_filled_from): its samples as runs along rows and
/// the values they were filled with, run after run. The values are those of any window that
/// holds the region's box, since they depend on that box alone.
struct FilledVoidRegion {
  SampleRuns runs;
  std::vector<double> values;  ///< one per sample of the runs, in their order
};

/// A void region that a window cuts inside the grid: it was not filled.
struct OpenVoidRegion {
  SampleRect extent;        ///< bounding box of its void samples inside the window, grid coordinates
  std::size_t samples = 0;  ///< its void samples inside the window
};

/// What a fill did, over the window (the whole grid for fill_voids).
struct VoidFillStats {
  std::size_t voids = 0;             ///< non-finite samples on entry
  std::size_t regions = 0;           ///< 4-connected void regions (counting open and capped ones)
  std::size_t filled = 0;            ///< samples filled
  std::size_t filled_regions = 0;    ///< regions filled
  std::size_t capped_regions = 0;    ///< regions over max_region_cells, left void (the window may
  std::size_t capped_samples = 0;    ///< not hold all of a capped region: its samples seen here)
  std::vector<OpenVoidRegion> open;  ///< regions cut by the window edge inside the grid, left void
  int iterations = 0;                ///< most conjugate-gradient iterations of any region
  double residual = 0;               ///< largest final residual of any region, metres * neighbours
  int sweeps = 0;                    ///< most Gauss-Seidel sweeps after the clip of any region
  double last_change = 0;            ///< largest change in a region's last sweep, metres
  std::vector<FilledVoidRegion>
      kept;  ///< filled regions of VoidFillOptions::keep_filled_from samples or more
};

/// Fills every void region of the width x height grid `z` (a window covering the grid).
VoidFillStats fill_voids(std::vector<double>& z, int width, int height, const VoidFillOptions& options = {});

/// Fills the void regions whose box lies inside `window` of a grid_width x grid_height grid;
/// `z` holds the window's samples only. See the header comment for the rule.
VoidFillStats fill_voids_in_window(std::vector<double>& z, SampleRect window, int grid_width, int grid_height,
                                   const VoidFillOptions& options = {});

}  // namespace terralod::blocks
