// ObjectMesh: the triangles of map objects that have a surface (issue 19: draped lines, extruded
// shapes), the one form in which the object builders hand geometry to a renderer, a checker or
// a file.
//
// Usage:
//   terralod::blocks::ObjectMesh m;                  // filled by a builder, e.g. a draped line
//   for (const auto& t : m.triangles) { /* m.positions[t[0]], ... */ }
//   m.append(other);                                 // one mesh for a whole layer
//
// Contract: positions are world metres (the terrain's world frame, like DrawnMesh); normals[v]
// is the unit normal of vertex v (empty when the builder makes none: a renderer then shades
// flat); triangles are counter-clockwise seen from outside the solid (from above, +z, for
// surfaces on the ground); triangle_object[t] is the index (the builder's, e.g. into
// ObjectPlacer::objects()) of the object triangle t belongs to.
// Memory: 48 bytes per vertex (24 without normals), 20 per triangle.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "terralod/pm/view.hpp"

namespace terralod::blocks {

struct ObjectMesh {
  std::vector<pm::Vec3> positions;                      ///< world metres
  std::vector<pm::Vec3> normals;                        ///< unit, per vertex, or empty
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< CCW seen from outside / above
  std::vector<std::uint32_t> triangle_object;           ///< per triangle: its object

  bool empty() const { return triangles.empty(); }
  void clear() {
    positions.clear();
    normals.clear();
    triangles.clear();
    triangle_object.clear();
  }
  /// Appends `m`'s vertices and triangles (indices shifted). Both have normals or neither does.
  void append(const ObjectMesh& m) {
    const auto base = static_cast<std::uint32_t>(positions.size());
    positions.insert(positions.end(), m.positions.begin(), m.positions.end());
    normals.insert(normals.end(), m.normals.begin(), m.normals.end());
    for (const auto& t : m.triangles) triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
    triangle_object.insert(triangle_object.end(), m.triangle_object.begin(), m.triangle_object.end());
  }
  std::size_t memory_bytes() const {
    return positions.capacity() * sizeof(pm::Vec3) + normals.capacity() * sizeof(pm::Vec3) +
           triangles.capacity() * 12 + triangle_object.capacity() * 4;
  }
};

}  // namespace terralod::blocks
