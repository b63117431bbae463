// Draped lines (issue 19: roads, rivers): the ribbon of a world-frame polyline lying on the
// terrain exactly as the runtime draws it this frame (terrain_runtime.hpp, geomorphs included),
// split where it crosses the drawn triangles' edges, as an ObjectMesh (object_mesh.hpp).
//
// Usage:
//   namespace tb = terralod::blocks;
//   rt.update(view, t);                                        // then, the same frame:
//   tb::ObjectMesh roads;
//   tb::drape_line(rt, points, /*width_m=*/8.0, /*object=*/k, roads);     // appends one ribbon
//   std::vector<tb::DrapedLine> lines = {{points, 8.0, k}, {river, 20.0, k + 1}};
//   const tb::DrapeStats s = tb::drape_lines(rt, lines, roads);           // appends many
//   draw(roads);   // with polygon offset: the ribbon is coplanar with the terrain
//
// Method: the ribbon's plan shape is the union of convex pieces: one rectangle per segment
// (the segment widened by width_m / 2 to each side) and, at each interior vertex where the
// line turns, a round join: the circular sector (radius width_m / 2, centred on the vertex)
// between the two rectangles' ends on the outer side of the turn, as a convex polygon of arc
// points at most 22.5 degrees apart (so the outline is the polyline's buffer with round joins
// and butt ends, up to the arcs' chords). Each piece is clipped (Sutherland-Hodgman, in plan)
// against every drawn triangle it overlaps, found with TerrainRuntime::drawn_triangles_in over
// the box of its segment (rectangle and join); each non-empty clip is fanned into triangles whose vertices
// are lifted onto that drawn triangle's plane (barycentric on its three world positions).
//
// Contract:
//   rt         after rt.update() of a frame: the ribbon lies on rt.drawn_mesh() of that frame.
//              Parts of the line over nothing drawn (outside the terrain, culled) are dropped.
//   line       world frame (the terrain's, like DrawnMesh), metres, finite (assert). Zero-length
//              segments (repeated points) are skipped; a line with fewer than two distinct
//              points gives nothing.
//   width_m    the ribbon's full width in plan (measured horizontally, not along the slope),
//              metres, finite and > 0 (assert).
//   object     written to out.triangle_object for every triangle of this ribbon.
//   out        appended to (never cleared). Every new vertex lies ON a drawn triangle (no z
//              offset: depth fighting with the terrain is the renderer's business, e.g. polygon
//              offset); every new triangle lies within one drawn triangle in plan, so it is in
//              that triangle's plane, and pieces of neighbouring drawn triangles meet along
//              their shared edge (both planes agree there): no gap, no fold. Triangles are CCW
//              seen from above (+z) in the world frame; normals are the drawn triangle's unit
//              normal, facing up (out.normals must be as long as out.positions before the call).
//              Pieces overlap at the inside of turns (the same surface: the overlap is hidden)
//              and vertices are not shared between pieces.
//   thread     const on rt; the first call of a frame builds drawn_height's index (the same rule
//              as drawn_height: no concurrent first calls).
// Cost: per segment, one drawn_triangles_in() over the box of its rectangle and join, plus one
// clip (3 half-planes) per piece and returned triangle whose boxes meet: O(pieces x drawn
// triangles under each segment's box), never O(all drawn triangles) per line. Memory: the output
// (object_mesh.hpp), plus a scratch of the triangle ids and polygons of one piece.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "terralod/blocks/object_layers.hpp"
#include "terralod/blocks/object_mesh.hpp"
#include "terralod/blocks/terrain_runtime.hpp"

namespace terralod::blocks {

/// One line of a batch: its points (the caller's, borrowed for the call), width and object.
struct DrapedLine {
  std::span<const WorldPoint> points;  ///< world frame, metres
  double width_m = 1.0;                ///< full width in plan, metres, > 0
  std::uint32_t object = 0;            ///< written to ObjectMesh::triangle_object
};

/// What a drape call did.
struct DrapeStats {
  std::size_t pieces = 0;                  ///< segment rectangles and joins built
  std::size_t drawn_triangles_tested = 0;  ///< clips tried (triangles returned by the index)
  std::size_t clips = 0;                   ///< non-empty clips (pieces x drawn triangles)
  std::size_t triangles = 0;               ///< triangles appended to the output
};

/// Appends the ribbon of `line` (width `width_m`, object `object`) on rt's drawn mesh to `out`.
DrapeStats drape_line(const TerrainRuntime& rt, std::span<const WorldPoint> line, double width_m,
                      std::uint32_t object, ObjectMesh& out);

/// Appends the ribbons of `lines`, in order, to `out` (one scratch for all of them).
DrapeStats drape_lines(const TerrainRuntime& rt, std::span<const DrapedLine> lines, ObjectMesh& out);

}  // namespace terralod::blocks
