// Draws the map objects placed this frame (issue 19) into the terrain's frame, for the flight
// tools and `terralod view`: each object as its layer's rules chose (PlacedObject::draw):
//   icon    the layer's icon image (rules icon_image, else the built-in pin) with its quads and
//           icon_size_m, standing on the drawn anchor;
//   label   the object's name at label_size_px above the anchor; all candidates of the frame
//           are decluttered first (blocks::LabelDeclutterer over the exact rectangles the
//           renderer draws: none overlap, higher priority wins, no flicker);
//   line    a line feature, or a polygon's rings (closed), draped on the drawn terrain
//           (object_drape.hpp) as a ribbon of line_width_m;
//   shape   a polygon extruded from the drawn terrain (object_shapes.hpp; a line feature is drawn
//           as its ribbon);
//   symbol  not drawn here: a 2D symbol lives in a thematic texture layer made from the object
//           layer ('terralod texture symbols'), drawn with the terrain's texture layers.
//
// Usage:
//   cli::ObjectDrawing drawing(ctx, placer);            // icon styles, the label font
//   placer.place(rt, view);                             // after rt.update()
//   pipeline.frame(...);                                // the terrain first
//   const cli::ObjectDrawStats s = drawing.draw(frame_source, placer, rt, view);
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "terralod/blocks/label_declutter.hpp"
#include "terralod/blocks/object_mesh.hpp"
#include "terralod/blocks/object_placement.hpp"
#include "terralod/blocks/object_shapes.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/render/object_renderer.hpp"

namespace terralod::cli {

struct ObjectDrawStats {
  std::size_t icons = 0, labels_shown = 0, label_candidates = 0, line_triangles = 0, shape_triangles = 0;
  double cpu_ms = 0.0;  ///< thread CPU of building the frame's instances and meshes
};

/// One HUD line: what the last draw() drew; with `timings`, its CPU time.
std::string drawn_line(const ObjectDrawStats& s, bool timings);

class ObjectDrawing {
 public:
  /// Loads every layer's icon image (std::runtime_error naming an unreadable file) and the font,
  /// and plans the polygons' footprints. `placer` must outlive this and be the one draw() gets.
  ObjectDrawing(render::GlContext& ctx, const blocks::ObjectPlacer& placer);
  ObjectDrawStats draw(render::FrameSource& frame, const blocks::ObjectPlacer& placer,
                       const blocks::TerrainRuntime& rt, const pm::View& view);

 private:
  render::ObjectRenderer renderer_;
  std::vector<render::IconStyleId> icon_style_;  // per layer
  std::unique_ptr<blocks::LabelDeclutterer> declutter_;
  int declutter_w_ = 0, declutter_h_ = 0;
  std::vector<render::IconInstance> icons_;
  std::vector<blocks::LabelCandidate> candidates_;
  std::vector<render::LabelInstance> labels_;
  blocks::ShapeExtruder shapes_;
  std::vector<blocks::PlacedObject> shape_objects_;
  std::vector<blocks::WorldPoint> ring_;  // a polygon ring, closed
  blocks::ObjectMesh lines_, shapes_mesh_;
};

}  // namespace terralod::cli
