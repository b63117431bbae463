// The private parts of TerrainRuntime that its files share (terrain_runtime.hpp declares the
// class): the resident block, one selected node's patch, a drawn triangle evaluated on its own,
// assemble()'s buffers, and the share of tau that every patch is selected at.
//
// The runtime's files: terrain_runtime.cpp (opening, options, the frame: update()),
// terrain_runtime_selection.cpp (step 2), terrain_runtime_residency.cpp (step 3: loads, the
// queue, eviction), terrain_runtime_seams.cpp (steps 4-5: seams, offsets clamped to the bound,
// the drawn mesh and its bound), terrain_runtime_heights.cpp (heights under a point).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

#include "grid_triangle.hpp"
#include "summary_store.hpp"
#include "terralod/blocks/seam_stitch.hpp"
#include "terralod/blocks/terrain_runtime.hpp"

namespace terralod::blocks {

namespace detail {

// The share of tau every patch is selected at: half, since the stitch can at most double the
// error of a border face (terrain_runtime.hpp, "The bound"), less a relative 1e-9 so that the
// rounding of the separately computed bounds (~1e-15) can never carry a frame over tau.
constexpr double kSelectShare = 0.5 * (1.0 - 1e-9);

// PM blocks, like coarse nodes, are selected at kSelectShare of tau.
inline pm::RefinementOptions refinement_options(const RuntimeOptions& o, double tau) {
  pm::RefinementOptions r;
  r.tolerance_px = kSelectShare * tau;
  r.morph_seconds = o.morph_seconds;
  r.morph_mode = pm::MorphMode::Vertical;  // plan positions stay on the samples: seams hold
  return r;
}

}  // namespace detail

// A resident block: its data and its refinement, kept while resident.
struct TerrainRuntime::Block {
  std::shared_ptr<const LoadedBlock> data;
  std::unique_ptr<pm::SelectiveRefinement> sel;
  std::uint64_t last_used = 0;   // frame it was last wanted
  std::uint64_t last_drawn = 0;  // frame it was last drawn (0: never)
  pm::RenderMesh rm;             // the refinement's displayed mesh, cached while it does not change
  bool rm_valid = false;
  bool blending = false;  // swap-in blend from `old` running
  double blend_t0 = 0;
  std::vector<detail::Tri3> old;  // whole-grid triangles drawn over the block before it arrived
  std::unordered_map<std::uint32_t, double> old_z;  // old surface at local samples
};

// One selected node's mesh this frame (whole-grid samples).
struct TerrainRuntime::Patch {
  std::int64_t node = 0;
  StitchPatch sp;  // domain, vertices (col,row), triangles
  std::vector<double> rest_z, display_z;
  std::vector<double> tri_error;             // logical error per triangle, metres
  double bound_px = 0;                       // own bound of the unstitched triangles at rest
  const pm::Heightfield* heights = nullptr;  // PM blocks: the block's samples (block-local)
  pm::ErrorMetric metric = pm::ErrorMetric::Continuous;
  double zlo = 0, zhi = 0;  // height range of the terrain's samples in the domain
};

// A drawn triangle that is evaluated on its own (stitched, or with a moving corner).
struct TerrainRuntime::Eval {
  std::uint32_t tri;
  double error;                // e_T (a stitched piece: its source's error plus the inserted corners' delta)
  double source_error;         // the error of the triangle it was cut from (itself when not stitched)
  std::array<double, 3> base;  // the source's true plane at the three corners
  std::size_t patch;
};

// Buffers of assemble(), kept from frame to frame so that a frame allocates nothing new.
struct TerrainRuntime::Scratch {
  std::vector<std::size_t> original_vertices;
  std::vector<StitchPatch> sps;
  std::unordered_map<std::uint64_t, std::uint32_t> border;
  std::vector<double> rest, display, allowed;
  std::vector<std::vector<std::uint32_t>> gidx;
  std::vector<Eval> eval;
  std::vector<std::uint8_t> moving;
  std::vector<std::uint32_t> piece;
};

}  // namespace terralod::blocks
