// The runtime's vertex hierarchy is the collapse DAG (collapse_dag.hpp): the PM paper's
// hierarchy of vsplits, with face-based dependencies. These tests check its hierarchy
// invariants - saturated errors, nested bounding volumes (boxes, and spheres as in Fig. 4)
// that hold the faces their collapse creates, fixed corners, border vertices on their border -
// on hand-made, generated (with holes and a non-square transform) and real terrain, through
// the independent checker of tests/support/dag_hierarchy_check.hpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "dag_hierarchy_check.hpp"
#include "screen_error_checker.hpp"
#include "terralod/pm/collapse_dag.hpp"
#include "terralod/pm/terrain_generator.hpp"

namespace {

using namespace terralod::pm;
using terralod::test::dag_hierarchy_violation;

Heightfield generated(int w, int h, bool metres, std::uint64_t seed = 5) {
  return generate_terrain({.width = w, .height = h, .seed = seed, .quantize_to_metres = metres});
}

void expect_hierarchy(const ProgressiveMesh& pm, const char* label) {
  for (VolumeKind kind : {VolumeKind::Box, VolumeKind::Sphere}) {
    const CollapseDag dag(pm, {kind});
    EXPECT_EQ(dag_hierarchy_violation(dag), "")
        << label << (kind == VolumeKind::Box ? " (boxes)" : " (spheres)");
  }
}

TEST(CollapseDagHierarchy, SaturatesNonMonotoneErrors) {
  // Collapse errors need not increase along the sequence. On a flat 3 x 3 grid, c0 = s4 -> s0
  // (error 5) changes the faces around s1 that c1 = s1 -> s0 (error 2) removes, so c1 depends
  // on c0 and its saturated error is 5.
  const Heightfield hf(3, 3);
  const ProgressiveMesh pm = ProgressiveMesh::from_parts(hf, ErrorMetric::Continuous, 1.0,
                                                         {Collapse{4, 0, 5.0}, Collapse{1, 0, 2.0}}, {});
  const CollapseDag dag(pm);
  ASSERT_EQ(dag.collapse_count(), 2u);
  ASSERT_EQ(std::vector<std::uint32_t>(dag.preds(1).begin(), dag.preds(1).end()),
            std::vector<std::uint32_t>{0});
  EXPECT_EQ(dag.saturated_error(0), 5.0);
  EXPECT_EQ(dag.saturated_error(1), 5.0);
  expect_hierarchy(pm, "3x3 non-monotone");
}

TEST(CollapseDagHierarchy, CheckerCatchesABorderVertexLeavingItsRow) {
  // s1 (column 1 of row 0) collapsing onto the centre s4 replays (no face flips) but leaves
  // the grid's border: the DAG is built, and the independent check must reject it.
  Heightfield hf(3, 3);
  hf.at(1, 1) = 3.0;
  const ProgressiveMesh pm =
      ProgressiveMesh::from_parts(hf, ErrorMetric::Continuous, 1.0, {Collapse{1, 4, 1.0}}, {});
  const CollapseDag dag(pm);
  EXPECT_NE(dag_hierarchy_violation(dag).find("leaves its row"), std::string::npos);
}

TEST(CollapseDagHierarchy, GeneratedTerrains) {
  for (bool metres : {false, true}) {
    expect_hierarchy(ProgressiveMesh::build(generated(65, 65, metres)), metres ? "65x65 metres" : "65x65");
    expect_hierarchy(ProgressiveMesh::build(generated(129, 97, metres, /*seed=*/9)),
                     metres ? "129x97 metres" : "129x97");
  }
}

TEST(CollapseDagHierarchy, GeneratedTerrainWithHoles) {
  Heightfield hf = generated(97, 81, /*metres=*/true, /*seed=*/21);
  std::vector<std::uint8_t> mask(hf.size(), 1);
  const int W = hf.width(), H = hf.height();
  auto block = [&](int c0, int r0, int w, int h) {
    for (int r = r0; r < r0 + h; ++r)
      for (int c = c0; c < c0 + w; ++c) {
        mask[std::size_t(r) * W + c] = 0;
        hf.at(c, r) = 0.0;
      }
  };
  block(W / 4, H / 4, 5, 4);
  block(W / 2, H / 2, 3, 6);
  block(2 * W / 3, H / 6, 1, 1);
  hf.set_mask(std::move(mask));
  hf.transform = GridTransform::north_up(/*x0=*/1000.0, /*y0=*/2000.0, /*dx=*/30.0, /*dy=*/45.0);
  const ProgressiveMesh pm = ProgressiveMesh::build(hf);
  expect_hierarchy(pm, "97x81 with holes");
  const CollapseDag dag(pm);
  std::size_t hole_samples_removed = 0;
  for (std::uint32_t s = 0; s < hf.size(); ++s)
    if (!hf.valid(s)) hole_samples_removed += dag.removed_by(s) != CollapseDag::kNone;
  EXPECT_EQ(hole_samples_removed, 0u);
}

TEST(CollapseDagHierarchy, RealTileCrop) {
  const auto crop = terralod::test::read_hgt_crop("N44W072.hgt", 760, 800, 129);
  if (!crop) GTEST_SKIP() << "N44W072.hgt not found in " << TERRALOD_DATA_DIR;
  const ProgressiveMesh pm = ProgressiveMesh::build(*crop);
  expect_hierarchy(pm, "N44W072 129x129 crop");
  const CollapseDag dag(pm);
  std::size_t roots = 0;  // collapses no other depends on: the DAG's top
  for (std::uint32_t c = 0; c < dag.collapse_count(); ++c) roots += dag.succs(c).empty();
  std::printf("N44W072 129x129 crop: %zu collapses, %zu without successors, max saturated error %.3f m\n",
              dag.collapse_count(), roots, pm.max_error());
}

}  // namespace
