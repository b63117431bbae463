// Map objects on the terrain as drawn (issue 19, parts 4 and 5): the objects of some object
// layers (object_layers.hpp) anchored every frame at the height of the mesh the runtime draws
// (terrain_runtime.hpp, geomorphs included), culled by the view frustum through a uniform grid,
// switched on and off by layer, and picked by a ray (nearest object, else the drawn ground).
//
// Usage:
//   namespace tb = terralod::blocks;
//   const auto db = tb::BlockDatabase::open("terrain.db");
//   tb::ObjectPlacer objects(db, {"peaks", "huts"});          // reads the layers once
//   tb::TerrainRuntime rt("terrain.db");
//   ... rt.update(view, t);                                    // then, the same frame:
//   for (const tb::PlacedObject& p : objects.place(rt, view))  // the objects in view and
//     if (p.draw == tb::Representation::Icon)                  // within their rules
//       draw_icon(p.object->name, p.anchor);                   // anchor.z: the drawn height
//   objects.set_layer_visible("huts", false);                  // from the next place()
//   if (auto hit = objects.pick_pixel(rt, 640, 360))           // after place(), same frame
//     hit->object ? show(hit->object->feature.attributes) : show(hit->point);
//
// Contract:
//   layers     names of object layers of `db`, each at most once (std::invalid_argument for a
//              repeat); a missing layer is the DatabaseError "<db>: ..." of object_features().
//              Every feature of a layer is one MapObject, in the order (layer, feature id).
//   anchor     the plan point an object stands on (world frame, metres, never moved):
//              a point: the point; a line: the point halfway along it (by length; its first
//              vertex when its length is 0); a polygon: the area centroid of its exterior ring
//              minus its holes (it may lie outside a concave polygon), or the mean of the
//              exterior ring's vertices when that area is 0.
//   name       the value of the layer's label field when it has one, else of the attribute
//              "name"; when that is missing or empty, the feature id in decimal, and `named` is
//              false: such an object gets no label where its rules draw a label (a layer of
//              peaks, some unnamed, labels the named ones), and is still picked by its id.
//   rules      each layer's design rules (object_rules.hpp): its stored rules file, else the
//              default rule (everything drawn as the layer's kind). An object's extent is
//              icon_size_m for a point, else the larger side of its features' plan box (at least
//              1 mm); its size on screen at distance d is extent * view.focal_px() / d; its
//              priority is the rules' priority field (priority_value; 0 without one).
//   place      after rt.update() of a frame, with that frame's view: every object of a visible
//              layer whose anchor the runtime draws (rt.drawn_height(x, y) is not NaN: objects
//              over nothing drawn, e.g. outside the terrain, are skipped), whose anchor at that
//              height lies in the view's closed frustum (pm::View::contains), and whose rules
//              draw it at its distance d (draw = rules.choose(d, size on screen) is not None):
//              d = |G' (anchor - eye)|, the distance as the view's camera sees it through its
//              ground scale (pm/view.hpp; TerrainRuntime::fit_camera sets it), which is ground
//              metres on a continent-wide frame, not the frame's metres. anchor.z is that drawn
//              height, so objects never float or sink as the level of detail changes.
//              Order: by grid cell (in the order the quadrant traversal below visits them), then
//              layer, then feature id: the same input gives the same order.
//   cost       place(): grid cells are culled by quadrants against the frustum and against the
//              farthest distance any visible layer's rules draw at (ObjectRules::
//              max_drawn_distance, with the layer's largest extent): a cell's box is its plan
//              rectangle x the terrain's height range, which holds every drawn height. Objects of
//              culled cells, of hidden layers, of layers whose rules end nearer than the cell, and
//              objects whose plan distance alone puts them beyond their layer's rules are not
//              touched (beyond their rules they cost nothing). An object tested costs one
//              drawn_height() (one bucket of the drawn mesh), one frustum test and one choose().
//              pick(): O(objects placed + drawn triangles) (one exact ray test per triangle).
//   pick       a ray from `origin` along `direction` (non-zero; normalised here) against the
//              objects of the last place() and the drawn mesh of the same frame (asserted: same
//              runtime frame). An object is a sphere around its drawn anchor whose radius is
//              pick_radius_px pixels at the anchor's depth in the last view (a disc of that
//              many pixels on screen). The nearest object hit (smallest distance along the ray
//              to the point nearest its anchor) wins, unless the ray meets the drawn terrain
//              more than that radius before it (hidden behind a hill); otherwise the first
//              point where the ray meets a drawn triangle (edges included); otherwise nullopt.
// Memory: every feature of the layers with its attributes (object_layers.hpp), plus 20 bytes
// per object and 4 per grid cell per layer for the grid, and the placed objects of a frame
// (memory_bytes(); 100,000 points with two attributes: about 450 bytes each, measured by
// terralod-bench-objects).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/object_layers.hpp"
#include "terralod/blocks/object_rules.hpp"
#include "terralod/blocks/terrain_runtime.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::blocks {

struct PlacementOptions {
  /// Radius of an object for picking, pixels on screen at its anchor's depth, > 0.
  double pick_radius_px = 8.0;
};

/// One object of a layer: its feature and what placement derives from it once.
struct MapObject {
  std::size_t layer = 0;  ///< index into ObjectPlacer::layers()
  ObjectKind kind = ObjectKind::Icon;
  std::string name;       ///< see the contract
  bool named = false;     ///< the name is the feature's (false: its id; no label is drawn)
  WorldPoint anchor;      ///< plan point, world frame (see the contract)
  double extent_m = 0;    ///< size for screen-size rules, metres (see the contract)
  double priority = 0;    ///< for decluttering labels (see the contract)
  ObjectFeature feature;  ///< as stored: id, geometry, attributes
};

/// An object in view this frame.
struct PlacedObject {
  const MapObject* object = nullptr;           ///< owned by the placer
  pm::Vec3 anchor;                             ///< x, y: object->anchor; z: the drawn height there
  Representation draw = Representation::None;  ///< what its layer's rules draw it as (never None)
  double distance = 0.0;                       ///< |G' (anchor - eye)|, metres as seen (see place)
};

/// What the last place() did.
struct PlacementStats {
  std::size_t cells_visited = 0;   ///< grid cells not culled (their objects were tested)
  std::size_t regions_culled = 0;  ///< quadrants of cells outside the frustum
  std::size_t objects_tested = 0;  ///< objects of visible layers in the visited cells
  std::size_t beyond_rules = 0;    ///< of those, dropped because their rules draw nothing there
  std::size_t objects_placed = 0;  ///< of those, drawn, in the frustum and drawn by their rules
  double place_ms = 0.0;           ///< wall time of place()
};

struct PickResult {
  const MapObject* object = nullptr;  ///< the object hit; nullptr: the ground
  pm::Vec3 point;                     ///< the object's drawn anchor, or the ground point
  double distance = 0.0;              ///< metres along the ray (to the point nearest the anchor)
};

class ObjectPlacer {
 public:
  /// Reads `layer_names` of `db` (see the contract); every layer starts visible.
  ObjectPlacer(const BlockDatabase& db, const std::vector<std::string>& layer_names,
               const PlacementOptions& options = {});

  const std::vector<ObjectLayerInfo>& layers() const { return layers_; }
  /// The design rules of layer `layer` (an index into layers()), see the contract.
  const ObjectRules& rules(std::size_t layer) const { return rules_.at(layer); }
  const std::vector<MapObject>& objects() const { return objects_; }
  /// Shows or hides a layer from the next place(); std::invalid_argument for a layer not read.
  void set_layer_visible(const std::string& layer, bool visible);
  bool layer_visible(const std::string& layer) const;

  /// The objects in view this frame (see the contract); valid until the next place().
  const std::vector<PlacedObject>& place(const TerrainRuntime& rt, const pm::View& view);
  const std::vector<PlacedObject>& placed() const { return placed_; }
  const PlacementStats& stats() const { return stats_; }
  /// Bytes held: the objects with their features (geometry, attributes, names; heap strings
  /// counted by capacity), the grid and the last frame's placed objects.
  std::size_t memory_bytes() const;

  /// Picks along a ray (see the contract); call after place() in the same frame.
  std::optional<PickResult> pick(const TerrainRuntime& rt, const pm::Vec3& origin,
                                 const pm::Vec3& direction) const;
  /// Picks along the ray from the last view's eye through image point (px, py) (pixels, the
  /// conventions of pm/view.hpp: (0, 0) the top-left corner, y down).
  std::optional<PickResult> pick_pixel(const TerrainRuntime& rt, double px, double py) const;

 private:
  std::size_t layer_index(const std::string& layer) const;
  void visit(const TerrainRuntime& rt, const pm::View& view, int i0, int j0, int i1, int j1, double zlo,
             double zhi);
  void place_cell(const TerrainRuntime& rt, const pm::View& view, std::size_t cell, double cell_distance);

  PlacementOptions opt_;
  std::vector<ObjectLayerInfo> layers_;
  std::vector<bool> visible_;
  std::vector<ObjectRules> rules_;  // per layer
  std::vector<double> max_extent_;  // per layer: the largest extent_m of its objects
  std::vector<double> reach_;       // per layer, this frame: max_drawn_distance (-inf: hidden)
  double max_reach_ = 0;            // this frame: the largest reach_
  std::vector<MapObject> objects_;
  // The grid over the anchors' plan box: nx x ny cells; cell (i, j) of layer l holds the objects
  // items_[l][start_[l][j nx + i] .. start_[l][j nx + i + 1]) (indices into objects_).
  int nx_ = 1, ny_ = 1;
  double x0_ = 0, y0_ = 0, cell_w_ = 1, cell_h_ = 1;
  std::vector<std::vector<std::uint32_t>> start_;
  std::vector<std::vector<std::uint32_t>> items_;
  std::vector<std::vector<WorldPoint>> item_anchors_;  // the anchors of items_, in its order
  std::vector<PlacedObject> placed_;
  PlacementStats stats_;
  std::optional<pm::View> view_;  // of the last place()
  std::uint64_t frame_ = 0;       // the runtime frame of the last place()
};

}  // namespace terralod::blocks
