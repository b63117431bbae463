// A test terrain ready for view-dependent refinement: its heightfield, the PM built from it and
// the collapse DAG over that PM, owned together so that the references between them stay valid.
//
// Usage:
//   const terralod::test::RefinableTerrain t(terralod::pm::generate_terrain(options));
//   terralod::pm::SelectiveRefinement sr(t.dag, refinement_options);
//
// Contract: the object must not be moved or copied once built (dag refers to pm, pm to hf's
// samples); keep it in place or behind a pointer. Cost: one ProgressiveMesh::build of h.
#pragma once

#include <utility>

#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::test {

struct RefinableTerrain {
  pm::Heightfield hf;
  pm::ProgressiveMesh pm;
  pm::CollapseDag dag;
  explicit RefinableTerrain(pm::Heightfield h, pm::VolumeKind kind = pm::VolumeKind::Box)
      : hf(std::move(h)), pm(pm::ProgressiveMesh::build(hf)), dag(pm, {kind}) {}
  RefinableTerrain(const RefinableTerrain&) = delete;
  RefinableTerrain& operator=(const RefinableTerrain&) = delete;
};

}  // namespace terralod::test
