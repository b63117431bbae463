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

#include <cstdint>
#include <map>
#include <memory>
#include <utility>

#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/heightfield.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "terralod/pm/terrain_generator.hpp"

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

/// The generated size x size terrain of `seed`, built once per process and shared by the tests.
inline const RefinableTerrain& generated_refinable(int size, std::uint64_t seed) {
  static std::map<std::pair<int, std::uint64_t>, std::unique_ptr<RefinableTerrain>> cache;
  auto& t = cache[{size, seed}];
  if (!t) {
    pm::TerrainOptions o;
    o.width = o.height = size;
    o.seed = seed;
    t = std::make_unique<RefinableTerrain>(pm::generate_terrain(o));
  }
  return *t;
}

}  // namespace terralod::test
