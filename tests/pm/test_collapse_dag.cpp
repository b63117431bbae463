// The runtime's vertex hierarchy is the collapse DAG (collapse_dag.hpp): the PM paper's
// hierarchy of vsplits, with face-based dependencies. These tests check its hierarchy
// invariants - saturated errors, nested bounding volumes (boxes, and spheres as in Fig. 4)
// that hold the faces their collapse creates, fixed corners, border vertices on their border -
// on hand-made, generated (with holes and a non-square transform) and real terrain, through
// the independent checker of tests/support/dag_hierarchy_check.hpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "dag_hierarchy_check.hpp"
#include "mesh_checker.hpp"
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

// A DAG that skips the PM's first collapses (DagOptions::skip, what the runtime loads for a far
// block): its leaves are exactly the PM's mesh after them, its collapses the rest, every leaf
// face is within its leaf error by the independent checker, floor_error() stays within the
// floor asked for, and the hierarchy invariants hold (saturation counting the leaves removed).
void expect_partial_dags(const Heightfield& hf) {
  const ProgressiveMesh pm = ProgressiveMesh::build(hf);
  const std::vector<Collapse>& all = pm.collapses();
  std::vector<double> errors;
  for (const Collapse& c : all) errors.push_back(c.error);
  std::sort(errors.begin(), errors.end());
  const auto sorted_triangles = [](std::vector<std::array<std::uint32_t, 3>> t) {
    for (auto& x : t) std::rotate(x.begin(), std::min_element(x.begin(), x.end()), x.end());
    std::sort(t.begin(), t.end());
    return t;
  };
  for (double q : {0.0, 0.5, 0.9, 0.99, 1.0}) {
    const double floor_m =
        q == 0.0 ? -1.0 : errors[std::min(errors.size() - 1, std::size_t(q * errors.size()))];
    const std::size_t skip = CollapseDag::skip_for_floor(pm, floor_m);
    for (std::size_t i = 0; i < skip; ++i) ASSERT_LE(all[i].error, floor_m);
    if (skip < all.size()) {
      EXPECT_GT(all[skip].error, floor_m);
    }
    const CollapseDag dag(pm, {.volume = VolumeKind::Box, .skip = skip});
    const std::string label = "skip " + std::to_string(skip) + " of " + std::to_string(all.size());
    ASSERT_EQ(dag.skipped(), skip) << label;
    ASSERT_EQ(dag.collapse_count(), all.size() - skip) << label;
    for (std::uint32_t c = 0; c < dag.collapse_count(); ++c)
      ASSERT_TRUE(dag.collapse(c).u == all[skip + c].u && dag.collapse(c).w == all[skip + c].w) << label;
    // The leaves are the PM's mesh after `skip` collapses.
    const TriangleMesh after = pm.extract_after(skip);
    std::vector<std::array<std::uint32_t, 3>> want, leaves;
    for (const auto& t : after.triangles)
      want.push_back({after.vertices[t[0]], after.vertices[t[1]], after.vertices[t[2]]});
    for (std::uint32_t f : dag.full_faces()) leaves.push_back(dag.face(f));
    ASSERT_EQ(sorted_triangles(leaves), sorted_triangles(want)) << label;
    EXPECT_EQ(dag.full_vertex_count(), after.vertices.size()) << label;
    // Every leaf within its error; the floor within what was asked.
    double floor_seen = 0.0;
    for (std::uint32_t f : dag.full_faces()) {
      const auto& t = dag.face(f);
      const terralod::test::TriangleError e = terralod::test::triangle_error(hf, t[0], t[1], t[2]);
      ASSERT_LE(e.max(), dag.leaf_error(f) + 1e-9) << label << ", leaf " << f;
      floor_seen = std::max(floor_seen, dag.leaf_error(f));
    }
    EXPECT_EQ(dag.floor_error(), floor_seen) << label;
    if (skip == 0) {
      EXPECT_EQ(dag.floor_error(), 0.0);
    }
    EXPECT_LE(dag.floor_error(), std::max(0.0, floor_m)) << label;
    for (VolumeKind kind : {VolumeKind::Box, VolumeKind::Sphere})
      EXPECT_EQ(dag_hierarchy_violation(CollapseDag(pm, {.volume = kind, .skip = skip})), "") << label;
    // Fewer collapses, less memory.
    if (skip > all.size() / 2) {
      EXPECT_LT(dag.memory_bytes(), CollapseDag(pm).memory_bytes() * 3 / 4) << label;
    }
  }
}

TEST(CollapseDagPartial, LeavesAreThePmMeshAfterTheSkippedCollapses) {
  Heightfield hf = generated(97, 81, /*metres=*/false, /*seed=*/13);
  hf.transform = GridTransform::north_up(/*x0=*/500.0, /*y0=*/-300.0, /*dx=*/20.0, /*dy=*/30.0);
  expect_partial_dags(hf);
}

TEST(CollapseDagPartial, LeavesAroundHoles) {
  Heightfield hf = generated(81, 73, /*metres=*/true, /*seed=*/23);
  std::vector<std::uint8_t> mask(hf.size(), 1);
  for (int r = 20; r < 31; ++r)
    for (int c = 30; c < 37; ++c) mask[std::size_t(r) * hf.width() + c] = 0, hf.at(c, r) = 0.0;
  mask[std::size_t(50) * hf.width() + 10] = 0;
  hf.set_mask(std::move(mask));
  expect_partial_dags(hf);
}

}  // namespace
