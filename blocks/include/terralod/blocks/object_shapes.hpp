// Extruded shapes (issue 19, part 2): polygon footprints of an object layer (e.g. buildings)
// extruded by a height attribute into closed meshes that stand on the terrain as drawn this
// frame (geomorphs included) without ever floating above it.
//
// Usage:
//   namespace tb = terralod::blocks;
//   tb::ObjectPlacer objects(db, {"buildings"});
//   tb::ShapeExtruder shapes(objects);              // plans every polygon's roof once
//   tb::ObjectMesh mesh;                            // kept across frames: no reallocation
//   ... rt.update(view, t);                         // then, the same frame:
//   shapes.extrude(rt, objects.place(rt, view), mesh);   // or only the placed objects whose
//   draw(mesh);                                          // rules chose Representation::Shape
//   // mesh.triangle_object[t]: index into objects.objects(); shapes.stats(): what was skipped
//
//   tb::ShapeFootprint f = tb::plan_footprint(feature.rings);   // the plan alone (roof triangles)
//
// Footprint plan (plan_footprint; once per feature, at construction of a ShapeExtruder):
//   rings      the exterior ring, then holes (ObjectFeature::rings), world metres, finite. Either
//              orientation (rings are normalised: exterior counter-clockwise seen from +z, holes
//              clockwise, so the solid is left of every edge); a closing vertex equal to the
//              first and repeated consecutive vertices are dropped; collinear vertices are kept
//              (every ring vertex is a roof vertex, so walls and roof share their edges).
//   exactness  orientation and intersection tests are exact (64/128-bit integers) on the
//              vertices snapped to a grid of (largest side of the exterior ring's box) / 2^30
//              relative to that box (under 1 micrometre for a 1 km footprint): features finer
//              than that grid may merge. Output coordinates are the input's, never snapped.
//   roof       ear clipping after bridging each hole to the outer boundary (D. Eberly,
//              "Triangulation by Ear Clipping", Geometric Tools 2002-2015, sections 2-5: holes
//              in decreasing order of their largest x, each bridged from that vertex to the
//              nearest mutually visible boundary vertex). Triangles index `points`, are
//              counter-clockwise seen from +z, cover the polygon exactly once (their areas sum
//              to the polygon's), and use every vertex: points.size() + 2 holes - 2 of them.
//              Counter-clockwise on the grid: three input vertices collinear within it may
//              make a sliver whose area in the input coordinates has either sign, below
//              grid x perimeter.
//   degenerate a ring with under 3 distinct vertices or zero area: as an exterior ring, the plan
//              is empty (status Degenerate: no roof, no error); as a hole, the hole is dropped.
//              No rings, or a coordinate that is not finite: Degenerate too.
//   not simple a hole vertex outside the exterior ring's box, no bridge or no ear left, or ears
//              that do not cover the polygon's area exactly with the count above: the plan is
//              empty with status NotSimple. Self-crossing rings are not searched for; they
//              usually end so. Bad data is counted (ShapePlanStats), never thrown.
//   cost       O(n^2) to O(n^3) for n vertices (every ear test scans the remaining vertices),
//              once per feature: milliseconds for a few hundred vertices.
//
// Extrusion (ShapeExtruder::extrude; every frame):
//   placed     the objects placed this frame by the ObjectPlacer given at construction
//              (asserted: each PlacedObject points into its objects()); the caller picks which
//              (e.g. by the layers' rules). Objects that are not polygons are passed over
//              (stats().not_polygons); so are empty plans (stats().empty_plans).
//   ground     footprints over nothing drawn (rt.drawn_height NaN at some footprint vertex) are
//              skipped (stats().skipped_undrawn). Otherwise let B be the footprint's world box
//              and S the set of heights of the drawn surface at the vertices of each drawn
//              triangle of rt.drawn_triangles_in(B) clipped to B (the triangle's plane there),
//              plus rt.drawn_height at the footprint's vertices. The drawn surface is piecewise
//              linear, so its minimum and maximum over B are in S; the footprint lies in B.
//              (Clipped, not the triangles' own vertices: a coarse triangle reaching far past
//              the footprint would otherwise add the relief of the whole triangle.)
//              base = min S: at or below the drawn surface everywhere under the footprint
//                     (the building never floats, whatever the level of detail or geomorph).
//              roof = max S + height: `height` is measured from the highest drawn ground
//                     under the footprint's box, so the roof is at least `height` above the
//                     drawn ground everywhere under the footprint.
//   height     the value of the layer's height_field (ObjectLayerInfo::height_field), read by
//              priority_value (object_rules.hpp), when it is a finite number > 0; otherwise
//              (no height_field, attribute missing, null, not a number, <= 0) the default
//              ObjectShapeOptions::default_height_m, and the feature is counted in
//              plan_stats().default_heights.
//   mesh       `out` is cleared, then holds one closed solid per extruded shape: per ring edge
//              a wall quad (4 vertices, 2 triangles) from base to roof, the roof triangles at
//              the roof and the same triangles reversed at the base (the floor, hidden in the
//              ground). Vertices are split at creases (flat normals): the solid is closed by
//              position (every edge between two positions is used by exactly two triangles, in
//              opposite directions), triangles are counter-clockwise seen from outside, normals
//              unit and outward (walls horizontal, roof +z, floor -z; walls of holes face the
//              courtyard). Its volume is the footprint's area x (roof - base).
//              triangle_object[t] is the index of the triangle's object in placer.objects().
//   cost       O(footprint vertices + drawn triangles under its box) per shape; no allocation
//              once `out` and the extruder's buffers have grown to a frame's size.
// Memory: per polygon object its plan: 16 bytes per vertex plus 12 per roof triangle; per frame
// the mesh: 48 bytes per vertex (4 per wall edge, 2 per roof vertex) and 20 per triangle.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "terralod/blocks/object_layers.hpp"
#include "terralod/blocks/object_mesh.hpp"
#include "terralod/blocks/object_placement.hpp"
#include "terralod/blocks/terrain_runtime.hpp"

namespace terralod::blocks {

struct ObjectShapeOptions {
  /// Height (metres, finite, > 0) of shapes without a valid height attribute.
  double default_height_m = 10.0;
};

/// A footprint planned once: normalised rings and the roof's triangles.
struct ShapeFootprint {
  enum class Status : std::uint8_t { Ok, Degenerate, NotSimple };
  Status status = Status::Degenerate;
  /// Ring r's vertices: points[ring_start[r] .. ring_start[r + 1]); ring 0 the exterior
  /// (counter-clockwise from +z), then holes (clockwise); the solid is left of every edge.
  std::vector<WorldPoint> points;
  std::vector<std::uint32_t> ring_start;
  std::vector<std::array<std::uint32_t, 3>> roof;  ///< into points, CCW from +z
  double area = 0.0;                               ///< m^2: exterior minus holes
  WorldPoint min, max;                             ///< world box of the exterior ring
  bool empty() const { return roof.empty(); }
};

/// Plans a polygon's footprint (see "Footprint plan" above); never throws for bad geometry.
ShapeFootprint plan_footprint(const std::vector<std::vector<WorldPoint>>& rings);

/// What the constructor planned.
struct ShapePlanStats {
  std::size_t polygons = 0;         ///< polygon objects of the placer
  std::size_t degenerate = 0;       ///< of those, zero area (empty plan)
  std::size_t not_simple = 0;       ///< of those, not triangulable (empty plan)
  std::size_t default_heights = 0;  ///< of those, without a valid height attribute
  double plan_ms = 0.0;
};

/// What the last extrude() did.
struct ShapeFrameStats {
  std::size_t shapes = 0;           ///< solids written to the mesh
  std::size_t skipped_undrawn = 0;  ///< footprints with a vertex over nothing drawn
  std::size_t empty_plans = 0;      ///< degenerate or not simple footprints
  std::size_t not_polygons = 0;     ///< placed objects that are points or lines
  std::size_t drawn_triangles = 0;  ///< drawn triangles examined, all shapes together
  double extrude_ms = 0.0;
};

class ShapeExtruder {
 public:
  /// Plans every polygon object of `placer` (kept by reference: it must outlive this).
  /// std::invalid_argument when options.default_height_m is not finite and > 0.
  explicit ShapeExtruder(const ObjectPlacer& placer, const ObjectShapeOptions& options = {});

  /// Writes the solids of the polygon objects among `placed` into `out` (see "Extrusion").
  /// Call after rt.update() of the frame the objects were placed in.
  void extrude(const TerrainRuntime& rt, std::span<const PlacedObject> placed, ObjectMesh& out);

  /// The plan of object i of placer.objects() (empty for points and lines).
  const ShapeFootprint& footprint(std::size_t i) const { return plans_.at(i); }
  /// The extrusion height of object i (metres; see "height").
  double height(std::size_t i) const { return heights_.at(i); }
  const ShapePlanStats& plan_stats() const { return plan_stats_; }
  const ShapeFrameStats& stats() const { return stats_; }

 private:
  const ObjectPlacer& placer_;
  std::vector<ShapeFootprint> plans_;  // per object of placer_
  std::vector<double> heights_;        // per object of placer_
  ShapePlanStats plan_stats_;
  ShapeFrameStats stats_;
  std::vector<std::uint32_t> tris_;  // drawn_triangles_in's output, reused
};

}  // namespace terralod::blocks
