// Independent checker of one drawn frame of a terrain runtime: the screen-space error of the
// displayed surface at every sample in view, coverage of the view, and cracks.
//
// Usage:
//   terralod::test::DrawnFrame f = terralod::test::drawn_frame(mesh.samples, positions_z, mesh.triangles, W);
//   terralod::test::FrameCheck c = terralod::test::check_drawn_frame(hf, f, camera);
//   EXPECT_LE(c.max_error_px, stats.bound_px * (1 + 1e-9) + 1e-9) << c.describe();
//   EXPECT_TRUE(c.watertight()) << c.describe();
//   EXPECT_EQ(c.uncovered_in_view, 0u) << c.describe();
//
// Independence: only plain data (sample ids, heights, triangles, the Heightfield and the
// Camera) and the GLM projector of screen_error_checker.hpp; nothing of the runtime.
//
// What is measured:
//   - error: for every valid sample whose true point (x, y, h) or displayed point is inside the
//     frustum (or whose vertical segment between them crosses it), the projected length of the
//     part inside the frustum of the vertical segment from the displayed surface (the first
//     non-degenerate triangle containing the sample in plan view, barycentric, long double) to
//     h. The displayed surface is piecewise linear and the terrain is the surface through the
//     samples, so this is the error at the samples (the metric of Samples).
//   - coverage: samples whose true point is inside the frustum but lie under no triangle.
//   - cracks: triangles with plan-view orientation <= 0; directed edges used twice; a vertex
//     strictly inside another edge (T-junction, exact integer test); one sample drawn at two
//     positions; boundary edges (used once) that are not on the terrain border and have an
//     endpoint whose true point is inside the frustum (a hole where terrain is in view: a
//     culled neighbour's box holds its border samples, so it would not have been culled);
//     boundary edges with an endpoint beside a hole (an invalid sample among its 8 neighbours)
//     are the terrain's own border there, not cracks.
// Cost: O(samples + triangles x their bounding boxes). Memory: 8 bytes per sample.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "screen_error_checker.hpp"
#include "terralod/pm/heightfield.hpp"

namespace terralod::test {

/// A drawn mesh as plain data: vertex v is terrain sample samples[v] at displayed height z[v].
struct DrawnFrame {
  std::vector<std::uint64_t> samples;
  std::vector<double> z;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

struct FrameCheck {
  double max_error_px = 0;  ///< largest projected error at a sample in view
  double max_error_m = 0;   ///< its vertical length
  int worst_col = -1, worst_row = -1;
  std::size_t samples_in_view = 0;    ///< samples whose true point is inside the frustum
  std::size_t uncovered_in_view = 0;  ///< of those, under no triangle
  std::size_t flipped = 0, doubled_edges = 0, t_junctions = 0, split_vertices = 0;
  std::size_t holes_in_view = 0;  ///< boundary edges inside the terrain with an endpoint in view
  std::size_t triangles = 0;
  bool watertight() const {
    return flipped == 0 && doubled_edges == 0 && t_junctions == 0 && split_vertices == 0 &&
           holes_in_view == 0;
  }
  std::string describe() const;
};

FrameCheck check_drawn_frame(const pm::Heightfield& hf, const DrawnFrame& frame, const pm::Camera& camera);

}  // namespace terralod::test
