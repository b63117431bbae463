// DrawnMesh: the terrain mesh of one frame exactly as it is drawn (displayed heights, geomorphs
// included), the one form in which the runtime hands its result to a renderer, a checker or a
// file.
//
// Usage:
//   const terralod::blocks::DrawnMesh& m = runtime.drawn_mesh();
//   for (const auto& t : m.triangles) { /* m.positions[t[0]], ... */ }
//
// Contract: positions are world metres (x, y from BlockGrid::world of the vertex's sample, z
// the displayed height); samples[v] is the terrain sample (row * grid_width + col) of vertex v;
// a terrain sample is at most one vertex; triangles are CCW in (col,row) plan view, like every
// pm/ mesh (clockwise seen from +z for north-up transforms, whose determinant is negative);
// triangle_node[t] is the approximation-tree node triangle t was drawn for.
// Memory: 32 bytes per vertex, 20 per triangle.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "terralod/pm/memory_bytes.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::blocks {

struct DrawnMesh {
  std::vector<pm::Vec3> positions;                      ///< world metres, displayed heights
  std::vector<std::uint64_t> samples;                   ///< terrain sample of each vertex
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< CCW in (col,row)
  /// Per triangle: the approximation-tree node it was drawn for.
  std::vector<std::int64_t> triangle_node;

  std::size_t memory_bytes() const {
    return pm::capacity_bytes(positions) + pm::capacity_bytes(samples) + pm::capacity_bytes(triangles) +
           pm::capacity_bytes(triangle_node);
  }
};

}  // namespace terralod::blocks
