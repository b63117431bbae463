// The reference PM build: the same greedy L-infinity collapses as ProgressiveMesh::build, run
// by OpenMesh's own decimater framework (DecimaterT with ModLInfT, linf_decimater_module.hpp).
//
// Usage:
//   terralod::pm::Heightfield hf = terralod::pm::generate_terrain();
//   terralod::pm::ProgressiveMesh pm = terralod::pm::build_with_decimater(hf);   // one call
//   terralod::pm::TriangleMesh m = pm.extract(/*max_error=*/2.0);                 // as build()'s
//
// What it does: makes the full-resolution OpenMesh TriMesh of the grid (one vertex per valid
// sample, point (col, row, height); the faces of ProgressiveMesh::full_face added cell by
// cell, row by row, with the code the builder uses, so that the faces OpenMesh refuses around
// holes are the same dropped faces), runs DecimaterT with ModLInfT as its only (non-binary,
// priority) module until no legal collapse is left, records every collapse DecimaterT performs
// (u = the removed sample, w = the kept one, error = ModLInfT's E for it, rounded up to
// ProgressiveMesh::error_quantum_for(hf) as build() rounds), and assembles the PM with
// ProgressiveMesh::from_parts. The result is an ordinary ProgressiveMesh: same file format,
// same extract() guarantee, loadable into CollapseDag (which replays the collapses).
//
// Why a function of its own and not a static of ProgressiveMesh: it is a second, independent
// route to the same object, for comparisons and for users of OpenMesh's framework, with its own
// cost and its own notion of progress; ProgressiveMesh stays the one concept "a PM and its
// extraction", and DecimaterT is instantiated in openmesh_build.cpp only.
//
// Contract:
//   - hf: at least 2 x 2 samples, fewer than 2^31, every valid sample finite
//     (std::invalid_argument otherwise, as build()).
//   - options.metric: the error measure of ModLInfT and of the PM. options.max_error (metres,
//     >= 0): collapses whose E exceeds it are illegal (ModLInfT::set_max_error); the recorded
//     errors may exceed it by less than one quantum, as build()'s. options.progress: called
//     through OpenMesh's Observer about every 1/64 of the collapses (fraction = collapses /
//     (valid samples - 4), at most 1) and once with 1.0 at the end; returning false aborts
//     DecimaterT, and the function throws std::runtime_error "progressive mesh build cancelled".
//     options.threads and options.parallel_strips are ignored: DecimaterT runs on one thread.
//   - The sequence differs from build()'s (DecimaterT breaks ties by its own heap and refuses a
//     few more collapses than build(), see BaseDecimaterT::is_collapse_legal), so the two PMs
//     are alike, not equal.
// Cost: slow. After each collapse DecimaterT re-measures every candidate of every vertex of
// the removed vertex's ring, each in full, with no lower bounds and no caches; measured on the
// generated terrain, one thread each: 4x build()'s CPU time at 257 x 257, 5x at 513 x 513, the
// gap growing with the grid (candidates are measured over ever larger triangles). Memory:
// OpenMesh's mesh with status bits, DecimaterT's heap and three vertex properties (peak RSS
// of `terralod pm` the same as the fast route's at 257 x 257 and 513 x 513), plus 16 bytes per
// collapse.
#pragma once

#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::pm {

/// Builds the PM of `hf` through OpenMesh's DecimaterT and ModLInfT (see above).
ProgressiveMesh build_with_decimater(const Heightfield& hf, const BuildOptions& options = {});

}  // namespace terralod::pm
